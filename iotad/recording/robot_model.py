"""The arm's robot model for Foxglove: the xArm6 URDF the simulation loads (pybullet_data's
`xarm/xarm6_with_gripper.urdf`), its kinematic tree, and the frame of every link for given
joint positions (what a `foxglove.FrameTransforms` carries), computed from the URDF itself.

The URDF's meshes are `package://xarm_description/...` and `package://xarm_gripper/...`;
`mesh_path` finds them in pybullet_data, which `iotad view` serves to Foxglove as assets and
`iotad export` embeds in the recording's model entities.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

URDF = "xarm/xarm6_with_gripper.urdf"      # sim/worlds/arm.py's "xarm6"
ARM_JOINTS = tuple(f"joint{k}" for k in range(1, 7))
ROOT_FRAME = "world"


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str                       # revolute, prismatic, fixed, ...
    parent: str
    child: str
    xyz: tuple[float, float, float]
    rotation: tuple[float, float, float, float]  # of the joint's origin (x, y, z, w)
    axis: tuple[float, float, float]


@dataclass(frozen=True)
class Visual:
    link: str
    mesh: str                       # package://... as the URDF says
    xyz: tuple[float, float, float]
    rotation: tuple[float, float, float, float]


def data_root() -> Path:
    import pybullet_data
    return Path(pybullet_data.getDataPath())


@lru_cache(maxsize=1)
def urdf_text() -> str:
    return (data_root() / URDF).read_text()


def mesh_path(uri: str) -> Path | None:
    """The file a `package://` mesh URI of the model names, if it is one of pybullet_data's."""
    if not uri.startswith("package://"):
        return None
    path = (data_root() / "xarm" / uri[len("package://"):]).resolve()
    if data_root().resolve() not in path.parents or not path.is_file():
        return None
    return path


@lru_cache(maxsize=1)
def model() -> tuple[tuple[Joint, ...], tuple[Visual, ...]]:
    root = ET.fromstring(urdf_text())
    joints = []
    for element in root.findall("joint"):
        origin = element.find("origin")
        xyz, rpy = _origin(origin)
        axis = element.find("axis")
        joints.append(Joint(element.get("name"), element.get("type"), element.find("parent").get("link"),
                            element.find("child").get("link"), xyz, quaternion_from_rpy(*rpy),
                            tuple(float(v) for v in axis.get("xyz").split()) if axis is not None else (0.0, 0.0, 1.0)))
    visuals = []
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            mesh = visual.find("geometry/mesh")
            if mesh is None:
                continue
            xyz, rpy = _origin(visual.find("origin"))
            visuals.append(Visual(link.get("name"), mesh.get("filename"), xyz, quaternion_from_rpy(*rpy)))
    return tuple(joints), tuple(visuals)


def link_transforms(positions: dict[str, float]) -> list[tuple[str, str, tuple, tuple]]:
    """(parent, child, translation, rotation) of every joint of the model for `positions`
    (joint name -> radians; a joint not named is at 0)."""
    found = []
    for joint in model()[0]:
        angle = positions.get(joint.name, 0.0) if joint.kind in ("revolute", "continuous") else 0.0
        rotation = quaternion_multiply(joint.rotation, quaternion_about(joint.axis, angle))
        translation = joint.xyz
        if joint.kind == "prismatic":
            offset = positions.get(joint.name, 0.0)
            turned = rotate(joint.rotation, tuple(a * offset for a in joint.axis))
            translation = tuple(t + o for t, o in zip(joint.xyz, turned))
        found.append((joint.parent, joint.child, translation, rotation))
    return found


# ---------------------------------------------------------------------------- quaternions (x, y, z, w)

def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float, float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def quaternion_about(axis: tuple, angle: float) -> tuple[float, float, float, float]:
    norm = math.sqrt(sum(a * a for a in axis)) or 1.0
    s = math.sin(angle / 2) / norm
    return (axis[0] * s, axis[1] * s, axis[2] * s, math.cos(angle / 2))


def quaternion_multiply(a: tuple, b: tuple) -> tuple[float, float, float, float]:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def rotate(q: tuple, v: tuple) -> tuple[float, float, float]:
    x, y, z, w = q
    p = quaternion_multiply(quaternion_multiply(q, (v[0], v[1], v[2], 0.0)), (-x, -y, -z, w))
    return p[0], p[1], p[2]


def _origin(origin: ET.Element | None) -> tuple[tuple, tuple]:
    if origin is None:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    xyz = tuple(float(v) for v in (origin.get("xyz") or "0 0 0").split())
    rpy = tuple(float(v) for v in (origin.get("rpy") or "0 0 0").split())
    return xyz, rpy
