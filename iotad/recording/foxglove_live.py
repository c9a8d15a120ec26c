"""A running system as a Foxglove WebSocket server (foxglove-sdk), for `iotad view`: each message
logged on the channels `foxglove_mapping` names, the robot in 3D from `foxglove_scene`."""
from __future__ import annotations

from typing import Any

from iotad.recording.foxglove_mapping import (LOG_TOPIC, described_channels, joint_names, log_lines, log_message,
                                             topic_of, typed, views)


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
        for key, type_name, schema in described_channels(spec):
            self.types[key] = type_name
            self.schemas[topic_of(key)] = schema

    def message(self, key: str, value: Any, stamp_ns: int) -> None:
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
                if kind == "joints":  # the joint map's names, where known
                    from iotad.node_host.wire import parse_key

                    path = (parse_key(key) or ("", "/".join(key.split("/")[2:-1])))[1]
                    message = {"joints": joint_names(message["joints"],
                                                     self.scene.robots.names_for(path, len(message["joints"])))}
                channel.log(typed(kind, message, stamp_ns), log_time=stamp_ns)
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
        for _, level, line in log_lines(path, events):
            self.log_channel.log(log_message(path, level, line, stamp_ns), log_time=stamp_ns)
            self.sent += 1
