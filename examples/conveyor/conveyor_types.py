"""Message types of the conveyor arm (examples/conveyor.toml), shared by its IOTAs.

The camera frame carries its image as raw RGB bytes (an immutable value, recorded as base64):
an array of 4800 ints per frame would cost more to check and record than the rest of the system.
"""
from __future__ import annotations

import base64
from typing import Any

from iotad.kernel.types import Array, BadValue, Bool, Float, Int, Struct, Type

MAX_BLOBS = 4  # objects one camera frame reports to planning
REQ_SWITCHING = 1.0  # s between requests: the scheduler's req switching time (Figure 2's)


class RgbImageType(Type):
    """`width` x `height` RGB pixels, row-major, as `bytes` (3 per pixel)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.size = self.width * self.height * 3
        self.name = f"rgb{self.width}x{self.height}"

    def check(self, value: Any) -> None:
        if not isinstance(value, bytes) or len(value) != self.size:
            raise BadValue(f"expected {self.size} bytes of RGB ({self.width}x{self.height}), "
                           f"got {type(value).__name__} of {len(value) if hasattr(value, '__len__') else '?'}")

    def to_plain(self, value: Any) -> Any:
        return base64.b64encode(value).decode("ascii")

    def from_plain(self, plain: Any) -> bytes:
        if isinstance(plain, bytes):
            value = plain
        elif isinstance(plain, str):
            try:
                value = base64.b64decode(plain, validate=True)
            except ValueError as exc:
                raise BadValue(f"{self.name}: not base64: {exc}") from None
        else:
            raise BadValue(f"{self.name}: expected base64 text, got {type(plain).__name__}")
        self.check(value)
        return value

    def default(self) -> bytes:
        return bytes(self.size)

    def json_schema(self) -> dict:
        return {"type": "string", "title": self.name, "contentEncoding": "base64",
                "maxLength": (self.size + 2) // 3 * 4}

    def __eq__(self, other: object) -> bool:
        return isinstance(other, RgbImageType) and (other.width, other.height) == (self.width, self.height)

    def __hash__(self) -> int:
        return hash(self.name)


IMAGE_SIZE = 40
RGB_IMAGE = RgbImageType(IMAGE_SIZE, IMAGE_SIZE)

# One end-effector camera image and where the camera was (forward kinematics of the measured
# joints, as a real arm's driver would stamp it): eye position, looking direction, image up.
CAMERA_FRAME = Struct("cameraFrame", t=Float(0, None), rgb=RGB_IMAGE, fov=Float(1, 179),
                      eye=Array(Float, 3), forward=Array(Float, 3), up=Array(Float, 3))

# What vision saw in one frame: up to MAX_BLOBS coloured blobs, their centres on the belt plane.
SIGHTING = Struct("sighting", t=Float(0, None), count=Int(0, MAX_BLOBS), x=Array(Float, MAX_BLOBS),
                  y=Array(Float, MAX_BLOBS), colour=Array(Int(0, 3), MAX_BLOBS), pixels=Array(Int(0, None), MAX_BLOBS))

# Planning's perceptual goal: look at the object `target` predicted at (x, y) at time t, moving
# at vy along the belt; target -1: no object known, look upstream where new objects appear.
LOOK_GOAL = Struct("lookGoal", target=Int(-1, None), x=Float, y=Float, vy=Float, t=Float(0, None))

# Planning's manipulative goal: pick object `target` predicted at (x, y) at time t moving at vy.
PICK_GOAL = Struct("pickGoal", target=Int(0, None), x=Float, y=Float, vy=Float, t=Float(0, None))

# Manipulation's report on a pick goal: the motion ran (committed) or not.
PICK_DONE = Struct("pickDone", target=Int(0, None), committed=Bool)

# The world's count of objects (ground truth from the simulation, for the record and the tests).
TALLY = Struct("conveyorTally", t=Float(0, None), spawned=Int(0, None), held=Int(0, None),
               placed=Int(0, None), missed=Int(0, None), dropped=Int(0, None))

COLOUR_NAMES = ("red", "green", "blue", "yellow")
# The world as Foxglove draws it (iotad/recording/foxglove_scene.py), with every camera frame:
# belt [x, length, width, height] (centred at y = 0, carrying toward -y), bin [x, y, size, height],
# and the cubes in the world (on the belt, held, falling or in the bin), the newest MAX_SHOWN,
# their centres and colours (indices into COLOUR_NAMES).
MAX_SHOWN = 8
CONVEYOR_SCENE = Struct("conveyorScene", t=Float(0, None), belt=Array(Float, 4), bin=Array(Float, 4),
                        cube_size=Float(0, None), count=Int(0, MAX_SHOWN), x=Array(Float, MAX_SHOWN),
                        y=Array(Float, MAX_SHOWN), z=Array(Float, MAX_SHOWN),
                        colour=Array(Int(0, len(COLOUR_NAMES) - 1), MAX_SHOWN))
