"""The conveyor arm's simulated controllers with the world's end-effector camera and object count.

`ConveyorSim` is `SimulatedOdrives` on the "conveyor" world (sim/worlds/conveyor.py) with two
more outputs, because the camera and the belt live in the same PyBullet client as the arm and a
process of its own could not see them:

    camera (output, cameraFrame)   every `camera_period`: the end-effector camera's image and pose
    tally  (output, conveyorTally) whenever an object appears, is grasped, placed, missed or dropped
    scene  (output, conveyorScene) with every camera frame: the belt, the bin and the cubes, to draw

Each is stamped with the world's time on the engine's clock (`clock_time`), which vision,
planning and manipulation compare with their own now() to predict where an object will be.

The tally is ground truth from the simulation: for the record, the plot and the tests; no
controller reads it (planning works from what vision sees).
"""
from __future__ import annotations

import pybullet

from iotad import Internal, Output, Param
from sim.odrive_sim import SimulatedOdrives

from conveyor_types import CAMERA_FRAME, COLOUR_NAMES, CONVEYOR_SCENE, IMAGE_SIZE, MAX_SHOWN, TALLY

CAMERA_FOV = 60.0
CAMERA_AHEAD = 0.05  # m from the end-effector link along its z axis (as ConveyorWorld.camera_image)


class ConveyorSim(SimulatedOdrives):
    world = Param("conveyor")
    camera_period = Param(0.1)        # s between camera frames

    camera = Output(CAMERA_FRAME)
    snap = Internal()
    tally = Output(TALLY)
    scene = Output(CONVEYOR_SCENE)

    def init(self):
        # checked before the world opens, so that a bad parameter leaves no world behind
        if self.world != "conveyor":
            raise ValueError(f"ConveyorSim drives the conveyor world, not {self.world!r}")
        if isinstance(self.camera_period, bool) or not isinstance(self.camera_period, (int, float)) \
                or not self.camera_period > 0:
            raise ValueError(f"camera_period must be seconds > 0, got {self.camera_period!r}")
        super().init()
        self.frame = None
        self.drawn = None  # the scene of the last camera frame, until it is out
        self.counted = self._count()
        self.reported = None

    # deadlines, so that no legal schedule (the random policy's) lets frames fall behind
    @camera.action(value=lambda self: self.frame, when=lambda self: self.frame is not None,
                   within=(0, "camera_period"))
    def sent_frame(self):
        self.frame = None

    @snap.action(within=(lambda self: self.camera_period, lambda self: self.camera_period + self.timing_slack))
    def shot(self):
        self.frame = self._shot()
        self.drawn = self._scene()

    @scene.action(value=lambda self: self.drawn, when=lambda self: self.drawn is not None,
                  within=(0, "camera_period"))
    def sent_scene(self):
        self.drawn = None

    @tally.action(value=lambda self: self.counted, when=lambda self: self.counted_key() != self.reported,
                  within=(0, "timing_slack"))
    def sent_tally(self):
        self.reported = self.counted_key()

    def _step(self) -> None:
        super()._step()
        world = self.plant
        key = (sum(c.state != "waiting" for c in world.cubes), int(world.held is not None),
               world.placed, world.missed, world.dropped)
        if key != self.counted_key():
            self.counted = self._count()

    def counted_key(self):
        c = self.counted
        return (c.spawned, c.held, c.placed, c.missed, c.dropped)

    def _count(self):
        world = self.plant
        return TALLY(t=self.clock_time, spawned=sum(c.state != "waiting" for c in world.cubes),
                     held=int(world.held is not None), placed=world.placed, missed=world.missed,
                     dropped=world.dropped)

    def _shot(self):
        """The camera image and pose now."""
        world = self.plant
        position, orientation = world.end_effector_pose()
        m = pybullet.getMatrixFromQuaternion(orientation)
        forward, up = [m[2], m[5], m[8]], [m[0], m[3], m[6]]
        eye = [p + CAMERA_AHEAD * f for p, f in zip(position, forward)]
        image = world.camera_image(IMAGE_SIZE, IMAGE_SIZE, fov=CAMERA_FOV)
        return CAMERA_FRAME(t=self.clock_time, rgb=image.tobytes(), fov=CAMERA_FOV, eye=eye, forward=forward, up=up)

    def _scene(self):
        """The belt, the bin and the cubes now (the newest MAX_SHOWN of those in the world)."""
        world = self.plant
        shown = [c for c in world.cubes if c.body >= 0][-MAX_SHOWN:]
        centres = [pybullet.getBasePositionAndOrientation(c.body, physicsClientId=world.client)[0] for c in shown]
        pad = [0.0] * (MAX_SHOWN - len(shown))
        return CONVEYOR_SCENE(
            t=self.clock_time, belt=[world.belt_x, world.belt_length, world.belt_width, world.belt_height],
            bin=[*world.bin_position, world.bin_size, world.bin_height], cube_size=world.cube_size,
            count=len(shown), x=[c[0] for c in centres] + pad, y=[c[1] for c in centres] + pad,
            z=[c[2] for c in centres] + pad, colour=[COLOUR_NAMES.index(c.colour) for c in shown] + [0] * len(pad))
