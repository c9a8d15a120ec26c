"""Message types of the conveyor arm (examples/conveyor.toml), shared by its IOTAs.

The camera frame carries its image as raw RGB bytes (an immutable value): an array of 4800 ints
per frame would cost more to check and record than the rest of the system. On the wire and in
recordings the bytes are zlib-compressed, then base64 (`zlib:...`): a rendered frame's flat
colours shrink about 45 times (4800 bytes to ~100). Raw, the camera's 10 frames a second (about
0.5 Mbit/s) were most of what arm's nodes sent to the other hosts, the traces aside (docs/hosts.md,
"A slowed link"). Older recordings' plain base64 frames still read.
"""
from __future__ import annotations

import base64
import zlib
from typing import Any

from iotad.kernel.types import Array, BadValue, Bool, Float, Int, Struct, Type

MAX_BLOBS = 4  # objects one camera frame reports to planning
REQ_SWITCHING = 1.0  # s between requests: the scheduler's req switching time (Figure 2's)


ZLIB = "zlib:"  # not in base64's alphabet: a plain base64 frame (an older recording's) never starts so


class RgbImageType(Type):
    """`width` x `height` RGB pixels, row-major, as `bytes` (3 per pixel); plain: `zlib:` and the
    base64 of the zlib-compressed bytes (or, from older recordings, the base64 of the bytes)."""

    def __init__(self, width: int, height: int):
        self.width, self.height = int(width), int(height)
        self.size = self.width * self.height * 3
        self.name = f"rgb{self.width}x{self.height}"

    def check(self, value: Any) -> None:
        if not isinstance(value, bytes) or len(value) != self.size:
            raise BadValue(f"expected {self.size} bytes of RGB ({self.width}x{self.height}), "
                           f"got {type(value).__name__} of {len(value) if hasattr(value, '__len__') else '?'}")

    def to_plain(self, value: Any) -> Any:
        # level 1: nearly all of level 9's gain on rendered frames, at a fraction of its time
        return ZLIB + base64.b64encode(zlib.compress(value, 1)).decode("ascii")

    def from_plain(self, plain: Any) -> bytes:
        if isinstance(plain, bytes):
            value = plain
        elif isinstance(plain, str):
            packed = plain.startswith(ZLIB)
            try:
                value = base64.b64decode(plain[len(ZLIB):] if packed else plain, validate=True)
            except ValueError as exc:
                raise BadValue(f"{self.name}: not base64: {exc}") from None
            if packed:
                value = self._inflate(value)
        else:
            raise BadValue(f"{self.name}: expected base64 text, got {type(plain).__name__}")
        self.check(value)
        return value

    def _inflate(self, packed: bytes) -> bytes:
        """The frame's bytes; never more than one byte past its size, whatever a bad payload
        claims (a small payload may inflate to gigabytes)."""
        inflater = zlib.decompressobj()
        try:
            value = inflater.decompress(packed, self.size + 1)
        except zlib.error as exc:
            raise BadValue(f"{self.name}: not zlib data: {exc}") from None
        if len(value) == self.size and (inflater.unconsumed_tail or not inflater.eof):
            raise BadValue(f"{self.name}: the zlib data holds more than {self.size} bytes, or is cut short")
        return value

    def default(self) -> bytes:
        return bytes(self.size)

    def json_schema(self) -> dict:
        # zlib's worst case, its compressBound (zlib.h), base64 of it
        packed = self.size + (self.size >> 12) + (self.size >> 14) + (self.size >> 25) + 13
        return {"type": "string", "title": self.name,
                "description": "'zlib:' then the base64 of the zlib-compressed RGB bytes",
                "maxLength": len(ZLIB) + (packed + 2) // 3 * 4}

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
