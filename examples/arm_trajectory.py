"""`ArmTrajectory`: the trajectory requester of examples/arm_can.toml, a small IOTA that streams
per-joint setpoints (channels/joints.py) to the CAN motor node.

It waits for the arm's first joint state (its origin: the trajectory starts where the arm is),
then, every `period`, sends the next point of a path through `waypoints`: from the origin to the
first waypoint, then on to each next one, `segment` seconds per leg with a cosine blend (zero
velocity at each waypoint), starting `start` seconds after the first joint state. Velocity
feed-forward is the path's derivative; torque feed-forward is zero. After the last waypoint it
holds there. Time is its own count of periods, not the clock, so the same path comes out in
virtual time and in real time, and it goes on unchanged when the motor node restarts.
"""
from __future__ import annotations

import math

from channels.joints import joint_setpoints, joint_states
from iotad import Input, Iota, Output, Param

SETPOINTS, STATES = joint_setpoints(6), joint_states(6)


class ArmTrajectory(Iota):
    waypoints = Param([[0.0] * 6])   # joint vectors (rad), visited in order
    segment = Param(1.5)             # s per leg
    start = Param(0.5)               # s after the first joint state before the first leg
    period = Param(0.01)             # s between setpoints

    joint_states = Input(STATES, switching=0)
    setpoints = Output(SETPOINTS, switching=0)

    def init(self):
        if not self.waypoints or any(len(w) != 6 for w in self.waypoints):
            raise ValueError(f"waypoints must be a non-empty list of 6-joint vectors, got {self.waypoints!r}")
        if self.segment <= 0 or self.period <= 0 or self.start < 0:
            raise ValueError("segment and period must be > 0 and start >= 0 (seconds)")
        self.origin = None
        self.k = 0          # setpoints sent since the first joint state

    @joint_states.input
    def measured(self, value):
        if self.origin is None:
            self.origin = [float(q) for q in value.position]

    @setpoints.action(value=lambda self: self.point(self.k * self.period), when=lambda self: self.origin is not None,
                      after="period")
    def sent(self):
        self.k += 1

    def point(self, t: float):
        """The setpoint `t` seconds after the first joint state."""
        legs = [self.origin] + [list(map(float, w)) for w in self.waypoints]
        s = (t - self.start) / self.segment
        if s <= 0:
            leg, u = 0, 0.0
        elif s >= len(legs) - 1:
            leg, u = len(legs) - 2, 1.0
        else:
            leg, u = int(s), s - int(s)
        a, b = legs[leg], legs[leg + 1]
        blend = (1 - math.cos(math.pi * u)) / 2
        rate = math.pi / (2 * self.segment) * math.sin(math.pi * u)
        return SETPOINTS(position=[x + (y - x) * blend for x, y in zip(a, b)],
                         velocity_ff=[(y - x) * rate for x, y in zip(a, b)], torque_ff=[0.0] * 6)
