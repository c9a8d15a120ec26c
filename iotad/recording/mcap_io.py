"""Recordings: writing iotad events to MCAP and reading them back, whole or cut short.

One MCAP channel per key (`iota/<system>/<path>/<channel>[/<index>]`, `.../@trace`,
`iota/<system>/@launcher`), message encoding `msgpack` with a `jsonschema` schema per type.
A recording carries what replay and check need and nothing else must be found:

- attachment `spec/<path>.json` per node: the node's `@spec` answer (source, text, params,
  channels), so the node can be rebuilt from the recording alone;
- attachment `system.toml` (or `system.json` for an in-process run): the system file;
- metadata `iotad.recording`: system name, time unit, clock origin, who wrote it;
- messages on `@recorder/gaps`: sequence gaps the recorder saw (they survive a kill),
  and metadata `iotad.gaps` with their total at a clean finish;
- messages on `@recorder/malformed` (only if any): what came on a `@trace` key that was neither
  an event nor a burst of events, or an element of a burst that was no event (not a map, or a
  map without a finite `t` and string `kind` and `action`: `trace_event_problem`), and an
  `@launcher` or `@heartbeat` payload that was no msgpack map. None of them is written on its
  own key, where every reader takes what it finds for an event.

Every message on a `@trace` channel is one trace event, whether the node sent it alone or in a
burst (the recorder splits bursts).

Reading goes through one sequential pass of `mcap.stream_reader.StreamReader`, which also reads
a file that a killed writer left without a footer; `complete` says whether the footer was there.
"""
from __future__ import annotations

import hashlib
import importlib.util
import inspect
import json
import linecache
import math
import os
import struct
import sys
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from itertools import accumulate
from pathlib import Path
from typing import IO, Any, Callable, Iterable, Iterator

import msgpack
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel as McapChannel, Footer, Message, MessageIndex, Metadata, Schema
from mcap.writer import MCAP0_MAGIC as MCAP_MAGIC
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import CompressionType, Writer

from iotad.host import wire
from iotad.kernel.types import to_plain

MESSAGE_ENCODING = "msgpack"
SCHEMA_ENCODING = "jsonschema"
PROFILE = "iotad"
GAP_TOPIC = "@recorder/gaps"
MALFORMED_TOPIC = "@recorder/malformed"  # what a recorder got on @trace that is no event (nor burst), etc.
FORMAT = "iotad-mcap/1"
SET_METADATA = "iotad.split_set"  # in the set file of a split recording: its member files

# Every message on a `@trace` key is one event in the trace JSONL shape (docs/design.md section 5); a
# node host's first one is its engine-start record (kind `start`, `wire.start_event`).
TRACE_SCHEMA = {
    "title": "iotad trace event", "type": "object",
    "properties": {"t": {"type": "number"}, "iota": {"type": "string"}, "action": {"type": "string"},
                   "index": {"type": ["integer", "null"]},
                   "kind": {"enum": ["input", "output", "internal", "violation", "start"]}, "value": {}},
    "required": ["t", "iota", "action", "kind"]}
GAP_SCHEMA = {
    "title": "iotad sequence gap", "type": "object",
    "properties": {"key": {"type": "string"}, "expected": {"type": "integer"}, "got": {"type": "integer"},
                   "missing": {"type": "integer"}}}
MALFORMED_SCHEMA = {
    "title": "iotad malformed trace sample", "type": "object",
    "properties": {"key": {"type": "string"}, "seq": {"type": "integer"}, "message": {"type": "string"},
                   "data": {}}}
LAUNCHER_SCHEMA = {"title": "iotad launcher event", "type": "object"}
HEARTBEAT_SCHEMA = {"title": "iotad heartbeat", "type": "object",
                    "properties": {"t": {"type": "number"}, "firings": {"type": "integer"},
                                   "queue": {"type": "integer"}}}
PERMISSIVE_SCHEMA: dict = {"title": "any msgpack value"}  # unknown type: anything goes


class RecordingError(Exception):
    """A file is not a readable iotad recording (one-line message)."""


def trace_event_problem(event: dict) -> str:
    """Why a decoded `@trace` map is not a trace event the tools can read ("" if it is one)."""
    t = event.get("t")
    if t.__class__ not in (int, float) or not math.isfinite(t):
        return f"its time t is {t!r}, not a finite number"
    for name in ("kind", "action"):
        if not isinstance(event.get(name), str):
            return f"its {name} is {event.get(name)!r}, not a string"
    if not isinstance(event.get("iota", ""), str):
        return f"its iota is {event.get('iota')!r}, not a string"
    index = event.get("index")
    if index is not None and index.__class__ is not int:
        return f"its index is {index!r}, not an integer"
    if event["kind"] == "violation" and not isinstance(event.get("value"), dict):
        return f"a violation whose value is {event.get('value')!r}, not a map"
    return ""


def packb(value: Any) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def unpackb(data: bytes) -> Any:
    return msgpack.unpackb(data, raw=False, strict_map_key=False)


