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
new file; a recording that cannot go on is reported and makes the exit status 1, never silent
(`iotad.launcher.run.recorder_supervision`).

Its options come in three frozen objects (`iotad.launcher.options`); what it knows of each node
is a `NodeRun` in a `NodeState` (`iotad.launcher.run.node_run`).
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
from pathlib import Path
from typing import Any

from iotad.node_host import wire
from iotad.machine.clock_offset import ClockServer
from iotad.kernel.clock import steady_wall, wall
from iotad.node_host.node_config import CONFIGURATION_ERROR
from iotad.node_host.stop_signals import Flag
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.run.node_run import NodeRun, NodeState
from iotad.launcher.options import AccessOptions, LaunchOptions, RecordingOptions
from iotad.launcher.processes import FAILED_TO_START, Child, RestartPolicy, describe_exit, log_tail, stop_all
from iotad.launcher.run.recorder_supervision import RECORDER_STALL, RecorderSupervisor, RecordingError
from iotad.launcher.system.system_file import Port, System, with_port
from iotad.launcher.run.tally import VALUE_LABELS, Tally

# Exit status of `run()` by stop reason: 128 + the signal, like a shell.
_SIGNAL_STATUS = {"interrupted": 130, "SIGTERM": 143, "SIGHUP": 129}


