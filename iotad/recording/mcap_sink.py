"""Writing a recording: `McapSink`, an MCAP file of iotad events whose schemas and channels are
registered on first use, and the schema each recorded topic gets."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import IO, Any, Callable

from mcap.records import Channel as McapChannel, Schema
from mcap.writer import CompressionType, Writer

from iotad.node_host import wire
from iotad.recording.mcap_batch_writer import BatchWriter, spill_chunk_indexes
from iotad.recording.mcap_format import (GAP_SCHEMA, GAP_TOPIC, HEARTBEAT_SCHEMA, LAUNCHER_SCHEMA, MALFORMED_SCHEMA,
                                         MALFORMED_TOPIC, MESSAGE_ENCODING, PERMISSIVE_SCHEMA, PROFILE,
                                         SCHEMA_ENCODING, SET_METADATA, TRACE_SCHEMA, json_default)
from iotad.recording.mcap_reader import Recording


class McapSink:
    """An MCAP file of iotad events: schemas and channels registered on first use.

    `flush()` closes the chunk in progress and pushes it to the file: call it on a timer so a
    killed writer loses only what arrived since (the mcap writer keeps a whole chunk in memory).
    """

    def __init__(self, output: str | Path | IO[bytes], *, chunk_size: int = 4 * 1024 * 1024,
                 compression: CompressionType = CompressionType.ZSTD):
        self._file = open(output, "wb") if isinstance(output, (str, Path)) else output
        self._owns_file = isinstance(output, (str, Path))
        self.writer = Writer(self._file, chunk_size=chunk_size, compression=compression)
        # One chunk index per flush (20 a second at the recorder's 50 ms) would otherwise stay in
        # memory until `finish`, ~1 KB each: 1.2 MB a minute. They wait in a temp file instead.
        self._spilled = spill_chunk_indexes(self.writer, Path(output).parent if self._owns_file else None)
        self.writer.start(profile=PROFILE, library=f"iotad {_version()}")
        self._schemas: dict[tuple[str, str], int] = {}
        self.channels: dict[str, int] = {}
        self.counts: dict[str, int] = {}
        self.finished = False
        self._commit: Callable[[], None] = lambda: None  # a fast writer's batch into the chunk
        self.write_pair = self._write_pair  # replaced by the fast writer's

    def schema(self, name: str, schema: dict) -> int:
        text = json.dumps(schema, sort_keys=True)
        key = (name, text)
        schema_id = self._schemas.get(key)
        if schema_id is None:
            schema_id = self._schemas[key] = self.writer.register_schema(name, SCHEMA_ENCODING, text.encode())
        return schema_id

    def channel(self, topic: str, schema_name: str, schema: dict, metadata: dict[str, str] | None = None) -> int:
        channel_id = self.channels.get(topic)
        if channel_id is None:
            schema_id = self.schema(schema_name, schema)
            channel_id = self.channels[topic] = self.writer.register_channel(
                topic, MESSAGE_ENCODING, schema_id, metadata or {})
        return channel_id

    def write(self, channel_id: int, log_ns: int, publish_ns: int, sequence: int, data: bytes) -> None:
        self._commit()  # after what a batch writer holds: the file keeps the order of the writes
        self.writer.add_message(channel_id, log_ns, data, publish_ns, sequence & 0xFFFFFFFF)

    def fast_writer(self) -> Callable[[int, int, int, int, bytes], None]:
        """`write` for the recorder's hot loop: a message costs one struct.pack and three list
        appends; what it wrote goes into the chunk in progress at the next `flush` (or `write`,
        `finish`, or `commit()`), all at once (`BatchWriter`, which keeps the Writer's statistics
        and indexes). Plain `write` if this mcap's Writer lacks the fields it needs. The caller
        should `commit()` every few thousand messages: a chunk is closed at `chunk_size` only
        when a batch goes in."""
        batch = BatchWriter.of(self.writer)
        if batch is None:
            return self.write
        self._commit()
        self._commit = batch.commit
        self.write_pair = batch.write_pair
        return batch.write

    def _write_pair(self, channel_id: int, log_ns: int, publish_ns: int, sequence: int, data: bytes,
                    channel_id2: int, publish_ns2: int, sequence2: int, data2: bytes) -> None:
        self.write(channel_id, log_ns, publish_ns, sequence, data)
        self.write(channel_id2, log_ns, publish_ns2, sequence2, data2)

    def commit(self) -> None:
        """Put what the fast writer holds into the chunk in progress (in memory)."""
        self._commit()

    def attach(self, name: str, media_type: str, data: bytes, log_ns: int | None = None) -> None:
        now = time.time_ns() if log_ns is None else log_ns
        self.writer.add_attachment(now, now, name, media_type, data)

    def add_spec(self, path: str, spec: dict, log_ns: int | None = None) -> None:
        self.attach(f"spec/{path}.json", "application/json", json.dumps(spec, default=json_default).encode(), log_ns)

    def add_metadata(self, name: str, data: dict[str, Any]) -> None:
        self.writer.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v, default=json_default)
                                        for k, v in data.items()})

    def flush(self) -> None:
        self._commit()
        self.writer.flush()

    def size(self) -> int:
        """Bytes written to the file so far (what `flush` pushed out; not the chunk in progress)."""
        try:
            return self._file.tell()
        except (OSError, ValueError):
            return 0

    def finish(self) -> None:
        if self.finished:
            return
        self.finished = True
        self._commit()
        try:
            self.writer.finish()
        finally:
            if self._spilled is not None:
                self._spilled.close()
        self._file.flush()
        if self._owns_file:
            self._file.close()


def _version() -> str:
    from iotad import __version__
    return __version__


def channel_schemas(spec: dict) -> dict[str, tuple[str, dict]]:
    """channel name -> (schema name, JSON schema), from a stored spec's channel list."""
    out: dict[str, tuple[str, dict]] = {}
    for entry in spec.get("channels") or []:
        if not isinstance(entry, dict) or "name" not in entry:
            continue
        schema = entry.get("schema") or entry.get("json_schema")
        if isinstance(schema, dict):
            out[entry["name"]] = (str(entry.get("type_name") or entry.get("type") or schema.get("title") or entry["name"]), schema)
        elif entry.get("type") is None and "type" in entry:
            out[entry["name"]] = ("null", {"type": "null"})
    if out:
        return out
    try:  # a node host that did not give schemas: build the IOTA and ask its types
        # (here, not at the top: the ESPRIT compiler is loaded only for such a node)
        from iotad.esprit.stored_spec import build_node
        from iotad.kernel.compose import flatten
        iota = build_node(spec)
        for leaf in flatten(iota).leaves:
            for name, channel in leaf.iota.iota_spec.channels.items():
                if channel.type is not None:
                    out.setdefault(name, (channel.type.name, channel.type.json_schema()))
    except Exception:  # noqa: BLE001 - schemas are a nicety; permissive ones still record everything
        pass
    return out


