"""A robot for the 3D view and exports from its URDF and the system's joint map: which URDF the
simulated drives load (`world = "urdf"`), the joint names a motor node's joint states carry (its
`joints` parameter), and each link's frame for given joint positions, by name, for any number of
joints. Read from the nodes' specs, live (`@spec`) or recorded."""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from iotad.recording import robot_model


@dataclass(frozen=True)
class Shape:
    """A visual of plain geometry: box (size x, y, z), cylinder (radius, length), sphere (radius)."""

    link: str
    kind: str
    size: tuple[float, ...]
    xyz: tuple[float, float, float]
    rotation: tuple[float, float, float, float]
    rgba: tuple[float, float, float, float]


@dataclass(frozen=True)
class UrdfRobot:
    path: str
    text: str
    joints: tuple[robot_model.Joint, ...]
    shapes: tuple[Shape, ...]
    meshes: tuple[robot_model.Visual, ...]

    @property
    def movable(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints if j.kind in ("revolute", "continuous", "prismatic"))

    def link_transforms(self, positions: dict[str, float]) -> list[tuple[str, str, tuple, tuple]]:
        """(parent, child, translation, rotation) of every joint for `positions` (name -> rad or m)."""
        found = []
        for joint in self.joints:
            angle = positions.get(joint.name, 0.0) if joint.kind in ("revolute", "continuous") else 0.0
            rotation = robot_model.quaternion_multiply(joint.rotation, robot_model.quaternion_about(joint.axis, angle))
            translation = joint.xyz
            if joint.kind == "prismatic":
                offset = positions.get(joint.name, 0.0)
                turned = robot_model.rotate(joint.rotation, tuple(a * offset for a in joint.axis))
                translation = tuple(t + o for t, o in zip(joint.xyz, turned))
            found.append((joint.parent, joint.child, translation, rotation))
        return found

    def root_link(self) -> str:
        children = {j.child for j in self.joints}
        parents = [j.parent for j in self.joints if j.parent not in children]
        return parents[0] if parents else (self.joints[0].parent if self.joints else "base")


@lru_cache(maxsize=8)
def load_urdf(path: str) -> UrdfRobot:
    """The robot of the URDF file at `path` (ValueError when it cannot be read)."""
    try:
        text = Path(path).read_text()
        root = ET.fromstring(text)
    except (OSError, ET.ParseError) as exc:
        raise ValueError(f"{path}: cannot read it as a URDF ({exc})") from None
    joints = []
    for element in root.findall("joint"):
        xyz, rpy = robot_model._origin(element.find("origin"))
        axis = element.find("axis")
        joints.append(robot_model.Joint(element.get("name"), element.get("type"), element.find("parent").get("link"),
                                        element.find("child").get("link"), xyz, robot_model.quaternion_from_rpy(*rpy),
                                        tuple(float(v) for v in axis.get("xyz").split()) if axis is not None
                                        else (1.0, 0.0, 0.0)))
    materials = {m.get("name"): m for m in root.findall("material")}
    shapes, meshes = [], []
    for link in root.findall("link"):
        for visual in link.findall("visual"):
            xyz, rpy = robot_model._origin(visual.find("origin"))
            rotation = robot_model.quaternion_from_rpy(*rpy)
            mesh = visual.find("geometry/mesh")
            if mesh is not None:
                meshes.append(robot_model.Visual(link.get("name"), mesh.get("filename"), xyz, rotation))
                continue
            for kind, keys in (("box", ("size",)), ("cylinder", ("radius", "length")), ("sphere", ("radius",))):
                geometry = visual.find(f"geometry/{kind}")
                if geometry is None:
                    continue
                size = tuple(float(v) for key in keys for v in (geometry.get(key) or "0").split())
                shapes.append(Shape(link.get("name"), kind, size, xyz, rotation, _colour(visual, materials)))
    return UrdfRobot(str(path), text, tuple(joints), tuple(shapes), tuple(meshes))


def _colour(visual: ET.Element, materials: dict) -> tuple[float, float, float, float]:
    material = visual.find("material")
    colour = material.find("color") if material is not None else None
    if colour is None and material is not None and material.get("name") in materials:
        colour = materials[material.get("name")].find("color")
    if colour is not None and colour.get("rgba"):
        values = tuple(float(v) for v in colour.get("rgba").split())
        if len(values) == 4:
            return values
    return (0.75, 0.75, 0.8, 1.0)


def urdf_of(params: Any) -> str | None:
    """The URDF a node's params load (a simulated drives node with `world = "urdf"`), as a file."""
    if not isinstance(params, dict) or params.get("world") != "urdf":
        return None
    urdf = (params.get("world_options") or {}).get("urdf") if isinstance(params.get("world_options"), dict) else None
    if not isinstance(urdf, str) or not urdf:
        return None
    from iotad.kernel.package_files import is_package_ref, package_file

    try:
        path = package_file(urdf) if is_package_ref(urdf) else Path(urdf)
    except ValueError:
        return None
    return str(path) if path.is_file() else None


def joint_names_of(params: Any) -> list[str] | None:
    """The joint names a motor node's joint map gives (its `joints` parameter), in order."""
    joints = params.get("joints") if isinstance(params, dict) else None
    if isinstance(joints, list) and joints and all(isinstance(j, dict) and isinstance(j.get("name"), str)
                                                   for j in joints):
        return [j["name"] for j in joints]
    return None


class RobotsOfSystem:
    """What the nodes' specs say of the robot: the URDF, and the joint names of each node's
    `joint_states` (by node path). `learn(spec)` takes one node's spec (`path`, `params`)."""

    def __init__(self):
        self.urdf: UrdfRobot | None = None
        self.names: dict[str, list[str]] = {}  # node path -> its joint names

    def learn(self, spec: Any) -> None:
        if not isinstance(spec, dict):
            return
        params = spec.get("params")
        file = urdf_of(params)
        if file is not None:
            try:
                self.urdf = load_urdf(file)
            except ValueError:
                pass
        names = joint_names_of(params)
        path = spec.get("path")
        if names is not None and isinstance(path, str):
            self.names[path] = names

    def names_for(self, path: str, count: int) -> list[str] | None:
        """The joint names of node `path`'s joint-states value of `count` joints, if its map says."""
        names = self.names.get(path)
        return names if names is not None and len(names) == count else None
