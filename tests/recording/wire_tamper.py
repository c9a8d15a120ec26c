"""Tampering with a recording's messages (the wire, or one node's trace) for the delivery tests:
`rewrite(source, target, change)` copies an MCAP file with `change(messages) -> messages`
applied to the whole list of `RecordedMessage`s, keeping attachments, metadata and schemas."""
from __future__ import annotations

import json
from dataclasses import replace

from iotad.recording.mcap_format import packb
from iotad.recording.mcap_reader import read_recording, RecordedMessage
from iotad.recording.mcap_sink import McapSink


def rewrite(source, target, change):
    recording = read_recording(source)
    schema_of = {}
    for message in recording.messages:
        if message.topic not in schema_of:
            schema = recording.schema_of(message.topic)
            try:
                schema_of[message.topic] = (schema.name, json.loads(schema.data)) if schema else ("any", {})
            except (TypeError, ValueError):
                schema_of[message.topic] = (schema.name, {})
    # a format 2 burst's per-frame messages are the reader's, not the file's: the copy holds the burst
    messages = change([m for m in recording.messages if not m.derived])
    sink = McapSink(target)
    for attachment in recording.attachments:
        sink.attach(attachment.name, attachment.media_type, attachment.data)
    for name, data in recording.metadata.items():
        sink.writer.add_metadata(name, data)
    for message in sorted(messages, key=lambda m: m.log_time):
        name, schema = schema_of.get(message.topic, ("any", {}))
        channel = sink.channel(message.topic, name, schema)
        sink.write(channel, message.log_time, message.publish_time, message.sequence, message.data)
    sink.finish()
    return target


def index_of(messages, topic, predicate=lambda value: True, nth=0):
    """Position of the nth message on `topic` whose decoded value satisfies `predicate`."""
    found = [k for k, m in enumerate(messages) if m.topic == topic and predicate(m.value)]
    return found[nth]


def with_value(message: RecordedMessage, value) -> RecordedMessage:
    return replace(message, data=packb(value))
