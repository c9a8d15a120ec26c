"""Reading a recording: one file, whole or cut short by a kill, or a split recording's set of
files read as one (`read_recording`), or its messages streamed (`iter_messages`).

Reading goes through one sequential pass of `mcap.stream_reader.StreamReader`, which also reads
a file that a killed writer left without a footer; `complete` says whether the footer was there.
A chunk or attachment that fails its CRC, or a record that cannot be read in a file that ends
like a finished one, is damage (`Recording.damaged`), never a recording cut short.
"""
from __future__ import annotations

import json
import math
import os
import struct
import sys
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable, Iterator

from mcap.records import Attachment, Channel as McapChannel, Footer, Message, Metadata, Schema
from mcap.stream_reader import CRCValidationError, StreamReader
from mcap.writer import MCAP0_MAGIC as MCAP_MAGIC

from iotad.node_host import wire
from iotad.recording.mcap_format import (CAN_AT_END, EXPORTED, GAP_TOPIC, MALFORMED_TOPIC, RUN_END, RUN_ERROR, SET_METADATA,
                                         RecordingError, format_version, packb, trace_event_problem, unpackb)


@dataclass(slots=True)  # a recording holds a million of them: ~100 bytes each saved
class RecordedMessage:
    topic: str
    log_time: int
    publish_time: int
    sequence: int
    data: bytes
    # made by the reader, not in the file: a format 2 burst's per-frame events (iotad.recording.bursts);
    # what copies a recording (merge, recover) leaves them out
    derived: bool = False

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
    # made by a reader (this module, a merge), never by hand: `Recording("x.mcap")` would read
    # nothing and answer every question with an empty list, so it is refused (`__post_init__`)
    built: bool = field(default=False, repr=False, compare=False, kw_only=True)

    def __post_init__(self):
        if not self.built:
            raise TypeError(f"Recording({self.path!r}) reads nothing: open a recording with "
                            "iotad.open_recording(path) (or iotad.recording.mcap_reader.read_recording(path))")

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
    def can_at_end(self) -> dict[str, list[dict]]:
        """{bus: the frames it still held when a virtual run ended (`iotad.can_at_end`: ended with
        their burst to come, on the wire, or queued; each with `state`)}; {} where none or unsaid."""
        meta = self.metadata.get(CAN_AT_END)
        try:
            buses = json.loads(meta.get("buses", "{}")) if meta is not None else {}
        except (TypeError, ValueError):
            return {}
        return {bus: [f for f in frames if isinstance(f, dict)] for bus, frames in buses.items()
                if isinstance(frames, list)} if isinstance(buses, dict) else {}

    @property
    def can_at_end_t(self) -> float | None:
        """When the frames of `can_at_end` were under way: the run's end."""
        meta = self.metadata.get(CAN_AT_END)
        try:
            return float(json.loads(meta.get("t", "null"))) if meta is not None else None
        except (TypeError, ValueError):
            return None

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

    def subscribed_to_trace(self, node: str) -> bool:
        """Whether the recorder subscribed to `node`'s trace: a recording that names its `keys`
        may hold only some nodes' (one host's own, or the hub's when a host keeps its traces
        home), where another node's heartbeats may still be; what it was not made to hold is
        judged in the merge of the hosts' recordings, not here."""
        keys = self.info.get("keys")
        if not isinstance(keys, list):
            return True
        trace = wire.trace_key(self.system or "", node)
        return any(isinstance(k, str) and wire.keyexpr_matches(k, trace) for k in keys)

    @property
    def format_version(self) -> int:
        """The recording format it states (`iotad.recording` metadata "format"); 1 where it states none."""
        return format_version(self.info)

    def trace(self, node: str | None = None, starts: bool = False, derived: bool = True) -> list[dict]:
        """Trace events (from `@trace` keys) of one node or of all, in recorded order; the
        engine-start records (kind `start`) only with `starts`. A format 2 bus's bursts come with
        the per-frame events they hold (`iotad.recording.bursts`) unless `derived` is False: a
        node's own check and replay take its events as it fired them."""
        out = []
        for message in self.messages:
            if not message.topic.endswith("/" + wire.TRACE):
                continue
            if not derived and message.derived:
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
                if message.derived:
                    event["derived"] = True  # read out of a burst (iotad.recording.bursts)
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
        after the new process was spawned). A process restarted while the recorder could not hear
        it (its host cut off), whose start record and first events are not here, gets one made
        from the recorder's note of it (`wire.restart_note`, marked `"from": "recorder"`), before
        the first event heard of it, which carries the gap: the process before is judged up to
        its last event heard, the new one from its own start, never one as the other."""
        # the node's events as it fired them: a format 2 bus's bursts, not the frames read out of them
        events = [e for e in self.trace(node, starts=True) if not e.get("derived")]
        restarts = []
        for gap in self.trace_gaps(node):
            # the first event heard after the gap carries it: a checker stops there (positions
            # are those of `trace`, before the start records go in below)
            position = gap.pop("position")
            events[position]["missed"] = gap
            if isinstance(gap.get("process"), dict):
                restarts.append((position, gap))
        starts = [e for e in events if e.get("kind") == wire.START_KIND]
        value = starts[0].get("value") if starts else None
        if not isinstance(value, dict) or not isinstance(value.get("wall"), (int, float)):
            return events  # an in-process recording, or nothing to anchor the launcher's times on
        offset = float(value["wall"]) - float(starts[0]["t"])
        recorded = {e["value"].get("pid") for e in starts if isinstance(e.get("value"), dict)}
        for position, gap in reversed(restarts):
            # a process whose start record was not heard (restarted while its host was cut off):
            # its start record made from the recorder's note, so that it is judged as a new run
            process = gap["process"]
            pid, started = process.get("pid"), process.get("started_ns")
            if pid in recorded or not isinstance(started, int):
                del events[position]["missed"]  # its start is here after all (a merged file)
                continue
            recorded.add(pid)
            t = started / 1e9 - offset
            gap["why"] = (f"its process was restarted unheard: pid {pid} started at t={t:.6g}, and its start "
                          f"and first events were not heard; " + gap["why"])
            events.insert(position, {"t": t, "iota": starts[0].get("iota", node), "action": starts[0].get("action", "@start"),
                                     "index": None, "kind": wire.START_KIND, "node": node,
                                     "value": {"wall": started / 1e9, "pid": pid, "from": "recorder"}})
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

    def trace_gaps(self, node: str) -> list[dict]:
        """Where `node`'s trace misses events that this recording never heard: the recorder's
        sequence gaps on the node's `@trace` key (a host cut off from the recorder's for longer
        than zenoh's lease, whose events were sent into closed links; a recorder that fell
        behind), each placed in the trace. In trace order: {"position": the index, in
        `trace(node, starts=True)`, of the first event heard after the gap, "missing": how many
        events it lacks, "from_t" / "to_t": the `t` of the events heard either side of it,
        "log_ns": when the recorder noticed it, "why": what the recording says of it, and for a
        new process whose start was not heard, "process": its pid and started_ns}; positions
        count the node's own events, not those read out of a format 2 burst. A merged
        recording keeps only the gaps that no host's file filled."""
        noted = []
        for message in self.messages:
            if message.topic != GAP_TOPIC:
                continue
            try:
                gap = message.value
            except RecordingError:
                continue
            key = gap.get("key") if isinstance(gap, dict) else None
            parsed = wire.parse_key(key) if isinstance(key, str) else None
            if parsed is not None and parsed[1] == node and parsed[2] == wire.TRACE \
                    and isinstance(gap.get("got"), int) and isinstance(gap.get("expected"), int):
                noted.append((message.log_time, key, gap))
        if not noted:
            return []
        out = []
        keys = {key for _, key, _ in noted}
        on_key: dict[str, list[RecordedMessage]] = {key: [] for key in keys}
        for message in self.messages:
            if message.topic in keys and not message.derived:  # positions are in the node's own events
                on_key[message.topic].append(message)
        # per key: where its sequence numbers jump, by the number jumped to (MCAP keeps 32 bits)
        jumps_to: dict[str, dict[int, list[int]]] = {}
        for key, messages in on_key.items():
            found = jumps_to[key] = {}
            for k in range(1, len(messages)):
                if messages[k].sequence != (messages[k - 1].sequence + 1) & 0xFFFFFFFF:
                    found.setdefault(messages[k].sequence, []).append(k)
        for log_ns, key, gap in noted:
            messages = on_key[key]
            process = gap.get("process")
            if isinstance(process, dict):
                # a new process (`wire.restart_note`): its first event heard, which may follow the
                # one before with no jump (both number from 0); received with the note
                got = gap["got"] & 0xFFFFFFFF
                heard = [k for k in range(1, len(messages)) if messages[k].sequence == got]
                at = next((k for k in heard if messages[k].log_time == log_ns),
                          next((k for k in heard if messages[k].log_time >= log_ns), None))
                if at is None:
                    continue
            else:
                # the message whose sequence number jumped to `got`: the one the recorder noticed it
                # on (its receipt time), else the first (a merge moves receipt times onto the hub's clock)
                jumps = jumps_to[key].get(gap["got"] & 0xFFFFFFFF)
                if not jumps:
                    continue
                at = next((k for k in jumps if messages[k].log_time == log_ns), jumps[0])
            try:
                times = [messages[k].value.get("t") for k in (at - 1, at)]
            except (RecordingError, AttributeError):
                continue  # no trace events: `trace` names the damage
            if all(isinstance(t, (int, float)) and not isinstance(t, bool) for t in times):
                out.append({"position": at, "missing": gap["got"] - gap["expected"], "from_t": float(times[0]),
                            "to_t": float(times[1]), "log_ns": log_ns,
                            **({"process": dict(process)} if isinstance(process, dict) else {}),
                            **({"why": gap["why"]} if isinstance(gap.get("why"), str) else {})})
        launcher = self.launcher_events() if out else []
        for gap in out:  # a merge's note says why (a recorder down between two files); else the launcher's events
            gap.setdefault("why", self._why_missed(node, gap["from_t"], gap["to_t"], launcher))
        return sorted(out, key=lambda gap: gap["position"])

    def _why_missed(self, node: str, from_t: float, to_t: float, events: list[dict]) -> str:
        """Why a trace misses events between `from_t` and `to_t` (spec units, the node's clock), as
        the launcher's `events` tell: its host lost (a `down` event naming the host, and
        `host_back` when it came back), or else the recorder's word only."""
        origin = (self.specs.get(node) or {}).get("origin")
        if not isinstance(origin, (int, float)):
            return "its sequence numbers jumped: the recorder never got them"
        unit = self.time_unit

        def t_of(event: dict) -> float | None:
            ns = event.get("t_ns")
            return (ns / 1e9 - origin) / unit if isinstance(ns, int) else None

        for down in events:
            t = t_of(down)
            host = down.get("host")
            if down.get("event") != "down" or down.get("node") != node or down.get("pid") is not None \
                    or not isinstance(host, str) or t is None or not from_t <= t <= to_t:
                continue
            back = next((b for b in events if b.get("event") == "host_back" and b.get("host") == host
                         and (t_of(b) or -math.inf) >= t), None)
            return (f"host {host} lost: its nodes down at t={t:.6g}, "
                    + (f"back at t={t_of(back):.6g}" if back is not None else "not back by the recording's end"))
        return "its sequence numbers jumped: the recorder never got them"

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

    def clock_offsets(self) -> dict[str, list]:
        """host -> its clock's offset to the hub's and bound over the run, as (t, offset, bound)
        in time order (`iotad.recording.clock_offsets`); empty for a system on one host."""
        from iotad.recording.clock_offsets import clock_offsets
        return clock_offsets(self)

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
    if recording.format_version >= 2:
        from iotad.recording.bursts import expand
        expand(recording, RecordedMessage)  # a burst's frames read as format 1's events, each frame on its own
    return recording


PROGRESS_EVERY = 2.0  # s between `progress` calls while a file is read


def _read_file(path: Path, progress: Callable[[str, int, int], None] | None = None) -> Recording:
    """`progress(file, bytes read, bytes in all)`, if given, every PROGRESS_EVERY s of reading."""
    recording = Recording(str(path), built=True)
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
        scratch = Recording(str(file), built=True)
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
    recording = Recording(str(path), built=True)
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
    out = Recording(str(path), built=True, complete=index.complete, truncated_reason=index.truncated_reason,
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
