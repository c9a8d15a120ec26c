"""Export a recording as MCAP that Foxglove opens, on the topics `iotad view` shows live.

Every channel message goes out through the mapping `iotad view` serves (`foxglove_mapping`):
on `/<node path>/<channel>[/<k>]` as JSON with its channel type's schema (a bare value, such as
an enum name "COMMIT", wrapped as `{"value": ...}`; a CAN frame with its `decoded` name), and
where it fits one of Foxglove's well-known schemas on `<topic>/joints` (`foxglove.JointStates`,
named as the joint map names them) and `<topic>/pose` (`foxglove.PoseInFrame`); the nodes'
traces give `/log` (`foxglove.Log`: acks, `mdl_command`, every violation). Everything else the
recording holds (the `@trace`, `@launcher`, `@recorder` topics...) is copied on its own topic as
JSON. Beside them, the robot in 3D (`iotad.recording.foxglove_scene`): the arm's model, frames and
joint states, Buggy's arena, path and pose, in Foxglove's own schemas. A format 2 bus's bursts go
out as they are and, frame by frame, on format 1's topics (its `frames` log and `rx/<k>`), as the
reader expands them.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from iotad.node_host import wire
from iotad.recording.foxglove_mapping import (LOG_TOPIC, described_channels, joint_names, json_schema, log_lines,
                                              log_message, topic_of, typed, views)
from iotad.recording.foxglove_scene import SceneWriter
from iotad.recording.mcap_format import EXPORTED
from iotad.recording.mcap_reader import Recording
from iotad.recording.mcap_sink import McapSink


def _is_object_schema(schema: dict) -> bool:
    # A permissive schema (no "type") says nothing: objects stay as they are, bare values are wrapped.
    return schema.get("type") in ("object", None)


class _JsonChannels:
    """The export's JSON channels, registered on first use, one schema record per distinct schema."""

    def __init__(self, writer: Any):
        self.writer = writer
        self.ids: dict[str, int] = {}
        self.schema_ids: dict[tuple, int] = {}
        self.count = 0

    def write(self, topic: str, name: str, schema: dict, metadata: dict, value: Any, log_time: int,
              publish_time: int, sequence: int) -> None:
        channel_id = self.ids.get(topic)
        if channel_id is None:
            text = json.dumps(schema, sort_keys=True).encode()
            schema_id = self.schema_ids.get((name, text))
            if schema_id is None:
                schema_id = self.schema_ids[(name, text)] = self.writer.register_schema(name, "jsonschema", text)
            channel_id = self.ids[topic] = self.writer.register_channel(topic, "json", schema_id, metadata)
        data = json.dumps(value, separators=(",", ":"), default=repr).encode()
        self.writer.add_message(channel_id, log_time, data, publish_time, sequence)
        self.count += 1


