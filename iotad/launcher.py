"""The launcher: runs a checked system as one process per node around a zenoh hub, supervises
them, reports what happens, and stops everything it started.

One thread (the caller's, normally the main thread) owns every child: it spawns them (so the
parent-death signal of `iotad.supervisor` stays armed for as long as the launcher lives), decides
restarts and stops them. zenoh callbacks and process waiters only put events on its queue (or
stamp a heartbeat time). A node's death is seen three ways: its process exits (waiter thread),
its liveliness token goes away (zenoh), or its heartbeat goes stale while the process still runs
(a frozen Python loop): then it is killed and restarted like a crash.
"""
from __future__ import annotations

import json
import os
import queue
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from importlib.util import find_spec
from pathlib import Path
from typing import Any, Callable

from . import wire
from .supervisor import FAILED_TO_START, Child, RestartPolicy, describe_exit, stop_all
from .system import NodeSpec, Port, System, with_port

ALIVE = "@alive"
HEARTBEAT = "@heartbeat"
ORIGIN = "@origin"


@dataclass
class NodeRun:
    """What the launcher knows of one node it runs."""

    spec: NodeSpec
    child: Child
    policy: RestartPolicy
    state: str = "waiting"        # waiting starting running lost backoff stopping stopped exited failed
    restarts: int = 0
    consecutive: int = 0          # restarts since it last ran healthy_after seconds
    restart_at: float | None = None
    live_since: float | None = None
    lost_since: float | None = None
    last_beat: float | None = None
    killed_for: str | None = None  # why the launcher killed it (stale heartbeat...), reported on exit
    last_code: int | None = None

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def finished(self) -> bool:
        return self.state in ("stopped", "exited", "failed")


@dataclass
class Tally:
    """What crossed the system's keys while it ran: for the summary at the end."""

    values: dict[str, Counter] = field(default_factory=dict)      # channel key -> Counter of values
    violations: Counter = field(default_factory=Counter)           # node path -> count
    examples: list[str] = field(default_factory=list)              # first violation messages
    lock: threading.Lock = field(default_factory=threading.Lock)

    def channel(self, key: str, value: Any) -> None:
        label = value if isinstance(value, (str, bool, int)) and not isinstance(value, float) else "*"
        with self.lock:
            self.values.setdefault(key, Counter())[label] += 1

    def trace(self, path: str, event: Any) -> None:
        if isinstance(event, dict) and event.get("kind") == "violation":
            with self.lock:
                self.violations[path] += 1
                if len(self.examples) < 5:
                    value = event.get("value") or {}
                    message = value.get("message") if isinstance(value, dict) else value
                    self.examples.append(f"{path} t={event.get('t', 0):.3f}: {message}")


