"""The robot in 3D for Foxglove, from a system's channel values: the xArm6's model, its links'
frames and named joint states; Buggy's arena, path and pose. Live (`iotad view`) and recorded
(`iotad export --json`) alike, as Foxglove's own message types (foxglove-sdk's schemas).

`SceneTracker.feed(key, value, stamp_ns)` takes one channel message and returns what it shows,
as (topic, message) pairs, keeping what it needs across messages (the arena's landmarks, the
path so far, whether the model went out). What it recognises, by shape:

- six joint positions or more (`position`, optional `velocity`, `effort`): the arm, its first
  six joints (a seventh is the conveyor's gripper). Once: the URDF on
  `/robot_description` and the links' meshes as a SceneUpdate on `/scene/arm_model` (each entity
  locked to its link's frame); each time: `/scene/transforms` (FrameTransforms from `world`
  through every link, computed from the URDF) and `/scene/arm_joints` (JointStates, joint1..6).
- landmarks (`kind` WALL, CRACK, FOOD, EATEN, GROWN with `x1, y1, x2, y2`): Buggy's arena on
  `/scene/arena`: the wall square, the cracks, the food (eaten food goes grey).
- a planar pose (`x`, `y`, `yaw`): `/scene/pose` (PoseInFrame) and the path so far on `/scene/path`.
- the conveyor's world (`belt` [x, length, width, height], `bin` [x, y, size, height], `cube_size`
  and `count` cubes at `x`, `y`, `z` with `colour` indices: examples/conveyor's `conveyorScene`):
  the belt, the bin and the cubes on `/scene/conveyor`.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from iotad.recording import robot_model

WORLD = robot_model.ROOT_FRAME
ROBOT_DESCRIPTION = "/robot_description"
ARM_MODEL, TRANSFORMS, ARM_JOINTS = "/scene/arm_model", "/scene/transforms", "/scene/arm_joints"
ARENA, PATH, POSE = "/scene/arena", "/scene/path", "/scene/pose"
CONVEYOR = "/scene/conveyor"
TOPICS = (ARM_MODEL, TRANSFORMS, ARM_JOINTS, ARENA, PATH, POSE, CONVEYOR)
# the cubes' colours by index, as the conveyor world paints them (red, green, blue, yellow)
CUBE_COLOURS = ((0.9, 0.1, 0.1), (0.1, 0.8, 0.1), (0.1, 0.2, 0.9), (0.95, 0.85, 0.1))
PATH_STEP = 0.01  # m: a pose closer than this to the path's last point adds none
URDF_SCHEMA = {"title": "std_msgs/msg/String", "type": "object", "properties": {"data": {"type": "string"}}}


class SceneTracker:
    """`embed`: the link meshes go inside the model entities (a file, which must stand alone);
    else they are `package://` URLs that the live server answers as assets."""

    def __init__(self, embed: bool = False):
        self.embed = embed
        self.arm_key: str | None = None
        self.model_sent = False
        self.landmarks: dict[tuple[str, int], dict] = {}
        self.path: list[tuple[float, float]] = []
        from iotad.recording.urdf_robot import RobotsOfSystem

        self.robots = RobotsOfSystem()

    def learn(self, spec: Any) -> None:
        """One node's spec (live `@spec`, or a recording's): a URDF its simulated drives load,
        the joint names its joint map gives; the robot is then drawn from them."""
        self.robots.learn(spec)

    def feed(self, key: str, value: Any, stamp_ns: int) -> list[tuple[str, Any]]:
        if not isinstance(value, dict):
            return []
        out: list[tuple[str, Any]] = []
        positions = value.get("position")
        named = self._named_robot(key, positions)
        if named is not None:
            robot, names = named
            self.arm_key = key
            if not self.model_sent:
                self.model_sent = True
                out += [(ROBOT_DESCRIPTION, {"data": robot.text}), (ARM_MODEL, urdf_model(robot, self.embed, stamp_ns))]
            out += [(TRANSFORMS, urdf_transforms(robot, dict(zip(names, (float(p) for p in positions))), stamp_ns)),
                    (ARM_JOINTS, joint_states(value, stamp_ns, names))]
        elif isinstance(positions, list) and len(positions) >= len(robot_model.ARM_JOINTS) \
                and all(_number(p) for p in positions) and self.arm_key in (None, key):
            self.arm_key = key
            if not self.model_sent:
                self.model_sent = True
                out += [(ROBOT_DESCRIPTION, {"data": robot_model.urdf_text()}), (ARM_MODEL, self.arm_model(stamp_ns))]
            out += [(TRANSFORMS, transforms(positions, stamp_ns)), (ARM_JOINTS, joint_states(value, stamp_ns))]
        if value.get("kind") in ("WALL", "CRACK", "FOOD", "EATEN", "GROWN") and \
                all(_number(value.get(k)) for k in ("x1", "y1", "x2", "y2")):
            kind = value["kind"]
            group = "FOOD" if kind in ("EATEN", "GROWN") else kind
            self.landmarks[(group, int(value.get("id", 0)))] = dict(value, kind=kind)
            out.append((ARENA, arena(self.landmarks.values(), stamp_ns)))
        if _is_conveyor(value):
            out.append((CONVEYOR, conveyor(value, stamp_ns)))
        yaw = value.get("yaw", value.get("heading"))
        if _number(value.get("x")) and _number(value.get("y")) and _number(yaw):
            x, y = float(value["x"]), float(value["y"])
            if not self.path or math.hypot(x - self.path[-1][0], y - self.path[-1][1]) >= PATH_STEP:
                self.path.append((x, y))
                out.append((PATH, path(self.path, stamp_ns)))
            out.append((POSE, pose_in_frame(x, y, float(yaw), stamp_ns)))
        return out

    def _named_robot(self, key: str, positions: Any):
        """(the URDF robot, the joint names) when this is a joint-states value of a node whose
        joint map names its joints and the system's drives load a URDF with those joints."""
        robot = self.robots.urdf
        if robot is None or not isinstance(positions, list) or not all(_number(p) for p in positions) \
                or self.arm_key not in (None, key):
            return None
        from iotad.node_host import wire

        parsed = wire.parse_key(key)
        names = self.robots.names_for(parsed[1], len(positions)) if parsed else None
        if not names or not set(names) & set(robot.movable):
            return None
        return robot, names

    def arm_model(self, stamp_ns: int) -> Any:
        from foxglove.messages import ModelPrimitive, SceneEntity, SceneUpdate, Vector3

        entities = []
        for number, visual in enumerate(robot_model.model()[1]):
            if self.embed:
                path = robot_model.mesh_path(visual.mesh)
                if path is None:
                    continue
                source = {"data": path.read_bytes(), "media_type": "model/stl"}
            else:
                source = {"url": visual.mesh}
            entities.append(SceneEntity(
                timestamp=_stamp(stamp_ns), frame_id=visual.link, id=f"xarm6/{number}/{visual.link}", frame_locked=True,
                models=[ModelPrimitive(pose=_pose(visual.xyz, visual.rotation), scale=Vector3(x=1.0, y=1.0, z=1.0),
                                       color=_color(0.85, 0.85, 0.9, 1.0), **source)]))
        return SceneUpdate(entities=entities)


