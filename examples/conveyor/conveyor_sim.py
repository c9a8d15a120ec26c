"""The conveyor arm's simulated controllers with the world's end-effector camera and object count.

`ConveyorSim` is `SimulatedOdrives` on the "conveyor" world (sim/worlds/conveyor.py) with two
more outputs, because the camera and the belt live in the same PyBullet client as the arm and a
process of its own could not see them:

    camera (output, cameraFrame)   every `camera_period`: the end-effector camera's image and pose
    tally  (output, conveyorTally) whenever an object appears, is grasped, placed, missed or dropped

The tally is ground truth from the simulation: for the record, the plot and the tests; no
controller reads it (planning works from what vision sees).
"""
from __future__ import annotations

import pybullet

from iotad import Internal, Output, Param
from sim.odrive_sim import SimulatedOdrives

from conveyor_types import CAMERA_FRAME, IMAGE_SIZE, TALLY

CAMERA_FOV = 60.0
CAMERA_AHEAD = 0.05  # m from the end-effector link along its z axis (as ConveyorWorld.camera_image)


class ConveyorSim(SimulatedOdrives):
    world = Param("conveyor")
    camera_period = Param(0.1)        # s between camera frames

    camera = Output(CAMERA_FRAME)
    snap = Internal()
    tally = Output(TALLY)

    def init(self):
        # checked before the world opens, so that a bad parameter leaves no world behind
        if self.world != "conveyor":
            raise ValueError(f"ConveyorSim drives the conveyor world, not {self.world!r}")
        if isinstance(self.camera_period, bool) or not isinstance(self.camera_period, (int, float)) \
                or not self.camera_period > 0:
            raise ValueError(f"camera_period must be seconds > 0, got {self.camera_period!r}")
        super().init()
        self.frame = None
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
        return TALLY(t=self.sim_time, spawned=sum(c.state != "waiting" for c in world.cubes),
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
        return CAMERA_FRAME(t=self.sim_time, rgb=image.tobytes(), fov=CAMERA_FOV, eye=eye, forward=forward, up=up)
