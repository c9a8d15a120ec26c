"""The interface a world offers the simulated motor controllers: named joints to read and drive.

`SimulatedOdrives` knows a world only through this: each control step it reads every joint's
position and velocity, hands each driven joint a torque (None: that joint's motor is off), and
advances the world by one `time_step`. Positions are radians (rad/s, Nm), as in joint messages.
"""
from __future__ import annotations

from typing import Protocol, Sequence


class Plant(Protocol):
    time_step: float                  # seconds one `step` advances
    joint_names: tuple[str, ...]      # the joints an axis may drive, in a fixed order

    def joint_inertias(self) -> list[float]:
        """Inertia seen at each joint (kg m^2) in the current pose: what default gains scale with."""

    def effort_limits(self) -> list[float]:
        """Most torque each joint's motor may give (Nm), from the robot's description."""

    def velocity_limits(self) -> list[float]:
        """Most speed of each joint (rad/s), from the robot's description."""

    def read_joints(self) -> tuple[list[float], list[float]]:
        """Positions (rad) and velocities (rad/s) of every joint, in `joint_names` order."""

    def apply_torques(self, torques: Sequence[float | None]) -> None:
        """The torque of each joint's motor until the next call; None: motor off (brake or coast)."""

    def step(self) -> None:
        """Advance the world by `time_step`."""

    def close(self) -> None:
        """Release what the world holds (its physics client)."""
