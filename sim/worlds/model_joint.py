"""A joint integrated here rather than in PyBullet: one inertia with viscous friction and limits.

For the joints PyBullet cannot drive by torque at 240 Hz, or need not: the xArm gripper (its
fingers are mimic joints of a 30 g knuckle, far too light for an explicit torque loop at this
step) and Buggy's two actuators (the body is moved kinematically). Integration is semi-implicit
Euler with the friction term implicit, so any friction is stable; position stops at the limits.
"""
from __future__ import annotations

import math


class ModelJoint:
    """position (rad), velocity (rad/s); `step(torque, dt)` advances them."""

    __slots__ = ("inertia", "friction", "lower", "upper", "brake_torque", "position", "velocity")

    def __init__(self, inertia: float, friction: float = 0.0, lower: float = -math.inf, upper: float = math.inf,
                 brake_torque: float = 0.0, position: float = 0.0):
        if not inertia > 0:
            raise ValueError(f"a model joint needs an inertia > 0, got {inertia!r}")
        self.inertia, self.friction = float(inertia), float(friction)
        self.lower, self.upper = float(lower), float(upper)
        self.brake_torque = float(brake_torque)  # what holds it while the motor is off
        self.position, self.velocity = float(position), 0.0

    def step(self, torque: float | None, dt: float) -> None:
        """Advance by dt under the motor torque (Nm); None: motor off, only the brake acts."""
        inertia = self.inertia
        if torque is None:
            # a brake is a friction torque up to brake_torque that stops the joint
            stop = self.velocity * inertia / dt
            torque = -max(-self.brake_torque, min(self.brake_torque, stop))
        velocity = (self.velocity + torque * dt / inertia) / (1.0 + self.friction * dt / inertia)
        position = self.position + velocity * dt
        if position < self.lower:
            position, velocity = self.lower, max(velocity, 0.0)
        elif position > self.upper:
            position, velocity = self.upper, min(velocity, 0.0)
        self.position, self.velocity = position, velocity
