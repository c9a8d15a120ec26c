"""How iotad's channels show in Foxglove: topics, schemas and the well-known views of a value
(pure functions, no server), one mapping for both writers: `foxglove_live.Bridge` serves it for
`iotad view`, `foxglove_export.export_json` writes it for `iotad export --json`, so that a live
system and its recording show the same topics with the same values.

Every channel of every live node becomes a Foxglove channel with the channel type's JSON schema,
topic `/<node path>/<channel>[/<k>]`, each message logged at its send time (the wire attachment's
stamp). Where a value fits one of Foxglove's well-known schemas it is logged there as well, so
that the 3D and plot panels work without configuration:

- joint states (`position` array, optional `velocity` and `effort`): `foxglove.JointStates` on
  `<topic>/joints`, joints named `j0`, `j1`, ...;
- planar poses (`x`, `y` and `yaw`, `theta` or `heading`): `foxglove.PoseInFrame` in frame
  `world` on `<topic>/pose`;
- CAN frames (`canFrame`): the JSON message also carries `decoded`, the ODrive CAN Simple message
  by name (`Heartbeat node=3 ...`), or why it is not one.

- the robot in 3D (`iotad.recording.foxglove_scene`): the arm's URDF on `/robot_description`,
  its link meshes, frames and named joint states, Buggy's arena, path and pose, on `/scene/...`;
  the meshes' `package://` URLs are answered as assets from pybullet_data (`asset`).

`/log` (`foxglove.Log`) carries the schedulers' acks and `mdl_command` as info lines and every
violation as a warning, from the nodes' `@trace`. The mapping is pure (`views`, `log_lines`), so
it is tested without a server; `typed` and `log_message` make foxglove-sdk's messages of it.
"""
from __future__ import annotations

import math
from typing import Any, Iterator

LOG_TOPIC = "/log"
LOGGED_OUTPUTS = ("ack", "mdl_command")  # outputs worth a line in /log as they fire


def topic_of(key: str) -> str:
    """`iota/<system>/<path>/<channel>[/<k>]` -> `/<path>/<channel>[/<k>]`."""
    return "/" + "/".join(key.split("/")[2:])


def joint_states(value: Any) -> dict | None:
    if not isinstance(value, dict) or not isinstance(value.get("position"), list):
        return None
    positions = value["position"]
    if not all(isinstance(p, (int, float)) for p in positions):
        return None
    joints = []
    for k, position in enumerate(positions):
        joint = {"name": f"j{k}", "position": float(position)}
        for field in ("velocity", "effort"):
            series = value.get(field)
            if isinstance(series, list) and k < len(series) and isinstance(series[k], (int, float)):
                joint[field] = float(series[k])
        joints.append(joint)
    return {"joints": joints}


def planar_pose(value: Any) -> dict | None:
    if not isinstance(value, dict):
        return None
    yaw = next((value[k] for k in ("yaw", "theta", "heading") if isinstance(value.get(k), (int, float))), None)
    x, y = value.get("x"), value.get("y")
    if yaw is None or not isinstance(x, (int, float)) or not isinstance(y, (int, float)):
        return None
    return {"x": float(x), "y": float(y), "z": float(value.get("z", 0.0) or 0.0),
            "qz": math.sin(yaw / 2), "qw": math.cos(yaw / 2)}


def can_decoded(value: Any) -> str:
    from iotad.can.frame import Frame, FrameError
    from iotad.can.odrive import decode, describe

    try:
        return describe(decode(Frame.from_value(value)))
    except (FrameError, ValueError) as exc:
        return f"not ODrive CAN Simple: {exc}"


def views(key: str, type_name: str | None, value: Any) -> Iterator[tuple[str, str, Any]]:
    """What to log for one channel message: (topic, kind, message) with kind "json" (the value,
    as its channel's schema says), "joints" or "pose" (well-known schemas)."""
    topic = topic_of(key)
    if type_name == "canFrame" and isinstance(value, dict):
        yield topic, "json", {**value, "decoded": can_decoded(value)}
    else:
        yield topic, "json", value if isinstance(value, dict) else {"value": value}
    joints = joint_states(value)
    if joints is not None:
        yield topic + "/joints", "joints", joints
    pose = planar_pose(value)
    if pose is not None:
        yield topic + "/pose", "pose", pose


def log_lines(path: str, events: list) -> Iterator[tuple[float, str, str]]:
    """(event time, level, line) for /log from a node's trace events."""
    for event in events:
        if not isinstance(event, dict):
            continue
        kind, action, index, value = event.get("kind"), event.get("action"), event.get("index"), event.get("value")
        label = action if index is None else f"{action}[{index}]"
        if kind == "violation":
            detail = value if isinstance(value, dict) else {}
            yield event.get("t", 0.0), "warning", (f"{path}.{label}: {detail.get('violation', 'violation')}: "
                                                   f"{detail.get('message', '')}")
        elif kind == "output" and action in LOGGED_OUTPUTS:
            yield event.get("t", 0.0), "info", f"{path}.{label} = {value}"


def described_channels(spec: dict) -> Iterator[tuple[str, str | None, dict]]:
    """(key, type name, Foxglove JSON schema) of every channel key a node's `@spec` describes."""
    for channel in spec.get("channels") or []:
        if not isinstance(channel, dict):
            continue
        for key in channel.get("keys") or []:
            yield key, channel.get("type_name"), json_schema(channel)


def joint_names(joints: list[dict], names: list[str] | None) -> list[dict]:
    """The joints named as the node's joint map names them (`names`), where known."""
    return [dict(j, name=name) for j, name in zip(joints, names)] if names else joints


def typed(kind: str, message: dict, stamp_ns: int) -> Any:
    """The foxglove-sdk message of a well-known view of `views` ("joints" or "pose")."""
    from foxglove.messages import JointState, JointStates, Pose, PoseInFrame, Quaternion, Vector3

    if kind == "joints":
        return JointStates(timestamp=_stamp(stamp_ns), joints=[JointState(**j) for j in message["joints"]])
    return PoseInFrame(timestamp=_stamp(stamp_ns), frame_id="world", pose=Pose(
        position=Vector3(x=message["x"], y=message["y"], z=message["z"]),
        orientation=Quaternion(x=0.0, y=0.0, z=message["qz"], w=message["qw"])))


def log_message(path: str, level: str, line: str, stamp_ns: int) -> Any:
    """One /log line of `log_lines` as a foxglove-sdk `Log`."""
    from foxglove.messages import Log, LogLevel

    return Log(timestamp=_stamp(stamp_ns), level=LogLevel.Warning if level == "warning" else LogLevel.Info,
               message=line, name=path)


def _stamp(stamp_ns: int) -> Any:
    from foxglove.messages import Timestamp

    return Timestamp(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)


def json_schema(described: dict) -> dict:
    """A channel's schema as @spec describes it, with `decoded` for CAN frames; values that are
    not objects are wrapped as {"value": ...} (Foxglove's JSON channels carry objects)."""
    schema = described.get("schema") or {}
    if schema.get("type") != "object":
        return {"type": "object", "properties": {"value": schema}}
    if described.get("type_name") == "canFrame":
        schema = {**schema, "properties": {**schema.get("properties", {}), "decoded": {"type": "string"}}}
    return schema
