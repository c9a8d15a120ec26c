"""Export a recording as JSON-encoded MCAP, which Foxglove displays and plots field by field.

Every message becomes a JSON object: trace events and struct values already are; a bare value
(an enum name such as "COMMIT", a number, nothing) is wrapped as `{"value": ...}` and its JSON
Schema wrapped the same way, because Foxglove shows fields of objects. Beside them, the robot in
3D (`iotad.recording.foxglove_scene`): the arm's model, frames and joint states, Buggy's arena,
path and pose, in Foxglove's own schemas. A format 2 bus's bursts go out as they are and, frame by
frame, on format 1's topics (its `frames` log and `rx/<k>`), as the reader expands them.
"""
from __future__ import annotations

import json
from pathlib import Path

from mcap.records import Channel as McapChannel

from iotad.node_host import wire
from iotad.recording.foxglove_scene import SceneWriter
from iotad.recording.mcap_format import EXPORTED
from iotad.recording.mcap_reader import Recording
from iotad.recording.mcap_sink import McapSink


def _is_object_schema(schema: dict) -> bool:
    # A permissive schema (no "type") says nothing: objects stay as they are, bare values are wrapped.
    return schema.get("type") in ("object", None)


def export_json(recording: Recording, output: str | Path, extra_metadata: dict[str, dict] | None = None) -> int:
    """Write `output` with message encoding `json`; attachments and metadata are copied, and
    `extra_metadata` added. Returns the count."""
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
        ids: dict[str, tuple[int, bool]] = {}
        schema_ids: dict[tuple, int] = {}
        scene = SceneWriter(sink.writer)
        for spec in recording.specs.values():  # the robot's URDF and joint names, as the system gives them
            scene.tracker.learn(spec)
        count = 0
        for message in recording.messages:
            entry = ids.get(message.topic)
            if entry is None:
                channel = by_topic.get(message.topic)
                if channel is None:  # a frame read out of a format 2 burst: its format 1 topic, for Foxglove
                    channel = by_topic[message.topic] = McapChannel(
                        id=0, topic=message.topic, message_encoding="json", schema_id=0,
                        metadata={"derived": "iotad.recording.bursts"})
                stored = recording.schemas.get(channel.schema_id)
                try:
                    schema = json.loads(stored.data) if stored is not None else {}
                except ValueError:
                    schema = {}
                wrap = not _is_object_schema(schema)
                if wrap:
                    schema = {"type": "object", "title": schema.get("title", "value"),
                              "properties": {"value": schema}}
                name = stored.name if stored is not None else "any"
                text = json.dumps(schema, sort_keys=True).encode()
                key = (name, text)
                schema_id = schema_ids.get(key)
                if schema_id is None:
                    schema_id = schema_ids[key] = sink.writer.register_schema(name, "jsonschema", text)
                channel_id = sink.writer.register_channel(channel.topic, "json", schema_id, dict(channel.metadata))
                entry = ids[message.topic] = (channel_id, wrap)
            channel_id, wrap = entry
            value = message.value  # a damaged payload: RecordingError, naming the message
            if wrap or not isinstance(value, dict):
                value = {"value": value}
            data = json.dumps(value, separators=(",", ":"), default=repr).encode()
            sink.writer.add_message(channel_id, message.log_time, data, message.publish_time, message.sequence)
            count += 1
            parsed = wire.parse_key(message.topic)
            if parsed is not None and not parsed[2].startswith("@"):
                scene.feed(message.topic, message.value, message.log_time)
        count += scene.count
    finally:
        sink.finish()
    return count
