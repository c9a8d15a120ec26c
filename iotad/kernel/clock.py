"""Clocks: where "now" comes from and how the engine waits for the next deadline or input.

A clock owns the engine's inbox of external inputs. `VirtualClock` jumps straight to the next
event (deterministic: tests, replay, fast simulation); `RealClock` reads the monotonic clock and
blocks on a thread-safe queue that zenoh callbacks feed. The engine needs only these methods.
"""
from __future__ import annotations

import heapq
import itertools
import math
import os
import queue
import time
from typing import Any, Callable

# A drill of a host whose clock is wrong (tests of clock correction across hosts, docs/hosts.md):
# every wall-clock reading of this process, and of the processes it starts, is off by this many
# seconds. Zero unless IOTAD_CLOCK_SKEW says otherwise.
CLOCK_SKEW_ENV = "IOTAD_CLOCK_SKEW"
# The drill of a clock that drifts: this host's clocks (wall and monotonic) run fast by this many
# seconds per second (1e-3: it gains a millisecond a second), counted from IOTAD_CLOCK_DRIFT_FROM
# (a wall-clock time), which the first process of the drill sets for the processes it starts, so
# that a launcher and its nodes drift as one machine's clock would.
CLOCK_DRIFT_ENV = "IOTAD_CLOCK_DRIFT"
CLOCK_DRIFT_FROM_ENV = "IOTAD_CLOCK_DRIFT_FROM"


def _seconds(name: str, example: str) -> float:
    try:
        return float(os.environ.get(name) or 0.0)
    except ValueError:
        raise SystemExit(f"{name}={os.environ[name]!r}: expected seconds, e.g. {example}") from None


_SKEW = _seconds(CLOCK_SKEW_ENV, "0.05")
_DRIFT = _seconds(CLOCK_DRIFT_ENV, "0.001")
if _DRIFT and not os.environ.get(CLOCK_DRIFT_FROM_ENV):
    os.environ[CLOCK_DRIFT_FROM_ENV] = repr(time.time())
_DRIFT_FROM = _seconds(CLOCK_DRIFT_FROM_ENV, "1764000000.0") if _DRIFT else 0.0
_DRIFT_MONOTONIC = time.monotonic() - (time.time() - _DRIFT_FROM) if _DRIFT else 0.0


def wall() -> float:
    """This host's wall clock (`time.time()`, plus the drills' skew and drift): what origins are in."""
    now = time.time()
    return now + _SKEW + _DRIFT * (now - _DRIFT_FROM) if _DRIFT else now + _SKEW


def _drifting_monotonic() -> float:
    now = time.monotonic()
    return now + _DRIFT * (now - _DRIFT_MONOTONIC)


# This host's monotonic clock, what a real-time clock counts elapsed time by: `time.monotonic`
# itself (a clock's hot path: no call more), or running fast by the drift drill.
monotonic: Callable[[], float] = _drifting_monotonic if _DRIFT else time.monotonic


# How close together the two readings of `wall_and_monotonic` must be to be taken at once.
PAIRED = 50e-6


def wall_and_monotonic() -> tuple[float, float]:
    """`wall()` and `monotonic()` read at one instant, to within PAIRED where the machine allows:
    the pair anchors a clock that counts wall time by the monotonic clock, and every process of a
    host must anchor the same clock. Read one after the other, another thread could take the GIL
    between them (its switch interval is 5 ms): a loaded host's launcher once anchored its clock
    6 ms behind its nodes', and a merge of the hosts' recordings then had each of base's messages
    to brain received 5 to 6 ms before it was sent. So the wall is read between two monotonic
    readings, again until they are close (at most 20 tries; the closest pair otherwise), and paired
    with their midpoint."""
    best: tuple[float, float, float] | None = None
    for _ in range(20):
        before = monotonic()
        now = wall()
        after = monotonic()
        if best is None or after - before < best[0]:
            best = (after - before, now, (before + after) / 2)
        if after - before <= PAIRED:
            break
    return best[1], best[2]


def steady_wall() -> Callable[[], float]:
    """A wall clock that reads `wall()` now and then advances by `monotonic()`, as a `RealClock`
    does: a step of the system clock (an administrator, NTP) after this call does not move it.
    Clock offsets between hosts are measured on these, the clocks node times are counted on."""
    start_wall, start = wall_and_monotonic()
    return lambda: start_wall + (monotonic() - start)


class Clock:
    virtual = True

    def now(self) -> float:  # pragma: no cover - interface
        raise NotImplementedError

    def post(self, item: Any, t: float | None = None) -> None:  # pragma: no cover - interface
        """Queue an external input; a virtual clock delivers it at `t`, a real one on arrival."""
        raise NotImplementedError

    def wait(self, deadline: float) -> Any | None:  # pragma: no cover - interface
        """Return the next input due no later than `deadline`, or None once `deadline` is reached."""
        raise NotImplementedError


class VirtualClock(Clock):
    virtual = True

    def __init__(self, start: float = 0.0):
        self._now = start
        self._inbox: list = []
        self._seq = itertools.count()  # keeps arrival order among inputs at one instant

    def now(self) -> float:
        return self._now

    def post(self, item: Any, t: float | None = None) -> None:
        t = self._now if t is None else t
        if t < self._now:
            raise ValueError(f"input at t={t} is in the past (now {self._now})")
        heapq.heappush(self._inbox, (t, next(self._seq), item))

    def wait(self, deadline: float) -> Any | None:
        if self._inbox and self._inbox[0][0] <= deadline:
            t, _, item = heapq.heappop(self._inbox)
            self._now = t
            return item
        if not math.isinf(deadline):
            self._now = max(self._now, deadline)
        return None

    def pending(self) -> int:
        return len(self._inbox)


class RealClock(Clock):
    """Seconds since the clock was made, scaled by `time_unit` (seconds per spec time unit)."""

    virtual = False

    def __init__(self, time_unit: float = 1.0, origin: float | None = None):
        """`origin` is a wall-clock time (`time.time()`) that is t=0, so that nodes started by
        one launcher share a timeline; time then advances by the monotonic clock."""
        self.time_unit = time_unit
        now, mono = wall_and_monotonic()  # anchored as its host's launcher anchors its clock
        self._origin = mono if origin is None else mono - (now - origin)
        self.origin_wall = now if origin is None else origin
        self._inbox: queue.Queue = queue.Queue()

    def now(self) -> float:
        return (monotonic() - self._origin) / self.time_unit

    def post(self, item: Any, t: float | None = None) -> None:
        self._inbox.put(item)

    # A longer wait overflows the platform's timed lock; returning early is harmless, as the
    # engine waits again until its deadline.
    max_timeout = 3600.0

    def wait(self, deadline: float) -> Any | None:
        timeout = None if math.isinf(deadline) else \
            min(self.max_timeout, max(0.0, (deadline - self.now()) * self.time_unit))
        try:
            if timeout == 0.0:
                return self._inbox.get_nowait()
            return self._inbox.get(timeout=timeout)
        except queue.Empty:
            return None
