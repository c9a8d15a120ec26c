"""The launcher of one host: runs a checked system as one process per node around a zenoh hub,
supervises them, reports what happens, and stops everything it started.

It builds its parts in order, each complete when built, and runs the loop that owns them: the
`Hub` (`iotad.launcher.run.hub`: the zenoh session, its access control, endpoints and clock), the
`NodeSupervisor` (`iotad.launcher.run.node_supervision`: start order, liveliness, heartbeats,
restarts), the `RecorderSupervisor` (`iotad.launcher.run.recorder_supervision`) and, on a hub
that starts the other hosts, their `Fleet`. One thread (the caller's, normally the main thread)
owns every child: it spawns them (so the parent-death signal of `iotad.launcher.processes` stays
armed for as long as the launcher lives), decides restarts and stops them. zenoh callbacks and
process waiters only put events on its queue (or stamp a heartbeat time).

Failure policy. A node that exits is restarted by its restart policy (`backoff` doubling, at
most `max_restarts`); once the policy gives up, the launcher says so with the tail of the node's
output (its stderr) and keeps the other nodes running, unless the node is `required`, in which
case it stops the whole system (exit status 1). The recorder is watched like a node: if it dies,
the cut-short file is named (`iotad recover` makes it whole) and a new recorder continues in a
new file; a recording that cannot go on is reported and makes the exit status 1, never silent.

Its options come in three frozen objects (`iotad.launcher.options`); what it knows of each node
is a `NodeRun` in a `NodeState` (`iotad.launcher.run.node_run`).
"""
from __future__ import annotations

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
from iotad.kernel.clock import steady_wall
from iotad.node_host.stop_signals import Flag
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.run.hub import Hub, LauncherError
from iotad.launcher.run.node_run import NodeRun, NodeState
from iotad.launcher.run.node_supervision import NodeSupervisor, settle, status_rows, stop_nodes
from iotad.launcher.options import AccessOptions, LaunchOptions, RecordingOptions
from iotad.launcher.processes import Child, RestartPolicy, describe_exit
from iotad.launcher.run.recorder_supervision import RECORDER_STALL, RecorderSupervisor, RecordingError
from iotad.launcher.system.system_file import Port, System, with_port
from iotad.launcher.run.tally import VALUE_LABELS, Tally

# Exit status of `run()` by stop reason: 128 + the signal, like a shell.
_SIGNAL_STATUS = {"interrupted": 130, "SIGTERM": 143, "SIGHUP": 129}


