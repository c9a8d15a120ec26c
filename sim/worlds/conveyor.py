"""The conveyor arm's world (the paper's Figure 1): the xArm6 beside a belt carrying cubes, and a bin.

Layout (metres, the arm's base at the origin, x ahead of it): the belt runs along y at
x = `belt_x`, its top `belt_height` above the floor, and carries cubes toward -y at `belt_speed`;
a cube appears at the upstream end (y = +belt_length/2) every `cube_interval` seconds from
`first_cube` on, `cube_count` in all, its colour and a small sideways offset drawn from `seed`.
A cube that reaches the downstream end falls off and counts as `missed`. The bin is an open box
at `bin_position`.

Simplifications, on purpose:
- The belt is kinematic: a cube on it is put where the belt has carried it every step, not
  dragged by friction, so the belt speed is exact and a run is cheap.
- Grasping is a fixed constraint, not finger friction: when the gripper closes past
  `grasp_closure` (0..1) with a cube's centre within `grasp_radius` of the grasp point
  (between the fingers), the cube is fixed to the hand; when it opens below
  `release_closure` the constraint goes and the cube falls. Only a closing counts: a closed hand
  that meets a cube does not pick it up. Cubes do not collide with the arm at all, so the hand
  cannot knock them off the belt.
- A released cube that comes to rest inside the bin counts as `placed`; at rest anywhere else,
  as `dropped`. Either is then put to sleep (Bullet's own deactivation: a sleeping body still
  collides, and wakes when something hits it), so a pile in the bin does not make every later
  step dearer: without it a step cost 31 us with an empty bin and 134 us with 20 cubes in it.
The end-effector camera (`camera_image`) renders with TinyRenderer on demand only, without the
arm's own meshes (it looks away from them, and they are nearly all the rendering cost): a 64x64
image costs ~1-2 ms instead of ~18.
"""
from __future__ import annotations

import math
import random
from dataclasses import dataclass, field

import pybullet

from . import physics
from .arm import ArmWorld

COLOURS = {"red": (0.9, 0.1, 0.1, 1), "green": (0.1, 0.8, 0.1, 1), "blue": (0.1, 0.2, 0.9, 1),
           "yellow": (0.95, 0.85, 0.1, 1)}
WAITING, RIDING, HELD, FREE, PLACED, MISSED, DROPPED = (
    "waiting", "riding", "held", "free", "placed", "missed", "dropped")
REST_SPEED = 0.02  # m/s: a free cube slower than this, low enough, has come to rest


@dataclass
class Cube:
    index: int
    colour: str
    spawn_time: float
    offset: float                 # m, sideways on the belt
    state: str = WAITING
    body: int = -1
    constraint: int = -1
    history: list = field(default_factory=list)  # (time, state) changes


