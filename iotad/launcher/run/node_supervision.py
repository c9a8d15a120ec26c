"""The node runs of one host's launcher: started in `after` order behind the start gate, watched
three ways (process exit, liveliness token, heartbeat), restarted by their policy, stopped at the
end; and what the nodes' traces carry, counted for the summary.

A node's death is seen three ways: its process exits (a waiter thread queues it), its liveliness
token goes away (zenoh), or its heartbeat goes stale while the process still runs (a frozen
Python loop): then it is killed and restarted like a crash. zenoh callbacks only queue events or
stamp a heartbeat time; everything else runs on the launcher's thread, which owns every child.
"""
from __future__ import annotations

import json
import queue
import signal
import time
from pathlib import Path
from typing import Any, Callable

from iotad.node_host import wire
from iotad.node_host.node_config import CONFIGURATION_ERROR
from iotad.node_host.stop_signals import Flag
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.access.open_hosts import OpenHosts
from iotad.launcher.options import LaunchOptions
from iotad.launcher.processes import FAILED_TO_START, describe_exit, log_tail, stop_all
from iotad.launcher.run.hub import Hub
from iotad.launcher.run.node_run import NodeRun, NodeState
from iotad.launcher.system.system_file import System


class NodeSupervisor:
    """The nodes `runs` of `system` on `host`, supervised through `hub`, whose session it
    subscribes to on construction (every node's token and heartbeat, on any host).

    `view`: the status view. `want_stop(reason,
    line)`: a required node ended for good, the run must stop. `others_started`: this launcher's
    fleet starts the other hosts' nodes (their first liveliness then counts for --after-live)."""

    def __init__(self, system: System, host: str | None, runs: dict[str, NodeRun], hub: Hub, *,
                 launch: LaunchOptions, node_argv: Callable[[str], list[str]], run_dir: Path,
                 access: AccessControl | None, view: Any, hurry: Flag,
                 want_stop: Callable[[str, str], None], others_started: bool, events: queue.Queue):
        self.system, self.host, self.runs, self.hub = system, host, runs, hub
        self.options, self.node_argv, self.run_dir, self.access = launch, node_argv, run_dir, access
        self.view, self._hurry, self._want_stop = view, hurry, want_stop
        self.others_started, self._events = others_started, events
        self.alive_paths: set[str] = set()
        self.ever_alive: set[str] = set()  # every node path that has shown its token, on any host
        # The start gate: nodes started before it opens go live and wait; once every node is
        # live (or has ended for good) the launcher declares its token and their engines start
        # together, none of them running while another still imports on the same cores.
        self.gate_key = wire.gate_key(system.name, host)
        self.gate_open = not system.start_gate  # start_gate = false: no gate, as if always open
        self.system_live = False  # every node has been live (or ended) once: the system runs
        session = hub.session
        # an open run over hosts: what each node sends with BLOCK goes to other hosts with DROP, to
        # this host's sessions as sent (iotad/launcher/access/open_hosts.py)
        secured = access is not None and access.store is not None
        self.open_hosts = OpenHosts({name: run.policy.max_restarts for name, run in runs.items()},
                                    str(session.info.zid())) if OpenHosts.applies(system, host, secured) else None
        hub.declare(session.liveliness().declare_subscriber(
            wire.every_node(system.name, wire.ALIVE), self._on_liveliness, history=True))
        hub.declare(session.declare_subscriber(wire.every_node(system.name, wire.HEARTBEAT), self._on_heartbeat))
        self.failed_elsewhere: set[str] = set()  # other hosts' nodes their launcher gave up
        self.host_files: dict[str, list[str]] = {}  # host -> the files its restarted recorders went on in
        if others_started:
            hub.declare(session.declare_subscriber(wire.launcher_key(system.name), self._on_launcher_event))

    # ------------------------------------------------------------------ zenoh callbacks (their threads)
    def _on_liveliness(self, sample: Any) -> None:
        import zenoh
        path = wire.node_path(sample.key_expr, self.system.name, wire.ALIVE)
        if path is not None:
            self._events.put(("alive", path, sample.kind == zenoh.SampleKind.PUT, time.monotonic()))

    def _on_launcher_event(self, sample: Any) -> None:
        """Another host's launcher gave a node of its up (a configuration error, its restarts
        spent): it will not be live, and --after-live must not wait for it. Or its recorder was
        restarted: the file it goes on in is noted for the run's summary."""
        try:
            event = wire.decode(sample.payload.to_bytes())
        except wire.WireError:
            return
        if isinstance(event, dict) and event.get("event") == "recorder" and event.get("code") is None \
                and isinstance(event.get("file"), str) and isinstance(event.get("host"), str):
            # a host's recorder restarted in a new file: the run's `join them with` line names it
            files = self.host_files.setdefault(event["host"], [])
            if event["file"] not in files:
                files.append(event["file"])
        if isinstance(event, dict) and event.get("event") == "giveup":
            node = event.get("node")
            if node in self.system.nodes and node not in self.runs:
                self._events.put(("gaveup", node))

    def _on_heartbeat(self, sample: Any) -> None:
        path = wire.node_path(sample.key_expr, self.system.name, wire.HEARTBEAT)
        run = self.runs.get(path) if path is not None else None
        if run is not None and run.state in (NodeState.STARTING, NodeState.RUNNING, NodeState.LOST):
            run.last_beat = time.monotonic()  # one attribute store: safe across threads

    # ------------------------------------------------------------------ the launcher's turns
    def note_live(self) -> None:
        """The system runs once every node has been live (or ended) once."""
        self.system_live = self.system_live or self.everyone_live() or \
            (not self.runs and self.others_started and self.other_hosts_live())

    def supervise(self, now: float) -> None:
        """Open the gate when due, start the nodes whose `after` are live, restart the ones
        whose backoff is over, kill the silent ones."""
        system = self.system
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
                if run.spec.required:
                    self._want_stop(f"required node {run.name} cannot start",
                                    f"{run.name} is required and cannot start: stopping every node")
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

    def alive(self, path: str, present: bool, when: float) -> None:
        """A node's liveliness token came or went (any host's node)."""
        (self.alive_paths.add if present else self.alive_paths.discard)(path)
        if present:
            self.ever_alive.add(path)
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

    def exited(self, name: str, pid: int | None, code: int) -> None:
        """A node's process ended: restart it, or give it up, by its policy."""
        run = self.runs.get(name)
        if run is None or pid != run.child.pid:
            return
        now = time.monotonic()
        self.alive_paths.discard(run.name)
        uptime = now - run.child.started_at
        if run.state == NodeState.STOPPING:
            # the stop's exit status is not the node's last failure, which the summary reports
            run.state = NodeState.STOPPED
            self._event("exit", run, f"stopped ({describe_exit(code)}){self._stop_escalation(run)}", code=code)
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
        if run.spec.required:
            self._want_stop(f"required node {run.name} ended",
                            f"{run.name} is required and has ended for good: stopping every node")

    def host_changed(self, event: str, host: str) -> None:
        """Another host's agent was lost, or came back and runs its part again: its nodes are
        down (a launcher event each, in the recording) or starting again. Their peers learn of
        the restart from the nodes' own tokens when they come back (iotad/node_host/peer_restart.py)."""
        nodes = [name for name, spec in self.system.nodes.items() if spec.host == host]
        if event == "lost":
            for name in nodes:
                self.view.line(f"{name}: DOWN (host {host} lost)")
                self.hub.publish({"event": "down", "node": name, "host": host, "pid": None, "code": None,
                                  "t_ns": time.time_ns(), "message": f"host {host} lost"})
        elif event == "resumed":
            self.hub.launcher_event("host_back", f"host {host}: back; its nodes ran on while it was cut off "
                                                 f"({', '.join(nodes)})", host=host, resumed=True)
        else:
            self.hub.launcher_event("host_back", f"host {host}: back; its nodes start again ({', '.join(nodes)})",
                                    host=host, resumed=False)

    # ------------------------------------------------------------------ who is live
    def other_hosts_live(self) -> bool:
        """A hub that starts the other hosts through their agents: every node of theirs has been
        live once (they start seconds after this host's, an agent and a launcher later), so that
        --after-live's seconds are the whole system's. The start gates stay each host's own."""
        if not self.others_started:
            return True
        return all(name in self.ever_alive or name in self.failed_elsewhere
                   for name in self.system.nodes if name not in self.runs)

    def gave_up_elsewhere(self, name: str) -> None:
        """Its host's launcher gave `name` up for good (its own lines say why): it counts as
        ended, as a node of this host that failed for good does."""
        self.failed_elsewhere.add(name)

    def here_live(self) -> bool:
        """This host's nodes are all live (`everyone_live`); a hub host that holds no node of its
        own (only the hub and the recorder) has none to wait for: without this its --until never
        began and its recorder was judged as starting all run."""
        return self.everyone_live() or (not self.runs and self.others_started)

    def everyone_live(self) -> bool:
        """Every node is live or has ended for good, and one at least is live: a node that failed
        to start must not hold the others (nor the gate) for ever."""
        runs = self.runs.values()
        return bool(self.runs) and any(r.state == NodeState.RUNNING for r in runs) \
            and all(r.state == NodeState.RUNNING or r.finished for r in runs)

    def _open_gate(self) -> None:
        """Declare the start gate's token once every node is live: the waiting engines start."""
        if self.gate_open or not self.everyone_live():
            return
        self.gate_open = True
        try:
            self.hub.declare(self.hub.session.liveliness().declare_token(self.gate_key))
        except Exception as exc:  # noqa: BLE001 - a closing session; the nodes are being stopped
            self.view.line(f"warning: cannot open the start gate {self.gate_key}: {exc}")
            return
        self.hub.launcher_event("gate", f"start gate open: all {len(self.runs)} nodes are live or ended; "
                                        "their engines start now")

    # ------------------------------------------------------------------ starting and killing
    def _spawn(self, run: NodeRun, event: str) -> None:
        # another host's recording: its nodes connect to its launcher too, so that its recorder
        # hears them from their first event and while the hub is out of reach
        # (under access control only to its router, which links it to the hub: host_router.py)
        hub = self.hub
        routed = self.access is not None and self.access.router is not None
        config = self.system.node_config(run.name, hub.origin, hub.local if routed else hub.endpoints + hub.local)
        config["restarts"] = run.restarts  # its heartbeats say it: a tool attached later counts them
        if self.open_hosts is not None:
            config["zenoh"] = {**config.get("zenoh", {}), **self.open_hosts.node_settings(run.name, run.restarts)}
        if not self.gate_open:  # a node (re)started after the gate opened starts its engine at once
            config["start_gate"] = self.gate_key
        if hub.clock_watch is not None:  # its clock follows this host's measurements of the hub's
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

    def _event(self, event: str, run: NodeRun, text: str, code: int | None = None) -> None:
        self.view.line(f"{run.name}: {text}")
        self.hub.publish({"event": event, "node": run.name, "pid": run.child.pid, "code": code,
                          "t_ns": time.time_ns(), "restarts": run.restarts})

    # ------------------------------------------------------------------ the stop
    def _stop_escalation(self, run: NodeRun) -> str:
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


