"""The delivery check's accounts of a recording: one pass reads what each sender claims (its
trace's outputs), what each receiver took or refused (its inputs and violations), when each node
ran, the messages on each key and the recorder's sequence gaps; the checks
(`delivery_messages.py`, `delivery_can.py`) read these frozen accounts and write report rows.

A long recording holds hundreds of thousands of messages, and the check reads them all: what it
keeps of each is small. A value is kept packed (msgpack), as a range of the bytes of the message
that holds it (which the recording holds anyway: nothing is copied), and decoded only to compare
two that differ in their bytes (`same_value`) or to print one, never held decoded for the whole
check. The records are slotted (no dict per object) for the same reason.
"""
from __future__ import annotations

import json
import math
import sys
from array import array
from dataclasses import dataclass, field
from typing import Any, Callable

from iotad.node_host import wire
from iotad.recording.clock_offsets import widenings
from iotad.recording.mcap_format import packb, unpackb
from iotad.recording.mcap_reader import RecordedMessage, Recording
from iotad.recording.recorded_system import RecordedSystem
from iotad.recording.values import values_equal

GRACE = 0.1  # seconds: longer than any delivery seen here (~1 ms, tens under load) by far
MASK = 0xFFFFFFFF  # MCAP keeps 32 bits of a sequence number
MISTIMED = 1.0  # s: a receipt this near a message of its value that nothing took is that message, mistimed
CAN_TX, CAN_RX = "can_tx", "can_rx"
_UNDECODABLE = "<undecodable {} bytes>"


class Packed:
    """A record whose value is `data[start:end]`, packed."""

    __slots__ = ()

    @property
    def packed(self) -> bytes:
        return self.data[self.start:self.end]

    @property
    def value(self) -> Any:
        return unpackb(self.packed)


def _packed_in(data: bytes, value: Any) -> tuple[bytes, int, int]:
    """(bytes, start, end): where the bytes of `value` packed are, in `data` (a decoded event's
    own bytes, which hold its value packed the same way when the event was written with msgpack,
    as an engine's and a node host's are: any place with the same bytes will do), or, where
    they are not, in bytes of their own."""
    packed = packb(value)
    start = data.find(packed)
    if start < 0:
        return packed, 0, len(packed)
    return data, start, start + len(packed)


@dataclass(slots=True)
class Event(Packed):
    """What the check needs of one trace event: an input, a violation or a can_tx output."""

    t: float
    kind: str
    action: str
    index: int | None
    key: str | None                 # the key it was published or received on, if it names one
    ident: tuple[int, int] | None   # (seq, send_ns), if the event says
    iota: Any
    data: bytes                     # its value packed: data[start:end]
    start: int
    end: int
    raw: dict | None = None         # a violation's whole event: its value says what was refused


@dataclass(slots=True)
class Sent(Packed):
    node: str
    key: str
    t: float
    data: bytes                     # its value packed: data[start:end]
    start: int
    end: int
    ident: tuple[int, int] | None   # (seq, send_ns) as published, if the event says
    ordinal: int = 0                # its place among the sender's claims on the key

    @property
    def label(self) -> str:
        """How a report names the message: by its sequence number, else by its place."""
        return f"#{self.ident[0]}" if self.ident else f"output {self.ordinal}"


@dataclass(slots=True)
class Got(Packed):
    node: str
    key: str | None
    t: float
    data: bytes                     # its value packed: data[start:end]
    start: int
    end: int
    ident: tuple[int, int] | None
    action: str
    index: int | None


@dataclass(slots=True)
class OnWire:
    """A message on a key, as recorded (made for one key at a time, while it is checked)."""

    key: str
    t: float | None    # node clock, when it can be told (virtual time; a sender's origin)
    message: RecordedMessage
    ident: tuple[int, int]

    @property
    def packed(self) -> bytes:
        return self.message.data

    @property
    def value(self) -> Any:
        try:
            return self.message.value
        except Exception:  # noqa: BLE001 - bytes that are no msgpack: a value no one sent
            return _UNDECODABLE.format(len(self.message.data))


