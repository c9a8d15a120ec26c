"""The iotad recording format: MCAP profile, topics, message encoding, JSON schemas, metadata names.

One MCAP channel per key (`iota/<system>/<path>/<channel>[/<index>]`, `.../@trace`,
`iota/<system>/@launcher`), message encoding `msgpack` with a `jsonschema` schema per type.
A recording carries what replay and check need and nothing else must be found:

- attachment `spec/<path>.json` per node: the node's `@spec` answer (source, text, params,
  channels), so the node can be rebuilt from the recording alone (`iotad.esprit.stored_spec`);
- attachment `system.toml` (or `system.json` for an in-process run): the system file;
- metadata `iotad.recording`: system name, time unit, clock origin, who wrote it;
- messages on `@recorder/gaps`: sequence gaps the recorder saw (they survive a kill),
  and metadata `iotad.gaps` with their total at a clean finish;
- in a recording joined from several hosts' (`iotad merge`, `iotad.recording.merge`): messages on
  `@merge/gaps`, each a stretch where a host's events are missing from a recording (host,
  interval), and metadata `iotad.merge` (the files, their clock offsets, the gaps);
- messages on `@recorder/malformed` (only if any): what came on a `@trace` key that was neither
  an event nor a burst of events, or an element of a burst that was no event (not a map, or a
  map without a finite `t` and string `kind` and `action`: `trace_event_problem`), and an
  `@launcher` or `@heartbeat` payload that was no msgpack map. None of them is written on its
  own key, where every reader takes what it finds for an event.

Metadata `iotad.recording` states the format version (`format`: "iotad-mcap/2"; a file without
it is format 1). In format 2 a modelled CAN bus's `burst` output holds the frames it carried
(`iotad.can.burst_bus`) where format 1 had an `rx` output per frame and receiver and a `frames`
log per frame; readers expand each burst into those events (`iotad.recording.bursts`).

Every message on a `@trace` channel is one trace event, whether the node sent it alone or in a
burst (the recorder splits bursts). Writing: `mcap_sink`, `engine_sink`; reading: `mcap_reader`;
file names: `iotad.launcher.run.recording_paths`.
"""
from __future__ import annotations

import math
from typing import Any

import msgpack

from iotad.kernel.types import to_plain

MESSAGE_ENCODING = "msgpack"
SCHEMA_ENCODING = "jsonschema"
PROFILE = "iotad"
GAP_TOPIC = "@recorder/gaps"
MALFORMED_TOPIC = "@recorder/malformed"  # what a recorder got on @trace that is no event (nor burst), etc.
MERGE_GAP_TOPIC = "@merge/gaps"  # in a merged recording (`iotad merge`): where a host's events are missing
# The recording's format version, in its `iotad.recording` metadata ("format"). Format 2: a
# modelled CAN bus records the frames it carried in bursts (`iotad.can.burst_bus`), which readers
# expand into format 1's per-frame events (`iotad.recording.bursts`). A file without the field
# is format 1.
FORMAT_VERSION = 2
FORMAT_PREFIX = "iotad-mcap/"
FORMAT = f"{FORMAT_PREFIX}{FORMAT_VERSION}"


def format_name(version: int) -> str:
    return f"{FORMAT_PREFIX}{version}"


def format_version(info: dict) -> int:
    """The format version an `iotad.recording` metadata map states (1 where it states none)."""
    stated = info.get("format")
    if isinstance(stated, str) and stated.startswith(FORMAT_PREFIX):
        try:
            return int(stated[len(FORMAT_PREFIX):])
        except ValueError:
            return 1
    return 1
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
                   "missing": {"type": "integer"},
                   # a new process of a node, its first `got` trace events not heard (wire.restart_note)
                   "after": {"type": "integer"}, "process": {"type": "object"},
                   # a merge's note of events no file holds (a recorder down between two files)
                   "why": {"type": "string"}}}
MERGE_GAP_SCHEMA = {
    "title": "iotad host gap of a merged recording", "type": "object",
    "properties": {"host": {"type": ["string", "null"]}, "from_ns": {"type": "integer"}, "to_ns": {"type": "integer"},
                   "from_t": {"type": "number"}, "to_t": {"type": "number"}, "events": {"type": "integer"},
                   "reason": {"type": "string"}}}
MALFORMED_SCHEMA = {
    "title": "iotad malformed trace sample", "type": "object",
    "properties": {"key": {"type": "string"}, "seq": {"type": "integer"}, "message": {"type": "string"},
                   "data": {}}}
LAUNCHER_SCHEMA = {"title": "iotad launcher event", "type": "object"}
HEARTBEAT_SCHEMA = {"title": "iotad heartbeat", "type": "object",
                    "properties": {"t": {"type": "number"}, "firings": {"type": "integer"},
                                   "queue": {"type": "integer"}}}
PERMISSIVE_SCHEMA: dict = {"title": "any msgpack value"}  # unknown type: anything goes


# MCAP log and publish times are unsigned 64-bit nanoseconds from the origin.
MAX_RECORDED_SECONDS = ((1 << 64) - 1) / 1e9
# Metadata a virtual run writes when an error of iotad's own broke it off: {"error", "t"}.
RUN_ERROR = "iotad.run_error"
# metadata of a virtual run that ended as it should: the time its engine ran to (spec units). Every
# node ran until then, so a window that closed before it and never fired is a deadline missed.
RUN_END = "iotad.run_end"
# metadata of a virtual run that ended as it should, for each modelled bus (`BurstCanBus`) that still
# held frames: {"t": the end, "buses": {bus: [frames as a burst holds them, plus "state": "ended",
# "on the wire" or "queued"]}}: the frames cut at the end, which no burst records
CAN_AT_END = "iotad.can_at_end"
EXPORTED = "iotad.exported"  # metadata of a JSON copy (`iotad export --json`): which file it copies


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


def json_default(value: Any) -> Any:
    """`json.dumps(default=...)` for specs and metadata: plain data as it is, anything else its repr."""
    plain = to_plain(value)
    if plain is value:
        return repr(value)
    return plain