# ------------------------------------------------------------------------------------ writing
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
        self._spilled = _spill_chunk_indexes(self.writer, Path(output).parent if self._owns_file else None)
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
        `finish`, or `commit()`), all at once.

        The mcap Writer builds a Message object and five small writes per message (~6 us); this
        appends the same bytes and index entries itself, a batch at a time, and keeps the
        Writer's statistics, so `flush`/`finish` write the chunk, its indexes and the summary as
        usual. It relies on the Writer's private fields (mcap 1.x); if they are not there it is
        plain `write`. The caller should `commit()` every few thousand messages: a chunk is
        closed at `chunk_size` only when a batch goes in."""
        writer = self.writer
        builder = getattr(writer, "_Writer__chunk_builder", None)
        stats = getattr(writer, "_Writer__statistics", None)
        finalize = getattr(writer, "_Writer__maybe_finalize_chunk", None)
        record_writer = getattr(builder, "record_writer", None)
        if builder is None or stats is None or finalize is None or not hasattr(record_writer, "_buffer"):
            return self.write
        self._commit()
        pack = struct.Struct("<BQHIQQ").pack  # opcode, record length, channel, sequence, log, publish
        parts: list[bytes] = []  # header, data, header, data...
        channels: list[int] = []
        logs: list[int] = []
        indices = builder.message_indices
        channel_counts = stats.channel_message_counts
        add_parts, add_channel, add_log = parts.extend, channels.append, logs.append
        add_channels, add_logs = channels.extend, logs.extend

        def write(channel_id: int, log_ns: int, publish_ns: int, sequence: int, data: bytes) -> None:
            add_parts((pack(5, 22 + len(data), channel_id, sequence & 0xFFFFFFFF, log_ns, publish_ns), data))
            add_channel(channel_id)
            add_log(log_ns)

        def write_pair(channel_id: int, log_ns: int, publish_ns: int, sequence: int, data: bytes,
                       channel_id2: int, publish_ns2: int, sequence2: int, data2: bytes) -> None:
            """Two messages with the same log time (a trace event and the message it describes)."""
            add_parts((pack(5, 22 + len(data), channel_id, sequence & 0xFFFFFFFF, log_ns, publish_ns), data,
                       pack(5, 22 + len(data2), channel_id2, sequence2 & 0xFFFFFFFF, log_ns, publish_ns2), data2))
            add_channels((channel_id, channel_id2))
            add_logs((log_ns, log_ns))

        def commit() -> None:
            if not logs:
                return
            buffer = record_writer._buffer  # replaced by a new one after every chunk
            # where each message starts in the chunk: every other running total of the parts
            starts = list(accumulate(map(len, parts), initial=buffer.tell()))[:-1:2]
            buffer.write(b"".join(parts))
            first, last, count = min(logs), max(logs), len(logs)
            appenders = {}  # channel -> its index records' append
            for channel_id, record in zip(channels, zip(logs, starts)):
                try:
                    appenders[channel_id](record)
                except KeyError:
                    index = indices.get(channel_id)
                    if index is None:
                        index = indices[channel_id] = _MessageIndex(channel_id=channel_id, records=[])
                    appenders[channel_id] = index.records.append
                    index.records.append(record)
            for channel_id, n in Counter(channels).items():
                channel_counts[channel_id] += n
            if builder.num_messages == 0:
                builder.message_start_time, builder.message_end_time = first, last
            else:
                builder.message_start_time = min(builder.message_start_time, first)
                builder.message_end_time = max(builder.message_end_time, last)
            builder.num_messages += count
            if stats.message_count == 0:
                stats.message_start_time, stats.message_end_time = first, last
            else:
                stats.message_start_time = min(stats.message_start_time, first)
                stats.message_end_time = max(stats.message_end_time, last)
            stats.message_count += count
            parts.clear()
            channels.clear()
            logs.clear()
            finalize()  # closes the chunk if it has reached chunk_size

        self._commit = commit
        self.write_pair = write_pair
        return write

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
        self.attach(f"spec/{path}.json", "application/json", json.dumps(spec, default=_plain).encode(), log_ns)

    def add_metadata(self, name: str, data: dict[str, Any]) -> None:
        self.writer.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v, default=_plain)
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


class _SpilledChunkIndexes:
    """Stands in for the mcap Writer's list of chunk indexes: each index is written as its
    record bytes to an unnamed temp file (gone with the process, even after a SIGKILL) and read
    back once, by `Writer.finish`, which writes them into the summary. Iterating yields blocks
    of whole records with the one method the Writer calls on an index, `write(builder)`."""

    BLOCK = 1 << 20

    def __init__(self, folder: Path | None):
        import tempfile
        try:
            self._file = tempfile.TemporaryFile(dir=folder, prefix=".iotad-chunk-indexes-")
        except OSError:  # a read-only or odd folder: the system temp dir then
            self._file = tempfile.TemporaryFile(prefix=".iotad-chunk-indexes-")
        self._count = 0

    def append(self, index: Any) -> None:
        from mcap.data_stream import RecordBuilder
        builder = RecordBuilder()
        index.write(builder)
        self._file.write(builder.end())
        self._count += 1

    def __len__(self) -> int:
        return self._count

    def __iter__(self) -> Iterator[Any]:
        self._file.flush()
        self._file.seek(0)
        while True:
            block = self._file.read(self.BLOCK)
            if not block:
                break
            yield _RawRecords(block)
        self._file.seek(0, 2)

    def close(self) -> None:
        self._file.close()


class _RawRecords:
    """Record bytes that write themselves into a summary as they are."""

    __slots__ = ("data",)

    def __init__(self, data: bytes):
        self.data = data

    def write(self, builder: Any) -> None:
        builder.write(self.data)


def _spill_chunk_indexes(writer: Writer, folder: Path | None) -> _SpilledChunkIndexes | None:
    """Replace the Writer's in-memory chunk index list (a private field of mcap 1.x) by a
    `_SpilledChunkIndexes`; if the field is not there, leave the Writer as it is."""
    if not isinstance(getattr(writer, "_Writer__chunk_indices", None), list):
        return None
    spilled = _SpilledChunkIndexes(folder)
    writer._Writer__chunk_indices = spilled
    return spilled


class _MessageIndex(MessageIndex):
    """The same record, written with one `struct.pack` rather than two small writes per message
    (those cost ~1.5 us a message when a chunk is closed)."""

    def write(self, stream: Any) -> None:
        records = self.records
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write(struct.pack(f"<HI{2 * len(records)}Q", self.channel_id, len(records) * 16,
                                 *[n for record in records for n in record]))
        stream.finish_record()


def _plain(value: Any) -> Any:
    plain = to_plain(value)
    if plain is value:
        return repr(value)
    return plain


def _version() -> str:
    from iotad import __version__
    return __version__


# ------------------------------------------------------------------------------------ specs
def spec_record(iota: Any, path: str, time_unit: float = 1.0) -> dict:
    """The `@spec` answer for an in-process IOTA: what a node host would answer for it."""
    from iotad.kernel.model import param_values
    spec = iota.iota_spec
    if spec.source is not None:  # ESPRIT (or any spec that carries its text)
        source = {"kind": "esprit", "file": spec.source_path, "iota": spec.name}
        text = spec.source
    else:
        cls = type(iota)
        file = inspect.getsourcefile(cls)
        # the module's name too: a module of a package imports its neighbours relatively
        source = {"kind": "python", "ref": f"{file}:{cls.__name__}", "module": cls.__module__}
        text = Path(file).read_text() if file and Path(file).is_file() else None
    return {"path": path, "source": source, "text": text, "params": to_plain(param_values(iota)),
            "channels": channel_list(spec, param_values(iota)), "time_unit": time_unit}


def channel_list(spec: Any, params: dict | None = None) -> list[dict]:
    """The channel table of an instance: switching times and sizes that name a parameter are
    resolved with `params` (as a node host's @spec answer gives them)."""
    params = {} if params is None else params
    return [{"name": c.name, "direction": c.direction, "type": None if c.type is None else c.type.name,
             "schema": None if c.type is None else c.type.json_schema(),
             "switching_time": spec.switching_of(c, params) if isinstance(c.switching_time, str) else c.switching_time,
             "size": spec.size_of(c, params) if isinstance(c.size, str) else c.size} for c in spec.channels.values()]


def start_time(spec: dict | None) -> float:
    """When the node's engine started, in its own clock. `Recording.specs` adds `engine_start`
    from the node's `start` event on @trace (exact); a recording older than that event has only
    the `started` wall-clock stamp of the `@spec` answer (taken just before the engine started);
    in-process runs start at 0."""
    if not spec:
        return 0.0
    exact = spec.get("engine_start")
    if isinstance(exact, (int, float)):
        return float(exact)
    started, origin, unit = spec.get("started"), spec.get("origin"), spec.get("time_unit") or 1.0
    if isinstance(started, (int, float)) and isinstance(origin, (int, float)):
        return max(0.0, (started - origin) / unit)
    return 0.0


def build_node(spec: dict, name: str | None = None) -> Any:
    """Rebuild a node from its stored `@spec` answer (text first; the file only if no text)."""
    source = spec.get("source") or {}
    kind, params, text = source.get("kind"), dict(spec.get("params") or {}), spec.get("text")
    name = name or spec.get("path")
    if kind == "esprit":
        try:
            from iotad.esprit import load_iota
        except ImportError:
            raise RecordingError("this recording holds an ESPRIT spec, and iotad.esprit is not installed") from None
        if text and source.get("file"):
            # the stored text under its file's name: externs named relative to the spec
            # ("buggy_math.py:wrap") resolve next to it, as when the node loaded it
            from iotad.esprit import load_text
            return load_text(text, str(source["file"])).factory(source.get("iota"))(name, **params)
        return load_iota(text if text else source["file"], iota=source.get("iota"), name=name, **params)
    if kind == "python":
        ref = source.get("ref", "")
        file, _, cls_name = ref.rpartition(":")
        if text:
            cls = getattr(_module_from_text(text, file, _package_of(source, file)), cls_name, None)
            if cls is None:
                raise RecordingError(f"spec of {name}: its stored source has no {cls_name}")
        else:
            from iotad.kernel.python_loader import load_object
            cls = load_object(ref)
        return cls(name, **params)
    raise RecordingError(f"spec of {name}: unknown source kind {kind!r}")


def _package_of(source: dict, where: str) -> str | None:
    """The package a stored module's relative imports (`from .joint_map import ...`) resolve
    in: from the recorded module name, or from a `package.module` reference; None for a file
    that is no package's module."""
    module = source.get("module")
    if not module and where and not where.endswith(".py"):
        module = where  # a "package.module:Class" reference
    if not module or module == "__main__":
        return None
    try:
        found = importlib.util.find_spec(module)
    except (ImportError, ValueError):
        found = None
    if found is not None and found.submodule_search_locations is not None:
        return module  # the text is the package's __init__
    return module.rpartition(".")[0] or None


def _module_from_text(text: str, file: str, package: str | None = None) -> Any:
    """Import a stored Python source as a module; its text goes to linecache so that the
    dependency analysis (iotad.kernel.dependencies) can still read the functions' source.
    In `package` (imported first), so that its relative imports find the package's modules."""
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    name = f"_iotad_recorded_{digest}"
    if package:
        try:
            importlib.import_module(package)
            name = f"{package}.{name}"
        except ImportError:
            pass  # not installed here: relative imports will say so
    module = sys.modules.get(name)
    if module is not None:
        return module
    filename = f"<recorded {Path(file).name or 'spec'} {digest}>"
    linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
    folder = str(Path(file).parent) if file else ""
    if folder and Path(folder).is_dir() and folder not in sys.path:
        sys.path.append(folder)  # neighbours it imports, if they are still there
    spec = importlib.util.spec_from_loader(name, loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__file__ = filename
    sys.modules[name] = module
    try:
        exec(compile(text, filename, "exec"), module.__dict__)
    except Exception as exc:
        del sys.modules[name]
        raise RecordingError(f"stored source of {file}: {type(exc).__name__}: {exc}") from None
    return module


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
        iota = build_node(spec)
        from iotad.kernel.compose import flatten
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


# ------------------------------------------------------------------------------------ engine sink
_EVENT_KEYS = ("t", "iota", "action", "index", "kind", "value")  # an engine event's, in its order
_EVENT_HEAD = b"\x86\xa1t"  # msgpack: a map of 6, the key "t"
_VALUE_KEY = b"\xa5value"
_FLOAT64 = struct.Struct(">Bd").pack  # msgpack's float 64: 0xCB, big-endian double


# MCAP log and publish times are unsigned 64-bit nanoseconds from the origin.
MAX_RECORDED_SECONDS = ((1 << 64) - 1) / 1e9
# Metadata a virtual run writes when an error of iotad's own broke it off: {"error", "t"}.
RUN_ERROR = "iotad.run_error"
# metadata of a virtual run that ended as it should: the time its engine ran to (spec units). Every
# node ran until then, so a window that closed before it and never fired is a deadline missed.
RUN_END = "iotad.run_end"


def recording_header(root: Any, system: str | None = None, *, time_unit: float = 1.0, origin_ns: int = 0,
                     policy: Any = None, external: Iterable[str] = ()) -> dict[str, Any]:
    """What an `EngineRecorder` writes before the first event, as plain data (JSON and msgpack
    carry it as it is): the node paths, each node's spec, the recording's metadata and the
    system's description. A writer in another process starts from it (`writer_process`)."""
    from iotad.kernel.compose import Composite, flatten
    flat = flatten(root)
    prefix = root.instance_name + "/"
    node_path = {}
    for leaf in flat.leaves:
        rel = leaf.path[len(prefix):] if leaf.path.startswith(prefix) else leaf.path
        node_path[leaf.path] = rel or leaf.path
    # each spec as its JSON text reads back: what the file holds, whichever process writes it
    specs = {node_path[leaf.path]: json.loads(json.dumps(spec_record(leaf.iota, node_path[leaf.path], time_unit),
                                                         default=_plain))
             for leaf in flat.leaves}
    name = system or root.instance_name
    bindings = [[str(s), str(d)] for s, d in flat.bindings]
    metadata = {"format": FORMAT, "system": name, "time_unit": time_unit, "origin_ns": origin_ns,
                "clock": "virtual", "writer": "EngineRecorder", "root": root.instance_name,
                "nodes": list(specs), "bindings": bindings, "composite": isinstance(root, Composite),
                **_policy_info(policy)}
    # `external`: the system file's external inputs ("motor.can_rx"), which the delivery check
    # judges as fed from outside (an input script's) rather than as a binding's
    described = {"name": name, "nodes": {p: {k: s[k] for k in ("source", "params")} for p, s in specs.items()},
                 "bindings": bindings, "external": list(external)}
    return {"system": name, "time_unit": time_unit, "origin_ns": origin_ns, "node_path": node_path,
            "specs": specs, "metadata": metadata, "system_json": described}


class EngineRecorder:
    """An Engine sink that writes what a system of node hosts would publish: every event of a
    leaf on `iota/<system>/<path>/@trace`, every output on its channel key. Virtual time `t`
    becomes log and publish time `t * time_unit` seconds after `origin_ns`."""

    def __init__(self, sink: McapSink, root: Any, system: str | None = None, *, time_unit: float = 1.0,
                 origin_ns: int = 0, policy: Any = None, external: Iterable[str] = ()):
        self._begin(sink, recording_header(root, system, time_unit=time_unit, origin_ns=origin_ns,
                                           policy=policy, external=external))

    @classmethod
    def from_header(cls, sink: McapSink, header: dict[str, Any]) -> "EngineRecorder":
        """The recorder of a system known only by its `recording_header` (no IOTAs here)."""
        recorder = cls.__new__(cls)
        recorder._begin(sink, header)
        return recorder

    def _begin(self, sink: McapSink, header: dict[str, Any]) -> None:
        self.sink = sink
        self.system, self.time_unit, self.origin_ns = header["system"], header["time_unit"], header["origin_ns"]
        self.node_path = header["node_path"]
        self._ids: dict[str, list] = {}  # topic -> [channel id, next sequence]
        self._specs: dict[str, dict] = header["specs"]
        self._cache: dict[str, dict] = {}
        for path, spec in self._specs.items():
            sink.add_spec(path, spec, self.origin_ns)
        sink.add_metadata("iotad.recording", header["metadata"])
        sink.attach("system.json", "application/json", json.dumps(header["system_json"], default=_plain).encode(),
                    self.origin_ns)
        self._writers()

    # The hot path (bench/worlds.py): per event, one dict look-up for its node's @trace topic (and
    # one for an output's key), one msgpack pack each (one Packer: the bytes of `packb`), and the
    # sink's fast writer, whose batch goes into the chunk every COMMIT_EVERY events and before a
    # new channel is registered, so the file keeps the order of `write` calls one by one.
    COMMIT_EVERY = 4096

    def _topic(self, topic: str) -> list:
        """[channel id, next sequence] of a topic, registered on first use."""
        state = self._ids.get(topic)
        if state is None:
            name, schema = schema_for_topic(topic, self._specs, self._cache)
            self._commit()  # the messages before it go first, as with one `write` at a time
            state = self._ids[topic] = [self.sink.channel(topic, name, schema), 0]
        return state

    def _writers(self) -> None:
        fast = getattr(self.sink, "fast_writer", None)
        self._write = fast() if fast is not None else self.sink.write
        self._write_pair = getattr(self.sink, "write_pair", None)
        self._commit = getattr(self.sink, "commit", lambda: None)
        self._pack = msgpack.Packer(use_bin_type=True).pack
        self._entries: dict[tuple, list] = {}  # (iota, channel, index, kind) -> `_entry`
        self._pending = 0

    def _entry(self, event: dict, key: tuple | None) -> list:
        """[its fields packed (None: not an engine's event), node path, @trace topic, output topic
        (None until the first output)] of an event's (iota, channel, index, kind); kept by `key`."""
        iota = event["iota"]
        path = self.node_path.get(iota, iota)
        trace = self._topic(wire.trace_key(self.system, path))
        middle = None
        if key is not None:
            middle = self._pack({"iota": path, "action": event["action"], "index": event["index"],
                                 "kind": event["kind"]})[1:] + _VALUE_KEY
        output = None
        if event["kind"] == "output":
            output = self._ids.get(wire.channel_key(self.system, path, event["action"], event["index"]))
        entry = [middle, path, trace, output]
        if key is not None:
            self._entries[key] = entry
        return entry

    def __call__(self, event: dict) -> None:
        if self._pending >= self.COMMIT_EVERY:
            self._commit()
            self._pending = 0
        self._pending += 1
        t = event["t"]
        ns = self.origin_ns + int(round(t * self.time_unit * 1e9))
        pack = self._pack
        value = pack(event.get("value"))
        kind = event["kind"]
        try:
            key = (event["iota"], event["action"], event["index"], kind)
            entry = self._entries.get(key)
        except TypeError:  # an unhashable field: not from an engine
            key = entry = None
        if entry is None:
            entry = self._entry(event, key)
        middle, path, trace, output = entry
        if middle is not None and tuple(event) == _EVENT_KEYS:
            # the bytes of pack(dict(event, iota=path)), its value packed once for both messages:
            # map header, "t", t, then iota/action/index/kind (packed once), "value", value
            data = b"".join((_EVENT_HEAD, _FLOAT64(0xCB, t) if t.__class__ is float else pack(t), middle, value))
        else:
            data = pack(dict(event, iota=path))
        seq = trace[1]
        trace[1] = seq + 1
        if kind != "output":
            self._write(trace[0], ns, ns, seq, data)
            return
        if output is None:  # the first output on this key: its trace event, then its channel
            self._write(trace[0], ns, ns, seq, data)
            output = entry[3] = self._topic(wire.channel_key(self.system, path, event["action"], event["index"]))
            sequence = output[1]
            output[1] = sequence + 1
            self._write(output[0], ns, ns, sequence, value)
            return
        sequence = output[1]
        output[1] = sequence + 1
        if self._write_pair is None:
            self._write(trace[0], ns, ns, seq, data)
            self._write(output[0], ns, ns, sequence, value)
        else:
            self._write_pair(trace[0], ns, ns, seq, data, output[0], ns, sequence, value)


def _policy_info(policy: Any) -> dict[str, Any]:
    """How the run chose firing times within windows (replay repeats an eager run by itself, and
    follows the recorded times of any other): {"policy": "eager"} or {"policy": "random", "seed": 7}."""
    name = getattr(policy, "name", "eager")
    seed = getattr(policy, "seed", None)
    return {"policy": name} if seed is None else {"policy": name, "seed": seed}


def record_run(root: Any, output: str | Path, until: float, inputs: Iterable[dict] = (), policy: Any = None,
               system: str | None = None, **engine_options: Any):
    """Run `root` in virtual time up to `until` and write every event to `output` (an MCAP file).
    `inputs` are input-script entries (`iotad.kernel.input_script`). Returns the engine."""
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    sink = McapSink(output)
    try:
        recorder = EngineRecorder(sink, root, system, policy=policy)
        engine = Engine(root, VirtualClock(), policy, sinks=[recorder], **engine_options)
        for entry in inputs:
            if entry["t"] <= until:
                engine.post(entry.get("iota"), entry["action"], entry.get("value"), entry.get("index"), t=entry["t"])
        engine.run(until)
    finally:
        sink.finish()
    return engine


# ------------------------------------------------------------------------------------ reading
@dataclass(slots=True)  # a recording holds a million of them: ~100 bytes each saved
class RecordedMessage:
    topic: str
    log_time: int
    publish_time: int
    sequence: int
    data: bytes

    @property
    def value(self) -> Any:
        try:
            return unpackb(self.data)
        except Exception as exc:  # noqa: BLE001 - msgpack raises several kinds for bad bytes
            raise RecordingError(f"message #{self.sequence} on {self.topic} (log time {self.log_time} ns): "
                                 f"its payload is not msgpack ({type(exc).__name__}: {str(exc) or 'malformed'}); "
                                 f"the recording is damaged") from None


@dataclass
class Recording:
    """Everything in a recording, read in one pass; `complete` is False for a cut-short file."""

    path: str
    messages: list[RecordedMessage] = field(default_factory=list)
    schemas: dict[int, Schema] = field(default_factory=dict)
    channels: dict[int, McapChannel] = field(default_factory=dict)
    attachments: list[Attachment] = field(default_factory=list)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    complete: bool = False
    truncated_reason: str = ""
    # why the bytes are not what was written (a chunk or attachment failing its CRC, a record
    # that cannot be decoded in a file that ends like a finished one); reading stopped there
    damaged: str = ""
    header_library: str = ""
    # a split recording read as one (`read_recording` of its set file): the member files, in order
    files: list[str] = field(default_factory=list)

    # -- what it holds
    @property
    def recovered_from(self) -> str:
        """What `iotad recover` made this file of, when that recording was not whole ("" for any
        other): its end is missing, so it holds part of a run, whatever its own footer says."""
        meta = self.metadata.get("iotad.recovered")
        if meta is None or meta.get("was_complete") == "true":
            return ""
        damaged = meta.get("damaged")
        how = f"damaged: {damaged}" if damaged else f"cut short: {meta.get('stopped_at') or '?'}"
        return f"{meta.get('from') or 'a recording'} ({how})"

    @property
    def run_end(self) -> float | None:
        """The time a virtual run's engine ran to (spec units; None: not recorded)."""
        meta = self.metadata.get(RUN_END)
        try:
            t = float(json.loads(meta.get("t", "null"))) if meta is not None else None
        except (TypeError, ValueError):
            return None
        return t if t is not None and math.isfinite(t) else None

    @property
    def run_error(self) -> str:
        """How the run that made it broke off ("" for a run that ended as it should): an error
        of iotad itself, at the time it happened (`RUN_ERROR`, written by `iotad run --virtual`)."""
        meta = self.metadata.get(RUN_ERROR)
        if meta is None:
            return ""
        try:
            t = f" at t={float(json.loads(meta.get('t', 'null'))):.6g} s"
        except (TypeError, ValueError):
            t = ""
        return f"{meta.get('error') or 'an error'}{t}"

    @property
    def info(self) -> dict[str, Any]:
        raw = self.metadata.get("iotad.recording", {})
        out: dict[str, Any] = {}
        for key, value in raw.items():
            try:
                out[key] = json.loads(value)
            except (TypeError, ValueError):
                out[key] = value
        return out

    @property
    def specs(self) -> dict[str, dict]:
        out = {}
        for attachment in self.attachments:
            if attachment.name.startswith("spec/") and attachment.name.endswith(".json"):
                try:
                    spec = json.loads(attachment.data)
                except ValueError:
                    continue
                if isinstance(spec, dict):  # anything else is damage: the node reads as having no spec
                    out[attachment.name[5:-5]] = spec
        for node, t in self.start_times().items():
            if node in out and isinstance(out[node], dict):
                out[node]["engine_start"] = t
        return out

    def start_times(self) -> dict[str, float]:
        """node -> when its engine started (its `start` event on @trace; the first one if a
        restarted node has several, since the first windows are those of the first run)."""
        cached = self.__dict__.get("_start_times")
        if cached is not None and cached[0] == len(self.messages):
            return dict(cached[1])
        out: dict[str, float] = {}
        marker = packb(wire.START_KIND)
        for message in self.messages:
            # cheap test first: only a start record holds the packed string "start"
            if not message.topic.endswith("/" + wire.TRACE) or marker not in message.data:
                continue
            parsed = wire.parse_key(message.topic)
            event = message.value
            if parsed and isinstance(event, dict) and event.get("kind") == wire.START_KIND \
                    and isinstance(event.get("t"), (int, float)):
                out.setdefault(parsed[1], float(event["t"]))
        self.__dict__["_start_times"] = (len(self.messages), out)
        return dict(out)

    @property
    def system_text(self) -> str | None:
        for attachment in self.attachments:
            if attachment.name in ("system.toml", "system.json"):
                return attachment.data.decode(errors="replace")
        return None

    @property
    def time_unit(self) -> float:
        """Seconds per spec time unit: what a trace event's `t` counts (1.0 unless the system file
        says otherwise)."""
        def usable(unit: Any) -> bool:
            return isinstance(unit, (int, float)) and not isinstance(unit, bool) and unit > 0

        unit = self.info.get("time_unit")
        if not usable(unit):  # a recording without the metadata: its specs say it, if they agree
            units = {spec.get("time_unit") for spec in self.specs.values()}
            unit = units.pop() if len(units) == 1 else None
        return float(unit) if usable(unit) else 1.0

    @property
    def system(self) -> str | None:
        name = self.info.get("system")
        if name:
            return name
        for message in self.messages:
            parsed = wire.parse_key(message.topic)
            if parsed:
                return parsed[0]
        return None

    def topics(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for message in self.messages:
            counts[message.topic] = counts.get(message.topic, 0) + 1
        return counts

    def nodes(self) -> list[str]:
        found = set(self.specs)
        for topic in self.topics():
            parsed = wire.parse_key(topic)
            if parsed and parsed[1] and not parsed[2].startswith(wire.LAUNCHER):
                found.add(parsed[1])
        return sorted(found)

    def trace(self, node: str | None = None, starts: bool = False) -> list[dict]:
        """Trace events (from `@trace` keys) of one node or of all, in recorded order; the
        engine-start records (kind `start`) only with `starts`."""
        out = []
        for message in self.messages:
            if not message.topic.endswith("/" + wire.TRACE):
                continue
            parsed = wire.parse_key(message.topic)
            if parsed is None or (node is not None and parsed[1] != node):
                continue
            event = message.value
            if isinstance(event, dict):
                problem = trace_event_problem(event)
                if problem:
                    raise RecordingError(f"message #{message.sequence} on {message.topic} (log time "
                                         f"{message.log_time} ns) is no trace event: {problem}; the recording is damaged")
                if not starts and event.get("kind") == wire.START_KIND:
                    continue
                event.setdefault("node", parsed[1])
                # the same few strings are in every event: one copy of each, not one per event (a
                # long trace holds hundreds of thousands of events: a fifth of their memory)
                event["kind"], event["action"] = sys.intern(event["kind"]), sys.intern(event["action"])
                if "iota" in event:
                    event["iota"] = sys.intern(event["iota"])
                out.append(event)
        return out

    def process_trace(self, node: str) -> list[dict]:
        """`trace(node, starts=True)` with one `start` record per process that ran the node.

        A restarted process publishes its `start` record in its first `@trace` burst, right after
        it connects; that burst can miss the recorder (sent before the new session knew of its
        subscription), and the two processes would then read as one run, judged against one
        initial state. The launcher's events name every process (`live`, with its pid): for a
        process with no start record, one is made at its `live` time (node clock = wall clock
        minus the one offset every start record of the run shares), marked `"from": "launcher"`,
        and put after the events of the processes before it (before the first event recorded
        after the new process was spawned)."""
        events = self.trace(node, starts=True)
        starts = [e for e in events if e.get("kind") == wire.START_KIND]
        value = starts[0].get("value") if starts else None
        if not isinstance(value, dict) or not isinstance(value.get("wall"), (int, float)):
            return events  # an in-process recording, or nothing to anchor the launcher's times on
        offset = float(value["wall"]) - float(starts[0]["t"])
        recorded = {e["value"].get("pid") for e in starts if isinstance(e.get("value"), dict)}
        launcher = [e for e in self.launcher_events() if e.get("node") == node and isinstance(e.get("t_ns"), int)]
        spawned = {e.get("pid"): e["t_ns"] for e in launcher if e.get("event") in ("start", "restart")}
        for live in launcher:
            pid = live.get("pid")
            if live.get("event") != "live" or pid in recorded:
                continue
            recorded.add(pid)
            t = live["t_ns"] / 1e9 - offset
            since = spawned.get(pid, live["t_ns"]) / 1e9 - offset
            made = {"t": t, "iota": starts[0].get("iota", node), "action": starts[0].get("action", "@start"),
                    "index": None, "kind": wire.START_KIND, "node": node,
                    "value": {"wall": live["t_ns"] / 1e9, "pid": pid, "from": "launcher"}}
            at = next((k for k, e in enumerate(events) if float(e["t"]) > since), len(events))
            events.insert(at, made)
        return events

    def restart_times(self, node: str) -> list[float]:
        """When each process after the first that ran `node` started its engine (spec units, the
        node's clock): a restarted node begins again from its initial state (a world node, from a
        new world), which a picture of the run must not join to what came before."""
        starts = [float(e["t"]) for e in self.process_trace(node) if e.get("kind") == wire.START_KIND]
        return starts[1:]

    def violations(self) -> list[dict]:
        return [e for e in self.trace() if e.get("kind") == "violation"]

    def gaps(self) -> list[dict]:
        return [m.value for m in self.messages if m.topic == GAP_TOPIC]

    def malformed(self) -> list[dict]:
        """What the recorder got on `@trace` keys that was no trace event (see `MALFORMED_TOPIC`)."""
        return [m.value for m in self.messages if m.topic == MALFORMED_TOPIC]

    def launcher_events(self) -> list[dict]:
        """The launcher's events; a payload that is no msgpack map (a file written before the
        recorder set those aside) is left out, not an error: no reading depends on all of them."""
        out = []
        for message in self.messages:
            if message.topic.endswith("/" + wire.LAUNCHER):
                try:
                    value = unpackb(message.data)
                except Exception:  # noqa: BLE001 - msgpack raises several kinds for bad bytes
                    continue
                if isinstance(value, dict):
                    out.append(dict(value, log_time=message.log_time))
        return out

    def duration(self) -> float:
        if not self.messages:
            return 0.0
        times = [m.log_time for m in self.messages]
        return (max(times) - min(times)) / 1e9

    def schema_of(self, topic: str) -> Schema | None:
        for channel in self.channels.values():
            if channel.topic == topic:
                return self.schemas.get(channel.schema_id)
        return None


def read_recording(path: str | Path, whole_set: bool = True, salvage: bool = False,
                   progress: Callable[[str, int, int], None] | None = None) -> Recording:
    """Read a recording, complete or cut short by a kill; raise RecordingError if it is not MCAP,
    or if it is damaged (`Recording.damaged`) unless `salvage`: then what comes before the damage.

    The set file of a split recording (`iotad record --max-size/--max-duration`) reads as one
    recording made of all its members, in order (`files` lists them); `whole_set=False` reads
    the set file alone. A member file reads alone: each is a whole recording."""
    path = Path(path)
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    recording = _read_file(path, progress)
    if whole_set and SET_METADATA in recording.metadata:
        recording = _read_set(recording, path, progress)
    if recording.damaged and not salvage:
        raise RecordingError(f"{path}: damaged: {recording.damaged}; its data cannot be trusted. "
                             f"'iotad recover {path}' keeps what comes before the damage")
    return recording


PROGRESS_EVERY = 2.0  # s between `progress` calls while a file is read


def _read_file(path: Path, progress: Callable[[str, int, int], None] | None = None) -> Recording:
    """`progress(file, bytes read, bytes in all)`, if given, every PROGRESS_EVERY s of reading."""
    recording = Recording(str(path))
    size = path.stat().st_size
    next_report = time.monotonic() + PROGRESS_EVERY
    with open(path, "rb") as stream:
        try:
            for count, record in enumerate(_records(stream, recording)):
                if progress is not None and count % 4096 == 0 and time.monotonic() >= next_report:
                    next_report = time.monotonic() + PROGRESS_EVERY
                    progress(str(path), stream.tell(), size)
                if isinstance(record, Message):
                    channel = recording.channels.get(record.channel_id)
                    if channel is None:
                        raise RecordingError(f"{path}: message on unknown channel {record.channel_id}")
                    # one int for both times where they are the same (always, in a virtual run's)
                    publish_time = record.log_time if record.publish_time == record.log_time else record.publish_time
                    recording.messages.append(RecordedMessage(channel.topic, record.log_time,
                                                              publish_time, record.sequence, record.data))
                elif isinstance(record, Schema):
                    recording.schemas[record.id] = record
                elif isinstance(record, McapChannel):
                    if record.message_encoding == "json":
                        raise RecordingError(_json_copy(path))  # `iotad export --json` writes one for Foxglove
                    recording.channels[record.id] = record
                elif isinstance(record, Attachment):
                    recording.attachments.append(record)
                elif isinstance(record, Metadata):
                    if record.name == EXPORTED:  # a JSON copy of no message at all says so here
                        raise RecordingError(_json_copy(path))
                    recording.metadata[record.name] = dict(record.metadata)
        except RecordingError:
            raise
    return recording


EXPORTED = "iotad.exported"  # metadata of a JSON copy (`iotad export --json`): which file it copies


def _json_copy(path) -> str:
    # its payloads are JSON, not ours
    return (f"{path}: a JSON copy for Foxglove ('iotad export --json'); iotad's tools read the msgpack "
            f"recording it was exported from")


def set_files(path: str | Path) -> list[Path]:
    """The files that hold a recording's messages, in order: a split recording's members (those
    that exist), or the file itself."""
    path = Path(path)
    recording = _read_head(path)
    meta = recording.metadata.get(SET_METADATA)
    if meta is None:
        return [path]
    return [path.parent / name for name in _member_names(path, meta) if (path.parent / name).is_file()]


def iter_messages(path: str | Path) -> Iterator[RecordedMessage]:
    """The messages of a recording (of every member of a split one), streamed one at a time:
    for a recording too big to hold in memory. Stops quietly where a killed writer stopped."""
    for file in set_files(path):
        channels: dict[int, str] = {}
        scratch = Recording(str(file))
        with open(file, "rb") as stream:
            for record in _records(stream, scratch):
                if isinstance(record, Message):
                    topic = channels.get(record.channel_id)
                    if topic is None:
                        raise RecordingError(f"{file}: message on unknown channel {record.channel_id}")
                    yield RecordedMessage(topic, record.log_time, record.publish_time, record.sequence, record.data)
                elif isinstance(record, McapChannel):
                    channels[record.id] = record.topic
        if scratch.damaged:
            raise RecordingError(f"{file}: damaged: {scratch.damaged}; its data cannot be trusted")


def _read_head(path: Path) -> Recording:
    """The records before the first message or chunk: enough to tell a set file from a recording."""
    recording = Recording(str(path))
    if not path.is_file():
        raise RecordingError(f"{path}: no such file")
    with open(path, "rb") as stream:
        for record in _records(stream, recording):
            if isinstance(record, Metadata):
                recording.metadata[record.name] = dict(record.metadata)
            elif isinstance(record, (Message, McapChannel, Schema)) or type(record).__name__ == "Chunk":
                break
    return recording


def _member_names(path: Path, meta: dict[str, str]) -> list[str]:
    try:
        names = json.loads(meta.get("files", "[]"))
    except ValueError:
        raise RecordingError(f"{path}: the split recording's file list is not JSON") from None
    if not isinstance(names, list) or not all(isinstance(n, str) and "/" not in n for n in names):
        raise RecordingError(f"{path}: the split recording's file list is malformed")
    return names


def _read_set(index: Recording, path: Path, progress: Callable[[str, int, int], None] | None = None) -> Recording:
    """A split recording's members read as one: messages in member order, channels and schemas
    merged by topic and content, each attachment once (the first member's), metadata of the
    last member that has it (`iotad.recording`: the first's; `iotad.split_set`: the set file's)."""
    names = _member_names(path, index.metadata[SET_METADATA])
    set_id = index.metadata[SET_METADATA].get("set")
    out = Recording(str(path), complete=index.complete, truncated_reason=index.truncated_reason,
                    header_library=index.header_library)
    out.metadata[SET_METADATA] = index.metadata[SET_METADATA]
    schema_ids: dict[tuple, int] = {}
    channel_ids: dict[str, int] = {}
    attached: set[str] = set()
    last_time: int | None = None
    for position, name in enumerate(names):
        file = path.parent / name
        if not file.is_file():
            if position == len(names) - 1:
                # the recorder stopped between naming it and creating it, or it was deleted: the
                # set is not whole either way
                out.complete = False
                out.truncated_reason = f"{name}, the last file the set lists, is missing"
                continue
            raise RecordingError(f"{path}: {name}, file {position} of the split recording, is missing")
        member = _read_file(file, progress)
        _same_set(path, name, position, member, set_id)
        if member.messages:  # members follow each other in time: one put in another's place does not
            first = min(m.log_time for m in member.messages)
            if last_time is not None and first < last_time:
                raise RecordingError(f"{path}: {name} (file {position}) begins before the file before it ends: "
                                     "the set's files are out of order, or one is another run's")
            last_time = max(m.log_time for m in member.messages)
        out.files.append(str(file))
        hole = not member.complete and position < len(names) - 1
        if not member.complete:
            out.complete = False
            out.truncated_reason = f"{name}: {member.truncated_reason or 'cut short'}"
        if hole:
            # A file cut short before the last: what came between its end and the next file's
            # start is missing. Read as one across that hole, the trace would run on as if
            # nothing were missing, and a check would blame the nodes for windows that closed in
            # it. The set reads as a recording cut short here; each later file reads alone.
            later = names[position + 1:]
            out.truncated_reason += (f"; a hole in the split recording: the set is read up to there, its "
                                     f"{len(later)} later file(s) ({', '.join(later)}) each read alone")
        if member.damaged and not out.damaged:
            out.damaged = f"{name}: {member.damaged}"
        new_schema: dict[int, int] = {0: 0}
        for schema_id, schema in member.schemas.items():
            key = (schema.name, schema.encoding, bytes(schema.data))
            if key not in schema_ids:
                schema_ids[key] = len(schema_ids) + 1
                out.schemas[schema_ids[key]] = Schema(id=schema_ids[key], name=schema.name,
                                                      encoding=schema.encoding, data=schema.data)
            new_schema[schema_id] = schema_ids[key]
        for channel in member.channels.values():
            if channel.topic not in channel_ids:
                channel_ids[channel.topic] = len(channel_ids) + 1
                out.channels[channel_ids[channel.topic]] = McapChannel(
                    id=channel_ids[channel.topic], topic=channel.topic, message_encoding=channel.message_encoding,
                    schema_id=new_schema.get(channel.schema_id, 0), metadata=dict(channel.metadata))
        out.messages.extend(member.messages)
        for attachment in member.attachments:
            if attachment.name not in attached:
                attached.add(attachment.name)
                out.attachments.append(attachment)
        for name_, data in member.metadata.items():
            if name_ == "iotad.recording":
                out.metadata.setdefault(name_, data)
            elif name_ != SET_METADATA:
                out.metadata[name_] = data
        if hole:
            break
    if not out.files:
        raise RecordingError(f"{path}: a split recording none of whose files exist")
    return out


def _same_set(path: Path, name: str, position: int, member: Recording, set_id: Any) -> None:
    """A member names its set and its place in it (metadata `iotad.recording`, `split`): another
    run's file copied in, or members renamed, are refused, never read as this run's."""
    try:
        split = json.loads(member.metadata.get("iotad.recording", {}).get("split", "null"))
    except (TypeError, ValueError):
        split = None
    if not isinstance(split, dict):
        return  # cut before its metadata: nothing to compare (the member says it is incomplete)
    if split.get("set") != set_id:
        raise RecordingError(f"{path}: {name} belongs to another split recording (set {split.get('set')!r}, "
                             f"not {set_id!r}): a file of another run")
    if split.get("index") != position:
        raise RecordingError(f"{path}: {name} is file {split.get('index')} of its set, not file {position}: "
                             "the set's files were renamed or copied over each other")


def write_set_file(path: str | Path, set_id: str, files: list[str], info: dict[str, Any]) -> None:
    """Write (or replace, atomically) the set file of a split recording: an MCAP file holding no
    messages, only metadata `iotad.recording` (`info`) and `iotad.split_set` (`set`: an id that
    every member carries too, `files`: the members' names in order, in the same folder)."""
    import os
    path = Path(path)
    temp = path.with_name(f".{path.name}.tmp")
    sink = McapSink(temp)
    try:
        sink.add_metadata("iotad.recording", info)
        sink.add_metadata(SET_METADATA, {"set": set_id, "files": files})
    finally:
        sink.finish()
    os.replace(temp, path)


def member_path(path: str | Path, number: int) -> Path:
    """File `number` of the split recording whose set file is `path`: `fig2.mcap` -> `fig2_3.mcap`."""
    path = Path(path)
    return path.with_name(f"{path.stem}_{number}{path.suffix or '.mcap'}")


def existing_recording(path: str | Path) -> Path | None:
    """The file a new recording at `path` would replace: `path` itself, or the first member of a
    split recording of that name (`fig2_0.mcap`); None when there is none. Recordings are the
    evidence of a run: `run -o` and `record -o` replace one only when told to (--force)."""
    path = Path(path)
    for candidate in (path, member_path(path, 0)):
        if candidate.is_file() and (candidate != path or candidate.stat().st_size > 0):
            return candidate
    return None


def claim_file(path: str | Path) -> bool:
    """Create `path` empty, atomically: False if it is there already. A run claims its recording's
    name this way before anything writes it, so that two runs started together never share one
    file (each checked that no recording was there, then both wrote it). An empty file at the
    name is no recording (`existing_recording`): the writer replaces it."""
    try:
        os.close(os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644))
    except FileExistsError:
        return False
    return True


def unused_recording_path(path: str | Path, claim: bool = False) -> Path:
    """`path`, or `path` with -2, -3... before its suffix: the first name no recording holds (two
    runs started within the same second would otherwise share a time-stamped default name);
    with `claim`, the first one this process could create (`claim_file`)."""
    path = Path(path)
    candidate, number = path, 2
    while existing_recording(candidate) is not None or (claim and not _claimed(candidate)):
        candidate = path.with_name(f"{path.stem}-{number}{path.suffix}")
        number += 1
    return candidate


def _claimed(path: Path) -> bool:
    path.parent.mkdir(parents=True, exist_ok=True)
    return claim_file(path)


def _records(stream: IO[bytes], recording: Recording) -> Iterator[Any]:
    """Records of the data section; stops quietly where a killed writer stopped writing, and
    stops where the bytes are damaged (`recording.damaged` says how)."""
    reader = StreamReader(stream, record_size_limit=1 << 31, validate_crcs=True)  # chunks' CRCs
    records = reader.records
    first = True
    while True:
        try:
            record = next(records)
        except StopIteration:
            return
        except Exception as exc:  # noqa: BLE001 - the mcap reader raises many types on a cut-off file
            if first:
                raise RecordingError(f"{recording.path}: not an MCAP file ({type(exc).__name__}: {exc})") from None
            recording.truncated_reason = f"{type(exc).__name__}: {exc}"
            # A killed writer never wrote the closing magic: a file that ends with it was
            # finished, and what cannot be read in it was changed since.
            if isinstance(exc, CRCValidationError):
                recording.damaged = (f"a {type(exc.record).__name__.lower()} fails its CRC (stored {exc.expected}, "
                                     f"computed {exc.actual})")
            elif _ends_like_a_finished_file(stream):
                recording.damaged = f"a record cannot be read ({type(exc).__name__}: {exc})"
            return
        if first:
            recording.header_library = getattr(record, "library", "")
        first = False
        if isinstance(record, Footer):
            recording.complete = True
            return
        if isinstance(record, Attachment) and not _attachment_crc_holds(stream, record):
            recording.damaged = f"attachment {record.name!r} fails its CRC"
            return
        yield record


def _ends_like_a_finished_file(stream: IO[bytes]) -> bool:
    try:
        stream.seek(-len(MCAP_MAGIC), os.SEEK_END)
        return stream.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except (OSError, ValueError):
        return False


def _attachment_crc_holds(stream: IO[bytes], record: Attachment) -> bool:
    """Whether the attachment record just read (it ends where `stream` is) matches its CRC: the
    CRC-32 of its fields before the CRC, 0 for none (the MCAP specification). The mcap reader
    skips that field, so its bytes are read again here; attachments are few and small."""
    end = stream.tell()
    size = 1 + 8 + 8 + 8 + 4 + len(record.name.encode()) + 4 + len(record.media_type.encode()) + 8 + len(record.data) + 4
    try:
        stream.seek(end - size)
        raw = stream.read(size)
    finally:
        stream.seek(end)
    (stored,) = struct.unpack("<I", raw[-4:])
    return stored == 0 or stored == zlib.crc32(raw[9:-4])


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