def schema_for_topic(topic: str, specs: dict[str, dict], cache: dict[str, dict]) -> tuple[str, dict]:
    parsed = wire.parse_key(topic)
    if topic == GAP_TOPIC:
        return "iotad.gap", GAP_SCHEMA
    if topic == MALFORMED_TOPIC:
        return "iotad.malformed", MALFORMED_SCHEMA
    if topic.endswith("/" + wire.LAUNCHER):
        return "iotad.launcher_event", LAUNCHER_SCHEMA
    if parsed is None:
        return "any", PERMISSIVE_SCHEMA
    _, path, channel, _ = parsed
    if channel == wire.TRACE:
        return "iotad.trace_event", TRACE_SCHEMA
    if channel == wire.HEARTBEAT:
        return "iotad.heartbeat", HEARTBEAT_SCHEMA
    if path in specs:
        if path not in cache:
            cache[path] = channel_schemas(specs[path])
        found = cache[path].get(channel)
        if found:
            return found
    return "any", PERMISSIVE_SCHEMA


def write_set_file(path: str | Path, set_id: str, files: list[str], info: dict[str, Any]) -> None:
    """Write (or replace, atomically) the set file of a split recording: an MCAP file holding no
    messages, only metadata `iotad.recording` (`info`) and `iotad.split_set` (`set`: an id that
    every member carries too, `files`: the members' names in order, in the same folder)."""
    path = Path(path)
    temp = path.with_name(f".{path.name}.tmp")
    sink = McapSink(temp)
    try:
        sink.add_metadata("iotad.recording", info)
        sink.add_metadata(SET_METADATA, {"set": set_id, "files": files})
    finally:
        sink.finish()
    os.replace(temp, path)


def copy_recording(recording: Recording, output: str | Path, convert: Callable[[Schema | None, McapChannel, bytes],
                   tuple[Schema | None, McapChannel, bytes]] | None = None,
                   extra_metadata: dict[str, dict] | None = None) -> int:
    """Write a complete MCAP (summary, indexes) holding everything `recording` holds.
    `convert` may re-encode each channel's messages (export to JSON does). Returns the count."""
    sink = McapSink(output)
    try:
        ids: dict[str, int] = {}
        schema_ids: dict[tuple, int] = {}
        by_topic = {c.topic: c for c in recording.channels.values()}
        for attachment in recording.attachments:
            sink.writer.add_attachment(attachment.create_time, attachment.log_time, attachment.name,
                                       attachment.media_type, attachment.data)
        for name, data in recording.metadata.items():
            if name == SET_METADATA:
                continue  # the copy holds the messages itself: it is no set file
            sink.writer.add_metadata(name, data)
        if recording.files:  # a split recording made one file: say which files it was
            sink.add_metadata("iotad.joined", {"files": [Path(f).name for f in recording.files]})
        for name, data in (extra_metadata or {}).items():
            sink.add_metadata(name, data)
        count = 0
        for message in recording.messages:
            if message.derived:  # a burst's frames as the reader expanded them: the burst is copied
                continue
            channel_id = ids.get(message.topic)
            data = message.data
            if channel_id is None:
                channel = by_topic[message.topic]
                schema = recording.schemas.get(channel.schema_id)
                if convert is not None:
                    schema, channel, _ = convert(schema, channel, b"")
                schema_id = 0
                if schema is not None:
                    key = (schema.name, schema.encoding, bytes(schema.data))
                    schema_id = schema_ids.get(key) or schema_ids.setdefault(
                        key, sink.writer.register_schema(schema.name, schema.encoding, schema.data))
                channel_id = ids[message.topic] = sink.writer.register_channel(
                    channel.topic, channel.message_encoding, schema_id, dict(channel.metadata))
            if convert is not None:
                data = convert(None, by_topic[message.topic], data)[2]
            sink.writer.add_message(channel_id, message.log_time, data, message.publish_time, message.sequence)
            count += 1
    finally:
        sink.finish()
    return count
