"""The launcher: runs a checked system as one process per node around a zenoh hub, supervises
them, reports what happens, and stops everything it started.

One thread (the caller's, normally the main thread) owns every child: it spawns them (so the
parent-death signal of `iotad.launcher.processes` stays armed for as long as the launcher lives), decides
restarts and stops them. zenoh callbacks and process waiters only put events on its queue (or
stamp a heartbeat time). A node's death is seen three ways: its process exits (waiter thread),
its liveliness token goes away (zenoh), or its heartbeat goes stale while the process still runs
(a frozen Python loop): then it is killed and restarted like a crash.

Failure policy. A node that exits is restarted by its restart policy (`backoff` doubling, at
most `max_restarts`); once the policy gives up, the launcher says so with the tail of the node's
output (its stderr) and keeps the other nodes running, unless the node is `required`, in which
case it stops the whole system (exit status 1). The recorder is watched like a node: if it dies,
the cut-short file is named (`iotad recover` makes it whole) and a new recorder continues in a
new file; a recording that cannot go on is reported and makes the exit status 1, never silent.
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

from iotad.host import wire
from iotad.launcher.processes import FAILED_TO_START, Child, RestartPolicy, describe_exit, stop_all
from iotad.launcher.recording_paths import next_continuation, unwritable
from iotad.launcher.system_file import NodeSpec, Port, System, with_port
from iotad.launcher.violation_examples import ViolationExamples

ALIVE = "@alive"
HEARTBEAT = "@heartbeat"
ORIGIN = "@origin"
MIN_FREE_BYTES = 16 * 2**20   # refuse to start a recording on a file system with less free space
RECORDER_RESTARTS = 3         # new recorders after the first one died, before recording stops
RECORDER_STALL = 5.0          # s without a sign of life (its ready file touched) before a recorder is killed,
                              # at least; twice the system's heartbeat_timeout where that is longer (a slow host)
VALUE_LABELS = 32             # distinct values counted per channel for the summary; then "*"
# Exit status of `run()` by stop reason: 128 + the signal, like a shell.
_SIGNAL_STATUS = {"interrupted": 130, "SIGTERM": 143, "SIGHUP": 129}


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
    down_since: float | None = None  # when it exited, while it waits for its restart (backoff)
    down_at_end: float = 0.0      # state "down": seconds it had been down when the run ended
    live_since: float | None = None
    lost_since: float | None = None
    last_beat: float | None = None
    killed_for: str | None = None  # why the launcher killed it (stale heartbeat...), reported on exit
    last_code: int | None = None
    went_live: bool = False       # its liveliness token was seen at least once
    failures: int = 0             # exits with a failure status, not counting the run's stop

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def finished(self) -> bool:
        return self.state in ("stopped", "exited", "failed", "down")


@dataclass
class Tally:
    """What crossed the system's keys while it ran: for the summary at the end."""

    values: dict[str, Counter] = field(default_factory=dict)      # channel key -> Counter of values
    violations: Counter = field(default_factory=Counter)           # node path -> count
    examples: ViolationExamples = field(default_factory=ViolationExamples)  # first distinct violation lines
    lock: threading.Lock = field(default_factory=threading.Lock)

    def channel(self, key: str, value: Any) -> None:
        label = value if isinstance(value, (str, bool, int)) and not isinstance(value, float) else "*"
        with self.lock:
            counts = self.values.setdefault(key, Counter())
            if label not in counts and len(counts) >= VALUE_LABELS:
                label = "*"  # a counter, a sequence number...: bounded memory over a long run
            counts[label] += 1

    def trace(self, path: str, event: Any) -> None:
        if isinstance(event, dict) and event.get("kind") == "violation":
            with self.lock:
                self.violations[path] += 1
                value = event.get("value") or {}
                message = value.get("message") if isinstance(value, dict) else value
                self.examples.add(f"{path} t={event.get('t', 0):.3f}: {message}", event.get("index"))