class Launcher:
    """Runs the nodes of `system` that belong to `launch.host` (all of them when None), records
    them as `recording` says (None: no recording) and guards the hub as `access` says (None:
    zenoh's defaults, no authentication). `launch.console` receives every line it prints."""

    def __init__(self, system: System, launch: LaunchOptions = LaunchOptions(),
                 recording: RecordingOptions | None = None, access: AccessOptions | None = None,
                 fleet: Any = None):
        self.system, self.options = system, launch
        # the agents of the other hosts (iotad/launcher/hosts/fleet.py), for a hub launcher that starts
        # the whole of a system spread over hosts; asked to stop before this host's own nodes
        self.fleet = fleet
        self._hub_answered = False  # another host's launcher: the hub launcher answered its origin query
        self.host, self.until = launch.host, launch.until
        self._live_at: float | None = None  # with after_live: when every node was first live
        self.hub = with_port(system.listen, launch.port) if launch.port is not None else list(system.listen)
        self.origin = launch.origin
        self.node_argv = launch.node_argv or (lambda config: [sys.executable, "-m", "iotad.node_host", config])
        self._own_dir = launch.log_dir is None
        self.run_dir = Path(launch.log_dir) if launch.log_dir else Path(tempfile.mkdtemp(prefix=f"iotad-{system.name}-"))
        self.run_dir.mkdir(parents=True, exist_ok=True)
        # the hub's credentials and rules, made now: `iotad run --view` hands the tools' file to its viewer
        self.access: AccessControl | None = None if access is None else AccessControl.of(system, access)
        self.events: queue.Queue = queue.Queue()
        self.tally = Tally()
        self.alive_paths: set[str] = set()
        self._ever_alive: set[str] = set()  # every node path that has shown its token, on any host
        self.runs: dict[str, NodeRun] = {}
        for spec in system.nodes_on(self.host):
            child = Child(spec.name, [], log=self.run_dir / f"{spec.name.replace('/', '.')}.log",
                          on_exit=self._on_exit)
            policy = RestartPolicy(spec.restart, spec.max_restarts, spec.backoff)
            self.runs[spec.name] = NodeRun(spec, child, policy)
        self.session = None
        # this host's clock as its nodes count time (wall, then monotonic): what the hub answers
        # clock queries on, and what another host measures its offset on (iotad/launcher/hosts/clock_watch.py)
        self._steady = steady_wall()
        self.clock_watch = None  # another host's launcher, where the hub answered: its clock measured
        self._origin_publisher = None
        self._publisher = None
        self._event_seq = 0
        self._declared: list[Any] = []
        self._stop_reason: str | None = None
        self._interrupts = 0
        # Set by signal handlers, hence lock-free flags, not threading.Events (iotad.node_host.stop_signals)
        self._stop_asked = Flag()  # a stop was asked for (signal or request_stop)
        self._hurry = Flag()       # a second signal: skip the waiting of the stop
        self._signals: list[int] = []  # the stop signals received, in order; the loop takes them
        self._signals_taken = 0
        self._started = 0.0
        # The start gate: nodes started before it opens go live and wait; once every node is
        # live (or has ended for good) the launcher declares its token and their engines start
        # together, none of them running while another still imports on the same cores.
        self.gate_key = wire.gate_key(system.name, self.host)
        self.gate_open = not system.start_gate  # start_gate = false: no gate, as if always open
        self._system_live = False  # every node has been live (or ended) once: the system runs
        from iotad.launcher.run.status_view import StatusView
        self.view = StatusView(launch.console, launch.live_table, title=f"iotad run {system.file}")
        # the recorder: the hub's launcher records what reaches the hub, another host's launcher
        # what its own nodes do (iotad/launcher/hosts/host_recording.py)
        # made by _start_recorder, whole, once the hub session says where it records and from when
        self.recorder: RecorderSupervisor | None = None
        self._recording = recording
        self._local: list[str] = []      # another host's launcher: where its recorder and nodes reach it
        if self.access is not None and self.access.own is not None and not system.opens_hub(self.host):
            # under access control its session is its host's router, on a private unix socket
            # (iotad/launcher/access/host_router.py): its nodes and recorder reach nothing else
            self._local = [self.access.route(self.host)]
        self._hub_origin: float | None = None  # another host's launcher: the origin the hub answered
        self._clock: dict | None = None        # another host's launcher: its clock offset, as measured

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
            self._start_fleet()
            self.view.start()
            self._loop()
        finally:
            self._shutdown()
            self._restore_signals(previous)
        if self._stop_reason in _SIGNAL_STATUS:
            return _SIGNAL_STATUS[self._stop_reason]
        failed = any(r.state in (NodeState.FAILED, NodeState.DOWN) for r in self.runs.values()) or self.never_live() \
            or (self.fleet is not None and self.fleet.failures())
        # a recorder that died mid-run left a gap between its files: what happened then is lost
        return 1 if failed or (self.recorder is not None and self.recorder.incomplete) else 0

    def never_live(self) -> list[str]:
        """Nodes that failed every time they started and never went live: the run ended (its
        --until) while the restart policy still retried them, but the system never ran whole."""
        return [r.name for r in self.runs.values() if not r.went_live and r.failures]

    # ------------------------------------------------------------------ set-up
    def _install_signals(self) -> dict:
        if threading.current_thread() is not threading.main_thread():
            return {}

        def on_signal(signum, frame):
            # SIGTERM and SIGHUP stop exactly like Ctrl-C (a second one: no more patience). Only
            # noted here: a handler that took a lock (the event queue's put) could wait for ever
            # on the main thread it interrupted; the loop takes the signal within 50 ms.
            self._interrupts += 1
            self._signals.append(signum)
            self._stop_asked.set()
            if self._interrupts > 1:
                self._hurry.set()  # also cuts short a stop already under way

        previous = {}
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            previous[signum] = signal.signal(signum, on_signal)
        return previous

    @staticmethod
    def _restore_signals(previous: dict) -> None:
        for signum, handler in previous.items():
            signal.signal(signum, handler)

    def _open_session(self) -> None:
        from iotad.node_host.transport import open_session, reachable
        from iotad.launcher.system.can_env import unresolved

        system = self.system
        if (problem := unresolved(system, self.host)) is not None:  # [[can]] interface = "env", none set
            raise LauncherError(problem)
        if system.opens_hub(self.host):
            listen, connect = self.hub, list(system.connect)
        else:
            listen, connect = system.listen_for(self.host), self.hub
            if self.access is not None and self.access.router is not None:
                listen = list(self._local)
            elif self._recording is not None:  # its recorder and nodes connect here: a known port
                from iotad.launcher.hosts.host_recording import local_endpoints, pinned

                listen = pinned(listen)
                self._local = local_endpoints(listen)
        try:
            self.session = open_session(listen, connect, **(self.access.hub_options() if self.access else {}))
        except Exception as exc:  # noqa: BLE001 - zenoh says why in its message
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            if "Address already in use" in text:
                raise LauncherError(f"the hub endpoint {', '.join(listen)} is taken (another 'iotad run'?); "
                                    "choose another with --port") from None
            if self.access is not None and self.access.own is not None:  # another host's, under access control
                from iotad.node_host.admission import diagnose
                from iotad.machine.certificates import from_env

                text = f"not admitted: {diagnose(connect[0], from_env(), self.access.own.user).reason}"
            raise LauncherError(f"cannot open the hub session (listen {listen}, connect {connect}): {text}") from None
        session = self.session
        if system.opens_hub(self.host):  # with --port 0 this is the only place the port is told
            tools = reachable(listen[0])
            self.view.line(f"hub: {', '.join(listen)} (tools attach with --connect {tools}, e.g. iotad top --connect {tools})")
        for line in (self.access.opened(listen) if self.access and system.opens_hub(self.host) else ()):
            self.view.line(line)
        self._publisher = session.declare_publisher(wire.launcher_key(system.name))
        self._declared.append(self._publisher)
        self._declared.append(session.liveliness().declare_subscriber(
            wire.every_node(system.name, wire.ALIVE), self._on_liveliness, history=True))
        self._declared.append(session.declare_subscriber(wire.every_node(system.name, wire.HEARTBEAT), self._on_heartbeat))
        self._declared.append(session.declare_subscriber(wire.every_node(system.name, wire.TRACE), self._on_trace))
        if system.opens_hub(self.host):
            if self.origin is None:
                self.origin = wall()
            # the hub's clock, which every other host measures itself against (docs/hosts.md)
            self._declared.append(ClockServer(session, system.name, clock=self._steady))
            origin_payload = wire.encode({"origin": self.origin})
            key = wire.origin_key(system.name)
            self._declared.append(session.declare_queryable(key, lambda q: q.reply(key, origin_payload)))
        elif self.origin is None:
            self.origin = self._ask_origin()
            if self._hub_answered:  # a hub that answered has a clock to measure against
                self._correct_clock()

    def _ask_origin(self) -> float:
        """A launcher for one host of several takes the hub launcher's origin, so that every
        node's `t` counts from one instant; if the hub does not answer, its own (with a warning)."""
        deadline = time.monotonic() + self.system.start_timeout
        key = wire.origin_key(self.system.name)
        self.view.line(f"waiting up to {self.system.start_timeout:g} s for the hub launcher's clock origin on {key}")
        while time.monotonic() < deadline and not self._stop_asked.is_set():
            for reply in self.session.get(key, timeout=1.0):
                if reply.ok is not None:
                    self._hub_answered = True
                    self._hub_origin = float(wire.decode(reply.ok.payload.to_bytes())["origin"])
                    return self._hub_origin
            self._stop_asked.wait(0.2)
        if self._stop_asked.is_set():
            return wall()  # stopping before anything started: the origin no longer matters
        self.view.line(f"warning: no hub launcher answered on {key}; this host's nodes use its own clock origin")
        return wall()

    def _correct_clock(self) -> None:
        """Measure this host's clock against the hub's and move the origin by the offset, so that
        this host's nodes count `t` on the hub's timeline; then measure it again every
        `clock_period` during the run, and have the nodes' clocks follow (_clock_measured). Each
        measurement is a launcher event (`clock`, in the recording); one known no better than the
        system's `clock_bound`, or one that finds the nodes' clocks off by more, is a
        `clock_violation` event and a warning: windows on this host are then judged on a clock
        that may be off by that much."""
        from iotad.launcher.hosts.clock_watch import ClockWatch

        system = self.system
        self.clock_watch = watch = ClockWatch(
            self.session, system.name, self.host, self.origin, time_unit=system.time_unit, limit=system.clock_bound,
            period=system.clock_period, clock=self._steady, report=lambda reading: self.events.put(("clock", reading)))
        self._clock_measured(watch.first(stop=self._stop_asked))
        self._origin_publisher = self.session.declare_publisher(wire.host_origin_key(system.name, self.host))
        self._declared.append(self._origin_publisher)
        watch.start()

    def _clock_measured(self, reading: Any) -> None:
        """A measurement of this host's clock (a `ClockReading`, or why there is none): move the
        origin of nodes started from now on, tell the running ones, record it. A reading at start
        is said on the console; later ones only when they are violations (one every
        `clock_period` would drown the run's lines)."""
        if isinstance(reading, str):
            self._launcher_event("clock_violation", reading, host=self.host)
            return
        self.origin = self.clock_watch.origin
        if self._origin_publisher is not None:
            try:
                self._origin_publisher.put(wire.encode({"origin": self.origin}))
            except Exception:  # noqa: BLE001 - a closing session: the run is ending anyway
                pass
        event = reading.event()
        if self._clock is None and "offset" in event:
            # the clock measured at start, for this host's own recording (started after it)
            self._clock = dict(event, measured_ns=round(wall() * 1e9))
        self._launcher_event("clock_violation" if reading.problem else "clock", reading.message(),
                             quiet=not (reading.first or reading.problem), **event)

    def _start_recorder(self) -> None:
        """Start the recorder and wait until it has subscribed, before any node starts. A
        recording that cannot be written (no folder, no space, the recorder fails) is an error
        here, while nothing runs yet: --no-record runs without one."""
        if self._recording is not None:
            info, reach, nodes = None, self.hub, None
            if self.host is not None:  # a run spread over hosts: whose recording this is (iotad merge)
                from iotad.launcher.hosts.host_recording import run_info

                hub = self.system.opens_hub(self.host)
                origin = self.origin if hub or self._hub_origin is None else self._hub_origin
                info = run_info(self.host, hub, origin, None if hub else self._clock)
                if not hub and self._local:
                    reach = list(self._local)  # the host's own launcher, not the hub
                if not hub:
                    nodes = list(self.runs)  # its own nodes (the hub records the others)
            self.recorder = RecorderSupervisor(
                self.system, self._recording, hub=reach, run_dir=self.run_dir,
                env=self.access.recorder_env() if self.access else None, events=self.events,
                say=lambda text: self.view.line(text), announce=self._launcher_event, run_info=info, nodes=nodes)
            try:
                self.recorder.start()
            except RecordingError as exc:
                raise LauncherError(str(exc)) from None

    def _start_fleet(self) -> None:
        """Give every other host its part through its agent, before this host's nodes start (the
        start gate then waits for all of them together)."""
        if self.fleet is None:
            return
        from iotad.launcher.hosts.fleet import FleetError

        try:
            # a host lost or back is the loop's to report (its nodes' state, the recording);
            # Ctrl-C ends the wait for agents at once
            self.fleet.start(self.access, stop=self._stop_asked, say=self.view.line,
                             notify=lambda event, host: self.events.put(("host", event, host)))
        except FleetError as exc:
            raise LauncherError(str(exc)) from None

    # ------------------------------------------------------------------ zenoh callbacks (their threads)
    def _on_liveliness(self, sample: Any) -> None:
        import zenoh
        path = wire.node_path(sample.key_expr, self.system.name, wire.ALIVE)
        if path is not None:
            self.events.put(("alive", path, sample.kind == zenoh.SampleKind.PUT, time.monotonic()))

    def _on_heartbeat(self, sample: Any) -> None:
        path = wire.node_path(sample.key_expr, self.system.name, wire.HEARTBEAT)
        run = self.runs.get(path) if path is not None else None
        if run is not None and run.state in (NodeState.STARTING, NodeState.RUNNING, NodeState.LOST):
            run.last_beat = time.monotonic()  # one attribute store: safe across threads

    def _on_trace(self, sample: Any) -> None:
        # Outputs are counted from the nodes' traces, not from their keys: a subscriber to every
        # channel key would wake this process for every message, which the nodes pay for.
        path = wire.node_path(sample.key_expr, self.system.name, wire.TRACE)
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
            self._take_signals()
            if self._stop_reason is not None:
                return
            now = time.monotonic()
            self._supervise(now)
            since = self._until_counts_from(now)
            if since is not None and now - since >= self.until:
                self._stop_reason = "until"
                after = " after every node was live" if self.options.after_live else ""
                self.view.line(f"--until {self.until:g} s{after} reached: stopping")
                return
            if self.runs and all(r.finished for r in self.runs.values()):
                self._stop_reason = "all nodes ended"
                self.view.line("every node has ended: stopping")
                return
            if now - last_view >= 0.25:
                last_view = now
                self.view.update(self._rows(now))

    def _take_signals(self) -> None:
        """The stop signals the handler noted since the last turn, as stop requests."""
        while self._signals_taken < len(self._signals):
            signum = self._signals[self._signals_taken]
            self._signals_taken += 1
            self._handle(("stop", "interrupted" if signum == signal.SIGINT else signal.Signals(signum).name))

    def _next_wake(self, now: float) -> float:
        """At most 50 ms, less when a restart is due sooner: the backoff is all a restart waits."""
        due = [run.restart_at for run in self.runs.values() if run.state == NodeState.BACKOFF]
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
            if present:
                self._ever_alive.add(path)
            run = self.runs.get(path)
            if run is None:
                if present and self.host is not None:
                    self.view.line(f"{path}: live (on another host)")
                return
            if present and run.state in (NodeState.STARTING, NodeState.LOST):
                run.state, run.live_since, run.lost_since = NodeState.RUNNING, when, None
                run.went_live = True
                self._event("live", run, f"live (pid {run.child.pid})")
            elif not present and run.state == NodeState.RUNNING and run.child.running():
                run.state, run.lost_since = NodeState.LOST, when
                self._event("lost", run, "liveliness token gone while its process runs")
        elif kind == "exit":
            _, name, pid, code = item
            run = self.runs.get(name)
            if run is not None and pid == run.child.pid:
                self._exited(run, code)
        elif kind == "recorder":
            if self.recorder is not None:
                self.recorder.exited(item[1], item[2])
        elif kind == "clock":
            self._clock_measured(item[1])
        elif kind == "host":
            self._host_changed(item[1], item[2])

    def _host_changed(self, event: str, host: str) -> None:
        """Another host's agent was lost, or came back and runs its part again: its nodes are
        down (a launcher event each, in the recording) or starting again. Their peers learn of
        the restart from the nodes' own tokens when they come back (iotad/node_host/peer_restart.py)."""
        nodes = [name for name, spec in self.system.nodes.items() if spec.host == host]
        if event == "lost":
            for name in nodes:
                self.view.line(f"{name}: DOWN (host {host} lost)")
                self._publish({"event": "down", "node": name, "host": host, "pid": None, "code": None,
                               "t_ns": time.time_ns(), "message": f"host {host} lost"})
        elif event == "resumed":
            self._launcher_event("host_back", f"host {host}: back; its nodes ran on while it was cut off "
                                              f"({', '.join(nodes)})", host=host, resumed=True)
        else:
            self._launcher_event("host_back", f"host {host}: back; its nodes start again ({', '.join(nodes)})",
                                 host=host, resumed=False)

    def _exited(self, run: NodeRun, code: int) -> None:
        now = time.monotonic()
        self.alive_paths.discard(run.name)
        uptime = now - run.child.started_at
        if run.state == NodeState.STOPPING:
            # the stop's exit status is not the node's last failure, which the summary reports
            run.state = NodeState.STOPPED
            self._event("exit", run, f"stopped ({describe_exit(code)}){self._stop_escalation(run, code)}", code=code)
            return
        run.last_code = code
        reason = f" ({run.killed_for})" if run.killed_for else ""
        run.killed_for = None
        run.failures += code != 0
        tail = "" if code == 0 else log_tail(run.child)
        what = f"{describe_exit(code)}{reason} after {uptime:.1f} s"
        if uptime >= run.policy.healthy_after:
            run.consecutive = 0
        policy = run.policy
        if code != CONFIGURATION_ERROR and policy.wants_restart(code, run.restarts):
            delay = policy.delay(run.consecutive)
            run.consecutive += 1
            run.state, run.restart_at, run.down_since = NodeState.BACKOFF, now + delay, now
            self._event("exit", run, f"{what}; restart {run.restarts + 1}/{policy.max_restarts} "
                                     f"in {delay:.2f} s{tail}", code=code)
            return
        self._event("exit", run, what, code=code)
        if code == CONFIGURATION_ERROR:
            # the node host could not start with what it was given (its spec, its CAN bus...):
            # the same start fails the same way, so the node ends and its reason is said once
            run.state = NodeState.FAILED
            self._event("giveup", run, f"failed for good: {describe_exit(code)} is a configuration error, "
                                       f"which no restart mends{tail}", code=code)
        elif policy.mode == "never" or (code == 0 and policy.mode == "on-failure"):
            run.state = NodeState.EXITED if code == 0 else NodeState.FAILED
            if code != 0:
                self._event("giveup", run, f"failed for good: {describe_exit(code)}, and restart = "
                                           f"\"never\"{tail}", code=code)
        else:
            run.state = NodeState.FAILED
            self._event("giveup", run, f"gave up after {run.restarts} restarts (max_restarts = "
                                       f"{policy.max_restarts}); last: {describe_exit(code)}{tail}", code=code)
        if run.spec.required and self._stop_reason is None:
            self._stop_reason = f"required node {run.name} ended"
            self.view.line(f"{run.name} is required and has ended for good: stopping every node")

    def _stop_escalation(self, run: NodeRun, code: int) -> str:
        """How far the stop had to go, when it went past SIGINT."""
        interrupt, terminate = self.options.stop_timeouts
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
        if not self.options.after_live:
            return self._started
        if self._live_at is None and self._here_live() and self._other_hosts_live():
            self._live_at = now
            self.view.line(f"every node is live: --until {self.until:g} s counts from now")
        return self._live_at

    def _other_hosts_live(self) -> bool:
        """A hub that starts the other hosts through their agents: every node of theirs has been
        live once (they start seconds after this host's, an agent and a launcher later), so that
        --after-live's seconds are the whole system's. The start gates stay each host's own."""
        if self.fleet is None:
            return True
        return all(name in self._ever_alive for name in self.system.nodes if name not in self.runs)

    def _here_live(self) -> bool:
        """This host's nodes are all live (`_everyone_live`); a hub host that holds no node of its
        own (only the hub and the recorder) has none to wait for: without this its --until never
        began and its recorder was judged as starting all run."""
        return self._everyone_live() or (not self.runs and self.fleet is not None)

    def _everyone_live(self) -> bool:
        """Every node is live or has ended for good, and one at least is live: a node that failed
        to start must not hold the others (nor the gate) for ever."""
        runs = self.runs.values()
        return bool(self.runs) and any(r.state == NodeState.RUNNING for r in runs) \
            and all(r.state == NodeState.RUNNING or r.finished for r in runs)

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

    def _supervise(self, now: float) -> None:
        system = self.system
        self._system_live = self._system_live or self._everyone_live() or \
            (not self.runs and self.fleet is not None and self._other_hosts_live())
        if self.recorder is not None:
            self.recorder.supervise(system_starting=not self._system_live)
        self._open_gate()
        for run in self.runs.values():
            if run.state == NodeState.WAITING and all(dep in self.alive_paths for dep in run.spec.after):
                self._spawn(run, "start")
            elif run.state == NodeState.WAITING and (failed := [dep for dep in run.spec.after if dep in self.runs
                                                        and self.runs[dep].state == NodeState.FAILED]):
                # it can never start: say so, and let a run whose other nodes have ended end
                run.state = NodeState.FAILED
                self._event("giveup", run, f"will not start: it starts after {', '.join(failed)}, "
                                           "which failed for good")
                if run.spec.required and self._stop_reason is None:
                    self._stop_reason = f"required node {run.name} cannot start"
                    self.view.line(f"{run.name} is required and cannot start: stopping every node")
            elif run.state == NodeState.BACKOFF and now >= run.restart_at:
                run.restarts += 1
                self._spawn(run, "restart")
            elif run.state == NodeState.STARTING and now - run.child.started_at > system.start_timeout:
                self._kill(run, f"no liveliness token within {system.start_timeout:g} s")
            elif run.state == NodeState.RUNNING and now - (run.last_beat or run.live_since) > system.heartbeat_timeout:
                # Counted from the token when no heartbeat came yet: a node frozen between its
                # token and its first heartbeat is as stale as one frozen later.
                self._kill(run, f"no heartbeat for {now - (run.last_beat or run.live_since):.1f} s"
                                + (" (none since it went live)" if run.last_beat is None else ""))
            elif run.state == NodeState.LOST and now - run.lost_since > system.heartbeat_timeout:
                self._kill(run, f"liveliness token gone for {now - run.lost_since:.1f} s")

    def _spawn(self, run: NodeRun, event: str) -> None:
        # another host's recording: its nodes connect to its launcher too, so that its recorder
        # hears them from their first event and while the hub is out of reach
        # (under access control only to its router, which links it to the hub: host_router.py)
        routed = self.access is not None and self.access.router is not None
        config = self.system.node_config(run.name, self.origin, self._local if routed else self.hub + self._local)
        config["restarts"] = run.restarts  # its heartbeats say it: a tool attached later counts them
        if not self.gate_open:  # a node (re)started after the gate opened starts its engine at once
            config["start_gate"] = self.gate_key
        if self.clock_watch is not None:  # its clock follows this host's measurements of the hub's
            config["follow_origin"] = wire.host_origin_key(self.system.name, self.host)
        path = self.run_dir / f"{run.name.replace('/', '.')}.json"
        path.write_text(json.dumps(config, indent=1))
        run.child.argv = self.node_argv(str(path))
        if self.access is not None:
            run.child.env = self.access.node_env(run.name)  # its own credentials (IOTAD_CREDENTIALS)
        run.last_beat = run.live_since = run.lost_since = None
        try:
            run.child.start()
        except OSError as exc:
            run.state = NodeState.FAILED
            self._event("exit", run, f"cannot start: {exc}", code=FAILED_TO_START)
            return
        run.state = NodeState.STARTING
        what = "started" if event == "start" else f"restarted (#{run.restarts})"
        self._event(event, run, f"{what}, pid {run.child.pid}")

    def _kill(self, run: NodeRun, why: str) -> None:
        run.killed_for = why
        self._event("stale", run, f"{why}: killing pid {run.child.pid}")
        run.child.signal(signal.SIGKILL)
        run.state = NodeState.LOST           # until its exit arrives
        run.lost_since = float("inf")  # do not kill twice

    # ------------------------------------------------------------------ reporting
    def _event(self, event: str, run: NodeRun, text: str, code: int | None = None) -> None:
        self.view.line(f"{run.name}: {text}")
        self._publish({"event": event, "node": run.name, "pid": run.child.pid, "code": code,
                       "t_ns": time.time_ns(), "restarts": run.restarts})

    def _launcher_event(self, event: str, text: str, code: int | None = None, quiet: bool = False,
                        **extra: Any) -> None:
        """An event of the launcher itself (node None): the recorder's fate... `quiet`: recorded,
        not shown."""
        if not quiet:
            self.view.line(text)
        self._publish({"event": event, "node": None, "pid": os.getpid(), "code": code,
                       "t_ns": time.time_ns(), "message": text.split("\n", 1)[0], **extra})

    def _publish(self, payload: dict) -> None:
        if self._publisher is None:
            return
        if self.host is not None:
            payload.setdefault("host", self.host)  # a lost host's nodes are named with their own
        try:
            self._publisher.put(wire.encode(payload), attachment=wire.encode_attachment(self._event_seq))
            self._event_seq += 1
        except Exception:  # noqa: BLE001 - a closing session must not stop the shutdown
            pass

    def _rows(self, now: float) -> list[tuple]:
        rows = []
        for run in self.runs.values():
            uptime = f"{now - run.live_since:.1f}s" if run.live_since and run.state == NodeState.RUNNING else "-"
            beat = f"{now - run.last_beat:.2f}s" if run.last_beat and not run.finished else "-"
            state = run.state if run.state not in (NodeState.EXITED, NodeState.FAILED, NodeState.DOWN) or run.last_code is None else \
                f"{run.state} ({describe_exit(run.last_code)})"
            pid = str(run.child.pid) if run.child.pid and not run.finished else "-"
            rows.append((run.name, run.spec.host or "", pid, state, str(run.restarts), uptime, beat))
        return rows

    # ------------------------------------------------------------------ shutdown
    def _shutdown(self) -> None:
        """Other hosts' parts and this host's nodes first (the recorder sees them go), then the
        recorder, then the session."""
        if self.clock_watch is not None:
            self.clock_watch.close()  # no measurement of a hub that is going away
        if self.fleet is not None:
            self.fleet.stop(hurry=self._hurry)  # a second Ctrl-C ends its wait too
            self.fleet.close()
        if self.recorder is not None:
            self.recorder.stopping()  # its silence and its exit are the stop's now
        interrupt, terminate = self.options.stop_timeouts
        if self._interrupts > 1:
            interrupt = terminate = 0.0  # a second Ctrl-C: no more patience
            self._hurry.set()
        for run in self.runs.values():
            if run.child.running():
                run.state = NodeState.STOPPING
            elif run.state == NodeState.BACKOFF:
                run.state = NodeState.DOWN  # it crashed and its restart was still to come: not a clean stop
            elif run.state in (NodeState.WAITING, NodeState.STARTING, NodeState.RUNNING, NodeState.LOST):
                run.state = NodeState.STOPPED
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
            if run.state == NodeState.STOPPING:
                run.state = NodeState.STOPPED
            elif run.state == NodeState.DOWN:
                run.down_at_end = ended - run.down_since
        if self.recorder is not None:
            self.recorder.stop()
        self.view.update(self._rows(time.monotonic()))
        self.view.stop()
        for entity in reversed(self._declared):
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001
                pass
        self._declared.clear()
        if self.session is not None:
            from iotad.node_host.session_close import close_session

            session, self.session = self.session, None
            problem = close_session(session)  # never waits on a host that is cut off
            if problem:
                print(problem, flush=True)
        if self._own_dir and not any(r.state in (NodeState.FAILED, NodeState.DOWN) for r in self.runs.values()):
            shutil.rmtree(self.run_dir, ignore_errors=True)
        if self.access is not None:
            self.access.close()  # the credentials never outlive the run

    def summary(self) -> list[str]:
        """Lines for the end of a run: what each output carried, who received it, violations."""
        system, lines = self.system, []
        with self.tally.lock:
            values = {k: Counter(v) for k, v in self.tally.values.items()}
            violations, examples = Counter(self.tally.violations), self.tally.examples.lines()
            recordings = self.recorder.recordings if self.recorder is not None else []
            more = self.tally.examples.more(str(recordings[0]) if recordings else None)
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
        lines += [f"    {example}" for example in examples] + ([f"    {more}"] if more else [])
        never_live = self.never_live()
        for run in self.runs.values():
            if run.restarts:
                lines.append(f"  {run.name}: restarted {run.restarts} time(s)")
            if run.name in never_live:
                lines.append(f"  {run.name}: NEVER LIVE: it failed {run.failures} time(s), last with "
                             f"{describe_exit(run.last_code)} (its output above says why); the run's exit status is 1")
            elif run.state == NodeState.DOWN:
                lines.append(f"  {run.name}: DOWN AT THE END: {describe_exit(run.last_code)} "
                             f"{run.down_at_end:.1f} s before the run ended, its restart still to come; "
                             "the run's exit status is 1")
        if self.recorder is not None:
            lines += self.recorder.summary_lines()
        if self.access is not None:
            lines += self.access.summary_lines()
        if not self._own_dir or any(r.state in (NodeState.FAILED, NodeState.DOWN) for r in self.runs.values()):
            lines.append(f"  configs and logs: {self.run_dir}")
        if self.fleet is not None:
            lines += [f"  host {host}: {self.fleet.outcome(host)}" for host in self.fleet.hosts]
        return lines


class LauncherError(Exception):
    """The launcher cannot start (the hub endpoint is taken...): one line for the user."""


def _label_order(item: tuple) -> tuple:
    return (type(item[0]).__name__, item[0])


__all__ = ["RECORDER_STALL", "Launcher", "LauncherError", "NodeRun", "NodeState", "Tally"]
