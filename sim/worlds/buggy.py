"""Buggy's arena (the paper's Figures 3-5): walls, two cracks with food along them, and Buggy.

Buggy is a small differential-drive robot moved kinematically, not by contact physics: its two
actuators are the world's two joints, each a `ModelJoint` (an inertia with friction) that a
simulated ODrive axis drives by torque, usually in velocity mode:
- "drive": the wheels. Forward speed (m/s) = `wheel_radius` x its velocity (rad/s).
- "turn":  the heading. Its position is Buggy's yaw (rad), its velocity the turn rate.
Every step Buggy moves `speed * time_step` along its heading. It cannot pass a wall: a move that
would put its body (radius `body_radius`) into a wall is cut at the wall and counted in `bumps`
(a bumper, not physics), so Buggy never leaves the arena whatever drives it.

Sensors, in Buggy's body frame (x forward, y left; bearings in rad, + to the left):
- `proximity()`: distance and bearing of the nearest wall, from a fan of `proximity_rays` rays
  (one PyBullet rayTestBatch) reaching `proximity_range`; None when no wall is in range.
- `crack_vector()`: the vector from Buggy to the nearest point of the nearest crack within
  `crack_range` (perpendicular to the crack unless that point is an end); None when none.
- `food_detected()`: food within `food_range` of Buggy's centre. `eat()` removes that food.

PyBullet holds the geometry (walls with collision shapes for the rays; cracks, food and Buggy
only as visuals) and is never stepped: nothing in the arena moves by physics. The arena is
deterministic for a seed: the seed places the food along the cracks and Buggy's start pose.
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass
from typing import Sequence

import pybullet

from . import physics
from .model_joint import ModelJoint

Point = tuple[float, float]

# Two cracks in a 4 m arena (scaled with arena_size): long diagonals that do not cross.
DEFAULT_CRACKS = (((-0.38, -0.30), (0.25, -0.05)), ((-0.20, 0.15), (0.35, 0.35)))


@dataclass(frozen=True)
class Proximity:
    distance: float   # m, from Buggy's centre to the wall
    bearing: float    # rad in Buggy's frame, + to the left


@dataclass(frozen=True)
class CrackVector:
    x: float          # m, forward
    y: float          # m, to the left

    @property
    def distance(self) -> float:
        return math.hypot(self.x, self.y)


class BuggyWorld:
    """The arena and Buggy; a `Plant` with joints ("drive", "turn")."""

    joint_names = ("drive", "turn")

    # options that must be > 0 (sim.worlds.check_options)
    POSITIVE_OPTIONS = ("time_step", "arena_size", "wall_height", "wall_thickness", "body_radius", "wheel_radius",
                        "food_range", "proximity_range", "proximity_fov", "crack_range", "max_speed",
                        "max_turn_rate", "drive_inertia", "turn_inertia", "drive_effort", "turn_effort")

    def __init__(self, time_step: float = 1.0 / 240.0, seed: int = 0, arena_size: float = 4.0,
                 wall_height: float = 0.3, wall_thickness: float = 0.05, body_radius: float = 0.1,
                 wheel_radius: float = 0.05, cracks: Sequence[tuple[Point, Point]] | None = None,
                 food_per_crack: int = 3, food_range: float = 0.15, proximity_range: float = 1.0,
                 proximity_rays: int = 16, proximity_fov: float = 2 * math.pi, crack_range: float = 0.5,
                 start: tuple[float, float, float] | None = None, max_speed: float = 0.3,
                 max_turn_rate: float = 2.0, drive_inertia: float = 5e-3, turn_inertia: float = 2e-2,
                 drive_effort: float = 0.5, turn_effort: float = 0.5, friction: float = 1e-3,
                 brake_torque: float = 0.1):
        if not arena_size > 4 * body_radius:
            raise ValueError(f"arena_size {arena_size} m leaves no room for a body of radius {body_radius} m")
        if proximity_rays < 1:
            raise ValueError(f"proximity_rays must be >= 1, got {proximity_rays}")
        if food_per_crack < 0 or friction < 0 or brake_torque < 0:
            raise ValueError(f"food_per_crack, friction and brake_torque must be >= 0, got {food_per_crack}, "
                             f"{friction} and {brake_torque}")
        self.time_step = float(time_step)
        self.seed = seed
        self.arena_size, self.body_radius, self.wheel_radius = arena_size, body_radius, wheel_radius
        self.food_range, self.crack_range = food_range, crack_range
        self.proximity_range, self.proximity_rays, self.proximity_fov = proximity_range, proximity_rays, proximity_fov
        half = arena_size / 2
        # the walls' inner faces; Buggy's centre stays body_radius inside them
        self.inner = half - wall_thickness / 2
        self.limit = self.inner - body_radius
        rng = random.Random(seed)
        self.cracks: list[tuple[Point, Point]] = [
            (tuple(a), tuple(b)) for a, b in (cracks if cracks is not None else
                                              [((ax * arena_size, ay * arena_size), (bx * arena_size, by * arena_size))
                                               for (ax, ay), (bx, by) in DEFAULT_CRACKS])]
        for a, b in self.cracks:
            for x, y in (a, b):
                if abs(x) > self.inner or abs(y) > self.inner:
                    raise ValueError(f"crack {a}-{b} leaves the arena (inner half-size {self.inner:.3f} m)")
        self.food: list[Point] = []
        for a, b in self.cracks:
            for _ in range(food_per_crack):
                f = rng.uniform(0.1, 0.9)
                self.food.append((a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])))
        if start is None:
            margin = min(0.5, self.limit / 2)
            start = (rng.uniform(-self.limit + margin, self.limit - margin),
                     rng.uniform(-self.limit + margin, self.limit - margin), rng.uniform(-math.pi, math.pi))
        x, y, yaw = start
        if abs(x) > self.limit or abs(y) > self.limit:
            raise ValueError(f"start ({x}, {y}) is not inside the arena (|x|, |y| <= {self.limit:.3f} m)")
        self.x, self.y = float(x), float(y)
        # A motor that goes idle (estop, watchdog) leaves its joint to the brake: the gearbox's and
        # the wheels' resistance, which stop Buggy from full speed in about 0.3 s. Viscous friction
        # alone (time constant inertia / friction: 5 s) would let it coast across the arena.
        self.drive = ModelJoint(drive_inertia, friction, brake_torque=brake_torque)
        self.turn = ModelJoint(turn_inertia, friction, position=float(yaw), brake_torque=brake_torque)
        self._efforts = [drive_effort, turn_effort]
        self._speeds = [max_speed / wheel_radius, max_turn_rate]
        self._torques: list[float | None] = [None, None]
        self.bumps = 0
        self.eaten = 0
        self.distance = 0.0   # m travelled
        self.time = 0.0
        self.client = physics.connect(self.time_step, 0.0)
        self._build(half, wall_height, wall_thickness)

    def _build(self, half: float, height: float, thickness: float) -> None:
        client = self.client
        physics.box(client, (half, half, 0.005), (0, 0, -0.005), rgba=(0.85, 0.82, 0.75, 1), collision=False)
        grey = (0.45, 0.45, 0.5, 1)
        self.walls = [
            physics.box(client, (half, thickness / 2, height / 2), (0, y, height / 2), grey) for y in (-half, half)
        ] + [
            physics.box(client, (thickness / 2, half, height / 2), (x, 0, height / 2), grey) for x in (-half, half)
        ]
        for (ax, ay), (bx, by) in self.cracks:
            length = math.hypot(bx - ax, by - ay)
            orientation = pybullet.getQuaternionFromEuler((0, 0, math.atan2(by - ay, bx - ax)))
            physics.box(client, (length / 2, 0.01, 0.001), ((ax + bx) / 2, (ay + by) / 2, 0.001),
                        rgba=(0.2, 0.15, 0.1, 1), collision=False, orientation=orientation)
        self._food_bodies = [physics.box(client, (0.03, 0.03, 0.01), (fx, fy, 0.01), rgba=(0.1, 0.7, 0.2, 1),
                                         collision=False) for fx, fy in self.food]
        visual = pybullet.createVisualShape(pybullet.GEOM_CYLINDER, radius=self.body_radius, length=0.08,
                                            rgbaColor=(0.8, 0.3, 0.1, 1), physicsClientId=client)
        self.body = pybullet.createMultiBody(0, -1, visual, (self.x, self.y, 0.04), physicsClientId=client)
        # ray fan offsets: relative bearings, fixed; the world frame is added per call
        n, fov = self.proximity_rays, self.proximity_fov
        full = math.isclose(fov, 2 * math.pi)
        if full:  # all around, one ray straight ahead
            self._bearings = [math.remainder(2 * math.pi * k / n, 2 * math.pi) for k in range(n)]
        else:     # a fan centred ahead, its end rays on the edges
            self._bearings = [-fov / 2 + fov * k / (n - 1) if n > 1 else 0.0 for k in range(n)]

    # ------------------------------------------------------------------ Plant
    def joint_inertias(self) -> list[float]:
        return [self.drive.inertia, self.turn.inertia]

    def effort_limits(self) -> list[float]:
        return list(self._efforts)

    def velocity_limits(self) -> list[float]:
        return list(self._speeds)

    def read_joints(self) -> tuple[list[float], list[float]]:
        return [self.drive.position, self.turn.position], [self.drive.velocity, self.turn.velocity]

    def apply_torques(self, torques: Sequence[float | None]) -> None:
        self._torques = list(torques)

    def step(self) -> None:
        dt = self.time_step
        self.drive.step(self._torques[0], dt)
        self.turn.step(self._torques[1], dt)
        self.move(self.wheel_radius * self.drive.velocity * dt, self.turn.position)
        self.time += dt

    def close(self) -> None:
        physics.disconnect(self.client)

    # ------------------------------------------------------------------ motion
    def move(self, distance: float, heading: float) -> None:
        """Move `distance` m along `heading` (rad), cut at the walls (a bump)."""
        x = self.x + distance * math.cos(heading)
        y = self.y + distance * math.sin(heading)
        limit = self.limit
        if not (-limit <= x <= limit and -limit <= y <= limit):
            self.bumps += 1
            x = min(limit, max(-limit, x))
            y = min(limit, max(-limit, y))
        self.distance += math.hypot(x - self.x, y - self.y)
        self.x, self.y = x, y

    @property
    def yaw(self) -> float:
        return self.turn.position

    def pose(self) -> tuple[float, float, float]:
        """x, y (m) and heading (rad, wrapped to -pi..pi)."""
        return self.x, self.y, math.atan2(math.sin(self.yaw), math.cos(self.yaw))

    def speed(self) -> float:
        return self.wheel_radius * self.drive.velocity

    def sync_body(self) -> None:
        """Put Buggy's visual body where Buggy is (only pictures need it)."""
        pybullet.resetBasePositionAndOrientation(self.body, (self.x, self.y, 0.04),
                                                 pybullet.getQuaternionFromEuler((0, 0, self.yaw)),
                                                 physicsClientId=self.client)

    # ------------------------------------------------------------------ sensors
    def proximity(self) -> Proximity | None:
        """The nearest wall hit by the ray fan, or None if none is within range."""
        x, y, yaw, reach, z = self.x, self.y, self.yaw, self.proximity_range, 0.05
        starts, ends = [], []
        for bearing in self._bearings:
            angle = yaw + bearing
            starts.append((x, y, z))
            ends.append((x + reach * math.cos(angle), y + reach * math.sin(angle), z))
        hits = pybullet.rayTestBatch(starts, ends, physicsClientId=self.client)
        best = None
        for bearing, hit in zip(self._bearings, hits):
            if hit[0] >= 0 and (best is None or hit[2] < best[0]):
                best = (hit[2], bearing)
        if best is None:
            return None
        return Proximity(best[0] * reach, best[1])

    def crack_vector(self) -> CrackVector | None:
        """From Buggy to the nearest point of the nearest crack within range, in Buggy's frame."""
        best = None
        for a, b in self.cracks:
            px, py = closest_point(a, b, (self.x, self.y))
            d = math.hypot(px - self.x, py - self.y)
            if d <= self.crack_range and (best is None or d < best[0]):
                best = (d, px - self.x, py - self.y)
        if best is None:
            return None
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        _, dx, dy = best
        return CrackVector(c * dx + s * dy, -s * dx + c * dy)

    def _food_near(self) -> int | None:
        best = None
        for k, (fx, fy) in enumerate(self.food):
            d = math.hypot(fx - self.x, fy - self.y)
            if d <= self.food_range and (best is None or d < best[0]):
                best = (d, k)
        return None if best is None else best[1]

    def food_detected(self) -> bool:
        return self._food_near() is not None

    def eat(self) -> bool:
        """Eat the food within range (it is gone from the arena); False if there is none."""
        k = self._food_near()
        if k is None:
            return False
        del self.food[k]
        pybullet.removeBody(self._food_bodies.pop(k), physicsClientId=self.client)
        self.eaten += 1
        return True

    def inside(self) -> bool:
        """Buggy's body is wholly inside the walls."""
        return abs(self.x) <= self.limit + 1e-9 and abs(self.y) <= self.limit + 1e-9


def closest_point(a: Point, b: Point, p: Point) -> Point:
    """The point of segment a-b nearest to p."""
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length2 = dx * dx + dy * dy
    if length2 == 0:
        return a
    f = ((p[0] - ax) * dx + (p[1] - ay) * dy) / length2
    f = 0.0 if f < 0 else 1.0 if f > 1 else f
    return ax + f * dx, ay + f * dy