class Launcher:
    """Runs the nodes of `system` that belong to `launch.host` (all of them when None), records
    them as `recording` says (None: no recording) and guards the hub as `access` says (None:
    zenoh's defaults, no authentication). `launch.console` receives every line it prints.
    `fleet`: the agents of the other hosts (iotad/launcher/hosts/fleet.py), for a hub launcher
    that starts the whole of a system spread over hosts; asked to stop before this host's nodes.

    Its parts (`hub`, `nodes`, `recorder`) are built by `run()`, in that order, each whole."""

    def __init__(self, system: System, launch: LaunchOptions = LaunchOptions(),
                 recording: RecordingOptions | None = None, access: AccessOptions | None = None,
                 fleet: Any = None):
        self.system, self.options, self.fleet = system, launch, fleet
        self.host, self.until = launch.host, launch.until
        self.endpoints = with_port(system.listen, launch.port) if launch.port is not None else list(system.listen)
        self.node_argv = launch.node_argv or (lambda config: [sys.executable, "-m", "iotad.node_host", config])
        self._own_dir = launch.log_dir is None
        self.run_dir = Path(launch.log_dir) if launch.log_dir else Path(tempfile.mkdtemp(prefix=f"iotad-{system.name}-"))
        self.run_dir.mkdir(parents=True, exist_ok=True)
        # the hub's credentials and rules, made now: `iotad run --view` hands the tools' file to its viewer
        self.access: AccessControl | None = None if access is None else AccessControl.of(system, access)
        self._recording = recording
        self.events: queue.Queue = queue.Queue()
        self.tally = Tally()
        self.runs: dict[str, NodeRun] = {}
        for spec in system.nodes_on(self.host):
            child = Child(spec.name, [], log=self.run_dir / f"{spec.name.replace('/', '.')}.log",
                          on_exit=self._on_exit)
            policy = RestartPolicy(spec.restart, spec.max_restarts, spec.backoff)
            self.runs[spec.name] = NodeRun(spec, child, policy)
        from iotad.launcher.run.status_view import StatusView
        self.view = StatusView(launch.console, launch.live_table, title=f"iotad run {system.file}")
        # the parts, built whole by run() in this order
        self.hub: Hub | None = None
        self.nodes: NodeSupervisor | None = None
        self.recorder: RecorderSupervisor | None = None
        self._live_at: float | None = None  # with after_live: when every node was first live
        self._stop_reason: str | None = None
        self._host_failed = False  # another host's part exited by itself before the system ran whole
        self._interrupts = 0
        # Set by signal handlers, hence lock-free flags, not threading.Events (iotad.node_host.stop_signals)
        self._stop_asked = Flag()  # a stop was asked for (signal or request_stop)
        self._hurry = Flag()       # a second signal: skip the waiting of the stop
        self._signals: list[int] = []  # the stop signals received, in order; the loop takes them
        self._signals_taken = 0
        self._started = 0.0

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
            # this host's clock as its nodes count time (wall, then monotonic): what the hub
            # answers clock queries on, and what another host measures its offset on
            self.hub = Hub(self.system, self.host, self.endpoints, access=self.access,
                           recorded=self._recording is not None, origin=self.options.origin,
                           steady=steady_wall(), stop=self._stop_asked, events=self.events, view=self.view,
                           tally=self.tally)
            # subscribed before the recorder and the other hosts start: their tokens are seen from the first
            self.nodes = NodeSupervisor(
                self.system, self.host, self.runs, self.hub, launch=self.options, node_argv=self.node_argv,
                run_dir=self.run_dir, access=self.access, view=self.view, hurry=self._hurry,
                want_stop=self._want_stop, others_started=self.fleet is not None, events=self.events)
            self.recorder = self._start_recorder(self.hub)
            self._start_fleet()
            self.view.start()
            self._loop()
        finally:
            self._shutdown()
            self._restore_signals(previous)
        if self._stop_reason in _SIGNAL_STATUS:
            return _SIGNAL_STATUS[self._stop_reason]
        failed = self._host_failed or any(r.state in (NodeState.FAILED, NodeState.DOWN) for r in self.runs.values()) \
            or self.never_live() or (self.nodes is not None and self.nodes.failed_elsewhere) \
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

    def _start_recorder(self, hub: Hub) -> RecorderSupervisor | None:
        """The recorder, started and subscribed before any node starts: the hub's launcher
        records what reaches the hub, another host's launcher what its own nodes do
        (iotad/launcher/hosts/host_recording.py). A recording that cannot be written (no folder,
        no space, the recorder fails) is an error here, while nothing runs yet: --no-record runs
        without one."""
        if self._recording is None:
            return None
        info, reach, nodes = None, self.endpoints, None
        if self.host is not None:  # a run spread over hosts: whose recording this is (iotad merge)
            from iotad.launcher.hosts.host_recording import run_info

            opens = hub.opens_hub
            origin = hub.origin if opens or hub.hub_origin is None else hub.hub_origin
            info = run_info(self.host, opens, origin, None if opens else hub.clock)
            if not opens and hub.local:
                reach = list(hub.local)  # the host's own launcher, not the hub
            if not opens:
                nodes = list(self.runs)  # its own nodes (the hub records the others)
            elif self.system.hosts_keeping_traces():  # the others but those that keep theirs home
                nodes = [node.name for node in self.system.nodes_traced_at(self.host)]
        recorder = RecorderSupervisor(
            self.system, self._recording, hub=reach, run_dir=self.run_dir,
            env=self.access.recorder_env() if self.access else None, events=self.events,
            say=lambda text: self.view.line(text), announce=hub.launcher_event, run_info=info, nodes=nodes)
        try:
            recorder.start()
        except RecordingError as exc:
            raise LauncherError(str(exc)) from None
        return recorder

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

    def _on_exit(self, child: Child, code: int) -> None:  # a waiter thread
        self.events.put(("exit", child.name, child.pid, code))

    # ------------------------------------------------------------------ the loop
    def _loop(self) -> None:
        nodes, last_view = self.nodes, 0.0
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
            nodes.note_live()
            if self.recorder is not None:
                self.recorder.supervise(system_starting=not nodes.system_live)
            nodes.supervise(now)
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
                self.view.update(status_rows(self.runs, now))

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
        """One event of the queue, handed to the part it concerns."""
        kind = item[0]
        if kind == "stop":
            self._want_stop(item[1], f"{'Ctrl-C' if item[1] == 'interrupted' else item[1]}: stopping every node")
        elif kind == "alive":
            self.nodes.alive(*item[1:])
        elif kind == "exit":
            self.nodes.exited(*item[1:])
        elif kind == "recorder":
            if self.recorder is not None:
                self.recorder.exited(item[1], item[2])
        elif kind == "clock":
            self.hub.clock_measured(item[1])
        elif kind == "gaveup":
            self.nodes.gave_up_elsewhere(item[1])
        elif kind == "host" and item[1] == "exited":
            self._host_exited(item[2])
        elif kind == "host" and item[1] == "restarting":
            self._host_restarting(item[2])
        elif kind == "host":
            self.nodes.host_changed(item[1], item[2])

    def _host_exited(self, host: str) -> None:
        """Another host's part ended by itself (its launcher exited; not asked to stop). Before
        every node of that host had been live, or with a required node of its, the system cannot
        run whole: the run stops now, saying why in one line, rather than at its --until (or
        never, with --after-live). Else its nodes are down and the run goes on (its exit status
        will be 1), as for a node that failed for good."""
        code = self.fleet.exits.get(host)
        nodes = [name for name, spec in self.system.nodes.items() if spec.host == host]
        required = [name for name in nodes if self.system.nodes[name].required]
        never = [name for name in nodes if name not in self.nodes.ever_alive]
        if never or required:
            self._stop_for_host(host, code, f"before {', '.join(never)} had been live" if never
                                else f"and {', '.join(required)} {'is' if len(required) == 1 else 'are'} required")
            return
        if code == 0:  # every node of it ended, as a node's script may end: nothing failed
            self.view.line(f"host {host}: its part ended by itself (exit 0): its nodes ({', '.join(nodes)}) ended")
            return
        self.view.line(f"host {host}: its part exited with {code} by itself; its nodes ({', '.join(nodes)}) are down")
        for name in nodes:
            self.hub.publish({"event": "down", "node": name, "host": host, "pid": None, "code": code,
                              "t_ns": time.time_ns(), "message": f"host {host}: its part exited with {code}"})

    def _host_restarting(self, host: str) -> None:
        """Another host's part was killed mid-run and its agent starts it again (after a backoff,
        a bounded number of times: iotad/launcher/hosts/agent.py). Its nodes are down until the
        new part's nodes are live again (their tokens say so, as for any node). A part killed
        before each of its nodes had been live is a failed start, which ends the run as
        `_host_exited` says: a restart would most likely meet the same fate."""
        restart = self.fleet.restarts[host][-1]
        nodes = [name for name, spec in self.system.nodes.items() if spec.host == host]
        never = [name for name in nodes if name not in self.nodes.ever_alive]
        code = restart.get("code")
        if never:
            self._stop_for_host(host, code, f"before {', '.join(never)} had been live")
            return
        backoff = restart.get("in_s")
        backoff = f"{backoff:g}" if isinstance(backoff, (int, float)) else backoff
        line = (f"host {host}: its part was killed (exit {code}); its agent starts it again in "
                f"{backoff} s (restart {restart.get('attempt')} of {restart.get('of')}); "
                f"its nodes ({', '.join(nodes)}) are down until they are live again")
        self.hub.launcher_event("host_part_restarted", line, code=code, restarted_host=host,
                                attempt=restart.get("attempt"), of=restart.get("of"), backoff_s=restart.get("in_s"))
        for name in nodes:
            self.hub.publish({"event": "down", "node": name, "host": host, "pid": None, "code": code,
                              "t_ns": time.time_ns(), "message": f"host {host}: its part was killed; restarting"})

    def _stop_for_host(self, host: str, code: Any, why: str) -> None:
        """Another host's part ended (`code`) so that the system cannot run whole (`why`): one
        line, a `host_failed` event, and the run stops now."""
        line = f"host {host}: its part exited with {code} {why} (its lines above say why): stopping every node"
        self.hub.launcher_event("host_failed", line, code=code, quiet=True, failed_host=host)
        self._host_failed = True
        self._want_stop("host failed", line)

    def _want_stop(self, reason: str, line: str) -> None:
        """The run stops for `reason` (the first one given is the one it stops for)."""
        if self._stop_reason is None:
            self._stop_reason = reason
            self.view.line(line)

    def _until_counts_from(self, now: float) -> float | None:
        """When --until's seconds began (None: no --until, or not every node live yet). With
        after_live, a node that has ended for good counts as live, so a failed start cannot keep
        the run going for ever."""
        if self.until is None:
            return None
        if not self.options.after_live:
            return self._started
        if self._live_at is None and self.nodes.here_live() and self.nodes.other_hosts_live():
            self._live_at = now
            self.view.line(f"every node is live: --until {self.until:g} s counts from now")
        return self._live_at

    # ------------------------------------------------------------------ shutdown
    def _shutdown(self) -> None:
        """Other hosts' parts and this host's nodes first (the recorder sees them go), then the
        recorder, then the session."""
        if self.hub is not None:
            self.hub.stop_watching()  # no measurement of a hub that is going away
        if self.fleet is not None:
            self.fleet.stop(hurry=self._hurry)  # a second Ctrl-C ends its wait too
            self.fleet.close()
        if self.recorder is not None:
            self.recorder.stopping()  # its silence and its exit are the stop's now
        interrupt, terminate = self.options.stop_timeouts
        if self._interrupts > 1:
            interrupt = terminate = 0.0  # a second Ctrl-C: no more patience
            self._hurry.set()
        stop_nodes(self.runs, interrupt, terminate, self._hurry)
        # Report the exits now: the waiters queued them, and the recorder is still listening.
        while True:
            try:
                item = self.events.get_nowait()
            except queue.Empty:
                break
            if item[0] == "recorder" or (item[0] == "exit" and self.nodes is not None):
                self._handle(item)
        settle(self.runs, time.monotonic())
        if self.recorder is not None:
            self.recorder.stop()
        self.view.update(status_rows(self.runs, time.monotonic()))
        self.view.stop()
        if self.hub is not None:
            self.hub.close()
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
        for node in system.nodes_traced_at(self.host):  # another host's launcher: its own nodes
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
        home = system.hosts_keeping_traces() if system.opens_hub(self.host) else []
        if home:
            lines.append(f"  not counted here: the nodes of {', '.join(home)}, which keep their traces home "
                         "(their host's launcher and recording count them)")
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
            elsewhere = self.nodes.failed_elsewhere if self.nodes is not None else set()
            lines += [f"  {name}: FAILED FOR GOOD on host {self.system.nodes[name].host} (its lines above say why); "
                      "the run's exit status is 1" for name in sorted(elsewhere)]
            lines += [f"  host {host}: {self.fleet.outcome(host)}" for host in self.fleet.hosts]
        return lines


def _label_order(item: tuple) -> tuple:
    return (type(item[0]).__name__, item[0])


__all__ = ["RECORDER_STALL", "Launcher", "LauncherError", "NodeRun", "NodeState", "Tally"]
