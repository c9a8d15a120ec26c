"""Joining the recordings of one run's hosts into one (`iotad merge`): every message once, ordered by
the hub's clock, with each stretch that a host's events are missing from a recording marked.

A system spread over hosts is recorded by each host's launcher on its own machine (docs/hosts.md,
"The recording"): the hub's file holds what reached the hub, a host's file what its own nodes did,
also while the hub was out of reach. Each file's metadata says whose it is (`iotad.recording`
`run`: host, hub or not, the run's origin, the host's clock offset to the hub).

- **Order.** A host file's log times are on the host's clock: they are moved onto the hub's by the
  host's offset (`iotad.recording.recorded_clock`), then every message is ordered by that time.
  Publish times stay as the sender stamped them (the delivery check reads them on the sender's
  clock, with the sender's corrected origin), and so do the trace events' `t` (already on the hub's
  timeline: each host's origin was corrected at start).
- **Once.** A message that two recorders wrote (the same topic, sender's time, sequence number and
  bytes; a heartbeat, which carries no sender's time, by its bytes) is kept once: the copy of the host that owns it (the host of the node whose key it is, or
  of the launcher that sent it), whose file has its node's events in the order they happened.
- **Gaps.** A marked gap (`MERGE_GAP_TOPIC`, one message each, and the list in metadata
  `iotad.merge`) names the host and the interval (hub clock, and seconds of the run): events of a
  host's nodes that the hub's recording lacks (the host was cut off from the hub), events of a
  host's nodes outside its own recording (it began late or ended early), a host recording cut
  short, and a host of the system file whose recording was not given. A recorder's own sequence
  gap is kept only where no other file filled it.
- **Several files of one host.** A host's recording, the hub's included, may be in several
  files: its recorder was restarted (`split_1.mcap`, `split.arm_1.mcap`) or its launcher
  (`split.arm-2.mcap`). They are one recording, ordered by their first message; the stretch
  between a killed recorder's file and its successor's is a gap that says so, with how the old
  recorder ended (the launcher's `recorder` event `restarted`, which the new file holds).
"""
from __future__ import annotations

import bisect
import json
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable

from mcap.records import Channel as McapChannel, Schema

from iotad.node_host import wire
from iotad.recording.mcap_format import (GAP_SCHEMA, GAP_TOPIC, MERGE_GAP_SCHEMA, MERGE_GAP_TOPIC, MESSAGE_ENCODING,
                                         SCHEMA_ENCODING, RecordingError, packb)
from iotad.recording.mcap_reader import RecordedMessage, Recording
from iotad.recording.recorded_clock import ToHub, offsets, run_info

MERGE_METADATA = "iotad.merge"
ORIGIN_TOLERANCE = 1e-6  # s: two files whose runs began further apart are of different runs
# ns: how far outside the stretch between a host's two files another file's copy of an event may
# lie (the hub's receipt of it, against the host's clock moved onto the hub's)
HELD_SLACK = 500_000_000


class MergeError(RecordingError):
    """Recordings that cannot be joined (different systems or runs, a file twice...): one line."""


@dataclass
class Source:
    """One recording given to the merge, and what it says of itself."""

    path: str
    recording: Recording
    host: str | None
    hub: bool
    to_hub: ToHub
    kept: int = 0

    @property
    def name(self) -> str:
        return Path(self.path).name

    def who(self) -> str:
        return f"the hub's ({self.host})" if self.hub else f"host {self.host}'s"


@dataclass
class Merged:
    """What a merge wrote: the recording (not yet on disk), its gaps and a line per source."""

    recording: Recording
    gaps: list[dict] = field(default_factory=list)
    sources: list[Source] = field(default_factory=list)
    dropped: int = 0       # copies of a message another file also held
    recorder_gaps: int = 0  # recorders' sequence gaps no other file filled

    def lines(self) -> list[str]:
        out = []
        for source in self.sources:
            measured = source.to_hub.measured
            clock = "the hub's clock" if source.hub else (
                f"clock offset {measured[0].offset * 1e3:+.3f} ms +-{measured[0].bound * 1e3:.3f} ms"
                + (f" ({len(measured)} measurements)" if len(measured) > 1 else "") if measured else
                "no clock offset recorded: taken as the hub's")
            out.append(f"  {source.name}: {source.who()} recording, {len(source.recording.messages)} messages, "
                       f"{source.kept} kept; {clock}")
        out.append(f"  {len(self.recording.messages)} messages, {self.dropped} copies held twice kept once, "
                   f"{self.recorder_gaps} recorder sequence gap(s) left")
        out.append(f"  gaps: {len(self.gaps)}")
        out += [f"    {describe_gap(gap)}" for gap in self.gaps]
        return out


