"""The ODrive firmware's trapezoidal trajectory (INPUT_MODE TRAP_TRAJ), as plain Python.

The same planner and evaluation as the firmware's `TrapezoidalTrajectory` (trapTraj.cpp of the
open 0.5 firmware; 0.6 plans the same profile): from a position and velocity to a goal, at most
`vmax`, accelerating at `amax` and braking at `dmax`. A start faster than cruise, or toward the
wrong side, brakes first; a move too short to reach cruise is a triangle. Units are the axis's
(turns, turns/s, turns/s^2).
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class TrapezoidalTrajectory:
    xi: float   # start position
    xf: float   # goal
    vi: float   # start velocity
    ar: float   # acceleration of the first phase (signed)
    vr: float   # cruise velocity (signed)
    dr: float   # deceleration of the last phase (signed)
    ta: float   # durations: accelerating, cruising, decelerating; tf their sum
    tv: float
    td: float

    @property
    def tf(self) -> float:
        return self.ta + self.tv + self.td

    def eval(self, t: float) -> tuple[float, float, float]:
        """(position, velocity, acceleration) at `t` seconds after the start."""
        if t < 0.0:
            return self.xi, self.vi, 0.0
        if t < self.ta:
            return self.xi + self.vi * t + 0.5 * self.ar * t * t, self.vi + self.ar * t, self.ar
        if t < self.ta + self.tv:
            end_of_accel = self.xi + self.vi * self.ta + 0.5 * self.ar * self.ta * self.ta
            return end_of_accel + self.vr * (t - self.ta), self.vr, 0.0
        if t < self.tf:
            td = t - self.tf
            return self.xf + 0.5 * self.dr * td * td, self.dr * td, self.dr
        return self.xf, 0.0, 0.0


def plan(xf: float, xi: float, vi: float, vmax: float, amax: float, dmax: float) -> TrapezoidalTrajectory:
    """The profile from `xi` at velocity `vi` to rest at `xf`. Limits of 0 (an unconfigured
    axis) plan no motion: the goal at once, as a step."""
    if not (vmax > 0 and amax > 0 and dmax > 0):
        return TrapezoidalTrajectory(xi, xf, vi, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dx = xf - xi
    stop = math.copysign(vi * vi / (2.0 * dmax), vi)      # where braking now would stop
    s = 1.0 if dx - stop >= 0 else -1.0                    # the side of the cruise
    ar, dr, vr = s * amax, -s * dmax, s * vmax
    if s * vi > s * vr:                                    # faster than cruise: brake down to it
        ar = -s * amax
    ta = (vr - vi) / ar
    td = -vr / dr
    dx_min = 0.5 * ta * (vr + vi) + 0.5 * td * vr          # what reaching cruise covers
    if s * dx < s * dx_min:                                # short: a triangle
        vr = s * math.sqrt(max((dr * vi * vi + 2 * ar * dr * dx) / (dr - ar), 0.0))
        ta = max(0.0, (vr - vi) / ar)
        td = max(0.0, -vr / dr)
        tv = 0.0
    else:
        tv = (dx - dx_min) / vr
    return TrapezoidalTrajectory(xi, xf, vi, ar, vr, dr, ta, tv, td)