class Launcher:
    """Runs the nodes of `system` that belong to `host` (all of them when None).

    `node_argv(config_path)` builds a node's command line: `python -m iotad.node CONFIG` by
    default; tests pass a stand-in. `out` receives every line the launcher prints."""

    def __init__(self, system: System, *, host: str | None = None, port: int | None = None,
                 until: float | None = None, record: bool = True, record_path: str | None = None,
                 origin: float | None = None, log_dir: str | None = None,
                 node_argv: Callable[[str], list[str]] | None = None, console: Any = None,
                 live_table: bool | None = None, stop_timeouts: tuple[float, float] = (3.0, 2.0)):
        self.system, self.host, self.until = system, host, until
        self.hub = with_port(system.listen, port) if port is not None else list(system.listen)
        self.record, self.record_path = record, record_path
        self.origin = origin
        self.node_argv = node_argv or (lambda config: [sys.executable, "-m", "iotad.node", config])
        self.stop_timeouts = stop_timeouts
        self._own_dir = log_dir is None
        self.run_dir = Path(log_dir) if log_dir else Path(tempfile.mkdtemp(prefix=f"iotad-{system.name}-"))
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.events: queue.Queue = queue.Queue()
        self.tally = Tally()
        self.alive_paths: set[str] = set()
        self.runs: dict[str, NodeRun] = {}
        for spec in system.nodes_on(host):
            child = Child(spec.name, [], log=self.run_dir / f"{spec.name.replace('/', '.')}.log",
                          on_exit=self._on_exit)
            policy = RestartPolicy(spec.restart, spec.max_restarts, spec.backoff)
            self.runs[spec.name] = NodeRun(spec, child, policy)
        self.recorder: Child | None = None
        self.recording: Path | None = None
        self.session = None
        self._publisher = None
        self._event_seq = 0
        self._declared: list[Any] = []
        self._stop_reason: str | None = None
        self._interrupts = 0
        self._started = 0.0
        from .launcher_view import StatusView
        self.view = StatusView(console, live_table, title=f"iotad run {system.file}")

    # ------------------------------------------------------------------ public
    def request_stop(self, reason: str = "stop requested") -> None:
        """Thread-safe: ask the run loop to stop everything and return."""
        self.events.put(("stop", reason))

    def run(self) -> int:
        """Run until --until, Ctrl-C/SIGTERM, or until every node has ended for good.
        Returns 0 (clean), 1 (a node failed for good) or 130 (interrupted)."""
        previous = self._install_signals()
        self._started = time.monotonic()
        try:
            self._open_session()
            self._start_recorder()
            self.view.start()
            self._loop()
        finally:
            self._shutdown()
            self._restore_signals(previous)
        if self._stop_reason == "interrupted":
            return 130
        return 1 if any(r.state == "failed" for r in self.runs.values()) else 0

    # ------------------------------------------------------------------ set-up
    def _install_signals(self) -> dict:
        if threading.current_thread() is not threading.main_thread():
            return {}

        def on_signal(signum, frame):
            self._interrupts += 1
            self.events.put(("stop", "interrupted" if signum == signal.SIGINT else signal.Signals(signum).name))

        previous = {}
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            previous[signum] = signal.signal(signum, on_signal)
        return previous

    @staticmethod
    def _restore_signals(previous: dict) -> None:
        for signum, handler in previous.items():
            signal.signal(signum, handler)

    def _open_session(self) -> None:
        from .transport import open_session

        system = self.system
        if system.opens_hub(self.host):
            listen, connect = self.hub, list(system.connect)
        else:
            listen, connect = system.listen_for(self.host), self.hub
        try:
            self.session = open_session(listen, connect)
        except Exception as exc:  # noqa: BLE001 - zenoh says why in its message
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            if "Address already in use" in text:
                raise LauncherError(f"the hub endpoint {', '.join(listen)} is taken (another 'iotad run'?); "
                                    "choose another with --port") from None
            raise LauncherError(f"cannot open the hub session (listen {listen}, connect {connect}): {text}") from None
        session = self.session
        base = f"{wire.PREFIX}/{system.name}"
        self._publisher = session.declare_publisher(wire.launcher_key(system.name))
        self._declared.append(self._publisher)
        self._declared.append(session.liveliness().declare_subscriber(
            f"{base}/**/{ALIVE}", self._on_liveliness, history=True))
        self._declared.append(session.declare_subscriber(f"{base}/**/{HEARTBEAT}", self._on_heartbeat))
        self._declared.append(session.declare_subscriber(f"{base}/**", self._on_channel))
        self._declared.append(session.declare_subscriber(f"{base}/**/@trace", self._on_trace))
        if system.opens_hub(self.host):
            if self.origin is None:
                self.origin = time.time()
            origin_payload = wire.encode({"origin": self.origin})
            key = f"{base}/{ORIGIN}"
            self._declared.append(session.declare_queryable(key, lambda q: q.reply(key, origin_payload)))
        elif self.origin is None:
            self.origin = self._ask_origin()

    def _ask_origin(self) -> float:
        """A launcher for one host of several takes the hub launcher's origin, so that every
        node's `t` counts from one instant; if the hub does not answer, its own (with a warning)."""
        deadline = time.monotonic() + self.system.start_timeout
        key = f"{wire.PREFIX}/{self.system.name}/{ORIGIN}"
        while time.monotonic() < deadline:
            for reply in self.session.get(key, timeout=1.0):
                if reply.ok is not None:
                    return float(wire.decode(reply.ok.payload.to_bytes())["origin"])
            time.sleep(0.2)
        self.view.line(f"warning: no hub launcher answered on {key}; this host's nodes use its own clock origin")
        return time.time()

    def _start_recorder(self) -> None:
        if not self.record or not self.system.opens_hub(self.host):
            return
        if find_spec("iotad.commands.record") is None:
            self.view.line("warning: this iotad has no 'record' command; running without a recording")
            return
        system = self.system
        if self.record_path:
            output = Path(self.record_path)
        else:
            stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(self.origin))
            output = Path("recordings") / f"{system.name}-{stamp}.mcap"
        output.parent.mkdir(parents=True, exist_ok=True)
        ready = self.run_dir / "recorder.ready"
        argv = [sys.executable, "-m", "iotad", "record", f"{wire.PREFIX}/{system.name}/**",
                "-o", str(output), "--system-file", str(system.path), "--ready-file", str(ready)]
        for endpoint in self.hub:
            argv += ["--connect", endpoint]
        for endpoint in system.listen_for(self.host):
            argv += ["--listen", endpoint]
        self.recorder = Child("recorder", argv, log=self.run_dir / "recorder.log")
        pid = self.recorder.start()
        deadline = time.monotonic() + 10.0
        while not ready.exists() and self.recorder.running() and time.monotonic() < deadline:
            time.sleep(0.02)
        if ready.exists():
            self.recording = output
            self.view.line(f"recording to {output} (recorder pid {pid})")
        else:
            self.view.line(f"warning: the recorder did not start ({describe_exit(self.recorder.code)}); "
                           f"see {self.recorder.log}; running without a recording")
            stop_all([self.recorder], 1.0, 1.0)
            self.recorder = None

    # ------------------------------------------------------------------ zenoh callbacks (their threads)
    def _path_of(self, key: str, suffix: str) -> str | None:
        prefix = f"{wire.PREFIX}/{self.system.name}/"
        key = str(key)
        if key.startswith(prefix) and key.endswith("/" + suffix):
            return key[len(prefix):-len(suffix) - 1]
        return None

    def _on_liveliness(self, sample: Any) -> None:
        import zenoh
        path = self._path_of(sample.key_expr, ALIVE)
        if path is not None:
            self.events.put(("alive", path, sample.kind == zenoh.SampleKind.PUT, time.monotonic()))

    def _on_heartbeat(self, sample: Any) -> None:
        path = self._path_of(sample.key_expr, HEARTBEAT)
        run = self.runs.get(path) if path is not None else None
        if run is not None and run.state in ("starting", "running", "lost"):
            run.last_beat = time.monotonic()  # one attribute store: safe across threads

    def _on_channel(self, sample: Any) -> None:
        try:
            value = wire.decode(sample.payload.to_bytes())
        except wire.WireError:
            value = "<malformed>"
        self.tally.channel(str(sample.key_expr), value)

    def _on_trace(self, sample: Any) -> None:
        path = self._path_of(sample.key_expr, "@trace")
        try:
            self.tally.trace(path or "?", wire.decode(sample.payload.to_bytes()))
        except wire.WireError:
            pass

    def _on_exit(self, child: Child, code: int) -> None:  # a waiter thread
        self.events.put(("exit", child.name, child.pid, code))

    # ------------------------------------------------------------------ the loop
    def _loop(self) -> None:
        last_view = 0.0
        while True:
            try:
                item = self.events.get(timeout=0.05)
            except queue.Empty:
                item = None
            while item is not None:
                self._handle(item)
                try:
                    item = self.events.get_nowait()
                except queue.Empty:
                    item = None
            if self._stop_reason is not None:
                return
            now = time.monotonic()
            self._supervise(now)
            if self.until is not None and now - self._started >= self.until:
                self._stop_reason = "until"
                self.view.line(f"--until {self.until:g} s reached: stopping")
                return
            if self.runs and all(r.finished for r in self.runs.values()):
                self._stop_reason = "all nodes ended"
                self.view.line("every node has ended: stopping")
                return
            if now - last_view >= 0.25:
                last_view = now
                self.view.update(self._rows(now))

    def _handle(self, item: tuple) -> None:
        kind = item[0]
        if kind == "stop":
            if self._stop_reason is None:
                self._stop_reason = item[1]
                self.view.line(f"{'Ctrl-C' if item[1] == 'interrupted' else item[1]}: stopping every node")
        elif kind == "alive":
            _, path, present, when = item
            (self.alive_paths.add if present else self.alive_paths.discard)(path)
            run = self.runs.get(path)
            if run is None:
                if present and self.host is not None:
                    self.view.line(f"{path}: live (on another host)")
                return
            if present and run.state in ("starting", "lost"):
                run.state, run.live_since, run.lost_since = "running", when, None
                self._event("live", run, f"live (pid {run.child.pid})")
            elif not present and run.state == "running" and run.child.running():
                run.state, run.lost_since = "lost", when
                self._event("lost", run, "liveliness token gone while its process runs")
        elif kind == "exit":
            _, name, pid, code = item
            run = self.runs.get(name)
            if run is not None and pid == run.child.pid:
                self._exited(run, code)

    def _exited(self, run: NodeRun, code: int) -> None:
        now = time.monotonic()
        run.last_code = code
        self.alive_paths.discard(run.name)
        uptime = now - run.child.started_at
        if run.state == "stopping":
            run.state = "stopped"
            self._event("exit", run, f"stopped ({describe_exit(code)})", code=code)
            return
        reason = f" after {run.killed_for}" if run.killed_for else ""
        run.killed_for = None
        tail = "" if code == 0 else _log_tail(run.child.log)
        self._event("exit", run, f"{describe_exit(code)}{reason} after {uptime:.1f} s{tail}", code=code)
        if uptime >= run.policy.healthy_after:
            run.consecutive = 0
        if run.policy.wants_restart(code, run.restarts):
            delay = run.policy.delay(run.consecutive)
            run.consecutive += 1
            run.state, run.restart_at = "backoff", now + delay
        elif run.policy.mode != "never" and run.restarts >= run.policy.max_restarts and (
                code != 0 or run.policy.mode == "always"):
            run.state = "failed"
            self._event("giveup", run, f"gave up after {run.restarts} restarts (max_restarts)", code=code)
        else:
            run.state = "exited" if code == 0 else "failed"

    def _supervise(self, now: float) -> None:
        system = self.system
        for run in self.runs.values():
            if run.state == "waiting" and all(dep in self.alive_paths for dep in run.spec.after):
                self._spawn(run, "start")
            elif run.state == "backoff" and now >= run.restart_at:
                run.restarts += 1
                self._spawn(run, "restart")
            elif run.state == "starting" and now - run.child.started_at > system.start_timeout:
                self._kill(run, f"no liveliness token within {system.start_timeout:g} s")
            elif run.state == "running" and run.last_beat is not None \
                    and now - run.last_beat > system.heartbeat_timeout:
                self._kill(run, f"no heartbeat for {now - run.last_beat:.1f} s")
            elif run.state == "lost" and now - run.lost_since > system.heartbeat_timeout:
                self._kill(run, f"liveliness token gone for {now - run.lost_since:.1f} s")

    def _spawn(self, run: NodeRun, event: str) -> None:
        config = self.system.node_config(run.name, self.origin, self.hub)
        path = self.run_dir / f"{run.name.replace('/', '.')}.json"
        path.write_text(json.dumps(config, indent=1))
        run.child.argv = self.node_argv(str(path))
        run.last_beat = run.live_since = run.lost_since = None
        try:
            run.child.start()
        except OSError as exc:
            run.state = "failed"
            self._event("exit", run, f"cannot start: {exc}", code=FAILED_TO_START)
            return
        run.state = "starting"
        what = "started" if event == "start" else f"restarted (#{run.restarts})"
        self._event(event, run, f"{what}, pid {run.child.pid}")

    def _kill(self, run: NodeRun, why: str) -> None:
        run.killed_for = why
        self._event("stale", run, f"{why}: killing pid {run.child.pid}")
        run.child.signal(signal.SIGKILL)
        run.state = "lost"           # until its exit arrives
        run.lost_since = float("inf")  # do not kill twice

    # ------------------------------------------------------------------ reporting
    def _event(self, event: str, run: NodeRun, text: str, code: int | None = None) -> None:
        self.view.line(f"{run.name}: {text}")
        if self._publisher is None:
            return
        payload = {"event": event, "node": run.name, "pid": run.child.pid, "code": code,
                   "t_ns": time.time_ns(), "restarts": run.restarts}
        if self.host is not None:
            payload["host"] = self.host
        try:
            self._publisher.put(wire.encode(payload), attachment=wire.encode_attachment(self._event_seq))
            self._event_seq += 1
        except Exception:  # noqa: BLE001 - a closing session must not stop the shutdown
            pass

    def _rows(self, now: float) -> list[tuple]:
        rows = []
        for run in self.runs.values():
            uptime = f"{now - run.live_since:.1f}s" if run.live_since and run.state == "running" else "-"
            beat = f"{now - run.last_beat:.2f}s" if run.last_beat and not run.finished else "-"
            state = run.state if run.state not in ("exited", "failed") else \
                f"{run.state} ({describe_exit(run.last_code)})"
            pid = str(run.child.pid) if run.child.pid and not run.finished else "-"
            rows.append((run.name, run.spec.host or "", pid, state, str(run.restarts), uptime, beat))
        return rows

    # ------------------------------------------------------------------ shutdown
    def _shutdown(self) -> None:
        """Nodes first (the recorder sees them go), then the recorder, then the session."""
        interrupt, terminate = self.stop_timeouts
        if self._interrupts > 1:
            interrupt = terminate = 0.0  # a second Ctrl-C: no more patience
        for run in self.runs.values():
            if run.child.running():
                run.state = "stopping"
            elif run.state in ("waiting", "backoff", "starting", "running", "lost"):
                run.state = "stopped"
        stop_all([r.child for r in self.runs.values()], interrupt, terminate)
        # Report the exits now: the waiters queued them, and the recorder is still listening.
        while True:
            try:
                item = self.events.get_nowait()
            except queue.Empty:
                break
            if item[0] == "exit":
                self._handle(item)
        for run in self.runs.values():
            if run.state == "stopping":
                run.state = "stopped"
        if self.recorder is not None:
            time.sleep(0.1)  # let the last events reach the recorder before it closes its file
            stop_all([self.recorder], 5.0, 2.0)
            if self.recorder.code not in (0, None):
                self.view.line(f"warning: the recorder ended with {describe_exit(self.recorder.code)}"
                               f"{_log_tail(self.recorder.log)}")
        self.view.update(self._rows(time.monotonic()))
        self.view.stop()
        for entity in reversed(self._declared):
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001
                pass
        self._declared.clear()
        if self.session is not None:
            session, self.session = self.session, None
            session.close()
        if self._own_dir and not any(r.state == "failed" for r in self.runs.values()):
            shutil.rmtree(self.run_dir, ignore_errors=True)

    def summary(self) -> list[str]:
        """Lines for the end of a run: what each output carried, who received it, violations."""
        system, lines = self.system, []
        with self.tally.lock:
            values = {k: Counter(v) for k, v in self.tally.values.items()}
            violations, examples = Counter(self.tally.violations), list(self.tally.examples)
        for node in system.nodes.values():
            for channel in node.channels.values():
                if channel.direction != "output":
                    continue
                for index in channel.members():
                    port = Port(node.name, channel.name, index)
                    counts = values.get(wire.channel_key(system.name, node.name, channel.name, index), Counter())
                    receivers = ", ".join(str(p) for p in system.receivers_of(port))
                    total = sum(counts.values())
                    shown = ", ".join(f"{v} x{n}" for v, n in sorted(counts.items()) if v != "*")
                    lines.append(f"  {str(port):<24} {'-> ' + receivers if receivers else '':<22} "
                                 f"{total:>4} events{': ' + shown if shown else ''}")
        lines.append(f"  violations: {sum(violations.values())}"
                     + (" (" + ", ".join(f"{p} x{n}" for p, n in sorted(violations.items())) + ")" if violations else ""))
        lines += [f"    {example}" for example in examples]
        for run in self.runs.values():
            if run.restarts:
                lines.append(f"  {run.name}: restarted {run.restarts} time(s)")
        if self.recording is not None:
            lines.append(f"  recording: {self.recording}")
        if not self._own_dir or any(r.state == "failed" for r in self.runs.values()):
            lines.append(f"  configs and logs: {self.run_dir}")
        return lines


class LauncherError(Exception):
    """The launcher cannot start (the hub endpoint is taken...): one line for the user."""


def _log_tail(log: Path | None, lines: int = 4) -> str:
    if log is None or not log.exists():
        return ""
    try:
        text = log.read_text(errors="replace").strip().splitlines()[-lines:]
    except OSError:
        return ""
    return "".join(f"\n    | {line}" for line in text)


__all__ = ["Launcher", "LauncherError", "NodeRun", "Tally"]