def stop_nodes(runs: dict[str, NodeRun], interrupt: float, terminate: float, hurry: Flag) -> None:
    """Stop every node still running (SIGINT, then SIGTERM, then SIGKILL); a node that waited
    for its restart is down, not cleanly stopped. Their exits are queued by their waiters."""
    for run in runs.values():
        if run.child.running():
            run.state = NodeState.STOPPING
        elif run.state == NodeState.BACKOFF:
            run.state = NodeState.DOWN  # it crashed and its restart was still to come: not a clean stop
        elif run.state in (NodeState.WAITING, NodeState.STARTING, NodeState.RUNNING, NodeState.LOST):
            run.state = NodeState.STOPPED
    stop_all([r.child for r in runs.values()], interrupt, terminate, hurry=hurry)


def settle(runs: dict[str, NodeRun], ended: float) -> None:
    """After the stop and its exits: a node whose exit never came is stopped; a down one is
    reported with how long it had been down."""
    for run in runs.values():
        if run.state == NodeState.STOPPING:
            run.state = NodeState.STOPPED
        elif run.state == NodeState.DOWN:
            run.down_at_end = ended - run.down_since


def status_rows(runs: dict[str, NodeRun], now: float) -> list[tuple]:
    """The status table's rows: one per node."""
    rows = []
    for run in runs.values():
        uptime = f"{now - run.live_since:.1f}s" if run.live_since and run.state == NodeState.RUNNING else "-"
        beat = f"{now - run.last_beat:.2f}s" if run.last_beat and not run.finished else "-"
        state = run.state if run.state not in (NodeState.EXITED, NodeState.FAILED, NodeState.DOWN) or run.last_code is None else \
            f"{run.state} ({describe_exit(run.last_code)})"
        pid = str(run.child.pid) if run.child.pid and not run.finished else "-"
        rows.append((run.name, run.spec.host or "", pid, state, str(run.restarts), uptime, beat))
    return rows


__all__ = ["NodeSupervisor", "settle", "status_rows", "stop_nodes"]