def transforms(positions: list, stamp_ns: int) -> Any:
    from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Vector3

    named = dict(zip(robot_model.ARM_JOINTS, (float(p) for p in positions)))  # zip: the first six
    return FrameTransforms(transforms=[
        FrameTransform(timestamp=_stamp(stamp_ns), parent_frame_id=parent, child_frame_id=child,
                       translation=Vector3(x=t[0], y=t[1], z=t[2]), rotation=Quaternion(x=r[0], y=r[1], z=r[2], w=r[3]))
        for parent, child, t, r in robot_model.link_transforms(named)])


def urdf_transforms(robot: Any, positions: dict[str, float], stamp_ns: int) -> Any:
    """Frames of a URDF robot's links for joint positions by name, from `world` on."""
    from foxglove.messages import FrameTransform, FrameTransforms, Quaternion, Vector3

    links = robot.link_transforms(positions)
    root = robot.root_link()
    if root != WORLD:
        links.insert(0, (WORLD, root, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)))
    return FrameTransforms(transforms=[
        FrameTransform(timestamp=_stamp(stamp_ns), parent_frame_id=parent, child_frame_id=child,
                       translation=Vector3(x=t[0], y=t[1], z=t[2]), rotation=Quaternion(x=r[0], y=r[1], z=r[2], w=r[3]))
        for parent, child, t, r in links])


