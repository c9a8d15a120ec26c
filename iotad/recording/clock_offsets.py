"""Each host's clock offset to the hub's and its bound over a run, as a recording holds them (the
launcher events `clock` and `clock_violation` of docs/hosts.md "Clocks"), and the widening of a
node's time judgements that its host's bound calls for (`iotad check`).

A node's events are stamped by its own clock, corrected onto the hub's timeline within the bound
its launcher measured; a window or switching time judged on those stamps is therefore widened by
that host's bound at that time, and no more. The hub's own nodes, and every node of a recording
without clock measurements (one host), are judged exactly."""
from __future__ import annotations

import bisect
from typing import Any, NamedTuple

CLOCK_EVENTS = ("clock", "clock_violation")


class ClockOffsetAt(NamedTuple):
    """hub clock = host clock + `offset` within +-`bound` (seconds), measured at `t` (spec time
    units, on the hub's timeline)."""
    t: float
    offset: float
    bound: float


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and value == value


def clock_offsets(recording: Any) -> dict[str, list[ClockOffsetAt]]:
    """host -> its clock measurements in time order, from the launcher events of `recording`
    (a `Recording`); a host whose clock was never measured (the hub's, or any host of a system
    on one machine) is not in it. An event without a measurement (no round trip answered) is
    left out: there is no offset to widen by, and the event itself says so."""
    out: dict[str, list[ClockOffsetAt]] = {}
    for event in recording.launcher_events():
        host = event.get("host")
        if event.get("event") not in CLOCK_EVENTS or not isinstance(host, str) \
                or not all(_number(event.get(k)) for k in ("t", "offset", "bound")) or event.get("used") is False:
            continue  # `used: false`: measured, not applied (worse than the one in use: clock_watch.DRIFT)
        out.setdefault(host, []).append(ClockOffsetAt(float(event["t"]), float(event["offset"]), float(event["bound"])))
    for readings in out.values():
        readings.sort()
    return out


def node_hosts(recording: Any) -> dict[str, str]:
    """node -> the host it ran on: as its launcher's events say (a launcher of one host of
    several names its host in each), else as the recorded system file says."""
    out: dict[str, str] = {}
    for event in recording.launcher_events():
        node, host = event.get("node"), event.get("host")
        if isinstance(node, str) and isinstance(host, str):
            out.setdefault(node, host)
    if out:
        return out
    from iotad.launcher.system.declaration import SystemFileError
    from iotad.recording.recorded_system import recorded_declaration

    try:
        declaration = recorded_declaration(recording)
    except SystemFileError:
        return out
    if declaration is not None:
        out = {name: node.host for name, node in declaration.nodes.items() if isinstance(node.host, str)}
    return out


class Widening:
    """How far the time judgements of one host's nodes are widened at time t (spec units): the
    bound of the measurement in force then (the latest at or before t; before the first, the
    first, which was made before any node ran)."""

    def __init__(self, host: str, readings: list[ClockOffsetAt], time_unit: float = 1.0):
        if not readings:
            raise ValueError(f"host {host}: no clock measurement to widen by")
        self.host, self.readings, self.time_unit = host, readings, time_unit
        self._times = [r.t for r in readings]

    def bound_at(self, t: float) -> float:
        """The bound in force at `t`, in seconds."""
        k = bisect.bisect_right(self._times, t) - 1
        return self.readings[max(k, 0)].bound

    def __call__(self, t: float) -> float:
        return self.bound_at(t) / self.time_unit

    def line(self) -> str:
        """What the check's report says of it."""
        bounds = [r.bound for r in self.readings]
        most, least = max(bounds), min(bounds)
        if most == least:
            by = f"by {most * 1e3:.3g} ms"
        else:
            by = f"by {least * 1e3:.3g} to {most * 1e3:.3g} ms, the bound at each time"
        return (f"windows of host {self.host} widened {by} (clock bound; {len(bounds)} measurement(s) of its "
                f"offset to the hub's clock)")


def widenings(recording: Any) -> dict[str, Widening]:
    """node -> the widening of its windows and switching times in `recording`; a node whose host's
    clock was never measured (the hub's host, or any node of a recording of one host) is not in
    it: it is judged exactly."""
    offsets = clock_offsets(recording)
    if not offsets:
        return {}
    unit = recording.time_unit
    by_host = {host: Widening(host, readings, unit) for host, readings in offsets.items()}
    return {node: by_host[host] for node, host in node_hosts(recording).items() if host in by_host}


__all__ = ["CLOCK_EVENTS", "ClockOffsetAt", "Widening", "clock_offsets", "node_hosts", "widenings"]