def same_value(a: Any, b: Any) -> bool:
    """`values_equal` of two records' values (each holds its value packed): the same bytes are
    the same value (a NaN in them too), while different bytes may still be equal values (1 and
    1.0, a map in another order), so those are decoded and compared."""
    return a.packed == b.packed or values_equal(a.value, b.value)


class Life:
    """When a node's engine ran: its runs (a start event each) and the last sign of life of each
    (a trace event or a heartbeat), in its clock."""

    def __init__(self, starts: list[float], signs: list[float], virtual_end: float | None):
        self.virtual_end = virtual_end
        starts = sorted(starts) or [-math.inf]
        self.runs: list[list[float]] = [[s, s] for s in starts]
        for t in signs:
            k = last_at_or_before(starts, t)
            run = self.runs[max(k, 0)]
            run[1] = max(run[1], t)
        self.seen = bool(signs) or virtual_end is not None

    def judge(self, t: float, grace: float, who: str) -> tuple[str, str]:
        """Why a message sent at `t` that `who` never took: ('lost' | 'unjudged', reason)."""
        if self.virtual_end is not None:  # one engine, which ran every node until its end
            if t + grace <= self.virtual_end:
                return "lost", f"{who} ran until t={self.virtual_end:.6g} in the same engine"
            return "unjudged", f"in flight when the run ended at t={self.virtual_end:.6g}"
        if not self.seen:
            return "unjudged", f"{who} has no trace in this recording"
        starts = [run[0] for run in self.runs]
        k = last_at_or_before(starts, t)
        if k < 0:
            return "unjudged", f"sent before {who}'s engine started (t={starts[0]:.6g}): nobody could receive it"
        start, last = self.runs[k]
        if t + grace <= last:
            return "lost", f"{who} was running until t={last:.6g}"
        down = self.down(t, grace, who)
        if down is not None:
            return "lost", down
        return "unjudged", (f"in flight when the run ended: {who}'s last sign of life is at t={last:.6g}, "
                            f"less than {grace:g} after the send")

    def down(self, t: float, grace: float, who: str) -> str | None:
        """Why a message sent at `t` found `who` between two runs (dead, not yet restarted), or None."""
        if self.virtual_end is not None or not self.seen:
            return None
        k = last_at_or_before([run[0] for run in self.runs], t)
        if k < 0 or k + 1 >= len(self.runs) or t + grace <= self.runs[k][1]:
            return None
        return (f"sent while {who} was down: its last sign of life at t={self.runs[k][1]:.6g}, "
                f"restarted at t={self.runs[k + 1][0]:.6g}")

    def before_start(self, t: float) -> bool:
        """Sent before the first start of a real-time node's engine (never in virtual time)."""
        return self.virtual_end is None and self.seen and t < self.runs[0][0]

    @property
    def trace_end(self) -> float | None:
        return self.runs[-1][1] if self.seen and self.virtual_end is None else None

    def untraced_at(self, t: float) -> float | None:
        """Where the trace of the real-time run that was going at `t` ends, if `t` is past it: a
        process killed there lost its last trace period (what it sent then is on the wire only)."""
        if not self.seen or self.virtual_end is not None:
            return None
        k = last_at_or_before([run[0] for run in self.runs], t)
        if k < 0:
            return None
        end = self.runs[k][1]
        return end if t > end else None


def last_at_or_before(ordered: list[float], t: float) -> int:
    k = -1
    for i, value in enumerate(ordered):
        if value <= t:
            k = i
        else:
            break
    return k


def ident_of(event: dict, seq_field: str = "seq", ns_field: str = "send_ns") -> tuple[int, int] | None:
    seq, ns = event.get(seq_field), event.get(ns_field)
    if isinstance(seq, int) and isinstance(ns, int) and not isinstance(seq, bool):
        return seq & MASK, ns
    return None