def export_json(recording: Recording, output: str | Path, extra_metadata: dict[str, dict] | None = None) -> int:
    """Write `output` for Foxglove; attachments and metadata are copied, and `extra_metadata`
    added. Returns the count of messages written."""
    sink = McapSink(output)
    try:
        for attachment in recording.attachments:
            sink.writer.add_attachment(attachment.create_time, attachment.log_time, attachment.name,
                                       attachment.media_type, attachment.data)
        for name, data in recording.metadata.items():
            sink.writer.add_metadata(name, data)
        for name, data in {EXPORTED: {"from": str(recording.path), "encoding": "json"}, **(extra_metadata or {})}.items():
            sink.add_metadata(name, data)
        by_topic = {c.topic: c for c in recording.channels.values()}
        stored_schemas: dict[str, tuple[str, dict]] = {}
        types: dict[str, str | None] = {}
        mapped: dict[str, dict] = {}        # mapped topic -> its channel's JSON schema (from @spec)
        json_channels = _JsonChannels(sink.writer)
        scene = SceneWriter(sink.writer)
        for spec in recording.specs.values():  # the robot's URDF and joint names, as the system gives them
            scene.tracker.learn(spec)
            for key, type_name, schema in described_channels(spec):
                types[key] = type_name
                mapped["/" + "/".join(key.split("/")[2:])] = schema
        for message in recording.messages:
            value = message.value  # a damaged payload: RecordingError, naming the message
            parsed = wire.parse_key(message.topic)
            stamp = message.log_time
            if parsed is not None and not parsed[2].startswith("@"):
                if message.topic not in types:  # a spec without keys (a virtual run's): the file's schema says
                    channel = by_topic.get(message.topic)
                    stored = recording.schemas.get(channel.schema_id) if channel is not None else None
                    types[message.topic] = stored.name if stored is not None else None
                    raw = _stored_raw(recording, channel)
                    if stored is None:  # a frame the reader derived from a burst: its node's spec says
                        types[message.topic], raw = _spec_channel(recording, parsed[1], parsed[2])
                    mapped.setdefault(topic_of(message.topic), json_schema({"schema": raw, "type_name": types[message.topic]}))
                type_name = types[message.topic]
                for topic, kind, view in views(message.topic, type_name, value):
                    if kind == "json":
                        json_channels.write(topic, type_name or "any", mapped[topic], {"key": message.topic}, view,
                                            stamp, message.publish_time, message.sequence)
                    else:
                        if kind == "joints":
                            joints = view["joints"]
                            view = {"joints": joint_names(joints, scene.tracker.robots.names_for(parsed[1], len(joints)))}
                        scene.write(topic, typed(kind, view, stamp), stamp)
                scene.feed(message.topic, value, stamp)
                continue
            name, schema = _stored(recording, by_topic, stored_schemas, message.topic)
            channel = by_topic.get(message.topic)
            wrapped = value if _is_object_schema(_stored_raw(recording, channel)) and isinstance(value, dict) \
                else {"value": value}
            json_channels.write(message.topic, name, schema, dict(channel.metadata) if channel is not None else
                                {"derived": "iotad.recording.bursts"}, wrapped, stamp, message.publish_time,
                                message.sequence)
            if parsed is not None and parsed[2] == wire.TRACE:
                for _, level, line in log_lines(parsed[1], value if isinstance(value, list) else [value]):
                    scene.write(LOG_TOPIC, log_message(parsed[1], level, line, stamp), stamp)
        count = json_channels.count + scene.count
    finally:
        sink.finish()
    return count


def _spec_channel(recording: Recording, node: str, name: str) -> tuple[str | None, dict]:
    """(type name, JSON schema) of channel `name` of `node` as its recorded spec declares it (a
    `can_tx` read back from a `can_tx_burst`, a bus's `rx` and `frames` from its bursts)."""
    spec = recording.specs.get(node)
    channels = spec.get("channels") if isinstance(spec, dict) else None
    for channel in channels if isinstance(channels, list) else ():
        if isinstance(channel, dict) and channel.get("name") == name:
            schema = channel.get("schema")
            return channel.get("type"), schema if isinstance(schema, dict) else {}
    return None, {}


def _stored_raw(recording: Recording, channel: Any) -> dict:
    stored = recording.schemas.get(channel.schema_id) if channel is not None else None
    try:
        schema = json.loads(stored.data) if stored is not None else {}
    except ValueError:
        schema = {}
    return schema if isinstance(schema, dict) else {}


def _stored(recording: Recording, by_topic: dict, cache: dict, topic: str) -> tuple[str, dict]:
    """(name, JSON schema) of a recorded topic as its file stores it, a bare value's wrapped as
    {"value": ...}; a topic the reader derived (a frame out of a format 2 burst) has none."""
    found = cache.get(topic)
    if found is None:
        channel = by_topic.get(topic)
        stored = recording.schemas.get(channel.schema_id) if channel is not None else None
        schema = _stored_raw(recording, channel)
        if not _is_object_schema(schema):
            schema = {"type": "object", "title": schema.get("title", "value"), "properties": {"value": schema}}
        found = cache[topic] = (stored.name if stored is not None else "any", schema)
    return found
