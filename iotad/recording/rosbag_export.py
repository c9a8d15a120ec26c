"""`iotad export --ros2`: a recording as a rosbag2 bag that ROS 2 tools read (`ros2 bag info`,
`ros2 bag play`): MCAP storage, `ros2msg` schemas, `cdr` encoding, rosbag2's metadata.yaml.
rosbags writes the bag, so its layout is rosbag2's own, not iotad's idea of it.

What goes in: every channel a `[[ros2]]` table maps, on its ROS 2 topic, as the bridge would
have sent it (the mapping's message, stamped with the recorded time); every value that came in
from ROS 2, as the message it was; and, beside them, every joint-state channel as a
sensor_msgs/msg/JointState and every pose channel as a geometry_msgs/msg/PoseStamped on
`/iotad/<node>/<channel>`. The recording stays the source of truth: the bag is a view of it.
"""
from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any, Callable

from iotad.node_host import wire
from iotad.kernel.ports import Port
from iotad.recording.mcap_reader import Recording
from iotad.ros2 import messages
from iotad.ros2.bridge import NODE_NAME
from iotad.ros2.mapping import Mapping

JOINT_STATE = "sensor_msgs/msg/JointState"
POSE = "geometry_msgs/msg/PoseStamped"
WORLD_FRAME = "world"


class RosbagExportError(Exception):
    """The bag cannot be written (its folder exists, a value does not fit its message)."""


def joint_state_fields(value: Any, names: list[str] | None = None) -> dict[str, Any] | None:
    """A JointState's fields for a joint-states value (position, velocity, effort arrays), else
    None; its joints named `names` (the joint map's), else joint1, joint2..."""
    if not isinstance(value, dict) or not all(isinstance(value.get(k), list) for k in ("position", "velocity", "effort")):
        return None
    count = len(value["position"])
    if names is None or len(names) != count:
        names = [f"joint{i + 1}" for i in range(count)]
    return {"name": list(names), "position": value["position"],
            "velocity": value["velocity"], "effort": value["effort"]}


def pose_fields(value: Any) -> dict[str, Any] | None:
    """A PoseStamped's fields for a planar pose value (x, y and yaw or heading), else None."""
    if not isinstance(value, dict):
        return None
    yaw = value.get("yaw", value.get("heading"))
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (value.get("x"), value.get("y"), yaw)):
        return None
    return {"header.frame_id": WORLD_FRAME, "pose.position.x": float(value["x"]), "pose.position.y": float(value["y"]),
            "pose.orientation.z": math.sin(yaw / 2), "pose.orientation.w": math.cos(yaw / 2)}


def topic_name(path: str, channel: str, index: int | None) -> str:
    """`/iotad/<node>/<channel>[/<index>]`, each name made a valid ROS 2 name token."""
    parts = ["iotad", *path.split("/"), channel] + ([] if index is None else [f"i{index}"])
    return "/" + "/".join(re.sub(r"\W", "_", p) if not p[0].isdigit() else f"_{p}" for p in parts)


def bridge_mappings(recording: Recording) -> list[Mapping]:
    spec = recording.specs.get(NODE_NAME) or {}
    if not str((spec.get("source") or {}).get("ref", "")).endswith(":ros2_bridge"):
        return []
    return [Mapping.from_plain(m) for m in (spec.get("params") or {}).get("mappings", [])]


def export_rosbag(recording: Recording, output: str | Path,
                  progress: Callable[[int], None] | None = None) -> dict[str, int]:
    """Write the bag folder `output` (it must not exist); the count of messages per topic."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    output = Path(output)
    if output.exists():
        raise RosbagExportError(f"{output} exists: a rosbag2 bag is a new folder (remove it or name another)")
    system = recording.system
    out_by_key: dict[str, list[Mapping]] = {}
    in_by_key: dict[str, Mapping] = {}
    constants: list[Mapping] = []
    for mapping in bridge_mappings(recording):
        if mapping.constant:  # the robot's description: published once, as the bridge opened
            constants.append(mapping)
        elif mapping.direction == "out":
            port = Port.parse(mapping.channel)  # as the system file's [[ros2]] channel was read
            key = wire.channel_key(system, port.node, port.channel, port.index)
            out_by_key.setdefault(key, []).append(mapping)
        else:
            in_by_key[mapping.key] = mapping.reversed()
    from iotad.recording.urdf_robot import joint_names_of

    # each motor node's joint names, as its joint map gives them (the recording holds its params)
    names = {spec.get("path", node): found for node, spec in recording.specs.items()
             if (found := joint_names_of(spec.get("params"))) is not None}
    counts: dict[str, int] = {}
    store = messages.typestore()
    try:
        writer = Writer(output, version=9, storage_plugin=StoragePlugin.MCAP)
    except Exception as exc:  # noqa: BLE001 - rosbags' WriterError and OSErrors say why
        raise RosbagExportError(f"{output}: cannot write a bag: {exc}") from None
    connections: dict[tuple[str, str], Any] = {}

    def write(topic: str, ros_type: str, data: bytes, stamp: int) -> None:
        connection = connections.get((topic, ros_type))
        if connection is None:
            connection = connections[(topic, ros_type)] = writer.add_connection(topic, ros_type, typestore=store)
        writer.write(connection, stamp, data)
        counts[topic] = counts.get(topic, 0) + 1

    with writer:
        for mapping in constants:
            first = next(iter(recording.messages), None)
            stamp = first.log_time if first is not None else 0
            write(mapping.topic, mapping.ros_type, _converted(mapping, None, stamp), stamp)
        for number, message in enumerate(recording.messages):
            if progress is not None and number % 10_000 == 0:
                progress(number)
            topic, stamp = message.topic, message.log_time
            mapped = out_by_key.get(topic)
            if mapped is not None:  # and beside it, a joint state or pose on /iotad/... below
                value = message.value
                for mapping in mapped:
                    write(mapping.topic, mapping.ros_type, _converted(mapping, value, stamp), stamp)
            inbound = in_by_key.get(topic)
            if inbound is not None:
                write(inbound.topic, inbound.ros_type, _converted(inbound, message.value, stamp), stamp)
                continue
            parsed = wire.parse_key(topic)
            if parsed is None or parsed[0] != system or parsed[1] == NODE_NAME or parsed[2].startswith("@"):
                continue
            value = message.value
            fields = joint_state_fields(value, names.get(parsed[1]))
            ros_type = JOINT_STATE
            if fields is None:
                fields, ros_type = pose_fields(value), POSE
            if fields is None:
                continue
            try:
                data = messages.serialize(messages.build(ros_type, fields, stamp_ns=stamp), ros_type)
            except messages.MessageError:
                continue  # not a joint state or pose after all (a NaN, a name too many): not exported
            write(topic_name(parsed[1], parsed[2], parsed[3]), ros_type, data, stamp)
    return counts


def _converted(mapping: Mapping, value: Any, stamp: int) -> bytes:
    try:
        return mapping.to_cdr(value, stamp)
    except (messages.MessageError, KeyError, IndexError, TypeError) as exc:
        raise RosbagExportError(f"{mapping.channel} -> {mapping.topic}: a recorded value does not fit: {exc}") from None