def describe_gap(gap: dict) -> str:
    """One line for a marked gap."""
    return (f"host {gap.get('host')}: t={gap.get('from_t', 0):.3f}..{gap.get('to_t', 0):.3f} s of the run: "
            f"{gap.get('reason', '')}")


def merge(paths: Iterable[str | Path], read: Any = None) -> Merged:
    """The recordings at `paths` joined as one (write it with `write_merged`). `read(path)` reads
    one (default `mcap_reader.read_recording`). Raises `MergeError` for files that do not belong
    together, `RecordingError` for a file that is no recording."""
    if read is None:
        from iotad.recording.mcap_reader import read_recording as read
    paths = [str(p) for p in paths]
    if len(paths) < 2:
        raise MergeError("merge joins the recordings of two hosts or more: give every host's file")
    if len({Path(p).resolve() for p in paths}) < len(paths):
        raise MergeError("a file is given twice: give each host's recording once")
    sources = [_source(path, read(path)) for path in paths]
    _same_run(sources)
    # the hub's first (its copy wins where no host owns one), each host's files in the order written
    sources.sort(key=lambda s: (not s.hub, _first_time(s)))
    return _Join(sources).run()


def _source(path: str, recording: Recording) -> Source:
    info = recording.info
    if info.get("clock") == "virtual":
        raise MergeError(f"{path}: a virtual run's recording; only the recordings of one real-time run's hosts merge")
    if "merged" in info:
        raise MergeError(f"{path}: already a merged recording (of {', '.join(map(str, info['merged']))}); "
                         "merge the hosts' own recordings")
    run = run_info(recording)
    if not isinstance(run.get("origin"), (int, float)) or not run.get("host"):
        raise MergeError(f"{path}: not a host's recording of a run spread over hosts (its metadata names no host "
                         "and run origin: 'iotad run -o' of a system with [hosts] writes one per host)")
    return Source(path, recording, str(run["host"]), bool(run.get("hub")), ToHub(offsets(recording)))


def _same_run(sources: list[Source]) -> None:
    first = sources[0]
    for other in sources[1:]:
        a, b = first.recording, other.recording
        if a.system != b.system:
            raise MergeError(f"{first.path} records system {a.system!r} and {other.path} system {b.system!r}: "
                             "recordings of different systems do not merge")
        if a.system_text is not None and b.system_text is not None and a.system_text != b.system_text:
            raise MergeError(f"{first.path} and {other.path} hold different system files of {a.system!r}: "
                             "recordings of different runs do not merge")
        origins = run_info(a)["origin"], run_info(b)["origin"]
        if abs(origins[0] - origins[1]) > ORIGIN_TOLERANCE:
            raise MergeError(f"{first.path} and {other.path} are recordings of different runs of {a.system!r} "
                             f"(they began at {origins[0]:.6f} and {origins[1]:.6f} on the hub's clock)")
    # several files of one host, the hub included, are one recording that its recorder's restart
    # (kill -9, frozen) or its launcher's split: `_host_gaps` names the stretch between them


def _first_time(source: Source) -> int:
    messages = source.recording.messages
    return source.to_hub(messages[0].log_time) if messages else 1 << 64