def short(value: Any) -> str:
    """A value as a report shows it: JSON, cut at 48 characters."""
    text = json.dumps(value, default=str) if not isinstance(value, str) else value
    return text if len(text) <= 48 else text[:45] + "..."


@dataclass(frozen=True)
class Accounts:
    """Everything the checks read of one recording, read once (`read_accounts`). Times are in
    spec units: `tolerance` (a nanosecond more than asked: file times are whole nanoseconds) and
    `grace` (how long a message may be in flight; 0 in virtual time, where a binding delivers
    at the instant of the firing)."""

    recording: Recording
    system: RecordedSystem
    virtual: bool
    mode: str                                   # virtual | traces | direct | unknown
    unit: float                                 # seconds per spec time unit
    tolerance: float
    grace: float
    specs: dict[str, dict]
    origin_ns: Any                              # a virtual run's origin on the file's clock
    # node -> its inputs, violations and can_tx outputs; every node with a trace event has a list
    events: dict[str, list[Event]]
    claims: dict[str, list[Sent]]               # key -> what its senders' traces say they published
    wire: dict[str, list[RecordedMessage]]      # key -> the messages recorded on it
    life: dict[str, Life]
    gaps: dict[str, list[tuple[int, int]]]      # key -> the recorder's sequence gaps (expected, got)
    # node -> where its trace misses events the recording never heard: (from_t, to_t, why), the
    # times of the events heard either side (`Recording.trace_gaps`)
    trace_gaps: dict[str, list[tuple[float, float, str]]] = field(default_factory=dict)
    # node -> the bound of its host's clock offset to the hub's over time (spec units), for the
    # nodes of the hosts whose clocks were measured (iotad/recording/clock_offsets.py)
    widen: dict[str, Any] = field(default_factory=dict)

    def clock_bound(self, node: str, t: float) -> float:
        """How far `node`'s time at `t` may be off the hub's timeline (spec units; 0: exact)."""
        widening = self.widen.get(node)
        return widening(t) if widening is not None else 0.0

    def on_wire(self, key: str) -> list[OnWire]:
        """The messages recorded on `key`, with their time on the sender's clock where it can be
        told (made when a check reads the key, and dropped after it)."""
        messages = self.wire.get(key)
        if not messages:
            return []
        node = wire.parse_key(key)[1]
        origin = (self.specs.get(node) or {}).get("origin")
        out = []
        for message in messages:
            t = None
            if self.virtual and isinstance(self.origin_ns, (int, float)):
                t = (message.publish_time - self.origin_ns) / 1e9 / self.unit
            elif isinstance(origin, (int, float)):
                t = (message.publish_time / 1e9 - origin) / self.unit
            out.append(OnWire(key, t, message, (message.sequence & MASK, message.publish_time)))
        return out

    def inside_composite(self, node: str, iota: Any) -> bool:
        """Whether a keyless event of a real-time node is one of its parts' (a composite node's
        internal outputs and deliveries: one engine in one process, nothing on the wire)."""
        return not self.virtual and iota not in (node, node.rsplit("/", 1)[-1])

    def covered(self, key: str) -> bool:
        """Whether the recording was made to hold the messages on `key`."""
        if self.mode in ("virtual", "traces"):
            return True
        keys = self.recording.info.get("keys")
        if isinstance(keys, list) and keys:
            return any(isinstance(k, str) and wire.keyexpr_matches(k, key) for k in keys)
        return key in self.wire

    def in_gap(self, key: str, seq: int) -> bool:
        return any(expected <= seq < got for expected, got in self.gaps.get(key, ()))

    def trace_not_held(self, node: str) -> bool:
        """Whether this recording was not made to hold `node`'s trace (its recorder subscribed to
        other nodes' only: one host's own recording, or the hub's when `node`'s host keeps its
        traces home) and holds none of it: what `node` sent is judged where its trace is, in
        the merge of the hosts' recordings."""
        return not self.events.get(node) and not self.recording.subscribed_to_trace(node)

    def trace_gap(self, node: str) -> bool:
        return bool(self.gaps.get(wire.trace_key(self.system.name, node)))

    def unheard(self, node: str, t: float) -> tuple[float, float, str] | None:
        """The gap in `node`'s trace where a message sent at `t` may have reached it unheard by the
        recording (it arrives at `t` or, within the grace, after), or None."""
        return next((gap for gap in self.trace_gaps.get(node, ()) if gap[0] - self.grace < t < gap[1]), None)

    def node_t(self, node: str, ns: int) -> float | None:
        origin = (self.specs.get(node) or {}).get("origin")
        if not isinstance(origin, (int, float)):
            return None
        return (ns / 1e9 - origin) / self.unit

    def mistimed(self, candidates: list, t: float, fits: Callable[[Any], bool]) -> Any:
        """The candidate nearest `t`, within MISTIMED, that `fits`: the message a receipt (or a
        wire copy) is, found at another time than it was sent. None if there is none."""
        near = [c for c in candidates if abs(c.t - t) <= MISTIMED / self.unit and fits(c)]
        return min(near, key=lambda c: abs(c.t - t)) if near else None

    def can_window(self) -> float:
        """How long a frame may wait for the bus before a later twin of it stands for it (the older
        one lost). The modelled bus of virtual time loses nothing and queues without bound: a
        congested one (50 kbit/s) delays frames by seconds, in each station's order."""
        return math.inf if self.virtual else GRACE / self.unit


