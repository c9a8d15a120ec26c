"""A host launcher's clock against the hub's over a whole run: measured at start (its nodes start
on the hub's origin moved by that offset) and every `clock_period` seconds after, on a thread of
its own; each measurement becomes a `ClockReading`, which the launcher records as a launcher event
(`clock`, or `clock_violation`) and hands on to its nodes as the hub's origin on this host's
clock (`wire.host_origin_key`), which their clocks follow (iotad/node_host/clock_correction.py).

A reading is a violation when the offset is known no better than the limit (`[system]
clock_bound`) or, after the first, when the nodes' clocks were off by more than the limit: the
offset moved that far since the correction they ran on (a clock drifting, or stepped under the
run). The first reading's offset itself is no violation: it is corrected before any node runs.

Offsets are measured on `steady_wall()` clocks on both sides, the clocks node times are counted
on: a step of a host's system clock during the run does not pass for an offset.

A later reading that agrees with the one in use (their intervals overlap) is applied only if it
knows the offset at least as well as that one still does: its bound grown by the drift two clocks
may have since (`DRIFT`); one that disagrees (the clock stepped) is applied whatever its bound. A measurement
across a slowed or cut link has round trips of a second and a bound to match (a bad day's: an
offset of +142 ms +-164 ms, against +0.04 ms +-0.26 ms ten seconds before); applied, it moved
every node of the host 142 ms on the hub's timeline, and back at the next reading: late,
expired and wrong-value findings that no fault of the nodes made. Such a reading is recorded
(`used: false`) and said, not applied; `iotad check` and `iotad merge` go by the ones applied."""
from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Callable

from iotad.machine.clock_offset import ClockError, ClockOffset, measure

# s a clock may drift per s from another: 100 ppm, what an undisciplined crystal may do (NTP keeps
# them within tens of ppm); a reading in use is trusted less by this much as it ages
DRIFT = 1e-4


@dataclass(frozen=True)
class ClockReading:
    """One measurement of `host`'s clock: hub = host + `offset` within +-`bound` (seconds), at
    `t` on the hub's timeline (spec units). `moved`: how far the offset moved since the
    correction the nodes ran on (0 for the first reading); `problem`: why it is a violation."""
    host: str
    t: float
    measured: ClockOffset
    moved: float
    first: bool
    problem: str = ""
    kept: ClockOffset | None = None  # not applied: the offset in use, its bound grown by drift, is better

    def event(self) -> dict:
        """The launcher event's fields (besides `event`, `message` and the launcher's own)."""
        return {"host": self.host, "t": self.t, **self.measured.as_plain(), "moved": self.moved,
                **({"used": False} if self.kept is not None else {})}

    def message(self) -> str:
        m = self.measured
        head = (f"host {self.host}: clock offset to the hub {m.offset * 1e3:+.3f} ms +-{m.bound * 1e3:.3f} ms "
                f"({m.samples} round trips)")
        if self.kept is not None:
            return (f"{head}; not used: the offset in use, {self.kept.offset * 1e3:+.3f} ms, is still known "
                    f"within +-{self.kept.bound * 1e3:.3f} ms")
        if self.problem:
            return f"warning: host {self.host}: {self.problem}"
        if self.first:
            return f"{head}; corrected"
        how = "behind" if self.moved > 0 else "ahead of"
        return f"{head}; its nodes' clocks were {abs(self.moved) * 1e3:.3f} ms {how} the hub's, corrected"


def judge(host: str, t: float, measured: ClockOffset, applied: float | None, limit: float) -> ClockReading:
    """The reading of `measured` for nodes whose clocks ran on offset `applied` (None: no node
    runs yet, this is the start)."""
    moved = 0.0 if applied is None else measured.offset - applied
    problem = measured.problem(limit)
    if not problem and abs(moved) > limit:
        how = "behind" if moved > 0 else "ahead of"
        problem = (f"its nodes' clocks were {abs(moved) * 1e3:.3f} ms {how} the hub's (the clock offset moved "
                   f"from {applied * 1e3:+.3f} ms to {measured.offset * 1e3:+.3f} ms +-{measured.bound * 1e3:.3f} ms "
                   f"since the last measurement), more than the allowed {limit * 1e3:.3f} ms; corrected")
    return ClockReading(host, t, measured, moved, applied is None, problem)


class ClockWatch:
    """Measures `host`'s clock against the hub of `system` over `session`: `first()` at once,
    then every `period` seconds on a thread (`start()`), each reading handed to `report` (on
    that thread: the launcher queues it). `hub_origin` is the run's origin on the hub's clock;
    `clock` this host's steady wall clock."""

    def __init__(self, session, system: str, host: str, hub_origin: float, *, time_unit: float,
                 limit: float, period: float, clock: Callable[[], float],
                 report: Callable[[ClockReading | str], None]):
        self.session, self.system, self.host = session, system, host
        self.hub_origin, self.time_unit, self.limit, self.period = hub_origin, time_unit, limit, period
        self.clock, self.report = clock, report
        self.applied: float | None = None  # the offset this host's nodes run on
        self._in_use: tuple[ClockOffset, float] | None = None  # the reading applied, and when (host clock)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def origin(self) -> float:
        """The hub's origin on this host's clock, by the latest reading (the hub's own unmeasured)."""
        return self.hub_origin - (self.applied or 0.0)

    def first(self, stop=None) -> ClockReading | str:
        """The measurement at start, before any node runs: a reading, or why there is none.
        `stop` (an object with `is_set()`): the launcher is stopping, give up."""
        return self._measure(stop)

    def _measure(self, stop=None) -> ClockReading | str:
        try:
            measured = measure(self.session, self.system, clock=self.clock, stop=self._stop if stop is None else stop)
        except ClockError as exc:
            kept = "not corrected" if self.applied is None else "corrected as measured before"
            return f"warning: host {self.host}: {exc}; this host's clock is {kept}"
        now = self.clock()
        t = (now + measured.offset - self.hub_origin) / self.time_unit
        if self._in_use is not None:
            used, since = self._in_use
            still = used.bound + DRIFT * max(0.0, now - since)
            agree = max(measured.offset - measured.bound, used.offset - still) \
                <= min(measured.offset + measured.bound, used.offset + still)
            if agree and measured.bound > still:  # says no more than the one in use, and less surely
                kept = ClockOffset(used.offset, still, used.samples, used.best_delay)
                return ClockReading(self.host, (now + used.offset - self.hub_origin) / self.time_unit, measured,
                                    0.0, False, kept=kept)
        reading = judge(self.host, t, measured, self.applied, self.limit)
        self.applied = measured.offset
        self._in_use = (measured, now)
        return reading

    def start(self) -> None:
        self._thread = threading.Thread(target=self._run, name=f"clock {self.host}", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            reading = self._measure()
            if not self._stop.is_set():
                self.report(reading)

    def close(self) -> None:
        """Stop measuring (a measurement under way gives up at its next round trip)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5.0)
            self._thread = None


__all__ = ["ClockReading", "ClockWatch", "judge"]