class _Join:
    """One merge, in passes over the sources' messages."""

    def __init__(self, sources: list[Source]):
        self.sources = sources
        self._subscribed: dict[str, bool] = {}  # topic -> whether the hub's recorder subscribed to it
        base = sources[0].recording
        self.base = base
        self.origin = float(run_info(base)["origin"])
        self.hosts_of_nodes = _node_hosts(base)
        self.hub_host = next((s.host for s in sources if s.hub), None) or _hub_host(base)
        self._owners: dict[str, str | None] = {}

    # ------------------------------------------------------------- ownership
    def owner(self, message: RecordedMessage) -> str | None:
        """The host whose events `message` is: a node's key -> the node's host; a launcher event ->
        the host that sent it; anything else -> the hub's."""
        topic = message.topic
        if topic.endswith("/" + wire.LAUNCHER):
            try:
                value = message.value
            except RecordingError:
                value = None
            host = value.get("host") if isinstance(value, dict) else None
            return host if isinstance(host, str) else self.hub_host
        owner = self._owners.get(topic, False)
        if owner is False:
            owner = self.hub_host
            parsed = wire.parse_key(topic)
            if parsed is not None and parsed[1]:
                path = parsed[1]
                while path not in self.hosts_of_nodes and "/" in path:
                    path = path.rsplit("/", 1)[0]
                owner = self.hosts_of_nodes.get(path) or self.hub_host
            self._owners[topic] = owner
        return owner

    # ------------------------------------------------------------- the merge
    def run(self) -> Merged:
        chosen: dict[tuple, tuple[int, int, int, RecordedMessage]] = {}
        held: list[set[tuple]] = []      # per source: the keys of its messages
        recorder_gaps: list[tuple[int, dict]] = []
        dropped = 0
        for si, source in enumerate(self.sources):
            keys: set[tuple] = set()
            seen: Counter = Counter()
            to_hub = source.to_hub
            for position, message in enumerate(source.recording.messages):
                if message.derived:  # a burst's frames as the reader expanded them: the burst is merged
                    continue
                if message.topic == GAP_TOPIC:
                    try:
                        gap = message.value
                    except RecordingError:
                        continue
                    if isinstance(gap, dict):
                        recorder_gaps.append((to_hub(message.log_time), gap))
                    continue
                # a sample without the sender's attachment (a heartbeat) has the receipt as its
                # publish time, which differs between recorders: its bytes name it (a beat's `t`)
                sent = None if message.publish_time == message.log_time else message.publish_time
                base = (message.topic, sent, message.sequence, message.data)
                key = (*base, seen[base])  # the n-th copy in one file matches the n-th in another
                seen[base] += 1
                keys.add(key)
                entry = chosen.get(key)
                if entry is None:
                    chosen[key] = (to_hub(message.log_time), si, position, message)
                    continue
                dropped += 1
                if self.owner(message) == source.host and self.owner(entry[3]) != self.sources[entry[1]].host:
                    chosen[key] = (to_hub(message.log_time), si, position, message)  # the owner's copy
            held.append(keys)
        ordered = sorted(chosen.values(), key=lambda e: (e[0], e[1], e[2]))
        for _, si, _, _ in ordered:
            self.sources[si].kept += 1
        messages = [RecordedMessage(m.topic, t, m.publish_time, m.sequence, m.data) for t, _, _, m in ordered]
        unheard = self._unheard_between_files(messages)
        gaps = self._host_gaps(chosen, held, ordered, unheard)
        left = self._recorder_gaps(recorder_gaps, messages) + [note for notes in unheard.values() for note in notes]
        left.sort(key=lambda item: item[0])
        recording = self._recording(messages, gaps, left)
        return Merged(recording, gaps, self.sources, dropped, len(left))

    def _traced(self, message: RecordedMessage) -> bool:
        return message.topic.endswith("/" + wire.TRACE)

    def _unheard_between_files(self, messages: list[RecordedMessage]) -> dict[str, list[tuple[int, dict]]]:
        """The trace events that no recording holds because a host's recorder was down between two
        of its files (killed, then restarted: its successor cannot know what it missed, so it
        noted nothing): per later file's name, a sequence-gap note (GAP_SCHEMA) for each of the
        host's nodes' trace keys whose numbers jump from one file's last to the next file's first,
        at that first message. A jump down is a new process (its numbers begin again), not a gap.
        A number counts as held only where another file holds it in the stretch between the two
        (on the hub's clock, within HELD_SLACK): an earlier process of the same node numbered its
        events from 0 too, and its numbers fill no later process's gap."""
        merged: dict[str, list[tuple[int, int]]] = {}  # key -> (hub time, sequence), in time order
        for message in messages:
            if self._traced(message):
                merged.setdefault(message.topic, []).append((message.log_time, message.sequence))
        by_host: dict[str | None, list[Source]] = {}
        for source in self.sources:
            by_host.setdefault(source.host, []).append(source)
        out: dict[str, list[tuple[int, dict]]] = {}
        for host, sources in by_host.items():
            if len(sources) < 2:
                continue
            ends = []  # per file in the order written: {key: (first message, last message)}
            for source in sorted(sources, key=_first_time):
                ends.append((source, {}))
                for message in source.recording.messages:
                    if not message.derived and self._traced(message) and self.owner(message) == host:
                        first_last = ends[-1][1].get(message.topic)
                        ends[-1][1][message.topic] = (first_last[0] if first_last else message, message)
            for (before, old), (after, new) in zip(ends, ends[1:]):
                for key, (first, _) in new.items():
                    last = old.get(key, (None, None))[1]
                    if last is None or first.sequence <= last.sequence + 1:
                        continue
                    times = merged.get(key, [])
                    low = bisect.bisect_left(times, (before.to_hub(last.log_time) - HELD_SLACK, -1))
                    high = bisect.bisect_right(times, (after.to_hub(first.log_time) + HELD_SLACK, 1 << 64))
                    there = {q for _, q in times[low:high]}
                    missing = [q for q in range(last.sequence + 1, first.sequence) if q not in there]
                    if missing:
                        out.setdefault(after.name, []).append((after.to_hub(first.log_time), {
                            "key": key, "expected": last.sequence + 1, "got": first.sequence, "missing": len(missing),
                            "why": f"its host's recorder was down between {before.name} and {after.name}"}))
        return out

    def _hub_subscribed(self, topic: str) -> bool:
        """Whether the hub's recorder subscribed to `topic` (its `keys`; a file that names none
        subscribed to everything). Asked once per topic."""
        known = self._subscribed
        if topic not in known:
            parsed = wire.parse_key(topic)
            node = parsed[1] if parsed else ""
            known[topic] = any(source.recording.subscribed_to_trace(node) for source in self.sources if source.hub)
        return known[topic]

    def _host_gaps(self, chosen: dict, held: list[set], ordered: list, unheard: dict) -> list[dict]:
        """The marked gaps: where a host's events are missing from the hub's recording or from its
        own (one file, or several when its launcher was started again during the run), and the
        hosts whose recording was not given. `unheard`: `_unheard_between_files`."""
        gaps: list[dict] = []
        hubs = {k for k, s in enumerate(self.sources) if s.hub}
        at_hub = set().union(*(held[k] for k in hubs)) if hubs else set()
        ends = self._recorder_news(chosen)
        start = ordered[0][0] if ordered else 0
        end = ordered[-1][0] if ordered else 0
        by_host: dict[str | None, list[int]] = {}
        for si, source in enumerate(self.sources):
            by_host.setdefault(source.host, []).append(si)
        for host, indices in by_host.items():
            mine = set().union(*(held[si] for si in indices))
            own = sorted((t, key) for key, (t, _, _, m) in chosen.items() if self._traced(m) and self.owner(m) == host)
            if hubs and not hubs & set(indices):
                # events of this host's nodes that its recording holds and the hub's does not,
                # where the hub's was made to hold them (a host that keeps its traces home,
                # `[hosts.NAME] traces = "home"`, sends the hub none: nothing is missing there)
                run: list[int] = []
                for t, key in [*own, (None, None)]:
                    if key is not None and key in mine and key not in at_hub \
                            and self._hub_subscribed(chosen[key][3].topic):
                        run.append(t)
                    elif run:
                        gaps.append(self._gap(host, run[0], run[-1], len(run),
                                              f"{len(run)} event(s) of its nodes did not reach the hub's recording "
                                              "(the host's own recording holds them)"))
                        run = []
            spans = []  # (first, last, source) of each of its files, on the hub's clock
            for si in indices:
                source = self.sources[si]
                times = [source.to_hub(m.log_time) for m in source.recording.messages]
                if times:
                    spans.append((min(times), max(times), source))
                else:
                    gaps.append(self._gap(host, start, end, 0, f"its recording ({source.name}) holds no message"))
            spans.sort(key=lambda span: span[0])
            outside = [t for t, key in own if key not in mine and not any(a <= t <= b for a, b, _ in spans)]
            for k in range(len(spans) + 1):
                low = spans[k - 1][1] if k else -1
                high = spans[k][0] if k < len(spans) else 1 << 64
                here = [t for t in outside if low < t < high]
                after = spans[k - 1] if k else None
                if after is not None and not after[2].recording.complete and k < len(spans) \
                        and (spans[k][2].name in ends["restarted"] or after[2].name in ends["ended"]):
                    # the launcher restarted its recorder, which went on in the next file
                    ended = ends["ended"].get(after[2].name)
                    lost = sum(note["missing"] for _, note in unheard.get(spans[k][2].name, []))
                    gaps.append(self._gap(host, after[1], high, len(here) + lost,
                                          f"its recorder was restarted: {after[2].name} was cut short "
                                          f"({ended or after[2].recording.truncated_reason or 'no footer'}) "
                                          f"at t={after[1] / 1e9 - self.origin:.3f} s, and the recording goes on "
                                          f"in {spans[k][2].name} from t={high / 1e9 - self.origin:.3f} s; "
                                          + (f"{len(here)} event(s) of its nodes in between only other recordings "
                                             "hold" if here else "no other recording holds an event of its nodes "
                                             "in between")
                                          + (f"; {lost} event(s) of its nodes' traces no recording holds (their "
                                             "numbers jump across it)" if lost else "")))
                elif after is not None and not after[2].recording.complete:
                    gaps.append(self._gap(host, after[1], high if k < len(spans) else max(end, after[1]), len(here),
                                          f"its recording ({after[2].name}) was cut short "
                                          f"({after[2].recording.truncated_reason or 'no footer'})"))
                elif here and k == 0:
                    gaps.append(self._gap(host, here[0], spans[0][0], len(here),
                                          f"its recording ({spans[0][2].name}) began after {len(here)} event(s) of "
                                          "its nodes; only other recordings hold them"))
                elif here and k == len(spans):
                    gaps.append(self._gap(host, after[1], here[-1], len(here),
                                          f"its recording ({after[2].name}) ended before {len(here)} event(s) of its "
                                          "nodes; only other recordings hold them"))
                elif here:
                    gaps.append(self._gap(host, here[0], here[-1], len(here),
                                          f"between its recordings {after[2].name} and {spans[k][2].name}: "
                                          f"{len(here)} event(s) of its nodes only other recordings hold"))
        given = {s.host for s in self.sources}
        for host in sorted({h for h in self.hosts_of_nodes.values() if h} - given):
            gaps.append(self._gap(host, start, end, 0, "no recording of this host was given: only what reached "
                                                       "the other recordings is here"))
        gaps.sort(key=lambda g: (g["from_ns"], g["host"]))
        return gaps

    def _recorder_news(self, chosen: dict) -> dict[str, dict[str, str]]:
        """What the launchers said of their recorders (`@launcher` events "recorder", by file
        name): "ended" -> how a file's recorder ended (its exit, as its launcher described it),
        "restarted" -> the files a restarted recorder went on in."""
        news: dict[str, dict[str, str]] = {"ended": {}, "restarted": {}}
        for _, _, _, message in chosen.values():
            if not message.topic.endswith("/" + wire.LAUNCHER):
                continue
            try:
                value = message.value
            except RecordingError:
                continue
            if not isinstance(value, dict) or value.get("event") != "recorder" or not isinstance(value.get("file"), str):
                continue
            name, text = Path(value["file"]).name, str(value.get("message", ""))
            if value.get("code") is not None:
                news["ended"][name] = text.split(";", 1)[0].removeprefix("recorder: ")
            elif "restarted" in text:
                news["restarted"][name] = text
                if isinstance(value.get("after"), str) and value.get("ended"):  # the last one's end, said again
                    news["ended"].setdefault(Path(value["after"]).name, str(value["ended"]))
        return news

    def _gap(self, host: str | None, from_ns: int, to_ns: int, events: int, reason: str) -> dict:
        return {"host": host, "from_ns": int(from_ns), "to_ns": int(to_ns),
                "from_t": from_ns / 1e9 - self.origin, "to_t": to_ns / 1e9 - self.origin,
                "events": events, "reason": reason}

    def _recorder_gaps(self, found: list[tuple[int, dict]], messages: list[RecordedMessage]) -> list[tuple[int, dict]]:
        """The recorders' sequence gaps that no other file filled, each once."""
        keys = {gap.get("key") for _, gap in found}
        sequences: dict[str, set[int]] = {}
        for message in messages:
            if message.topic in keys:
                sequences.setdefault(message.topic, set()).add(message.sequence)
        left, seen = [], set()
        for t, gap in sorted(found, key=lambda item: item[0]):
            try:
                ident = (gap["key"], int(gap["expected"]), int(gap["got"]))
            except (KeyError, TypeError, ValueError):
                continue
            if ident in seen:
                continue
            seen.add(ident)
            if isinstance(gap.get("process"), dict):
                # a new process's first events (wire.restart_note): filled where its start record
                # is here (sequence numbers alone would match the process before it)
                if not self._start_of(messages, ident[0], gap["process"].get("pid")):
                    left.append((t, gap))
                continue
            have = sequences.get(ident[0], set())
            if not all(seq & 0xFFFFFFFF in have for seq in range(ident[1], min(ident[2], ident[1] + 1_000_000))):
                left.append((t, gap))
        return left

    @staticmethod
    def _start_of(messages: list[RecordedMessage], key: str, pid) -> bool:
        """Whether `messages` hold the start record that the process `pid` sent on `key`."""
        for message in messages:
            if message.topic == key and message.sequence == 0:
                try:
                    value = message.value
                except RecordingError:
                    continue
                if isinstance(value, dict) and value.get("kind") == wire.START_KIND \
                        and isinstance(value.get("value"), dict) and value["value"].get("pid") == pid:
                    return True
        return False

    # ------------------------------------------------------------- the file
    def _recording(self, messages: list[RecordedMessage], gaps: list[dict],
                   recorder_gaps: list[tuple[int, dict]]) -> Recording:
        merged = Recording(path="merged", built=True)
        merged.complete = True
        schema_ids: dict[tuple, int] = {}
        topics: dict[str, int] = {}

        def channel(topic: str, schema: Schema | None, encoding: str = MESSAGE_ENCODING) -> None:
            schema_id = 0
            if schema is not None:
                ident = (schema.name, schema.encoding, bytes(schema.data))
                schema_id = schema_ids.get(ident, 0)
                if not schema_id:
                    schema_id = schema_ids[ident] = len(schema_ids) + 1
                    merged.schemas[schema_id] = Schema(schema_id, schema.data, schema.encoding, schema.name)
            channel_id = topics[topic] = len(topics) + 1
            merged.channels[channel_id] = McapChannel(channel_id, topic, encoding, {}, schema_id)

        for source in self.sources:
            recording = source.recording
            for mcap_channel in recording.channels.values():
                if mcap_channel.topic not in topics and mcap_channel.topic not in (GAP_TOPIC, MERGE_GAP_TOPIC):
                    channel(mcap_channel.topic, recording.schemas.get(mcap_channel.schema_id),
                            mcap_channel.message_encoding)
        extra: list[RecordedMessage] = []
        if recorder_gaps:
            channel(GAP_TOPIC, _schema("iotad.gap", GAP_SCHEMA))
            extra += [RecordedMessage(GAP_TOPIC, t, t, k, packb(gap)) for k, (t, gap) in enumerate(recorder_gaps)]
        if gaps:
            channel(MERGE_GAP_TOPIC, _schema("iotad.merge_gap", MERGE_GAP_SCHEMA))
            extra += [RecordedMessage(MERGE_GAP_TOPIC, g["from_ns"], g["from_ns"], k, packb(g))
                      for k, g in enumerate(gaps)]
        merged.messages = sorted(messages + extra, key=lambda m: m.log_time) if extra else messages
        merged.attachments = self._attachments()
        merged.metadata = self._metadata(gaps, recorder_gaps, messages)
        return merged

    def _attachments(self) -> list:
        """The system file once, and each node's spec from the recording of the node's own host."""
        chosen: dict[str, Any] = {}
        for source in self.sources:  # the hub's first
            for attachment in source.recording.attachments:
                name = attachment.name
                node = name[5:-5] if name.startswith("spec/") and name.endswith(".json") else None
                owned = node is not None and self.hosts_of_nodes.get(node) == source.host
                if name not in chosen or owned:
                    chosen[name] = attachment
        return list(chosen.values())

    def _metadata(self, gaps: list[dict], recorder_gaps: list, messages: list[RecordedMessage]) -> dict:
        base = self.base
        info = dict(base.metadata.get("iotad.recording", {}))
        hosts = [s.host for s in self.sources]
        info["writer"] = "iotad merge"
        info["merged"] = json.dumps([s.name for s in self.sources])
        info["run"] = json.dumps({"origin": self.origin, "hosts": hosts, "hub_host": self.hub_host})
        # what the merged recording was made to hold: what any of its files' recorders subscribed
        # to (the hub's alone leaves out a host that keeps its traces home; check reads this)
        keys = [source.recording.info.get("keys") for source in self.sources]
        if all(isinstance(k, list) for k in keys):
            info["keys"] = json.dumps(sorted({key for k in keys for key in k if isinstance(key, str)}))
        else:
            info.pop("keys", None)
        if messages:
            info["started_ns"] = json.dumps(messages[0].log_time)
        missing = sum(int(g.get("missing", 0) or 0) for _, g in recorder_gaps if isinstance(g, dict))
        merge_info = {"files": [{"file": s.name, "host": s.host, "hub": s.hub, "messages": len(s.recording.messages),
                                 "kept": s.kept, "complete": s.recording.complete,
                                 "offsets": [[o.since_ns, o.offset, o.bound] for o in s.to_hub.measured]}
                                for s in self.sources],
                      "gaps": gaps}
        return {"iotad.recording": info,
                "iotad.gaps": {"count": json.dumps(len(recorder_gaps)), "missing": json.dumps(missing)},
                MERGE_METADATA: {k: json.dumps(v) for k, v in merge_info.items()}}