class Launcher:
    """Runs the nodes of `system` that belong to `host` (all of them when None).

    `node_argv(config_path)` builds a node's command line: `python -m iotad.host CONFIG` by
    default; tests pass a stand-in. `out` receives every line the launcher prints."""

    # iotad.launcher.access_control.AccessControl (set by `iotad run` before `run()`), or None:
    # no authentication, no access control, zenoh's defaults.
    access: Any = None

    def __init__(self, system: System, *, host: str | None = None, port: int | None = None,
                 until: float | None = None, record: bool = True, record_path: str | None = None,
                 origin: float | None = None, log_dir: str | None = None,
                 node_argv: Callable[[str], list[str]] | None = None, console: Any = None,
                 live_table: bool | None = None, stop_timeouts: tuple[float, float] = (3.0, 2.0),
                 record_max_size: int | None = None, record_max_duration: float | None = None,
                 record_force: bool = False, after_live: bool = False):
        self.system, self.host, self.until = system, host, until
        # count `until` from the moment every node is first live, not from the launch: start-up
        # (imports, PyBullet worlds) can take 10-30 s in user-mode Linux and would eat the run
        self.after_live = after_live
        self._live_at: float | None = None
        # split the recording into numbered files (`iotad record --max-size/--max-duration`)
        self.record_max_size, self.record_max_duration = record_max_size, record_max_duration
        self.hub = with_port(system.listen, port) if port is not None else list(system.listen)
        self.record, self.record_path = record, record_path
        self.record_force = record_force  # the recorder may replace a recording at record_path (--force)
        self.origin = origin
        self.node_argv = node_argv or (lambda config: [sys.executable, "-m", "iotad.host", config])
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
        self.recording: Path | None = None        # the file being written now
        self.recordings: list[Path] = []          # every file this run wrote, in order
        self.recording_lost: str | None = None    # why recording stopped before the run did
        self._recorder_restarts = 0
        self._recorder_ready: Path | None = None  # a restarted recorder's ready file, until it exists
        self._recorder_beat: Path | None = None   # the running recorder's ready file, touched as it lives
        self._recorder_frozen = 0.0               # s of silence of a recorder killed as frozen
        self._shutting_down = False
        self.session = None
        self._publisher = None
        self._event_seq = 0
        self._declared: list[Any] = []
        self._stop_reason: str | None = None
        self._interrupts = 0
        self._stop_asked = threading.Event()  # a stop was asked for (signal or request_stop)
        self._hurry = threading.Event()       # a second signal: skip the waiting of the stop
        self._started = 0.0
        # The start gate: nodes started before it opens go live and wait; once every node is
        # live (or has ended for good) the launcher declares its token and their engines start
        # together, none of them running while another still imports on the same cores.
        self.gate_key = wire.gate_key(system.name, host)
        self.gate_open = not system.start_gate  # start_gate = false: no gate, as if always open
        from iotad.launcher.status_view import StatusView
        self.view = StatusView(console, live_table, title=f"iotad run {system.file}")

    # ------------------------------------------------------------------ public
    def discard(self) -> None:
        """Remove what the launcher made before it ran (its run folder), for a run that never started."""
        if self._own_dir:
            shutil.rmtree(self.run_dir, ignore_errors=True)

    def request_stop(self, reason: str = "stop requested") -> None:
        """Thread-safe: ask the run loop to stop everything and return."""
        self._stop_asked.set()
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
        if self._stop_reason in _SIGNAL_STATUS:
            return _SIGNAL_STATUS[self._stop_reason]
        failed = any(r.state in ("failed", "down") for r in self.runs.values()) or self.never_live()
        # a recorder that died mid-run left a gap between its files: what happened then is lost
        return 1 if failed or self.recording_lost or self._recorder_restarts else 0

    def never_live(self) -> list[str]:
        """Nodes that failed every time they started and never went live: the run ended (its
        --until) while the restart policy still retried them, but the system never ran whole."""
        return [r.name for r in self.runs.values() if not r.went_live and r.failures]

    # ------------------------------------------------------------------ set-up
    def _install_signals(self) -> dict:
        if threading.current_thread() is not threading.main_thread():
            return {}

        def on_signal(signum, frame):
            # SIGTERM and SIGHUP stop exactly like Ctrl-C (a second one: no more patience)
            self._interrupts += 1
            self._stop_asked.set()
            if self._interrupts > 1:
                self._hurry.set()  # also cuts short a stop already under way
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
        from iotad.host.transport import open_session, reachable
        from iotad.launcher.can_env import unresolved

        system = self.system
        if (problem := unresolved(system, self.host)) is not None:  # [[can]] interface = "env", none set
            raise LauncherError(problem)
        if system.opens_hub(self.host):
            listen, connect = self.hub, list(system.connect)
        else:
            listen, connect = system.listen_for(self.host), self.hub
        try:
            self.session = open_session(listen, connect, **(self.access.hub_options() if self.access else {}))
        except Exception as exc:  # noqa: BLE001 - zenoh says why in its message
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            if "Address already in use" in text:
                raise LauncherError(f"the hub endpoint {', '.join(listen)} is taken (another 'iotad run'?); "
                                    "choose another with --port") from None
            raise LauncherError(f"cannot open the hub session (listen {listen}, connect {connect}): {text}") from None
        session = self.session
        if system.opens_hub(self.host):  # with --port 0 this is the only place the port is told
            tools = reachable(listen[0])
            self.view.line(f"hub: {', '.join(listen)} (tools attach with --connect {tools}, e.g. iotad top --connect {tools})")
        for line in (self.access.opened(listen) if self.access and system.opens_hub(self.host) else ()):
            self.view.line(line)
        base = f"{wire.PREFIX}/{system.name}"
        self._publisher = session.declare_publisher(wire.launcher_key(system.name))
        self._declared.append(self._publisher)
        self._declared.append(session.liveliness().declare_subscriber(
            f"{base}/**/{ALIVE}", self._on_liveliness, history=True))
        self._declared.append(session.declare_subscriber(f"{base}/**/{HEARTBEAT}", self._on_heartbeat))
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
        while time.monotonic() < deadline and not self._stop_asked.is_set():
            for reply in self.session.get(key, timeout=1.0):
                if reply.ok is not None:
                    return float(wire.decode(reply.ok.payload.to_bytes())["origin"])
            self._stop_asked.wait(0.2)
        if self._stop_asked.is_set():
            return time.time()  # stopping before anything started: the origin no longer matters
        self.view.line(f"warning: no hub launcher answered on {key}; this host's nodes use its own clock origin")
        return time.time()

    def _start_recorder(self) -> None:
        """Start `iotad record` and wait until it has subscribed, before any node starts. A
        recording that cannot be written (no folder, no space, the recorder fails) is an error
        here, while nothing runs yet: --no-record runs without one."""
        if not self.record or not self.system.opens_hub(self.host):
            return
        if find_spec("iotad.cli.commands.record") is None:
            self.view.line("warning: this iotad has no 'record' command; running without a recording")
            return
        if not self.record_path:  # the CLI names it (run.launch): the launcher does not know the file names
            raise LauncherError("a recorded run needs record_path (the .mcap file to write)")
        output = Path(self.record_path)
        self._recording_since = time.time()  # files older than this are an earlier run's (--force replaces them)
        problem = unwritable(output, make_folder=True, min_free_bytes=MIN_FREE_BYTES)
        if problem:
            raise LauncherError(f"cannot record to {output}: {problem}; choose another file with -o, "
                                "or run without a recording (--no-record)")
        ready = self._spawn_recorder(output)
        deadline = time.monotonic() + max(10.0, self.system.start_timeout)
        while not ready.exists() and self.recorder.running() and time.monotonic() < deadline:
            time.sleep(0.02)
        if not ready.exists():
            recorder, self.recorder = self.recorder, None
            stop_all([recorder], 1.0, 1.0)
            why = describe_exit(recorder.code) if recorder.code is not None else \
                f"not subscribed after {deadline - recorder.started_at:.0f} s"
            raise LauncherError(f"the recorder did not start ({why}){_log_tail(recorder)}\n"
                                "run without a recording with --no-record")
        self._recorder_ready = None
        self.recording = output
        self.recordings.append(output)
        self.view.line(f"recording to {output} (recorder pid {self.recorder.pid})")

    def _spawn_recorder(self, output: Path) -> Path:
        system = self.system
        ready = self.run_dir / f"recorder{len(self.recordings)}.ready"
        ready.unlink(missing_ok=True)
        argv = [sys.executable, "-m", "iotad", "record", f"{wire.PREFIX}/{system.name}/**",
                "-o", str(output), "--system-file", str(system.path), "--ready-file", str(ready),
                "--from-traces",  # one wake-up per trace burst, not per message: see iotad.recording.recorder
                "--from-launcher"]  # the file checked and the name claimed: the recorder loads no node code
        if self.record_force:
            argv.append("--force")
        if self.record_max_size is not None:
            argv += ["--max-size", str(self.record_max_size)]
        if self.record_max_duration is not None:
            argv += ["--max-duration", repr(float(self.record_max_duration))]
        for endpoint in self.hub:  # a client of the hub, which relays each node's first sample
            argv += ["--connect", endpoint]
        # If the launcher is killed (-9), the recorder is interrupted, not killed: it writes the
        # file's summary and footer, and the recording stays complete up to that moment
        self.recorder = Child("recorder", argv, log=self.run_dir / "recorder.log",
                              env=self.access.recorder_env() if self.access else None,
                              on_exit=lambda child, code: self.events.put(("recorder", child.pid, code)),
                              death_signal=signal.SIGINT)
        self.recorder.start()
        self._recorder_ready = self._recorder_beat = ready
        return ready

    def _recorder_exited(self, pid: int, code: int) -> None:
        """The recorder ended while the system runs: name the cut file, continue in a new one."""
        recorder = self.recorder
        if recorder is None or recorder.pid != pid:
            return  # one the launcher stopped itself
        self.recorder = None
        cut = self.recording
        self.recording = None
        uptime = time.monotonic() - recorder.started_at
        state = "is complete" if code == 0 else f"was cut short: 'iotad recover {cut}' makes it whole"
        frozen, self._recorder_frozen = self._recorder_frozen, 0.0
        why = f" (frozen: no sign of life for {frozen:.1f} s)" if frozen else ""
        self._launcher_event("recorder", f"recorder: {describe_exit(code)}{why} after {uptime:.1f} s; {cut} {state}"
                             f"{_log_tail(recorder)}", code=code, file=str(cut))
        if self._shutting_down:
            self.recording_lost = f"the recorder ended with {describe_exit(code)} before the stop"
            return
        if self._recorder_restarts >= RECORDER_RESTARTS:
            self._lose_recording(f"the recorder died {self._recorder_restarts + 1} times")
            return
        self._recorder_restarts += 1
        output = next_continuation(self.recordings[0], self._recorder_restarts,
                                   self._recording_since if self.record_force else None)
        problem = unwritable(output, make_folder=True, min_free_bytes=MIN_FREE_BYTES)
        if problem:
            self._lose_recording(f"cannot record to {output}: {problem}")
            return
        try:
            self._spawn_recorder(output)
        except OSError as exc:  # out of processes, of file descriptors...
            self.recorder = None
            self._lose_recording(f"cannot start a new recorder: {exc}")
            return
        self.recording = output
        self.recordings.append(output)
        self.view.line(f"recorder: restarting (pid {self.recorder.pid}) to record to {output}")

    def _lose_recording(self, why: str) -> None:
        self.recording_lost = why
        self._launcher_event("recorder", f"recorder: RECORDING STOPPED: {why}; the nodes keep running", code=1)

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

    def _on_trace(self, sample: Any) -> None:
        # Outputs are counted from the nodes' traces, not from their keys: a subscriber to every
        # channel key would wake this process for every message, which the nodes pay for.
        path = self._path_of(sample.key_expr, "@trace")
        try:
            events = wire.trace_events(wire.decode(sample.payload.to_bytes()))  # a burst, or one event
        except wire.WireError:
            return
        for event in events:
            self.tally.trace(path or "?", event)
            if isinstance(event, dict) and event.get("kind") == "output" and isinstance(event.get("key"), str):
                self.tally.channel(event["key"], event.get("value"))

    def _on_exit(self, child: Child, code: int) -> None:  # a waiter thread
        self.events.put(("exit", child.name, child.pid, code))

    # ------------------------------------------------------------------ the loop
    def _loop(self) -> None:
        last_view = 0.0
        while True:
            try:
                item = self.events.get(timeout=self._next_wake(time.monotonic()))
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
            since = self._until_counts_from(now)
            if since is not None and now - since >= self.until:
                self._stop_reason = "until"
                after = " after every node was live" if self.after_live else ""
                self.view.line(f"--until {self.until:g} s{after} reached: stopping")
                return
            if self.runs and all(r.finished for r in self.runs.values()):
                self._stop_reason = "all nodes ended"
                self.view.line("every node has ended: stopping")
                return
            if now - last_view >= 0.25:
                last_view = now
                self.view.update(self._rows(now))

    def _next_wake(self, now: float) -> float:
        """At most 50 ms, less when a restart is due sooner: the backoff is all a restart waits."""
        due = [run.restart_at for run in self.runs.values() if run.state == "backoff"]
        return max(0.0, min([0.05, *(when - now for when in due)]))

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
                run.went_live = True
                self._event("live", run, f"live (pid {run.child.pid})")
            elif not present and run.state == "running" and run.child.running():
                run.state, run.lost_since = "lost", when
                self._event("lost", run, "liveliness token gone while its process runs")
        elif kind == "exit":
            _, name, pid, code = item
            run = self.runs.get(name)
            if run is not None and pid == run.child.pid:
                self._exited(run, code)
        elif kind == "recorder":
            self._recorder_exited(item[1], item[2])

    def _exited(self, run: NodeRun, code: int) -> None:
        now = time.monotonic()
        run.last_code = code
        self.alive_paths.discard(run.name)
        uptime = now - run.child.started_at
        if run.state == "stopping":
            run.state = "stopped"
            self._event("exit", run, f"stopped ({describe_exit(code)}){self._stop_escalation(run, code)}", code=code)
            return
        reason = f" ({run.killed_for})" if run.killed_for else ""
        run.killed_for = None
        run.failures += code != 0
        tail = "" if code == 0 else _log_tail(run.child)
        what = f"{describe_exit(code)}{reason} after {uptime:.1f} s"
        if uptime >= run.policy.healthy_after:
            run.consecutive = 0
        policy = run.policy
        if policy.wants_restart(code, run.restarts):
            delay = policy.delay(run.consecutive)
            run.consecutive += 1
            run.state, run.restart_at, run.down_since = "backoff", now + delay, now
            self._event("exit", run, f"{what}; restart {run.restarts + 1}/{policy.max_restarts} "
                                     f"in {delay:.2f} s{tail}", code=code)
            return
        self._event("exit", run, what, code=code)
        if policy.mode == "never" or (code == 0 and policy.mode == "on-failure"):
            run.state = "exited" if code == 0 else "failed"
            if code != 0:
                self._event("giveup", run, f"failed for good: {describe_exit(code)}, and restart = "
                                           f"\"never\"{tail}", code=code)
        else:
            run.state = "failed"
            self._event("giveup", run, f"gave up after {run.restarts} restarts (max_restarts = "
                                       f"{policy.max_restarts}); last: {describe_exit(code)}{tail}", code=code)
        if run.spec.required and self._stop_reason is None:
            self._stop_reason = f"required node {run.name} ended"
            self.view.line(f"{run.name} is required and has ended for good: stopping every node")

    def _stop_escalation(self, run: NodeRun, code: int) -> str:
        """How far the stop had to go, when it went past SIGINT."""
        interrupt, terminate = self.stop_timeouts
        if self._hurry.is_set() and run.child.last_signal in (signal.SIGKILL, signal.SIGTERM):
            return f": a second signal skipped the waiting; stopped by {signal.Signals(run.child.last_signal).name}"
        if run.child.last_signal == signal.SIGKILL:
            return (f": it ignored SIGINT ({interrupt:g} s) and SIGTERM ({terminate:g} s), "
                    "so it was killed with SIGKILL")
        if run.child.last_signal == signal.SIGTERM:
            return f": it did not stop within {interrupt:g} s of SIGINT; stopped by SIGTERM"
        return ""

    def _until_counts_from(self, now: float) -> float | None:
        """When --until's seconds began (None: no --until, or not every node live yet). With
        after_live, a node that has ended for good counts as live, so a failed start cannot keep
        the run going for ever."""
        if self.until is None:
            return None
        if not self.after_live:
            return self._started
        if self._live_at is None and self._everyone_live():
            self._live_at = now
            self.view.line(f"every node is live: --until {self.until:g} s counts from now")
        return self._live_at

    def _everyone_live(self) -> bool:
        """Every node is live or has ended for good, and one at least is live: a node that failed
        to start must not hold the others (nor the gate) for ever."""
        runs = self.runs.values()
        return bool(self.runs) and any(r.state == "running" for r in runs) \
            and all(r.state == "running" or r.finished for r in runs)

    def _open_gate(self) -> None:
        """Declare the start gate's token once every node is live: the waiting engines start."""
        if self.gate_open or not self._everyone_live():
            return
        self.gate_open = True
        try:
            self._declared.append(self.session.liveliness().declare_token(self.gate_key))
        except Exception as exc:  # noqa: BLE001 - a closing session; the nodes are being stopped
            self.view.line(f"warning: cannot open the start gate {self.gate_key}: {exc}")
            return
        self._launcher_event("gate", f"start gate open: all {len(self.runs)} nodes are live or ended; "
                                     "their engines start now")

    def _recorder_alive(self) -> None:
        """Kill a recorder that gave no sign of life for RECORDER_STALL s (SIGSTOP, a hung write):
        its exit is then handled as any other, and a new recorder takes over."""
        beat, recorder = self._recorder_beat, self.recorder
        if (beat is None or recorder is None or not recorder.running() or self._recorder_ready is not None
                or self._shutting_down):  # a stopping recorder writes its file's end: no sign of life then
            return
        try:
            silent = time.time() - beat.stat().st_mtime
        except OSError:
            return
        if silent > max(RECORDER_STALL, 2 * self.system.heartbeat_timeout):
            self._recorder_frozen = silent
            recorder.signal(signal.SIGKILL)

    def _supervise(self, now: float) -> None:
        system = self.system
        self._recorder_alive()
        self._open_gate()
        if self._recorder_ready is not None and self._recorder_ready.exists() and self.recorder is not None:
            # said once it listens, so that the new file holds the news of the old one's end
            self._recorder_ready = None
            self._launcher_event("recorder", f"recorder: restarted (pid {self.recorder.pid}), recording "
                                 f"continues in {self.recording}; the gap since {self.recordings[-2]} "
                                 "ended is lost", file=str(self.recording))
        for run in self.runs.values():
            if run.state == "waiting" and all(dep in self.alive_paths for dep in run.spec.after):
                self._spawn(run, "start")
            elif run.state == "waiting" and (failed := [dep for dep in run.spec.after if dep in self.runs
                                                        and self.runs[dep].state == "failed"]):
                # it can never start: say so, and let a run whose other nodes have ended end
                run.state = "failed"
                self._event("giveup", run, f"will not start: it starts after {', '.join(failed)}, "
                                           "which failed for good")
                if run.spec.required and self._stop_reason is None:
                    self._stop_reason = f"required node {run.name} cannot start"
                    self.view.line(f"{run.name} is required and cannot start: stopping every node")
            elif run.state == "backoff" and now >= run.restart_at:
                run.restarts += 1
                self._spawn(run, "restart")
            elif run.state == "starting" and now - run.child.started_at > system.start_timeout:
                self._kill(run, f"no liveliness token within {system.start_timeout:g} s")
            elif run.state == "running" and now - (run.last_beat or run.live_since) > system.heartbeat_timeout:
                # Counted from the token when no heartbeat came yet: a node frozen between its
                # token and its first heartbeat is as stale as one frozen later.
                self._kill(run, f"no heartbeat for {now - (run.last_beat or run.live_since):.1f} s"
                                + (" (none since it went live)" if run.last_beat is None else ""))
            elif run.state == "lost" and now - run.lost_since > system.heartbeat_timeout:
                self._kill(run, f"liveliness token gone for {now - run.lost_since:.1f} s")

    def _spawn(self, run: NodeRun, event: str) -> None:
        config = self.system.node_config(run.name, self.origin, self.hub)
        config["restarts"] = run.restarts  # its heartbeats say it: a tool attached later counts them
        if not self.gate_open:  # a node (re)started after the gate opened starts its engine at once
            config["start_gate"] = self.gate_key
        path = self.run_dir / f"{run.name.replace('/', '.')}.json"
        path.write_text(json.dumps(config, indent=1))
        run.child.argv = self.node_argv(str(path))
        if self.access is not None:
            run.child.env = self.access.node_env(run.name)  # its own credentials (IOTAD_CREDENTIALS)
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
        self._publish({"event": event, "node": run.name, "pid": run.child.pid, "code": code,
                       "t_ns": time.time_ns(), "restarts": run.restarts})

    def _launcher_event(self, event: str, text: str, code: int | None = None, **extra: Any) -> None:
        """An event of the launcher itself (node None): the recorder's fate..."""
        self.view.line(text)
        self._publish({"event": event, "node": None, "pid": os.getpid(), "code": code,
                       "t_ns": time.time_ns(), "message": text.split("\n", 1)[0], **extra})

    def _publish(self, payload: dict) -> None:
        if self._publisher is None:
            return
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
            state = run.state if run.state not in ("exited", "failed", "down") or run.last_code is None else \
                f"{run.state} ({describe_exit(run.last_code)})"
            pid = str(run.child.pid) if run.child.pid and not run.finished else "-"
            rows.append((run.name, run.spec.host or "", pid, state, str(run.restarts), uptime, beat))
        return rows

    # ------------------------------------------------------------------ shutdown
    def _shutdown(self) -> None:
        """Nodes first (the recorder sees them go), then the recorder, then the session."""
        self._shutting_down = True
        interrupt, terminate = self.stop_timeouts
        if self._interrupts > 1:
            interrupt = terminate = 0.0  # a second Ctrl-C: no more patience
            self._hurry.set()
        for run in self.runs.values():
            if run.child.running():
                run.state = "stopping"
            elif run.state == "backoff":
                run.state = "down"  # it crashed and its restart was still to come: not a clean stop
            elif run.state in ("waiting", "starting", "running", "lost"):
                run.state = "stopped"
        stop_all([r.child for r in self.runs.values()], interrupt, terminate, hurry=self._hurry)
        # Report the exits now: the waiters queued them, and the recorder is still listening.
        while True:
            try:
                item = self.events.get_nowait()
            except queue.Empty:
                break
            if item[0] in ("exit", "recorder"):
                self._handle(item)
        ended = time.monotonic()
        for run in self.runs.values():
            if run.state == "stopping":
                run.state = "stopped"
            elif run.state == "down":
                run.down_at_end = ended - run.down_since
        if self.recorder is not None:
            recorder, self.recorder = self.recorder, None  # its exit is ours, not a death
            time.sleep(0.1)  # let the last events reach the recorder before it closes its file
            stop_all([recorder], 5.0, 2.0)
            if recorder.code not in (0, None):
                self.recording_lost = self.recording_lost or f"the recorder ended with {describe_exit(recorder.code)}"
                self.view.line(f"warning: the recorder ended with {describe_exit(recorder.code)}; "
                               f"'iotad recover {self.recording}' makes the file whole"
                               f"{_log_tail(recorder)}")
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
        if self._own_dir and not any(r.state in ("failed", "down") for r in self.runs.values()):
            shutil.rmtree(self.run_dir, ignore_errors=True)
        if self.access is not None:
            self.access.close()  # the credentials never outlive the run

    def summary(self) -> list[str]:
        """Lines for the end of a run: what each output carried, who received it, violations."""
        system, lines = self.system, []
        with self.tally.lock:
            values = {k: Counter(v) for k, v in self.tally.values.items()}
            violations, examples = Counter(self.tally.violations), self.tally.examples.lines()
        for node in system.nodes.values():
            for channel in node.channels.values():
                if channel.direction != "output":
                    continue
                for index in channel.members():
                    port = Port(node.name, channel.name, index)
                    counts = values.get(wire.channel_key(system.name, node.name, channel.name, index), Counter())
                    receivers = ", ".join(str(p) for p in system.receivers_of(port))
                    total = sum(counts.values())
                    labelled = [(v, n) for v, n in counts.items() if v != "*"]
                    if len(labelled) >= VALUE_LABELS:
                        shown = f"{len(labelled)}+ distinct values"
                    else:
                        shown = ", ".join(f"{v} x{n}" for v, n in sorted(labelled, key=_label_order))
                    lines.append(f"  {str(port):<24} {'-> ' + receivers if receivers else '':<22} "
                                 f"{total:>4} events{': ' + shown if shown else ''}")
        lines.append(f"  violations: {sum(violations.values())}"
                     + (" (" + ", ".join(f"{p} x{n}" for p, n in sorted(violations.items())) + ")" if violations else ""))
        lines += [f"    {example}" for example in examples]
        never_live = self.never_live()
        for run in self.runs.values():
            if run.restarts:
                lines.append(f"  {run.name}: restarted {run.restarts} time(s)")
            if run.name in never_live:
                lines.append(f"  {run.name}: NEVER LIVE: it failed {run.failures} time(s), last with "
                             f"{describe_exit(run.last_code)} (its output above says why); the run's exit status is 1")
            elif run.state == "down":
                lines.append(f"  {run.name}: DOWN AT THE END: {describe_exit(run.last_code)} "
                             f"{run.down_at_end:.1f} s before the run ended, its restart still to come; "
                             "the run's exit status is 1")
        if len(self.recordings) == 1 and not self.recording_lost:
            lines.append(f"  recording: {self.recordings[0]}")
        elif len(self.recordings) == 1:
            lines.append(f"  recording (cut short: 'iotad recover' it): {self.recordings[0]}")
        elif self.recordings:
            lines.append(f"  recording in {len(self.recordings)} files (the recorder died): "
                         + ", ".join(str(p) for p in self.recordings)
                         + "; what happened between them is lost, so the run does not exit 0")
        if self.recording_lost:
            lines.append(f"  RECORDING INCOMPLETE: {self.recording_lost}")
        if self.access is not None:
            lines += self.access.summary_lines()
        if not self._own_dir or any(r.state in ("failed", "down") for r in self.runs.values()):
            lines.append(f"  configs and logs: {self.run_dir}")
        return lines


class LauncherError(Exception):
    """The launcher cannot start (the hub endpoint is taken...): one line for the user."""


def _log_tail(child: Child | None, lines: int = 4) -> str:
    """The last lines of a child's output since it last started (its stderr, where errors go;
    the log holds every start's, one after the other), for a report."""
    log = None if child is None else child.log
    if log is None:
        return ""
    try:
        with open(log, "rb") as stream:
            # a chatty log may be huge; an earlier start's lines are not this one's
            stream.seek(max(child.log_start, stream.seek(0, os.SEEK_END) - 4096))
            text = stream.read().decode(errors="replace").strip().splitlines()[-lines:]
    except OSError:
        return ""
    return "".join(f"\n    | {line}" for line in text)


def _label_order(item: tuple) -> tuple:
    return (type(item[0]).__name__, item[0])


__all__ = ["Launcher", "LauncherError", "NodeRun", "Tally"]
