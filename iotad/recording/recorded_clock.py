"""A host recording's clock offsets to the hub, as the recording holds them, and a time on the
host's clock moved onto the hub's (what `iotad merge` orders host recordings by).

hub clock = host clock + offset (`iotad.machine.clock_offset`). A host launcher's recorder stores the
offset its launcher measured at start in the file's metadata (`iotad.recording`: `run.clock`, with
the host clock's time of the measurement); every later measurement is a launcher event `clock` of
that host on `@launcher`, read by `iotad.recording.clock_offsets`. Merging reads offsets only
through `offsets` and `to_hub`.
"""
from __future__ import annotations

import bisect
from dataclasses import dataclass
from typing import Any



@dataclass(frozen=True)
class Offset:
    """From host time `since_ns` on (host clock), hub = host + `offset` s, within +-`bound` s."""

    since_ns: int
    offset: float
    bound: float


def run_info(recording: Any) -> dict:
    """The `run` entry of a recording's metadata (host, hub, origin, clock), {} where it has none."""
    run = recording.info.get("run")
    return run if isinstance(run, dict) else {}


def offsets(recording: Any) -> list[Offset]:
    """Every offset of the recording's host to the hub, oldest first, each from the host-clock
    time it was measured: the one measured at start (metadata), then each later measurement of
    its host (`iotad.recording.clock_offsets`, whose `t` is on the hub's timeline). [] for the
    hub's own recording (offset 0) and for a recording that holds none."""
    from iotad.recording.clock_offsets import clock_offsets

    run = run_info(recording)
    host, origin = run.get("host"), run.get("origin")
    if run.get("hub") or not _number(origin):
        return []
    found: list[Offset] = []
    clock = run.get("clock")
    if isinstance(clock, dict) and _number(clock.get("offset")):
        found.append(Offset(int(clock.get("measured_ns") or 0), float(clock["offset"]),
                            float(clock.get("bound") or 0.0)))
    unit = recording.time_unit
    for reading in clock_offsets(recording).get(host, []):
        hub_s = origin + reading.t * unit  # when it was measured, on the hub's clock: on the host's
        found.append(Offset(round((hub_s - reading.offset) * 1e9), reading.offset, reading.bound))
    found.sort(key=lambda o: o.since_ns)
    return found


class ToHub:
    """Host clock nanoseconds -> hub clock nanoseconds, by the offset measured last before that
    time (the first one before any measurement), and never earlier than any earlier host time's.

    A new offset smaller than the one before would map the host's next moments before its last
    ones: the merge, which orders by these times, would put a node's later events before its
    earlier ones, and a check that replays its trace would judge them in that order. Where an
    offset steps back, the hub's time holds still until the host's catches up, so a host's file
    keeps its own order."""

    def __init__(self, measured: list[Offset]):
        self.measured = measured
        self._since = [o.since_ns for o in measured]
        # per offset: the hub time that the host times before it reached, which none after may precede
        self._floor: list[int | None] = [None]
        for before, after in zip(measured, measured[1:]):
            reached = after.since_ns + round(before.offset * 1e9)
            last = self._floor[-1]
            self._floor.append(reached if last is None else max(reached, last))

    def offset_at(self, ns: int) -> Offset | None:
        if not self.measured:
            return None
        k = bisect.bisect_right(self._since, ns) - 1
        return self.measured[max(k, 0)]

    def __call__(self, ns: int) -> int:
        if not self.measured:
            return ns
        k = max(bisect.bisect_right(self._since, ns) - 1, 0)
        hub = ns + round(self.measured[k].offset * 1e9)
        floor = self._floor[k]
        return hub if floor is None or hub >= floor else floor


def to_hub(recording: Any) -> ToHub:
    """The recording's host clock moved onto the hub's (unchanged for the hub's own recording)."""
    return ToHub(offsets(recording))


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


__all__ = ["Offset", "ToHub", "offsets", "run_info", "to_hub"]