def read_accounts(recording: Recording, system: RecordedSystem, tolerance: float,
                  grace: float | None = None) -> Accounts:
    """The accounts of `recording`, read in one pass over its messages. `tolerance` is in spec
    time units; `grace` in seconds (default `GRACE`)."""
    info = recording.info
    virtual = info.get("clock") == "virtual"
    try:
        unit = float(info.get("time_unit") or 1.0)
    except (TypeError, ValueError):
        unit = 1.0
    reading = _Reading(system, virtual)
    reading.read(recording)
    gaps: dict[str, list[tuple[int, int]]] = {}
    for gap in recording.gaps():
        if isinstance(gap, dict) and isinstance(gap.get("key"), str):
            gaps.setdefault(gap["key"], []).append((int(gap.get("expected", 0)), int(gap.get("got", 0))))
    trace_gaps = {}
    for key in gaps:
        parsed = wire.parse_key(key)
        if parsed is not None and parsed[1] and parsed[2] == wire.TRACE:
            trace_gaps[parsed[1]] = [(g["from_t"], g["to_t"], g["why"]) for g in recording.trace_gaps(parsed[1])]
    return Accounts(
        recording, system, virtual, "virtual" if virtual else str(info.get("source") or "unknown"), unit,
        # a time read off the file (a message's log or publish time) is whole nanoseconds, while
        # a trace event's `t` is exact: with time_unit 0.001, t = 0.3333333 ms is 333333 ns on the
        # wire. Times are compared to a nanosecond more than the tolerance, in spec units.
        tolerance + 1e-9 / unit,
        # spec units; in virtual time a binding delivers at the instant of the firing
        0.0 if virtual else (GRACE if grace is None else grace) / unit,
        recording.specs, info.get("origin_ns") if virtual else None,
        reading.events, reading.claims, reading.wire, reading.lives(recording.specs, recording), gaps, trace_gaps,
        {} if virtual else widenings(recording))