class ConveyorWorld(ArmWorld):
    """The xArm6 with gripper, a belt of cubes, a bin and an end-effector camera."""

    # options that must be > 0 (sim.worlds.check_options)
    POSITIVE_OPTIONS = ("time_step", "cube_interval", "cube_size", "belt_length", "belt_width", "belt_height",
                        "bin_size", "bin_height", "grasp_radius")

    def __init__(self, time_step: float = 1.0 / 240.0, seed: int = 0, belt_speed: float = 0.05,
                 cube_count: int = 20, cube_interval: float = 5.0, first_cube: float = 1.0,
                 cube_size: float = 0.04, colours: tuple[str, ...] = tuple(COLOURS), belt_x: float = 0.45,
                 belt_length: float = 1.2, belt_width: float = 0.16, belt_height: float = 0.1,
                 bin_position: tuple[float, float] = (0.1, -0.45), bin_size: float = 0.2, bin_height: float = 0.1,
                 grasp_closure: float = 0.5, release_closure: float = 0.3, grasp_radius: float = 0.035,
                 **arm_options):
        super().__init__("xarm6", time_step=time_step, **arm_options)
        unknown = set(colours) - set(COLOURS)
        if unknown or not colours:
            raise ValueError(f"colours must be some of {', '.join(COLOURS)}, got {colours!r}")
        if not belt_speed >= 0 or not cube_interval > 0 or cube_count < 0:
            raise ValueError("belt_speed must be >= 0, cube_interval > 0 and cube_count >= 0")
        self.seed = seed
        self.belt_speed, self.cube_size = belt_speed, cube_size
        self.belt_x, self.belt_length, self.belt_width, self.belt_height = belt_x, belt_length, belt_width, belt_height
        self.bin_position, self.bin_size, self.bin_height = tuple(bin_position), bin_size, bin_height
        self.grasp_closure, self.release_closure, self.grasp_radius = grasp_closure, release_closure, grasp_radius
        self.time = 0.0
        self.placed = self.missed = self.dropped = 0
        self.held: Cube | None = None
        self._was_closed = False
        rng = random.Random(seed)
        self.cubes = [Cube(k, rng.choice(list(colours)), first_cube + k * cube_interval,
                           rng.uniform(-0.25, 0.25) * (belt_width - cube_size)) for k in range(cube_count)]
        self._arm_links = [-1] + list(range(pybullet.getNumJoints(self.body, physicsClientId=self.client)))
        self._arm_colours = [(shape[1], shape[7]) for shape in
                             pybullet.getVisualShapeData(self.body, physicsClientId=self.client)]
        self._build()

    def _build(self) -> None:
        client = self.client
        half_height = self.belt_height / 2
        self.belt = physics.box(client, (self.belt_width / 2, self.belt_length / 2, half_height),
                                (self.belt_x, 0, half_height), rgba=(0.15, 0.15, 0.15, 1))
        bx, by = self.bin_position
        h, s, t = self.bin_height, self.bin_size / 2, 0.005
        colour = (0.55, 0.4, 0.25, 1)
        self.bin_parts = [physics.box(client, (s, s, t), (bx, by, t), colour)] + [
            physics.box(client, (t, s, h / 2), (bx + dx * s, by, h / 2), colour) for dx in (-1, 1)] + [
            physics.box(client, (s, t, h / 2), (bx, by + dy * s, h / 2), colour) for dy in (-1, 1)]

    # ------------------------------------------------------------------ Plant
    def step(self) -> None:
        super().step()
        self.time += self.time_step
        self._spawn_and_carry()
        self._grasp_or_release()
        self._settle()

    def _spawn_and_carry(self) -> None:
        client, now, half = self.client, self.time, self.belt_length / 2
        z = self.belt_height + self.cube_size / 2
        for cube in self.cubes:
            if cube.state == WAITING and now >= cube.spawn_time:
                self._spawn(cube)
            if cube.state != RIDING:
                continue
            y = half - self.belt_speed * (now - cube.spawn_time)
            if y < -half:
                self._set_state(cube, MISSED)
                pybullet.removeBody(cube.body, physicsClientId=client)
                cube.body = -1
                self.missed += 1
                continue
            pybullet.resetBasePositionAndOrientation(cube.body, (self.belt_x + cube.offset, y, z), (0, 0, 0, 1),
                                                     physicsClientId=client)
            pybullet.resetBaseVelocity(cube.body, (0, -self.belt_speed, 0), (0, 0, 0), physicsClientId=client)

    def _spawn(self, cube: Cube) -> None:
        client, size = self.client, self.cube_size / 2
        cube.body = physics.box(client, (size, size, size),
                                (self.belt_x + cube.offset, self.belt_length / 2, self.belt_height + size),
                                rgba=COLOURS[cube.colour], mass=0.05)
        pybullet.changeDynamics(cube.body, -1, lateralFriction=1.0,
                                activationState=pybullet.ACTIVATION_STATE_ENABLE_SLEEPING, physicsClientId=client)
        for link in self._arm_links:
            pybullet.setCollisionFilterPair(cube.body, self.body, -1, link, 0, physicsClientId=client)
        self._set_state(cube, RIDING)

    def _grasp_or_release(self) -> None:
        closure = self.gripper_closure()
        closing = closure >= self.grasp_closure and not self._was_closed
        if closure >= self.grasp_closure:
            self._was_closed = True
        elif closure < self.release_closure:
            self._was_closed = False
            if self.held is not None:
                self._release()
        if closing and self.held is None:
            cube = self._cube_at_hand()
            if cube is not None:
                self._grasp(cube)

    def _cube_at_hand(self) -> Cube | None:
        tool = self.tool_point()
        best = None
        for cube in self.cubes:
            if cube.state not in (RIDING, FREE):
                continue
            position = pybullet.getBasePositionAndOrientation(cube.body, physicsClientId=self.client)[0]
            d = math.dist(tool, position)
            if d <= self.grasp_radius and (best is None or d < best[0]):
                best = (d, cube)
        return None if best is None else best[1]

    def _grasp(self, cube: Cube) -> None:
        client = self.client
        hand_position, hand_orientation = self.end_effector_pose()
        position, orientation = pybullet.getBasePositionAndOrientation(cube.body, physicsClientId=client)
        # the cube's pose in the hand's frame, kept by the constraint
        inverse = pybullet.invertTransform(hand_position, hand_orientation)
        local_position, local_orientation = pybullet.multiplyTransforms(*inverse, position, orientation)
        cube.constraint = pybullet.createConstraint(
            self.body, self.end_effector_link, cube.body, -1, pybullet.JOINT_FIXED, (0, 0, 0),
            local_position, (0, 0, 0), local_orientation, (0, 0, 0, 1), physicsClientId=client)
        self.held = cube
        self._set_state(cube, HELD)

    def _release(self) -> None:
        cube = self.held
        pybullet.removeConstraint(cube.constraint, physicsClientId=self.client)
        cube.constraint = -1
        self.held = None
        self._set_state(cube, FREE)

    def _settle(self) -> None:
        client = self.client
        for cube in self.cubes:
            if cube.state != FREE:
                continue
            velocity = pybullet.getBaseVelocity(cube.body, physicsClientId=client)[0]
            if math.hypot(*velocity) > REST_SPEED:
                continue
            position = pybullet.getBasePositionAndOrientation(cube.body, physicsClientId=client)[0]
            if self.in_bin(position):
                self._set_state(cube, PLACED)
                self.placed += 1
            elif position[2] < self.belt_height:  # on the floor: it will not get up again
                self._set_state(cube, DROPPED)
                self.dropped += 1
            else:  # it rests on the belt's edge or a bin wall: still free, still graspable
                continue
            self._sleep_at_rest()

    def _sleep_at_rest(self) -> None:
        """Put the placed and dropped cubes at rest to sleep: at once, not after Bullet's own two
        seconds below its thresholds, which a pile that a newcomer woke seldom meets."""
        client = self.client
        for cube in self.cubes:
            if cube.state in (PLACED, DROPPED) and math.hypot(
                    *pybullet.getBaseVelocity(cube.body, physicsClientId=client)[0]) <= REST_SPEED:
                pybullet.changeDynamics(cube.body, -1, activationState=pybullet.ACTIVATION_STATE_SLEEP,
                                        physicsClientId=client)

    def _set_state(self, cube: Cube, state: str) -> None:
        cube.state = state
        cube.history.append((round(self.time, 6), state))

    # ------------------------------------------------------------------ views
    def in_bin(self, position) -> bool:
        """Whether a cube at `position` is in the bin: over its floor, inside its walls (0.005 thick),
        at any height. A pile grows past the rim: a cube at rest on top of others in the bin is in
        it (with a height limit, a 10-minute run's fourth layer, over a rim of three, went uncounted
        until something knocked it down: no cube counted for 49 s of a fault-free run)."""
        bx, by = self.bin_position
        s = self.bin_size / 2 - 0.005
        return abs(position[0] - bx) < s and abs(position[1] - by) < s

    def cube_positions(self) -> dict[int, tuple[float, float, float]]:
        """Where the cubes in the world are (riding, held or free), by index: ground truth for tests."""
        return {cube.index: pybullet.getBasePositionAndOrientation(cube.body, physicsClientId=self.client)[0]
                for cube in self.cubes if cube.state in (RIDING, HELD, FREE)}

    def camera_image(self, width: int = 64, height: int = 64, fov: float = 60.0, near: float = 0.02,
                     far: float = 2.0):
        """The end-effector camera's RGB image, a (height, width, 3) uint8 array: it sits at the
        hand, looks along the tool axis, image up along the hand's x axis. Rendered now (TinyRenderer)."""
        import numpy

        position, orientation = self.end_effector_pose()
        m = pybullet.getMatrixFromQuaternion(orientation)
        forward, up = (m[2], m[5], m[8]), (m[0], m[3], m[6])
        eye = tuple(p + 0.05 * f for p, f in zip(position, forward))
        target = tuple(e + f for e, f in zip(eye, forward))
        view = pybullet.computeViewMatrix(eye, target, up)
        projection = pybullet.computeProjectionMatrixFOV(fov, width / height, near, far)
        # The arm's meshes are almost all of TinyRenderer's work (~17 ms of ~18 at 64x64) and a
        # camera looking out of the hand does not see them: they are made invisible for the shot.
        self._show_arm(False)
        try:
            _, _, rgba, _, _ = pybullet.getCameraImage(width, height, view, projection,
                                                       renderer=pybullet.ER_TINY_RENDERER,
                                                       physicsClientId=self.client)
        finally:
            self._show_arm(True)
        return numpy.asarray(rgba, dtype=numpy.uint8).reshape(height, width, 4)[:, :, :3]

    def _show_arm(self, visible: bool) -> None:
        for link, rgba in self._arm_colours:
            pybullet.changeVisualShape(self.body, link, rgbaColor=rgba if visible else (0, 0, 0, 0),
                                       physicsClientId=self.client)