def urdf_model(robot: Any, embed: bool, stamp_ns: int) -> Any:
    """A URDF robot's visuals, each locked to its link's frame: its boxes, cylinders and spheres,
    and its meshes (embedded from the files beside the URDF in an export; by URL live)."""
    from foxglove.messages import (CubePrimitive, CylinderPrimitive, ModelPrimitive, SceneEntity, SceneUpdate,
                                   SpherePrimitive, Vector3)

    entities = []
    for number, shape in enumerate(robot.shapes):
        pose, color = _pose(shape.xyz, shape.rotation), _color(*shape.rgba)
        if shape.kind == "box":
            size = Vector3(x=shape.size[0], y=shape.size[1], z=shape.size[2])
            primitive = {"cubes": [CubePrimitive(pose=pose, size=size, color=color)]}
        elif shape.kind == "cylinder":
            d = 2 * shape.size[0]
            primitive = {"cylinders": [CylinderPrimitive(pose=pose, size=Vector3(x=d, y=d, z=shape.size[1]),
                                                         bottom_scale=1.0, top_scale=1.0, color=color)]}
        else:
            d = 2 * shape.size[0]
            primitive = {"spheres": [SpherePrimitive(pose=pose, size=Vector3(x=d, y=d, z=d), color=color)]}
        entities.append(SceneEntity(timestamp=_stamp(stamp_ns), frame_id=shape.link, id=f"urdf/{number}/{shape.link}",
                                    frame_locked=True, **primitive))
    folder = Path(robot.path).parent
    for number, visual in enumerate(robot.meshes):
        file = folder / visual.mesh if "://" not in visual.mesh else None
        if embed:
            if file is None or not file.is_file():
                continue
            media = "model/obj" if file.suffix.lower() == ".obj" else "model/stl"
            source = {"data": file.read_bytes(), "media_type": media}
        else:
            source = {"url": file.as_uri() if file is not None else visual.mesh}
        entities.append(SceneEntity(
            timestamp=_stamp(stamp_ns), frame_id=visual.link, id=f"urdf/mesh/{number}/{visual.link}", frame_locked=True,
            models=[ModelPrimitive(pose=_pose(visual.xyz, visual.rotation), scale=Vector3(x=1.0, y=1.0, z=1.0),
                                   color=_color(0.85, 0.85, 0.9, 1.0), **source)]))
    return SceneUpdate(entities=entities)


def joint_states(value: dict, stamp_ns: int, names: list[str] | None = None) -> Any:
    from foxglove.messages import JointState, JointStates

    joints = []
    for k, name in enumerate(names or robot_model.ARM_JOINTS):
        fields = {"position": float(value["position"][k])}
        for field in ("velocity", "effort"):
            series = value.get(field)
            if isinstance(series, list) and k < len(series) and _number(series[k]):
                fields[field] = float(series[k])
        joints.append(JointState(name=name, **fields))
    return JointStates(timestamp=_stamp(stamp_ns), joints=joints)


def arena(landmarks: Any, stamp_ns: int) -> Any:
    from foxglove.messages import LinePrimitive, LinePrimitiveLineType, SceneEntity, SceneUpdate, SpherePrimitive

    lines, spheres = [], []
    for mark in landmarks:
        kind, x1, y1, x2, y2 = mark["kind"], mark["x1"], mark["y1"], mark["x2"], mark["y2"]
        if kind == "WALL":  # the square inside the walls, corner to corner
            corners = [(x1, y1), (x2, y1), (x2, y2), (x1, y2), (x1, y1)]
            lines.append(LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.03,
                                       points=[_point(x, y) for x, y in corners], color=_color(0.3, 0.3, 0.3, 1.0)))
        elif kind == "CRACK":
            lines.append(LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.02,
                                       points=[_point(x1, y1), _point(x2, y2)], color=_color(0.55, 0.35, 0.15, 1.0)))
        else:
            colour = _color(0.6, 0.6, 0.6, 0.6) if kind == "EATEN" else _color(0.2, 0.7, 0.25, 1.0)
            spheres.append(SpherePrimitive(pose=_pose((x1, y1, 0.03)), size=_vector(0.06, 0.06, 0.06), color=colour))
    return SceneUpdate(entities=[SceneEntity(timestamp=_stamp(stamp_ns), frame_id=WORLD, id="buggy/arena",
                                             lines=lines, spheres=spheres)])


def path(points: list[tuple[float, float]], stamp_ns: int) -> Any:
    from foxglove.messages import LinePrimitive, LinePrimitiveLineType, SceneEntity, SceneUpdate

    line = LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.01,
                         points=[_point(x, y, 0.005) for x, y in points], color=_color(0.1, 0.4, 0.9, 1.0))
    return SceneUpdate(entities=[SceneEntity(timestamp=_stamp(stamp_ns), frame_id=WORLD, id="buggy/path", lines=[line])])


def _is_conveyor(value: dict) -> bool:
    belt, tray, count = value.get("belt"), value.get("bin"), value.get("count")
    return (isinstance(belt, list) and len(belt) == 4 and isinstance(tray, list) and len(tray) == 4
            and isinstance(count, int) and all(isinstance(value.get(k), list) and len(value[k]) >= count
                                               for k in ("x", "y", "z", "colour"))
            and all(_number(v) for v in belt + tray + [value.get("cube_size")]))