class _Reading:
    """The one pass over a recording's messages, keeping little of each: the trace events a check
    reads (`take`), when each node ran, and which messages are on each key (decoded per key, as
    it is checked: `Accounts.on_wire`)."""

    def __init__(self, system: RecordedSystem, virtual: bool):
        self.system, self.virtual = system, virtual
        self.events: dict[str, list[Event]] = {}
        self.claims: dict[str, list[Sent]] = {}
        self.wire: dict[str, list[RecordedMessage]] = {}
        self.starts: dict[str, list[float]] = {}
        self.signs: dict[str, array] = {}  # node -> the times of its trace events and heartbeats

    def read(self, recording: Recording) -> None:
        system = self.system
        for message in recording.messages:
            parsed = wire.parse_key(message.topic)
            if parsed is None or (system.name and parsed[0] != system.name):
                continue
            channel = parsed[2]
            if channel == wire.TRACE or channel == wire.HEARTBEAT:
                try:
                    value = message.value
                except Exception:  # noqa: BLE001 - an undecodable message is no account of anything
                    continue
                if not isinstance(value, dict) or not isinstance(value.get("t"), (int, float)):
                    continue
                node = parsed[1]
                t = float(value["t"])
                self.signs.setdefault(node, array("d")).append(t)
                if channel == wire.TRACE:
                    index = value.get("index")
                    if not isinstance(value.get("action"), str) or not (index is None or type(index) is int):
                        continue  # no event of any channel: conformance reports what it is
                    if value.get("kind") == wire.START_KIND:
                        self.starts.setdefault(node, []).append(t)
                    else:
                        self.take(node, t, value, message.data)
            elif not channel.startswith("@"):
                self.wire.setdefault(message.topic, []).append(message)
        self.number_claims()

    def lives(self, specs: dict, recording: Recording) -> dict[str, Life]:
        """When each node ran: its own runs, or (virtual time) until the run's last sign of life.
        A node whose trace the recording was not made to hold has none here, its heartbeats
        notwithstanding: what it took is in another host's recording."""
        end = max((t for node_signs in self.signs.values() for t in node_signs), default=0.0)
        nodes = set(self.events) | set(specs) | {p.node for b in self.system.bindings for p in b}
        held = {node for node in nodes if node in self.events or recording.subscribed_to_trace(node)}
        return {node: Life(self.starts.get(node, []), self.signs.get(node, []) if node in held else [],
                           end if self.virtual else None)
                for node in nodes}

    def take(self, node: str, t: float, event: dict, data: bytes) -> None:
        """Keep what the checks read of one trace event of `node` (no start): an output's claim,
        an input, a violation (whole: its value says what was refused), a can_tx output (the bus
        check's); of any other event (internal firings), nothing but its time, a sign of life."""
        kept = self.events.setdefault(node, [])
        kind = event.get("kind")
        if kind not in ("input", "output", "violation"):
            return
        # the strings repeat in every event, and are kept once each (sys.intern)
        key = sys.intern(event["key"]) if isinstance(event.get("key"), str) else None
        iota = event.get("iota")
        record = Event(t, sys.intern(kind), sys.intern(event["action"]), event.get("index"), key, ident_of(event),
                        sys.intern(iota) if isinstance(iota, str) else iota, *_packed_in(data, event.get("value")),
                        event if kind == "violation" else None)
        if kind != "output" or record.action == CAN_TX:
            kept.append(record)
        if kind != "output":
            return
        if key is None:
            if not self.virtual and iota not in (node, node.rsplit("/", 1)[-1]):  # Accounts.inside_composite
                return  # an output inside a composite node that its root does not expose
            key = sys.intern(wire.channel_key(self.system.name, node, record.action, record.index))
        self.claims.setdefault(key, []).append(Sent(node, key, t, record.data, record.start, record.end, record.ident))

    def number_claims(self) -> None:
        """Number each key's claims (`Sent.ordinal`, as reports name a claim without a sequence
        number) node by node, in the order the nodes first appear on @trace, each node's claims in
        the order of its trace: a key that several nodes claim to publish on has them in that order."""
        rank = {node: k for k, node in enumerate(self.events)}
        for claims in self.claims.values():
            if any(claim.node != claims[0].node for claim in claims):
                claims.sort(key=lambda claim: rank[claim.node])  # stable: each node's keep their order
            for ordinal, claim in enumerate(claims):
                claim.ordinal = ordinal
