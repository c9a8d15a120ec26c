"""A running system as a Foxglove WebSocket server (foxglove-sdk), for `iotad view`: each message
logged on the channels `foxglove_mapping` names, the robot in 3D from `foxglove_scene`."""
from __future__ import annotations

from typing import Any

from iotad.recording.foxglove_mapping import LOG_TOPIC, json_schema, log_lines, topic_of, views


class Bridge:
    """Foxglove channels made on first use; `log` is the only way messages go out."""

    def __init__(self):
        import foxglove
        from foxglove.channels import JointStatesChannel, LogChannel, PoseInFrameChannel

        self._foxglove = foxglove
        self._json: dict[str, Any] = {}
        self._joints: dict[str, Any] = {}
        self._poses: dict[str, Any] = {}
        self._kinds = {"joints": (self._joints, JointStatesChannel), "pose": (self._poses, PoseInFrameChannel)}
        self.log_channel = LogChannel(LOG_TOPIC)
        from iotad.recording.foxglove_scene import SceneTracker

        from iotad.recording.foxglove_latched import LatchedScene

        self.scene = SceneTracker(embed=False)  # meshes by URL: the server answers them (asset)
        self.latched = LatchedScene()  # the URDF, meshes, arena, conveyor: again for each late viewer
        self._scene: dict[str, Any] = {}
        self.schemas: dict[str, dict] = {}   # topic -> JSON schema (from @spec)
        self.types: dict[str, str] = {}      # key -> type name
        self.sent = 0

    def describe(self, spec: dict) -> None:
        self.scene.learn(spec)  # a URDF the drives load, the joint names of a joint map
        for channel in spec.get("channels") or []:
            for key in channel.get("keys") or []:
                self.types[key] = channel.get("type_name")
                self.schemas[topic_of(key)] = json_schema(channel)

    def message(self, key: str, value: Any, stamp_ns: int) -> None:
        from foxglove.messages import JointState, JointStates, Pose, PoseInFrame, Quaternion, Timestamp, Vector3

        for topic, kind, message in views(key, self.types.get(key), value):
            if kind == "json":
                channel = self._json.get(topic)
                if channel is None:
                    channel = self._json[topic] = self._foxglove.Channel(topic, schema=self.schemas.get(topic) or {
                        "type": "object"})
                channel.log(message, log_time=stamp_ns)
            else:
                table, maker = self._kinds[kind]
                channel = table.get(topic)
                if channel is None:
                    channel = table[topic] = maker(topic)
                stamp = Timestamp(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000)
                if kind == "joints":
                    joints = message["joints"]
                    parsed = key.split("/")  # iota/<system>/<path...>/<channel>: the joint map's names if known
                    names = self.scene.robots.names_for("/".join(parsed[2:-1]), len(joints))
                    if names:
                        joints = [dict(j, name=name) for j, name in zip(joints, names)]
                    typed = JointStates(timestamp=stamp, joints=[JointState(**j) for j in joints])
                else:
                    typed = PoseInFrame(timestamp=stamp, frame_id="world", pose=Pose(
                        position=Vector3(x=message["x"], y=message["y"], z=message["z"]),
                        orientation=Quaternion(x=0.0, y=0.0, z=message["qz"], w=message["qw"])))
                channel.log(typed, log_time=stamp_ns)
            self.sent += 1
        for topic, message in self.scene.feed(key, value, stamp_ns):
            channel = self._scene.get(topic)
            if channel is None:
                channel = self._scene[topic] = self._scene_channel(topic, message)
            self.latched.keep(topic, channel, message, stamp_ns)
            channel.log(message, log_time=stamp_ns)
            self.sent += 1

    def _scene_channel(self, topic: str, message: Any) -> Any:
        import foxglove.channels

        from iotad.recording.foxglove_scene import URDF_SCHEMA

        if isinstance(message, dict):  # the URDF, as ROS's std_msgs/msg/String: Foxglove's URDF layer reads it
            return self._foxglove.Channel(topic, schema=URDF_SCHEMA)
        return getattr(foxglove.channels, f"{type(message).__name__}Channel")(topic)

    @staticmethod
    def asset(uri: str) -> bytes | None:
        """A mesh of the arm's URDF (`package://xarm_description/...`), for Foxglove's fetchAsset."""
        from iotad.recording.robot_model import mesh_path

        path = mesh_path(uri)
        return None if path is None else path.read_bytes()

    def trace(self, path: str, events: list, stamp_ns: int) -> None:
        from foxglove.messages import Log, LogLevel, Timestamp

        for _, level, line in log_lines(path, events):
            level_value = LogLevel.Warning if level == "warning" else LogLevel.Info
            self.log_channel.log(Log(timestamp=Timestamp(stamp_ns // 1_000_000_000, stamp_ns % 1_000_000_000),
                                     level=level_value, message=line, name=path), log_time=stamp_ns)
            self.sent += 1
