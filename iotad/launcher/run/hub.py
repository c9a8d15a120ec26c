"""The zenoh session of one host's launcher, open from construction to `close()`: the system's
hub (its listen endpoints, its access control, its clock origin and clock server) on the hub's
host, or on another host the link to it (the hub's origin, this host's clock measured against the
hub's, its own endpoints for its nodes and recorder); and the `@launcher` key on which the run's
events are published, so that the recording itself holds them.
"""
from __future__ import annotations

import os
import queue
import time
from typing import Any

from iotad.node_host import wire
from iotad.machine.clock_offset import ClockServer
from iotad.kernel.clock import wall
from iotad.node_host.stop_signals import Flag
from iotad.launcher.access.access_control import AccessControl
from iotad.launcher.run.tally import Tally, count_trace
from iotad.launcher.system.system_file import System


class LauncherError(Exception):
    """The launcher cannot start (the hub endpoint is taken...): one line for the user."""


class Hub:
    """The launcher's session of `system` for `host`, opened on construction (`LauncherError` if
    it cannot be). `endpoints`: where the hub listens (the hub's host) or is reached (another
    host). `recorded`: this host's run is recorded (another host's recorder and nodes then reach
    its launcher on a known port). `origin`: the run's origin (None: the hub's own now, or the one
    the hub answers). `stop`: set when a stop is asked (ends the waits for the hub). `events`:
    the launcher's queue, which gets ("clock", reading) for each later measurement of this host's
    clock. `view`: the status view, whose `line` says what happens. `tally`: what every node's
    trace carries is counted there, from the session's first moment."""

    def __init__(self, system: System, host: str | None, endpoints: list[str], *, access: AccessControl | None,
                 recorded: bool, origin: float | None, steady: Any, stop: Flag, events: queue.Queue, view: Any,
                 tally: Tally):
        self.system, self.host, self.endpoints, self.access = system, host, endpoints, access
        self.view, self._steady, self._stop, self._events, self.tally = view, steady, stop, events, tally
        self.origin = origin
        self.hub_origin: float | None = None   # another host's launcher: the origin the hub answered
        self.clock: dict | None = None         # another host's launcher: its clock offset, as measured at start
        self.clock_watch = None                # another host's launcher, where the hub answered: its clock measured
        self.local: list[str] = []             # another host's launcher: where its recorder and nodes reach it
        self.session = None
        self._declared: list[Any] = []
        self._publisher = None
        self._origin_publisher = None
        self._event_seq = 0
        self._hub_answered = False
        if access is not None and access.own is not None and not system.opens_hub(host):
            # under access control its session is its host's router, on a private unix socket
            # (iotad/launcher/access/host_router.py): its nodes and recorder reach nothing else
            self.local = [access.route(host)]
        try:
            self._open(recorded)
        except BaseException:
            self.close()
            raise

    @property
    def opens_hub(self) -> bool:
        return self.system.opens_hub(self.host)

    def _open(self, recorded: bool) -> None:
        from iotad.node_host.transport import open_session, reachable
        from iotad.launcher.system.can_env import unresolved

        system, access = self.system, self.access
        if (problem := unresolved(system, self.host)) is not None:  # [[can]] interface = "env", none set
            raise LauncherError(problem)
        if self.opens_hub:
            listen, connect = self.endpoints, list(system.connect)
        else:
            listen, connect = system.listen_for(self.host), self.endpoints
            if access is not None and access.router is not None:
                listen = list(self.local)
            elif recorded:  # its recorder and nodes connect here: a known port
                from iotad.launcher.hosts.host_recording import local_endpoints, pinned

                listen = pinned(listen)
                self.local = local_endpoints(listen)
        try:
            self.session = open_session(listen, connect, **(access.hub_options() if access else {}))
        except Exception as exc:  # noqa: BLE001 - zenoh says why in its message
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            if "Address already in use" in text:
                raise LauncherError(f"the hub endpoint {', '.join(listen)} is taken (another 'iotad run'?); "
                                    "choose another with --port") from None
            if access is not None and access.own is not None:  # another host's, under access control
                from iotad.node_host.admission import diagnose
                from iotad.machine.certificates import from_env

                text = f"not admitted: {diagnose(connect[0], from_env(), access.own.user).reason}"
            raise LauncherError(f"cannot open the hub session (listen {listen}, connect {connect}): {text}") from None
        session = self.session
        if self.opens_hub:  # with --port 0 this is the only place the port is told
            tools = reachable(listen[0])
            self.view.line(f"hub: {', '.join(listen)} (tools attach with --connect {tools}, e.g. iotad top --connect {tools})")
        for line in (access.opened(listen) if access and self.opens_hub else ()):
            self.view.line(line)
        self._publisher = session.declare_publisher(wire.launcher_key(system.name))
        self._declared.append(self._publisher)
        # outputs are counted from the nodes' traces (iotad/launcher/run/tally.py), from before
        # this host waits for the hub's origin: another host's nodes may run by then. Another
        # host's launcher counts its own nodes' only: a subscription to every trace would bring
        # every other host's whole trace stream across its link (vision's camera images, the
        # CAN bus), which on a link slowed to 256 kbit/s held the setpoints to arm back by up
        # to 3 s, and the arm's link watch tripped 48 times in 20 s
        count = lambda sample: count_trace(self.tally, system.name, sample)  # noqa: E731
        for key in trace_keys_counted(system, self.host):
            self._declared.append(session.declare_subscriber(key, count))
        if self.opens_hub:
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

    def declare(self, entity: Any) -> Any:
        """Keep a subscriber or token declared on this session until `close()`."""
        self._declared.append(entity)
        return entity

    # ------------------------------------------------------------------ the clock of another host
    def _ask_origin(self) -> float:
        """A launcher for one host of several takes the hub launcher's origin, so that every
        node's `t` counts from one instant; if the hub does not answer, its own (with a warning)."""
        deadline = time.monotonic() + self.system.start_timeout
        key = wire.origin_key(self.system.name)
        self.view.line(f"waiting up to {self.system.start_timeout:g} s for the hub launcher's clock origin on {key}")
        while time.monotonic() < deadline and not self._stop.is_set():
            for reply in self.session.get(key, timeout=1.0):
                if reply.ok is not None:
                    self._hub_answered = True
                    self.hub_origin = float(wire.decode(reply.ok.payload.to_bytes())["origin"])
                    return self.hub_origin
            self._stop.wait(0.2)
        if self._stop.is_set():
            return wall()  # stopping before anything started: the origin no longer matters
        self.view.line(f"warning: no hub launcher answered on {key}; this host's nodes use its own clock origin")
        return wall()

    def _correct_clock(self) -> None:
        """Measure this host's clock against the hub's and move the origin by the offset, so that
        this host's nodes count `t` on the hub's timeline; then measure it again every
        `clock_period` during the run, and have the nodes' clocks follow (clock_measured). Each
        measurement is a launcher event (`clock`, in the recording); one known no better than the
        system's `clock_bound`, or one that finds the nodes' clocks off by more, is a
        `clock_violation` event and a warning: windows on this host are then judged on a clock
        that may be off by that much."""
        from iotad.launcher.hosts.clock_watch import ClockWatch

        system = self.system
        self.clock_watch = watch = ClockWatch(
            self.session, system.name, self.host, self.origin, time_unit=system.time_unit, limit=system.clock_bound,
            period=system.clock_period, clock=self._steady, report=lambda reading: self._events.put(("clock", reading)))
        self.clock_measured(watch.first(stop=self._stop))
        self._origin_publisher = self.session.declare_publisher(wire.host_origin_key(system.name, self.host))
        self._declared.append(self._origin_publisher)
        watch.start()

    def clock_measured(self, reading: Any) -> None:
        """A measurement of this host's clock (a `ClockReading`, or why there is none): move the
        origin of nodes started from now on, tell the running ones, record it. A reading at start
        is said on the console; later ones only when they are violations (one every
        `clock_period` would drown the run's lines)."""
        if isinstance(reading, str):
            self.launcher_event("clock_violation", reading, host=self.host)
            return
        if reading.kept is not None:  # not applied (clock_watch.DRIFT): recorded, the nodes' clocks unmoved
            self.launcher_event("clock", reading.message(), quiet=True, **reading.event())
            return
        self.origin = self.clock_watch.origin
        if self._origin_publisher is not None:
            try:
                self._origin_publisher.put(wire.encode({"origin": self.origin}))
            except Exception:  # noqa: BLE001 - a closing session: the run is ending anyway
                pass
        event = reading.event()
        if self.clock is None and "offset" in event:
            # the clock measured at start, for this host's own recording (started after it)
            self.clock = dict(event, measured_ns=round(wall() * 1e9))
        self.launcher_event("clock_violation" if reading.problem else "clock", reading.message(),
                            quiet=not (reading.first or reading.problem), **event)

    # ------------------------------------------------------------------ the run's events
    def launcher_event(self, event: str, text: str, code: int | None = None, quiet: bool = False,
                       **extra: Any) -> None:
        """An event of the launcher itself (node None): the recorder's fate... `quiet`: recorded,
        not shown."""
        if not quiet:
            self.view.line(text)
        self.publish({"event": event, "node": None, "pid": os.getpid(), "code": code,
                      "t_ns": time.time_ns(), "message": text.split("\n", 1)[0], **extra})

    def publish(self, payload: dict) -> None:
        """One event on `@launcher` (the run's, named by its host on a run over hosts)."""
        if self._publisher is None:
            return
        if self.host is not None:
            payload.setdefault("host", self.host)  # a lost host's nodes are named with their own
        try:
            self._publisher.put(wire.encode(payload), attachment=wire.encode_attachment(self._event_seq))
            self._event_seq += 1
        except Exception:  # noqa: BLE001 - a closing session must not stop the shutdown
            pass

    # ------------------------------------------------------------------ the end
    def stop_watching(self) -> None:
        """No more measurement of a hub that is going away."""
        if self.clock_watch is not None:
            self.clock_watch.close()

    def close(self) -> None:
        """Undeclare everything, newest first, and close the session (never waiting on a host
        that is cut off)."""
        self.stop_watching()
        for entity in reversed(self._declared):
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001
                pass
        self._declared.clear()
        self._publisher = self._origin_publisher = None
        if self.session is not None:
            from iotad.node_host.session_close import close_session

            session, self.session = self.session, None
            problem = close_session(session)
            if problem:
                print(problem, flush=True)


def trace_keys_counted(system: System, host: str | None) -> list[str]:
    """The trace keys `host`'s launcher subscribes to for its summary (`System.nodes_traced_at`): at
    the hub every node's by one key expression, unless some host keeps its traces home."""
    if system.opens_hub(host) and not system.hosts_keeping_traces():
        return [wire.every_node(system.name, wire.TRACE)]
    return [wire.trace_key(system.name, node.name) for node in system.nodes_traced_at(host)]
