"""Geometry the conveyor arm's IOTAs share: the belt and bin layout, the hand's downward pose,
colour segmentation of a camera image, and pixels to points on the belt plane.

The layout numbers are the defaults of sim/worlds/conveyor.py; examples/conveyor.toml keeps them.
"""
from __future__ import annotations

import math

import numpy as np

BELT_X = 0.45            # m: the belt's centre line
BELT_TOP = 0.10          # m: its surface
CUBE = 0.04              # m: cube edge
OBJECT_Z = BELT_TOP + CUBE / 2   # the plane the centres of objects on the belt move in
BIN = (0.1, -0.45)       # m: the bin's centre
TOOL = 0.15              # m from the end-effector link (link6) to the grasp point, along its z
# link6 pointing straight down (its z axis along -z), as at the xArm6's home pose
DOWN = (1.0, 0.0, 0.0, 0.0)

# Colour classes of the segmentation: the cubes' colours (sim/worlds/conveyor.py COLOURS).
REFERENCE = ((0.9, 0.1, 0.1), (0.1, 0.8, 0.1), (0.1, 0.2, 0.9), (0.95, 0.85, 0.1))
MIN_SATURATION = 0.45    # max - min of a pixel's channels (0..1): the belt, floor and bin are below
MIN_PIXELS = 2


def hand_pose(x: float, y: float, z_tool: float) -> dict:
    """The MDL pose (plain) that puts the grasp point at (x, y, z_tool), the hand pointing down."""
    return {"position": [x, y, z_tool + TOOL], "orientation": list(DOWN)}


def segment(rgb: bytes, width: int, height: int) -> list[tuple[int, float, float, int]]:
    """Coloured blobs of an image: (colour class, mean column, mean row, pixels), biggest first.
    A pixel belongs to a class when it is saturated and nearest that class's colour (its channels
    and the class's each scaled to a peak of 1; the first class on a tie); blobs are 4-connected
    components of one class.

    Classifying pixels is numpy (a camera frame is 1,600 of them, ten a second: per pixel in
    Python it was 7% of the conveyor's virtual-time run); the components walk only the saturated
    pixels, a few dozen."""
    pixels = np.frombuffer(rgb, dtype=np.uint8, count=3 * width * height).reshape(-1, 3) / 255.0
    peak, low = pixels.max(axis=1), pixels.min(axis=1)
    saturated = np.flatnonzero(peak - low >= MIN_SATURATION)
    labels = [-1] * (width * height)
    if saturated.size:
        scaled = pixels[saturated] / peak[saturated, None]
        distances = np.stack([((scaled[:, 0] - r) ** 2 + (scaled[:, 1] - g) ** 2) + (scaled[:, 2] - b) ** 2
                              for r, g, b in _SCALED_REFERENCE], axis=1)
        for p, colour in zip(saturated.tolist(), distances.argmin(axis=1).tolist()):
            labels[p] = colour
    blobs, seen = [], set()
    for start in saturated.tolist():
        if start in seen:
            continue
        colour, stack, members = labels[start], [start], []
        seen.add(start)
        while stack:
            p = stack.pop()
            members.append(p)
            col, row = p % width, p // width
            for q, ok in ((p - 1, col > 0), (p + 1, col < width - 1), (p - width, row > 0), (p + width, row < height - 1)):
                if ok and q not in seen and labels[q] == colour:
                    seen.add(q)
                    stack.append(q)
        if len(members) >= MIN_PIXELS:
            blobs.append((colour, sum(p % width for p in members) / len(members),
                          sum(p // width for p in members) / len(members), len(members)))
    blobs.sort(key=lambda blob: -blob[3])
    return blobs


_SCALED_REFERENCE = tuple(tuple(c / max(colour) for c in colour) for colour in REFERENCE)


def pixel_ray(col: float, row: float, width: int, height: int, fov: float, forward, up):
    """The direction (world frame) through pixel (col, row) of a pinhole camera looking along
    `forward` with `up` the image's up (as PyBullet's computeViewMatrix), vertical field `fov`."""
    f = _unit(forward)
    u = _unit([a - _dot(up, f) * b for a, b in zip(up, f)])
    right = _cross(f, u)
    half = math.tan(math.radians(fov) / 2)
    nx = (2 * (col + 0.5) / width - 1) * half * width / height
    ny = (1 - 2 * (row + 0.5) / height) * half
    return [a + nx * b + ny * c for a, b, c in zip(f, right, u)]


def on_plane(eye, ray, z: float = OBJECT_Z):
    """Where the ray from `eye` meets the horizontal plane at height z; None if it does not."""
    if ray[2] > -1e-6:
        return None
    s = (z - eye[2]) / ray[2]
    return (eye[0] + s * ray[0], eye[1] + s * ray[1])


def _dot(a, b) -> float:
    return sum(x * y for x, y in zip(a, b))


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _unit(v):
    n = math.sqrt(_dot(v, v))
    return [x / n for x in v]
