"""A node clock's correction onto the hub's timeline, as its launcher measures it again during a
run: a correction forward is a step, one backward a slew; node time never runs backwards.

Why not step both ways: a step back would hand the engine a time before one it has already
recorded and judged by (a firing's window, an input's switching time, the trace's order), and
nothing in a node can take that. A step forward is what a late wake-up is to the engine already:
a firing due in the skipped interval fires at once, late by at most the step, which is the
error its clock had until then anyway. Backward, the clock runs slower by `SLEW` (its time
advances `1 - SLEW` per second) until it has given the difference back: a window lasts at most
that fraction longer on it, and the clock's error shrinks every second.

Why not slew both ways: a clock found behind would stay behind for the whole slew, its windows
judged late for that long; stepping forward removes the error at once.

`at(raw)` is called on every clock reading (the engine thread, the CAN reader): one tuple read,
no lock. `aim(target, raw)` comes from a zenoh callback; it swaps the whole state at once."""
from __future__ import annotations

import threading

# How much slower a node clock runs while it gives back a backward correction (2000 ppm, four
# times NTP's limit): a millisecond in half a second, far faster than any crystal drifts (tens
# of ppm), so a clock re-measured every few seconds has caught up long before the next time.
SLEW = 2e-3


class Correction:
    """What to add to a node clock's raw reading (spec time units), starting at 0."""

    def __init__(self, slew: float = SLEW):
        if not 0 < slew < 1:
            raise ValueError(f"slew must be between 0 and 1 (a fraction of the clock's rate), got {slew!r}")
        self.slew = slew
        # (the correction at raw time `since`, since, the correction aimed at): swapped whole
        self._state = (0.0, 0.0, 0.0)
        self._lock = threading.Lock()  # two aims at once (never: one subscriber) stay in order

    def at(self, raw: float) -> float:
        value, since, target = self._state
        if value <= target:
            return value  # stepped there already (or nothing to do)
        return max(target, value - self.slew * (raw - since))

    @property
    def target(self) -> float:
        return self._state[2]

    def aim(self, target: float, raw: float) -> float:
        """Correct towards `target` from raw time `raw` on: at once when it is ahead of the
        correction now, else by slewing. Returns the step taken now (0 when slewing)."""
        with self._lock:
            current = self.at(raw)
            if target >= current:
                self._state = (target, raw, target)
                return target - current
            self._state = (current, raw, target)
            return 0.0


__all__ = ["Correction", "SLEW"]