def _schema(name: str, schema: dict) -> Schema:
    return Schema(0, json.dumps(schema, sort_keys=True).encode(), SCHEMA_ENCODING, name)


def _node_hosts(recording: Recording) -> dict[str, str | None]:
    """node path -> its host, as the recorded system file says (bus loggers included)."""
    from iotad.launcher.system.declaration import SystemFileError
    from iotad.recording.recorded_system import recorded_declaration

    try:
        declaration = recorded_declaration(recording)
    except SystemFileError:
        declaration = None
    if declaration is None:
        return {}
    return {name: node.host for name, node in declaration.nodes.items()}


def _hub_host(recording: Recording) -> str | None:
    from iotad.launcher.system.declaration import SystemFileError
    from iotad.recording.recorded_system import recorded_declaration

    try:
        declaration = recorded_declaration(recording)
    except SystemFileError:
        return None
    return getattr(declaration, "hub_host", None) if declaration is not None else None


def merged_gaps(recording: Recording) -> list[dict]:
    """The gaps a merged recording marks ([] for any other recording)."""
    out = []
    for message in recording.messages:
        if message.topic == MERGE_GAP_TOPIC:
            try:
                value = message.value
            except RecordingError:
                continue
            if isinstance(value, dict):
                out.append(value)
    return out


def write_merged(merged: Merged, output: str | Path) -> int:
    """Write `merged` to `output` (a complete MCAP file); returns the messages written."""
    from iotad.recording.mcap_sink import copy_recording

    return copy_recording(merged.recording, output)


__all__ = ["MERGE_METADATA", "MergeError", "Merged", "Source", "describe_gap", "merge", "merged_gaps", "write_merged"]