def conveyor(value: dict, stamp_ns: int) -> Any:
    """The belt (a slab), the bin (floor and four walls) and the cubes, in `world`."""
    from foxglove.messages import CubePrimitive, SceneEntity, SceneUpdate

    x, length, width, height = value["belt"]
    bx, by, size, wall = value["bin"]
    thin = 0.01
    cubes = [CubePrimitive(pose=_pose((x, 0.0, height / 2)), size=_vector(width, length, height),
                           color=_color(0.2, 0.2, 0.22, 1.0))]
    tray = _color(0.55, 0.4, 0.25, 1.0)
    cubes.append(CubePrimitive(pose=_pose((bx, by, thin / 2)), size=_vector(size, size, thin), color=tray))
    for dx, dy, sx, sy in ((size / 2, 0, thin, size), (-size / 2, 0, thin, size), (0, size / 2, size, thin),
                           (0, -size / 2, size, thin)):
        cubes.append(CubePrimitive(pose=_pose((bx + dx, by + dy, wall / 2)), size=_vector(sx, sy, wall), color=tray))
    edge = float(value["cube_size"])
    for k in range(value["count"]):
        r, g, b = CUBE_COLOURS[value["colour"][k] % len(CUBE_COLOURS)]
        cubes.append(CubePrimitive(pose=_pose((value["x"][k], value["y"][k], value["z"][k])),
                                   size=_vector(edge, edge, edge), color=_color(r, g, b, 1.0)))
    return SceneUpdate(entities=[SceneEntity(timestamp=_stamp(stamp_ns), frame_id=WORLD, id="conveyor", cubes=cubes)])


def pose_in_frame(x: float, y: float, yaw: float, stamp_ns: int) -> Any:
    from foxglove.messages import PoseInFrame

    return PoseInFrame(timestamp=_stamp(stamp_ns), frame_id=WORLD,
                       pose=_pose((x, y, 0.0), (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))))


# ---------------------------------------------------------------------------- small builders

def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _stamp(stamp_ns: int) -> Any:
    from foxglove.messages import Timestamp
    return Timestamp(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)


def _point(x: float, y: float, z: float = 0.0) -> Any:
    from foxglove.messages import Point3
    return Point3(x=float(x), y=float(y), z=float(z))


def _vector(x: float, y: float, z: float) -> Any:
    from foxglove.messages import Vector3
    return Vector3(x=x, y=y, z=z)


def _color(r: float, g: float, b: float, a: float) -> Any:
    from foxglove.messages import Color
    return Color(r=r, g=g, b=b, a=a)


def _pose(xyz: tuple, rotation: tuple = (0.0, 0.0, 0.0, 1.0)) -> Any:
    from foxglove.messages import Pose, Quaternion, Vector3
    return Pose(position=Vector3(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
                orientation=Quaternion(x=rotation[0], y=rotation[1], z=rotation[2], w=rotation[3]))


class SceneWriter:
    """What a `SceneTracker` makes of a recording's messages, written into an MCAP file (an
    mcap `Writer`): each Foxglove type as a `protobuf` channel with foxglove-sdk's own schema,
    the URDF as a JSON `std_msgs/msg/String`."""

    def __init__(self, writer: Any):
        import json

        self._json = json
        self.writer = writer
        self.tracker = SceneTracker(embed=True)
        self.channels: dict[str, int] = {}
        self.schemas: dict[str, int] = {}
        self.count = 0

    def feed(self, key: str, value: Any, stamp_ns: int) -> None:
        for topic, message in self.tracker.feed(key, value, stamp_ns):
            self.write(topic, message, stamp_ns)

    def write(self, topic: str, message: Any, stamp_ns: int) -> None:
        """One message on `topic`: a foxglove-sdk message (protobuf), or the URDF (JSON)."""
        if isinstance(message, dict):
            data, name, encoding, schema_encoding, schema_data = (
                self._json.dumps(message).encode(), URDF_SCHEMA["title"], "json", "jsonschema",
                self._json.dumps(URDF_SCHEMA).encode())
        else:
            schema = message.get_schema()
            data, name, encoding, schema_encoding, schema_data = (
                message.encode(), schema.name, schema.encoding, schema.encoding, schema.data)
        channel = self.channels.get(topic)
        if channel is None:
            schema_id = self.schemas.get(name)
            if schema_id is None:
                schema_id = self.schemas[name] = self.writer.register_schema(name, schema_encoding, schema_data)
            channel = self.channels[topic] = self.writer.register_channel(topic, encoding, schema_id, {})
        self.writer.add_message(channel, stamp_ns, data, stamp_ns, self.count)
        self.count += 1
