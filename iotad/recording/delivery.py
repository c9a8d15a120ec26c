"""Delivery cross-check of a recording: what senders claim, what the wire carried, what receivers got.

Three accounts of every message are in a recording (docs/checking.md, "Delivery"):

- the sender's claim: an `output` event on its `@trace` (a node host adds the `key`, `seq` and
  `send_ns` it published with);
- the wire: the messages on the output's key. What they prove depends on how the file was made
  (`iotad.recording` metadata): `direct` (`iotad record`), the recorder's own subscription, a
  third witness; `traces` (`iotad run`), rebuilt by the recorder from the senders' traces, so they
  can only disagree with the claims if the file was edited or lost trace; `virtual`, written by
  the one engine that also wrote the traces;
- the receiver's account: an `input` event on its `@trace` (with the key it came on and the
  sender's `seq`/`send_ns`), or a recorded rejection of it (`switching_time`, `bad_value`,
  `malformed_payload`).

`check_delivery` matches them per binding of the recorded system file: by key, sequence number
and send time where the events carry them (real node hosts), else by time within the tolerance
and order (virtual time: a binding delivers at the instant of the firing). Each claim is
delivered, altered (a value differs), lost, rejected, or not judged: sent before the receiver's
engine started, or so close to its last sign of life (trace event or heartbeat) that the run
ended before it could arrive. Received or wire messages that no claim explains are duplicated
(the same message again) or unexplained. CAN buses (`[[can]]`, or the bus model of a virtual
run) are checked frame by frame: every station's `can_tx` against the `can_rx` of the others,
by content and order.
"""
from __future__ import annotations

import json
import math
import re
import sys
import tomllib
from array import array
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Iterable

from iotad.host import wire
from iotad.host.can_port import KEY_PREFIX as CAN_KEY_PREFIX
from iotad.kernel.engine import INPUT_REFUSALS
from iotad.launcher.system_file import Port  # one concrete channel, as the system file names it
from iotad.recording.mcap_format import packb, unpackb
from iotad.recording.mcap_reader import RecordedMessage, Recording

GRACE = 0.1  # seconds: longer than any delivery seen here (~1 ms, tens under load) by far
MASK = 0xFFFFFFFF  # MCAP keeps 32 bits of a sequence number
REJECTIONS = (*INPUT_REFUSALS, "malformed_payload")  # a receiver saw it and refused it (the engine, or its host)
OVERFLOW = "input_overflow"  # a receiver's full input queue dropped `dropped` inputs between two times
_BETWEEN = re.compile(r"between t=(?P<first>[-+\d.eE]+) and t=(?P<last>[-+\d.eE]+)")
PROBLEMS = ("lost", "altered", "duplicated", "unexplained", "reordered", "causality")
MISTIMED = 1.0  # s: a receipt this near a message of its value that nothing took is that message, mistimed
CAN_TX, CAN_RX = "can_tx", "can_rx"
BUS_LOG = "frames"  # a bus's log of every frame it carried (iotad.can.frame_log), if the recording has one
_ENDPOINT = re.compile(r"^\s*(?P<node>[^\s\[\]]+)\.(?P<channel>[A-Za-z_]\w*)(?:\[(?P<index>\d+)\])?\s*$")


# ------------------------------------------------------------------------------------ results
@dataclass
class Link:
    """One row of the report: a binding (sender -> receiver), an output key against the wire,
    inputs from outside, or one sender -> receiver pair of a CAN bus."""

    label: str
    kind: str                # binding | wire | external | can
    nodes: tuple[str, ...]   # the nodes it concerns (for --node)
    sent: int = 0
    delivered: int = 0
    lost: int = 0
    altered: int = 0
    duplicated: int = 0
    unexplained: int = 0
    rejected: int = 0
    unjudged: int = 0        # in flight when the run ended, or sent before the receiver started
    latencies: list[float] = field(default_factory=list)  # seconds, sender's firing -> receiver's input

    @property
    def problems(self) -> int:
        return self.lost + self.altered + self.duplicated + self.unexplained

    def latency(self) -> tuple[float, float, float] | None:
        """(p50, p99, max) in seconds, nearest rank; None without deliveries."""
        if not self.latencies:
            return None
        ordered = sorted(self.latencies)
        return _rank(ordered, 0.50), _rank(ordered, 0.99), ordered[-1]


@dataclass
class DeliveryFinding:
    code: str            # lost, altered, duplicated, unexplained, reordered, causality; or a note's kind
    link: str
    t: float | None      # spec time units: the sender's firing (or the receipt, for what no one sent)
    message: str
    problem: bool = True
    nodes: tuple[str, ...] = ()
    late: float | None = None  # seconds of latency, for delivered messages the plot may mark

    def __str__(self) -> str:
        when = "" if self.t is None else f"t={self.t:.6g} "
        return f"{when}[{self.code}] {self.link}: {self.message}"


@dataclass
class DeliveryReport:
    mode: str                       # virtual | traces | direct | unknown
    witness: str                    # what the wire is in this mode, in one sentence
    links: list[Link] = field(default_factory=list)
    findings: list[DeliveryFinding] = field(default_factory=list)
    notes: list[DeliveryFinding] = field(default_factory=list)
    # (link, t sent, latency in seconds, the nodes it concerns) of every delivery
    deliveries: list[tuple[str, float, float, tuple[str, ...]]] = field(default_factory=list)
    checked: bool = True
    reason: str = ""                # why nothing was checked

    @property
    def ok(self) -> bool:
        return not any(f.problem for f in self.findings)

    def totals(self, wire: bool = False) -> dict[str, int]:
        """Counts over the links to receivers (bindings, outside, CAN), or over the wire links."""
        out = {name: 0 for name in ("sent", "delivered", "lost", "altered", "duplicated", "unexplained",
                                    "rejected", "unjudged")}
        for link in self.links:
            if (link.kind == "wire") == wire:
                for name in out:
                    out[name] += getattr(link, name)
        return out

    def summary(self) -> str:
        if not self.checked:
            return f"delivery: not checked ({self.reason})"
        receivers, on_wire = self.totals(), self.totals(wire=True)
        links = sum(1 for link in self.links if link.kind != "wire")
        text = f"delivery: {receivers['delivered']} of {receivers['sent']} messages delivered as sent over {links} links"
        bad = _counted(receivers)
        order = sum(1 for f in self.findings if f.code in ("reordered", "causality"))
        bad += [f"{order} out of order"] if order else []
        text += f" ({', '.join(bad)})" if bad else ""
        if any(link.kind == "wire" for link in self.links):
            text += f"; the wire holds {on_wire['delivered']} of {on_wire['sent']} claimed messages as claimed"
            bad = _counted(on_wire)
            text += f" ({', '.join(bad)})" if bad else ""
        extra = [f"{receivers['rejected']} rejected by the receiver"] if receivers["rejected"] else []
        if receivers["unjudged"]:
            extra.append(f"{receivers['unjudged']} not judged (in flight at the end, or before the receiver started)")
        return text + ("; " + ", ".join(extra) if extra else "") + ("" if self.ok else ": PROBLEMS")

    def table(self) -> list[str]:
        width = max([44] + [len(link.label) for link in self.links])
        out = [f"  {'link':<{width}} {'sent':>5} {'deliv':>5} {'lost':>4} {'alter':>5} {'dup':>3} {'unexp':>5} "
               f"{'rej':>3} {'n/j':>3}  latency ms p50 / p99 / max"]
        for link in self.links:
            latency = link.latency()
            shown = "-" if latency is None else " / ".join(_ms(x) for x in latency)
            out.append(f"  {link.label:<{width}} {link.sent:>5} {link.delivered:>5} {link.lost:>4} {link.altered:>5} "
                       f"{link.duplicated:>3} {link.unexplained:>5} {link.rejected:>3} {link.unjudged:>3}  {shown}")
        return out

    def brief(self, limit: int = 10) -> list[str]:
        """The per-link summary `iotad info` shows: links to receivers (bindings, outside, CAN),
        the wire in one line, the first problems, and the totals."""
        if not self.checked:
            return [self.summary()]
        receivers = [link for link in self.links if link.kind != "wire"]
        report = DeliveryReport(self.mode, self.witness, links=receivers)
        out = report.table() if receivers else ["  no bindings or CAN buses"]
        on_wire = self.totals(wire=True)
        if any(link.kind == "wire" for link in self.links):
            bad = _counted(on_wire)
            out.append(f"  wire ({self.mode} recording): {on_wire['delivered']} of {on_wire['sent']} claimed "
                       f"messages as claimed" + (f" ({', '.join(bad)})" if bad else ""))
        problems = [f for f in self.findings if f.problem]
        out += [f"  {finding}" for finding in problems[:limit]]
        if len(problems) > limit:
            out.append(f"  ... {len(problems) - limit} more problem(s): iotad check lists them")
        unjudged = [n for n in self.notes if n.code == "not judged"]
        out += [f"  note: {note}" for note in unjudged[:limit]]
        return out

    def lines(self, limit: int = 20) -> list[str]:
        if not self.checked:
            return [self.summary()]
        out = [f"delivery, {self.mode} recording ({self.witness}):"]
        out += self.table() if self.links else ["  no bindings, outputs or CAN buses to check"]
        problems = [f for f in self.findings if f.problem]
        for finding in problems[:limit]:
            out.append(f"  {finding}")
        if len(problems) > limit:
            out.append(f"  ... {len(problems) - limit} more problem(s) (--all lists them)")
        for note in self.notes[:limit]:
            out.append(f"  note: {note}")
        if len(self.notes) > limit:
            out.append(f"  ... {len(self.notes) - limit} more note(s)")
        out.append(self.summary())
        return out


def _counted(totals: dict[str, int]) -> list[str]:
    return [f"{totals[name]} {name}" for name in ("lost", "altered", "duplicated", "unexplained") if totals[name]]


def _rank(ordered: list[float], p: float) -> float:
    return ordered[min(len(ordered) - 1, max(0, math.ceil(p * len(ordered)) - 1))]


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:.3g}"


def _short(value: Any) -> str:
    text = json.dumps(value, default=str) if not isinstance(value, str) else value
    return text if len(text) <= 48 else text[:45] + "..."


# ------------------------------------------------------------------------------------ the system
@dataclass
class RecordedSystem:
    """What delivery needs of the recorded system file: concrete bindings, external inputs, buses."""

    name: str
    bindings: list[tuple[Port, Port]] = field(default_factory=list)
    external: set[Port] = field(default_factory=set)
    buses: dict[str, list[str]] = field(default_factory=dict)  # bus -> its stations, in order
    bus_nodes: set[str] = field(default_factory=set)          # bus models (virtual time): not stations


def recorded_system(recording: Recording) -> RecordedSystem | str:
    """The system attached to `recording` (system.toml, or system.json of an in-process run),
    with family bindings expanded by the recorded channel tables; or why there is none."""
    toml_text = json_text = None
    for attachment in recording.attachments:
        if attachment.name == "system.toml":
            toml_text = attachment.data.decode(errors="replace")
        elif attachment.name == "system.json":
            json_text = attachment.data.decode(errors="replace")
    sizes = _channel_sizes(recording.specs)
    name = recording.system or ""
    pairs: list[tuple[str, str]] = []
    external: list[str] = []
    buses: dict[str, list[str]] = {}
    if toml_text is not None:
        try:
            table = tomllib.loads(toml_text)
        except tomllib.TOMLDecodeError as exc:
            return f"the recorded system.toml is not TOML: {exc}"
        pairs = [(b.get("from"), b.get("to")) for b in table.get("bind", []) if isinstance(b, dict)]
        system = table.get("system") if isinstance(table.get("system"), dict) else {}
        for raw in (table.get("external"), system.get("external")):
            if isinstance(raw, list):
                external += [e for e in raw if isinstance(e, str)]
        for bus in table.get("can", []) if isinstance(table.get("can"), list) else []:
            if isinstance(bus, dict) and isinstance(bus.get("name"), str) and isinstance(bus.get("stations"), list):
                buses[bus["name"]] = [s for s in bus["stations"] if isinstance(s, str)]
        prefix = ""
    elif json_text is not None:
        try:
            data = json.loads(json_text)
        except ValueError as exc:
            return f"the recorded system.json is not JSON: {exc}"
        if not isinstance(data, dict):
            return f"the recorded system.json is a {type(data).__name__}, not a JSON object"
        pairs = [tuple(p) for p in data.get("bindings", []) if isinstance(p, (list, tuple)) and len(p) == 2]
        if isinstance(data.get("external"), list):
            external += [e for e in data["external"] if isinstance(e, str)]
        root = recording.info.get("root") or data.get("name") or name
        prefix = f"{root}/"
    else:
        return "the recording holds no system file (system.toml or system.json), so no bindings"
    out = RecordedSystem(name)
    for source_text, target_text in pairs:
        source, target = _port(source_text, prefix), _port(target_text, prefix)
        if source is None or target is None:
            continue
        out.bindings += _expand(source, target, sizes)
    for text in external:
        port = _port(text, "")
        if port is not None:
            members = [port.index] if port.index is not None else _members(sizes.get((port.node, port.channel)))
            out.external.update(Port(port.node, port.channel, k) for k in members)
    if not buses:  # a virtual run: the bus is a node; station k's can_tx -> bus.tx[k], bus.rx[k] -> can_rx
        found: dict[str, dict[int, str]] = {}
        for source, target in out.bindings:
            if source.channel == CAN_TX and target.channel == "tx" and target.index is not None:
                found.setdefault(target.node, {})[target.index] = source.node
        buses = {bus: [stations[k] for k in sorted(stations)] for bus, stations in found.items()}
        out.bus_nodes = set(buses)
    out.buses = buses
    return out


def _port(text: Any, prefix: str) -> Port | None:
    if not isinstance(text, str):
        return None
    match = _ENDPOINT.match(text)
    if not match:
        return None
    node = match["node"]
    if prefix and node.startswith(prefix):
        node = node[len(prefix):]
    return Port(node, match["channel"], None if match["index"] is None else int(match["index"]))


def _channel_sizes(specs: dict[str, dict]) -> dict[tuple[str, str], int | None]:
    out: dict[tuple[str, str], int | None] = {}
    for node, spec in specs.items():
        for entry in (spec.get("channels") or []) if isinstance(spec, dict) else []:
            if isinstance(entry, dict) and isinstance(entry.get("name"), str):
                size = entry.get("size")
                out[(node, entry["name"])] = size if isinstance(size, int) else None
    return out


def _members(size: int | None) -> list[int | None]:
    return [None] if size is None else list(range(size))


def _expand(source: Port, target: Port, sizes: dict) -> list[tuple[Port, Port]]:
    """A family bound to a family binds member to member (docs/system-file.md)."""
    src_size = sizes.get((source.node, source.channel)) if source.index is None else None
    dst_size = sizes.get((target.node, target.channel)) if target.index is None else None
    if src_size is not None and dst_size is not None:
        return [(Port(source.node, source.channel, k), Port(target.node, target.channel, k))
                for k in range(min(src_size, dst_size))]
    return [(source, target)]


# ------------------------------------------------------------------------------------ accounts
# A long recording holds hundreds of thousands of messages, and the check reads them all: what it
# keeps of each is small. A value is kept packed (msgpack), as a range of the bytes of the message
# that holds it (which the recording holds anyway: nothing is copied), and decoded only to compare
# two that differ in their bytes (`_same_value`) or to print one, never held decoded for the whole
# check. The records are slotted (no dict per object) for the same reason.
_UNDECODABLE = "<undecodable {} bytes>"


class _Packed:
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
class _Event(_Packed):
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
class _Sent(_Packed):
    node: str
    key: str
    t: float
    data: bytes                     # its value packed: data[start:end]
    start: int
    end: int
    ident: tuple[int, int] | None   # (seq, send_ns) as published, if the event says
    ordinal: int = 0                # its place among the sender's claims on the key


@dataclass(slots=True)
class _Got(_Packed):
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
class _Wire:
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


# A float that may be a NaN (float 64 or 32, exponent all ones): equal bytes decode to equal
# values but for one, since a NaN inside a list or map is not equal to another NaN.
_MAY_BE_NAN = re.compile(rb"\xcb[\x7f\xff][\xf0-\xff]|\xca[\x7f\xff][\x80-\xff]")


def _same_value(a: Any, b: Any) -> bool:
    """`_same` of two records' values (each holds its value packed): the same bytes are the same
    value (but for a NaN), while different bytes may still be equal values (1 and 1.0, a map in
    another order), so those are decoded and compared."""
    packed = a.packed
    if packed == b.packed and not _MAY_BE_NAN.search(packed):
        return True
    return _same(a.value, b.value)


class _Life:
    """When a node's engine ran: its runs (a start event each) and the last sign of life of each
    (a trace event or a heartbeat), in its clock."""

    def __init__(self, starts: list[float], signs: list[float], virtual_end: float | None):
        self.virtual_end = virtual_end
        starts = sorted(starts) or [-math.inf]
        self.runs: list[list[float]] = [[s, s] for s in starts]
        for t in signs:
            k = _last_at_or_before(starts, t)
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
        k = _last_at_or_before(starts, t)
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
        k = _last_at_or_before([run[0] for run in self.runs], t)
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
        k = _last_at_or_before([run[0] for run in self.runs], t)
        if k < 0:
            return None
        end = self.runs[k][1]
        return end if t > end else None


def _last_at_or_before(ordered: list[float], t: float) -> int:
    k = -1
    for i, value in enumerate(ordered):
        if value <= t:
            k = i
        else:
            break
    return k


def _ident(event: dict, seq_field: str = "seq", ns_field: str = "send_ns") -> tuple[int, int] | None:
    seq, ns = event.get(seq_field), event.get(ns_field)
    if isinstance(seq, int) and isinstance(ns, int) and not isinstance(seq, bool):
        return seq & MASK, ns
    return None


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def _keyexpr_matches(expression: str, key: str) -> bool:
    """zenoh key-expression matching for `*` (one chunk) and `**` (any chunks); a chunk starting
    with '@' is matched only verbatim, as zenoh does."""
    pattern, chunks = expression.split("/"), key.split("/")

    def match(i: int, j: int) -> bool:
        if i == len(pattern):
            return j == len(chunks)
        if pattern[i] == "**":
            return any(match(i + 1, k) for k in range(j, len(chunks) + 1)
                       if not any(c.startswith("@") for c in chunks[j:k]))
        if j == len(chunks):
            return False
        if pattern[i] == "*":
            return not chunks[j].startswith("@") and match(i + 1, j + 1)
        return pattern[i] == chunks[j] and match(i + 1, j + 1)

    return match(0, 0)


# ------------------------------------------------------------------------------------ the check
class DeliveryChecker:
    def __init__(self, recording: Recording, tolerance: float, grace: float | None = None):
        self.recording = recording
        info = recording.info
        self.virtual = info.get("clock") == "virtual"
        self.mode = "virtual" if self.virtual else str(info.get("source") or "unknown")
        try:
            self.unit = float(info.get("time_unit") or 1.0)
        except (TypeError, ValueError):
            self.unit = 1.0
        # a time read off the file (a message's log or publish time) is whole nanoseconds, while
        # a trace event's `t` is exact: with time_unit 0.001, t = 0.3333333 ms is 333333 ns on the
        # wire. Times are compared to a nanosecond more than the tolerance, in spec units.
        self.tolerance = tolerance + 1e-9 / self.unit
        # spec units; in virtual time a binding delivers at the instant of the firing
        self.grace = 0.0 if self.virtual else (GRACE if grace is None else grace) / self.unit
        self.report = DeliveryReport(self.mode, _WITNESS.get(self.mode, _WITNESS["unknown"]))

    # -- reading the recording once
    def _read(self, system: RecordedSystem) -> None:
        """One pass over the messages, keeping little of each: the trace events a check reads
        (`_take`), when each node ran, and which messages are on each key (decoded per key, as it
        is checked: `_on_wire`)."""
        specs = self.recording.specs
        self.specs = specs
        self.origin_ns = self.recording.info.get("origin_ns") if self.virtual else None
        # node -> its inputs, violations and can_tx outputs; every node with a trace event has a list
        self.events: dict[str, list[_Event]] = {}
        self.claims: dict[str, list[_Sent]] = {}  # key -> what its senders' traces say they published
        self.wire: dict[str, list[RecordedMessage]] = {}
        starts: dict[str, list[float]] = {}
        signs: dict[str, array] = {}  # node -> the times of its trace events and heartbeats
        for message in self.recording.messages:
            parsed = wire.parse_key(message.topic)
            if parsed is None or (system.name and parsed[0] != system.name):
                continue
            channel = parsed[2]
            if channel == "@trace" or channel == "@heartbeat":
                try:
                    value = message.value
                except Exception:  # noqa: BLE001 - an undecodable message is no account of anything
                    continue
                if not isinstance(value, dict) or not isinstance(value.get("t"), (int, float)):
                    continue
                node = parsed[1]
                t = float(value["t"])
                signs.setdefault(node, array("d")).append(t)
                if channel == "@trace":
                    index = value.get("index")
                    if not isinstance(value.get("action"), str) or not (index is None or type(index) is int):
                        continue  # no event of any channel: conformance reports what it is
                    if value.get("kind") == wire.START_KIND:
                        starts.setdefault(node, []).append(t)
                    else:
                        self._take(system, node, t, value, message.data)
            elif not channel.startswith("@"):
                self.wire.setdefault(message.topic, []).append(message)
        self._number_claims()
        end = max((t for node_signs in signs.values() for t in node_signs), default=0.0)
        nodes = set(self.events) | set(specs) | {p.node for b in system.bindings for p in b}
        self.life = {node: _Life(starts.get(node, []), signs.get(node, []), end if self.virtual else None)
                     for node in nodes}
        self.gaps: dict[str, list[tuple[int, int]]] = {}
        for gap in self.recording.gaps():
            if isinstance(gap, dict) and isinstance(gap.get("key"), str):
                self.gaps.setdefault(gap["key"], []).append((int(gap.get("expected", 0)), int(gap.get("got", 0))))

    def _take(self, system: RecordedSystem, node: str, t: float, event: dict, data: bytes) -> None:
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
        record = _Event(t, sys.intern(kind), sys.intern(event["action"]), event.get("index"), key, _ident(event),
                        sys.intern(iota) if isinstance(iota, str) else iota, *_packed_in(data, event.get("value")),
                        event if kind == "violation" else None)
        if kind != "output" or record.action == CAN_TX:
            kept.append(record)
        if kind != "output":
            return
        if key is None:
            if self._inside_composite(node, iota):
                return  # an output inside a composite node that its root does not expose
            key = sys.intern(wire.channel_key(system.name, node, record.action, record.index))
        self.claims.setdefault(key, []).append(_Sent(node, key, t, record.data, record.start, record.end, record.ident))

    def _number_claims(self) -> None:
        """Number each key's claims (`_Sent.ordinal`, as reports name a claim without a sequence
        number) node by node, in the order the nodes first appear on @trace, each node's claims in
        the order of its trace: a key that several nodes claim to publish on has them in that order."""
        rank = {node: k for k, node in enumerate(self.events)}
        for claims in self.claims.values():
            if any(claim.node != claims[0].node for claim in claims):
                claims.sort(key=lambda claim: rank[claim.node])  # stable: each node's keep their order
            for ordinal, claim in enumerate(claims):
                claim.ordinal = ordinal

    def _on_wire(self, key: str) -> list[_Wire]:
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
            out.append(_Wire(key, t, message, (message.sequence & MASK, message.publish_time)))
        return out

    def _inside_composite(self, node: str, iota: Any) -> bool:
        """Whether a keyless event of a real-time node is one of its parts' (a composite node's
        internal outputs and deliveries: one engine in one process, nothing on the wire)."""
        return not self.virtual and iota not in (node, node.rsplit("/", 1)[-1])

    def _covered(self, key: str) -> bool:
        """Whether the recording was made to hold the messages on `key`."""
        if self.mode in ("virtual", "traces"):
            return True
        keys = self.recording.info.get("keys")
        if isinstance(keys, list) and keys:
            return any(isinstance(k, str) and _keyexpr_matches(k, key) for k in keys)
        return key in self.wire

    def _in_gap(self, key: str, seq: int) -> bool:
        return any(expected <= seq < got for expected, got in self.gaps.get(key, ()))

    def _trace_gap(self, node: str) -> bool:
        return bool(self.gaps.get(wire.trace_key(self.system.name, node)))

    def _node_t(self, node: str, ns: int) -> float | None:
        origin = (self.specs.get(node) or {}).get("origin")
        if not isinstance(origin, (int, float)):
            return None
        return (ns / 1e9 - origin) / self.unit

    def _finding(self, link: Link, code: str, t: float | None, message: str, problem: bool = True) -> None:
        finding = DeliveryFinding(code, link.label, t, message, problem, link.nodes)
        (self.report.findings if problem else self.report.notes).append(finding)

    # -- the checks
    def check(self, only: str | None = None) -> DeliveryReport:
        system = recorded_system(self.recording)
        if isinstance(system, str):
            self.report.checked, self.report.reason = False, system
            return self.report
        self.system = system
        self._read(system)
        sources_of: dict[Port, list[Port]] = {}
        for source, target in system.bindings:
            sources_of.setdefault(target, []).append(source)
        output_keys = self._output_keys(system)
        for key in sorted(output_keys):
            self._check_wire(key)
        for target in sorted(sources_of, key=str):
            self._check_target(target, sources_of[target])
        self._check_outside(system, sources_of, output_keys)
        for bus, stations in system.buses.items():
            self._check_bus(bus, stations)
        order = {"binding": 0, "external": 1, "can": 2, "wire": 3}
        self.report.links.sort(key=lambda link: (order.get(link.kind, 4), link.label))
        if only is not None:
            report = self.report
            report.links = [link for link in report.links if only in link.nodes]
            report.findings = [f for f in report.findings if only in f.nodes]
            report.notes = [f for f in report.notes if only in f.nodes]
            report.deliveries = [d for d in report.deliveries if only in d[3]]
        return self.report

    def _output_keys(self, system: RecordedSystem) -> set[str]:
        keys = set(self.claims)
        keys |= {wire.channel_key(system.name, s.node, s.channel, s.index) for s, _ in system.bindings}
        for topic in self.wire:
            parsed = wire.parse_key(topic)
            spec = self.specs.get(parsed[1]) or {}
            for entry in spec.get("channels") or []:
                if isinstance(entry, dict) and entry.get("name") == parsed[2] and entry.get("direction") == "output":
                    keys.add(topic)
        return keys

    def _check_wire(self, key: str) -> None:
        """The sender's claims on `key` against the messages the recording holds on it."""
        claims = self.claims.get(key, [])
        if not self._covered(key):
            return
        messages = self._on_wire(key)
        parsed = wire.parse_key(key)
        sender = parsed[1] if parsed else "?"
        port = Port(sender, parsed[2], parsed[3]) if parsed else None
        link = Link(f"{port} -> (wire)", "wire", (sender,), sent=len(claims))
        self.report.links.append(link)
        by_ident: dict[tuple[int, int], list[_Wire]] = {}
        if any(claim.ident is not None for claim in claims):  # none does in virtual time: no need
            for message in messages:
                by_ident.setdefault(message.ident, []).append(message)
        matched: set[int] = set()
        unkeyed: list[_Sent] = []
        for claim in claims:
            if claim.ident is None:
                unkeyed.append(claim)
                continue
            found = next((m for m in by_ident.get(claim.ident, ()) if id(m) not in matched), None)
            if found is None:
                self._wire_lost(link, key, claim)
                continue
            matched.add(id(found))
            self._compare_wire(link, claim, found)
        if unkeyed:
            rest = [m for m in messages if id(m) not in matched and m.t is not None]
            pairs = _align(unkeyed, rest, lambda c: c.t, lambda m: m.t, self.tolerance, self.tolerance + self.grace,
                           _same_value)
            for claim, found in pairs:
                if found is None:
                    # on the wire with its value, near its time, and taken by no other claim:
                    # that message, mistimed (as a receipt can be, `_check_target`)
                    found = self._mistimed(rest, claim.t, lambda m: id(m) not in matched and _same_value(claim, m))
                    if found is not None:
                        matched.add(id(found))
                        link.altered += 1
                        self._finding(link, "altered", claim.t, f"output {claim.ordinal} ({_short(claim.value)}), "
                                      f"published at t={claim.t:.6g}, is on the wire at t={found.t:.6g}: "
                                      f"{abs(found.t - claim.t) * self.unit * 1e3:.3g} ms from its time, beyond the "
                                      f"tolerance")
                        continue
                    self._wire_lost(link, key, claim)
                else:
                    matched.add(id(found))
                    self._compare_wire(link, claim, found)
        taken = {m.ident for m in messages if id(m) in matched}
        for message in messages:
            if id(message) in matched:
                continue
            if message.ident in taken:
                link.duplicated += 1
                self._finding(link, "duplicated", message.t, f"#{message.ident[0]} is on the wire twice")
                continue
            link.unexplained += 1
            self._finding(link, "unexplained", message.t,
                          f"#{message.ident[0]} ({_short(message.value)}) is on the wire, and {sender}'s trace "
                          f"claims no such message")

    def _mistimed(self, candidates: list, t: float, fits) -> Any:
        """The candidate nearest `t`, within MISTIMED, that `fits`: the message a receipt (or a
        wire copy) is, found at another time than it was sent. None if there is none."""
        near = [c for c in candidates if abs(c.t - t) <= MISTIMED / self.unit and fits(c)]
        return min(near, key=lambda c: abs(c.t - t)) if near else None

    def _wire_lost(self, link: Link, key: str, claim: _Sent) -> None:
        number = f"#{claim.ident[0]}" if claim.ident else f"output {claim.ordinal}"
        if claim.ident and self._in_gap(key, claim.ident[0]):
            self._finding(link, "not recorded", claim.t, f"{number} ({_short(claim.value)}): the recorder saw a "
                          "sequence gap here: it missed the message, which says nothing of its delivery", False)
            return
        link.lost += 1
        self._finding(link, "lost", claim.t, f"{number} ({_short(claim.value)}): {claim.node}'s trace says it was "
                      "published; the wire holds no such message")

    def _compare_wire(self, link: Link, claim: _Sent, message: _Wire) -> None:
        if _same_value(claim, message):
            link.delivered += 1
            return
        link.altered += 1
        number = f"#{claim.ident[0]}" if claim.ident else f"output {claim.ordinal}"
        self._finding(link, "altered", claim.t, f"{number}: {claim.node} sent {_short(claim.value)}, the wire "
                      f"carried {_short(message.value)}")

    def _inputs(self, target: Port, keys: set[str]) -> tuple[list[_Got], list[dict]]:
        """The receiver's input events and rejections (whole events) that concern `target`
        (bound from `keys`)."""
        got, rejected = [], []
        several = sum(1 for s, t in self.system.bindings if t.node == target.node and
                      wire.channel_key(self.system.name, s.node, s.channel, s.index) in keys) > 1
        for event in self.events.get(target.node, []):
            kind = event.kind
            here = event.action == target.channel and event.index == target.index
            if kind == "input":
                key = event.key
                if key is not None and key in keys:
                    if several and not here:
                        continue  # one key bound to two inputs of this node: the other one's
                elif key is not None or not here:
                    continue
                got.append(_Got(target.node, key, event.t, event.data, event.start, event.end, event.ident,
                                event.action, event.index))
            elif kind == "violation" and here and (event.raw.get("value") or {}).get("violation") in REJECTIONS + (OVERFLOW,):
                rejected.append(event.raw)
        return got, rejected

    def _check_target(self, target: Port, sources: list[Port]) -> None:
        """Every claim of the outputs bound to `target` against what `target`'s node took."""
        name = self.system.name
        keys = {wire.channel_key(name, s.node, s.channel, s.index): s for s in sources}
        got, rejections = self._inputs(target, set(keys))
        links = {key: Link(f"{source} -> {target}", "binding", (source.node, target.node),
                           sent=len(self.claims.get(key, []))) for key, source in keys.items()}
        self.report.links += list(links.values())
        claims = [c for key in keys for c in self.claims.get(key, [])]
        by_ident = {(c.key, c.ident): c for c in claims if c.ident is not None}
        taken: dict[int, _Got | None] = {}  # id(claim) -> the input that took it (None: a rejection)
        last_ordinal: dict[str, int] = {}
        unkeyed: list[_Got] = []
        for item in got:
            claim = by_ident.get((item.key, item.ident)) if item.ident is not None and item.key else None
            if item.ident is None or item.key is None:
                unkeyed.append(item)
                continue
            link = links[item.key]
            if claim is None:
                self._unclaimed(link, item, keys[item.key])
                continue
            if id(claim) in taken:
                link.duplicated += 1
                self._finding(link, "duplicated", claim.t, f"#{claim.ident[0]} ({_short(claim.value)}) received "
                              f"again at t={item.t:.6g} (first at t={taken[id(claim)].t:.6g})")
                continue
            taken[id(claim)] = item
            if claim.ordinal < last_ordinal.get(claim.key, -1):
                self._finding(link, "reordered", claim.t, f"#{claim.ident[0]} received at t={item.t:.6g}, after a "
                              "message sent later")
            last_ordinal[claim.key] = max(claim.ordinal, last_ordinal.get(claim.key, -1))
            self._delivered(link, claim, item)
        if unkeyed:
            free = sorted((c for c in claims if id(c) not in taken), key=lambda c: c.t)
            window = self.tolerance + self.grace
            pairs = _align(unkeyed, free, lambda g: g.t, lambda c: c.t, window, self.tolerance, _same_value)
            decoded: dict[int, Any] = {}  # id(claim) -> its value: each item below is compared with many

            def value_of(claim: _Sent) -> Any:
                if id(claim) not in decoded:
                    decoded[id(claim)] = claim.value
                return decoded[id(claim)]

            for item, claim in pairs:
                if claim is not None:
                    taken[id(claim)] = item
                    self._delivered(links[claim.key], claim, item)
                    continue
                value = item.value
                # a message sent with this value and taken by no receipt, near in time: the one
                # received, at another time than it was sent (an edited recording, a clock gone
                # wrong). Said as such, once, instead of the claim "lost" and this receipt
                # "duplicated" (of an earlier message with the same value) or "unexplained"
                claim = self._mistimed(claims, item.t, lambda c: id(c) not in taken and _same(value_of(c), value))
                if claim is not None:
                    taken[id(claim)] = item
                    link = links[claim.key]
                    link.altered += 1
                    number = f"#{claim.ident[0]}" if claim.ident else f"output {claim.ordinal}"
                    self._finding(link, "altered", claim.t, f"{number} ({_short(claim.value)}), sent at "
                                  f"t={claim.t:.6g}, was received at t={item.t:.6g}: "
                                  f"{abs(item.t - claim.t) * self.unit * 1e3:.3g} ms from its time, beyond the "
                                  f"tolerance")
                    continue
                # the same value again, after a delivery of it: a duplicate (else nobody sent it)
                twins = [c for c in claims if id(c) in taken and taken[id(c)] is not None
                         and c.t <= item.t + self.tolerance and _same(value_of(c), value)]
                twin = max(twins, key=lambda c: c.t) if twins else None
                link = links[twin.key] if twin else next(iter(links.values()))
                if twin is not None:
                    link.duplicated += 1
                    self._finding(link, "duplicated", twin.t, f"{_short(item.value)} received again at t={item.t:.6g}")
                elif self.virtual and target in self.system.external:
                    # bound and declared external: an input script's, posted into it from outside
                    self.report.notes.append(DeliveryFinding(
                        "external", f"(outside) -> {target}", item.t, f"{target.node} took "
                        f"{_short(item.value)} at t={item.t:.6g} from outside ({target} is external)", False,
                        (target.node,)))
                else:
                    link.unexplained += 1
                    self._finding(link, "unexplained", item.t, f"{target.node} took {_short(item.value)} at "
                                  f"t={item.t:.6g}, and no sender bound to {target} sent it")
        for event in rejections:  # the receiver saw the message and refused it: no loss
            t = float(event["t"])
            value = event.get("value") or {}
            if value.get("violation") == OVERFLOW:
                self._overflowed(links, claims, taken, t, value)
                continue
            # a node host names the message it refused (key, seq, send_ns): that claim exactly;
            # else the latest untaken claim sent by then
            ident, key = _ident(event), event.get("key")
            exact = by_ident.get((key, ident)) if ident is not None and key else None
            candidates = [exact] if exact is not None and id(exact) not in taken else \
                [c for c in claims if id(c) not in taken and t - self.tolerance - self.grace <= c.t <= t + self.tolerance]
            if not candidates:
                continue
            claim = max(candidates, key=lambda c: c.t)
            taken[id(claim)] = None
            links[claim.key].rejected += 1
        for claim in claims:
            if id(claim) in taken:
                continue
            link = links[claim.key]
            verdict, reason = self.life[target.node].judge(claim.t, self.grace, target.node) \
                if target.node in self.life else ("unjudged", f"{target.node} is not in this recording")
            number = f"#{claim.ident[0]}" if claim.ident else f"output {claim.ordinal}"
            if verdict == "lost":
                link.lost += 1
                self._finding(link, "lost", claim.t, f"{number} ({_short(claim.value)}) sent at t={claim.t:.6g} "
                              f"never reached {target}; {reason}")
            else:
                link.unjudged += 1
                self._finding(link, "not judged", claim.t, f"{number}: {reason}", False)

    def _overflowed(self, links: dict[str, Link], claims: list[_Sent], taken: dict, t: float, value: dict) -> None:
        """An `input_overflow` the receiver recorded: it dropped `dropped` inputs received between
        two times (its message says which): so many untaken claims sent by then were refused."""
        count = value.get("dropped")
        count = count if isinstance(count, int) and not isinstance(count, bool) else 1
        match = _BETWEEN.search(str(value.get("message") or ""))
        first, last = (float(match["first"]), float(match["last"])) if match else (-math.inf, t)
        window = self.tolerance + self.grace
        candidates = [c for c in claims if id(c) not in taken and first - window <= c.t <= last + self.tolerance]
        for claim in sorted(candidates, key=lambda c: c.t)[:count]:
            taken[id(claim)] = None
            links[claim.key].rejected += 1

    def _delivered(self, link: Link, claim: _Sent, item: _Got) -> None:
        latency = item.t - claim.t
        if not _same_value(claim, item):
            link.altered += 1
            number = f"#{claim.ident[0]}" if claim.ident else f"output {claim.ordinal}"
            self._finding(link, "altered", claim.t, f"{number}: {claim.node} sent {_short(claim.value)}, "
                          f"{item.node} received {_short(item.value)} at t={item.t:.6g}")
            return
        if latency < -self.tolerance:
            self._finding(link, "causality", claim.t, f"received at t={item.t:.6g}, {-latency * self.unit * 1e3:.3g} ms "
                          f"before it was sent")
        link.delivered += 1
        seconds = latency * self.unit  # one float for both lists: there is one per delivery
        link.latencies.append(seconds)
        self.report.deliveries.append((link.label, claim.t, seconds, link.nodes))

    def _unclaimed(self, link: Link, item: _Got, source: Port) -> None:
        """A received message (key, seq, send time) that the sender's trace does not hold."""
        seq = item.ident[0]
        sender = source.node
        sent_t = self._node_t(sender, item.ident[1])
        last = max((c.t for c in self.claims.get(item.key, [])), default=None)
        trace_end = self.life[sender].trace_end if sender in self.life else None
        if self._in_gap(item.key, seq) or self._trace_gap(sender):
            self._finding(link, "untraced", item.t, f"#{seq} received at t={item.t:.6g}; {sender}'s trace lost "
                          "events there (a sequence gap), so it may have claimed it", False)
            return
        if sent_t is not None and trace_end is not None and sent_t > trace_end and (last is None or sent_t > last):
            self._finding(link, "untraced", item.t, f"#{seq} received at t={item.t:.6g} was sent at t={sent_t:.6g}, "
                          f"after {sender}'s recorded trace ends (t={trace_end:.6g}; a killed node loses its "
                          "last trace period)", False)
            return
        link.unexplained += 1
        self._finding(link, "unexplained", item.t, f"{item.node} took #{seq} ({_short(item.value)}) on {item.key} at "
                      f"t={item.t:.6g}, and {sender}'s trace claims no such message")

    def _check_outside(self, system: RecordedSystem, sources_of: dict[Port, list[Port]], output_keys: set[str]) -> None:
        """Inputs from keys that no binding names (`iotad pub`, a foreign publisher): fine into an
        input that is external (declared, or bound to nothing); unexplained into a bound one. In a
        direct recording, also messages on input keys that no node took."""
        name = system.name
        bound_keys = {t: {wire.channel_key(name, s.node, s.channel, s.index) for s in sources}
                      for t, sources in sources_of.items()}
        links: dict[Port, Link] = {}
        received: set[tuple[str, tuple[int, int]]] = set()
        for node, events in self.events.items():
            for event in events:
                if event.kind != "input":
                    continue
                key = event.key
                port = Port(node, event.action, event.index)
                if key is None:
                    if port in sources_of:
                        continue  # a bound input without a key (virtual time): the binding's
                    if self._inside_composite(node, event.iota):
                        continue  # one part of a composite node to another, in its own process
                    key = "(input script)"  # virtual time: posted into an external input
                elif key.startswith(CAN_KEY_PREFIX) or node in system.bus_nodes:
                    continue  # a CAN frame: the bus check's
                elif key in bound_keys.get(port, ()) or any(key in keys for p, keys in bound_keys.items()
                                                            if p.node == node):
                    continue
                ident = event.ident
                if ident is not None:
                    received.add((key, ident))
                link = links.get(port)
                if link is None:
                    link = links[port] = Link(f"(outside) -> {port}", "external", (node,))
                link.sent += 1
                t = event.t
                if port in sources_of and port not in system.external:
                    link.unexplained += 1
                    self._finding(link, "unexplained", t, f"{node} took {_short(event.value)} from {key}, "
                                  f"which the system file does not bind to {port} (nor declares it external)")
                else:
                    link.delivered += 1
        self.report.links += [links[p] for p in sorted(links, key=str)]
        if self.mode != "direct":
            return  # elsewhere such messages are on the file only because a node took them
        for key in self.wire:
            if key in output_keys:
                continue
            for message in self._on_wire(key):
                if (key, message.ident) in received:
                    continue
                parsed = wire.parse_key(key)
                link = Link(f"(outside) -> {key}", "external", (parsed[1],))
                self.report.links.append(link)
                link.unexplained += 1
                self._finding(link, "unexplained", message.t, f"#{message.ident[0]} ({_short(message.value)}) on "
                              f"{key}: no node's output, and no node took it")

    # -- CAN
    def _check_bus(self, bus: str, stations: list[str]) -> None:
        """Frames each station sent (can_tx outputs) against the frames each other station received
        (can_rx inputs), by content and per-sender order (a CAN controller sends in FIFO order).
        Linear in the frames: each sender's unreceived frames wait in one queue per content."""
        sent: dict[str, list[tuple[float, tuple]]] = {}
        for s in stations:
            events = self.events.get(s, [])
            refused = {e.t for e in events if e.kind == "violation" and e.action == CAN_TX
                       and (e.raw.get("value") or {}).get("violation") == "can_send_failed"}
            frames = []
            for e in events:
                if e.kind == "output" and e.action == CAN_TX:
                    t = e.t
                    if t in refused:  # the port could not send it (recorded): nobody could receive it
                        refused.discard(t)
                        continue
                    frames.append((t, _frame(e.value)))
            sent[s] = frames
        self._check_bus_log(bus, stations, sent)
        window = self._can_window()  # a frame may wait behind others on a busy bus
        for receiver in stations:
            # (t, frame) of each frame it received
            got = [(e.t, _frame(e.value)) for e in self.events.get(receiver, [])
                   if e.kind == "input" and e.action == CAN_RX]
            senders = [s for s in stations if s != receiver]
            links = {s: Link(f"can {bus}: {s} -> {receiver}", "can", (s, receiver), sent=len(sent[s]))
                     for s in senders}
            self.report.links += list(links.values())
            waiting = _frame_queues(sent, senders)
            life = self.life.get(receiver)
            if life is not None:
                _unheard_before_start(waiting, sent, got, life)
            taken: dict[str, set[int]] = {s: set() for s in senders}
            last_taken: dict[str, int] = {}
            foreign: list[tuple[float, tuple]] = []
            heard_until = -math.inf  # the latest send time among the frames it received so far
            starts = [run[0] for run in life.runs] if life is not None and life.seen \
                and life.virtual_end is None else []

            def run_start(t: float) -> float:  # the engine start of the receiver's process at t
                k = _last_at_or_before(starts, t)
                return starts[k] if k >= 0 else -math.inf
            for t, frame in got:
                best = None
                for s in senders:
                    queue = waiting[s].get(frame)
                    if not queue:
                        continue
                    # an older twin was lost if the receiver already got a frame its sender sent
                    # after it (per-sender FIFO), or one any station sent well after it (the bus
                    # is one FIFO): a receiver that was frozen drains its backlog in order, late
                    while len(queue) > 1 and sent[s][queue[-2]][0] <= t + self.tolerance and (
                            queue[-1] < last_taken.get(s, -1)
                            or sent[s][queue[-1]][0] + window < heard_until
                            or sent[s][queue[-1]][0] + window < run_start(t)):
                        queue.pop()
                    k = queue[-1]
                    if sent[s][k][0] <= t + self.tolerance and (best is None or sent[s][k][0] < sent[best[0]][best[1]][0]):
                        best = (s, k)
                if best is None:
                    foreign.append((t, frame))
                    continue
                s, k = best
                waiting[s][frame].pop()
                taken[s].add(k)
                heard_until = max(heard_until, sent[s][k][0])
                link = links[s]
                t_sent = sent[s][k][0]
                if k < last_taken.get(s, -1):
                    self._finding(link, "reordered", t_sent,
                                  f"frame {_frame_text(frame)} received at t={t:.6g}, after a frame {s} sent later")
                last_taken[s] = max(k, last_taken.get(s, -1))
                link.delivered += 1
                latency = (t - t_sent) * self.unit
                link.latencies.append(latency)
                self.report.deliveries.append((link.label, t_sent, latency, link.nodes))
            by_head: dict[str, dict[tuple, deque]] = {s: {} for s in senders}
            for s in senders:
                for k, (_, frame) in enumerate(sent[s]):
                    if k not in taken[s]:
                        by_head[s].setdefault(frame[:3], deque()).append(k)
            altered: dict[str, set[int]] = {s: set() for s in senders}
            for t, frame in foreign:  # a frame no station sent: altered if one of the same id is missing
                pick = None
                for s in senders:
                    queue = by_head[s].get(frame[:3])
                    if queue and sent[s][queue[0]][0] <= t + self.tolerance and \
                            (pick is None or sent[s][queue[0]][0] < sent[pick][by_head[pick][frame[:3]][0]][0]):
                        pick = s
                if pick is None:
                    if self.virtual and Port(receiver, CAN_RX, None) in self.system.external:
                        # an input script's frame into a can_rx the system file declares external
                        self.report.notes.append(DeliveryFinding(
                            "external", f"can {bus}: (outside) -> {receiver}", t, f"{receiver} received frame "
                            f"{_frame_text(frame)} from outside (its {CAN_RX} is external)", False, (receiver,)))
                    elif self.virtual:  # every station of the modelled bus is a node: the frame is no one's
                        link = Link(f"can {bus}: (no station) -> {receiver}", "can", (receiver,))
                        self.report.links.append(link)
                        link.unexplained += 1
                        self._finding(link, "unexplained", t, f"{receiver} received frame {_frame_text(frame)}, "
                                      "which no station's can_tx sent")
                    else:
                        self.report.notes.append(DeliveryFinding(
                            "foreign", f"can {bus}: -> {receiver}", t, f"{receiver} received frame "
                            f"{_frame_text(frame)}, which no station's can_tx sent (a device that is not a node, "
                            "or a station's final frames)", False, (receiver,)))
                    continue
                k = by_head[pick][frame[:3]].popleft()
                altered[pick].add(k)
                links[pick].altered += 1
                self._finding(links[pick], "altered", sent[pick][k][0], f"{pick} sent frame "
                              f"{_frame_text(sent[pick][k][1])}, {receiver} received {_frame_text(frame)} at t={t:.6g}")
            for s in senders:
                for k, (t_sent, frame) in enumerate(sent[s]):
                    if k in taken[s] or k in altered[s]:
                        continue
                    life = self.life.get(receiver)
                    if life is not None and life.before_start(t_sent):
                        # a real bus delivers only to sockets open at the time: a station that had
                        # not started could not hear it, whatever it heard later
                        verdict, reason = life.judge(t_sent, window, receiver)
                    elif k < last_taken.get(s, -1):
                        verdict = "lost"
                        reason = (life is not None and life.down(t_sent, window, receiver)) or \
                            f"{receiver} received frames {s} sent after it"
                    elif receiver in self.life:
                        verdict, reason = self.life[receiver].judge(t_sent, window, receiver)
                    else:
                        verdict, reason = "unjudged", f"{receiver} is not in this recording"
                    self._unmatched_frame(links[s], verdict, reason, t_sent, frame, f"never reached {receiver}")

    def _unmatched_frame(self, link: Link, verdict: str, reason: str, t_sent: float, frame: tuple,
                         missed: str) -> None:
        """A sent frame nobody matched: counted and reported lost, or not judged, by `verdict`."""
        if verdict == "lost":
            link.lost += 1
            self._finding(link, "lost", t_sent, f"frame {_frame_text(frame)} sent at t={t_sent:.6g} {missed}; {reason}")
        else:
            link.unjudged += 1
            self._finding(link, "not judged", t_sent, f"frame {_frame_text(frame)}: {reason}", False)

    def _can_window(self) -> float:
        """How long a frame may wait for the bus before a later twin of it stands for it (the older
        one lost). The modelled bus of virtual time loses nothing and queues without bound: a
        congested one (50 kbit/s) delays frames by seconds, in each station's order."""
        return math.inf if self.virtual else GRACE / self.unit

    def _check_bus_log(self, bus: str, stations: list[str], sent: dict[str, list[tuple[float, tuple]]]) -> None:
        """Each station's can_tx frames against the bus's own log of the frames it carried (the
        modelled bus's `frames` output, `iotad.can.frame_log`: sender station and frame), in the
        station's order: a frame sent and never on the bus is lost, a frame on the bus its station
        never sent is unexplained (or altered, when one of the same id is missing)."""
        key = wire.channel_key(self.system.name, bus, BUS_LOG, None)
        log = self._on_wire(key)
        if not log:
            return
        params = (self.specs.get(bus) or {}).get("params") or {}
        fifo = params.get("station_queue", "fifo") == "fifo"  # else a station's frames may overtake
        window = self._can_window()
        links = {s: Link(f"can {bus}: {s} -> (bus)", "can", (s,), sent=len(sent[s])) for s in stations}
        self.report.links += list(links.values())
        waiting = _frame_queues(sent, stations)
        taken: dict[str, set[int]] = {s: set() for s in stations}
        last_taken: dict[str, int] = {}
        strays: list[tuple[float | None, str | None, tuple, Any]] = []
        # a real bus's log: no station, and none sent it; with the send time of the frame logged
        # before it (the log is in bus order, so a changed frame was sent after that one)
        nameless: list[tuple[float | None, tuple, float | None]] = []
        previous_sent: float | None = None
        end = max((m.t for m in log if m.t is not None), default=None)
        # a real-time log is a node (iotad.can.frame_log.BusLogger): it logs only while it runs
        logger = self.life.get(bus) if not self.virtual and bus not in self.system.bus_nodes else None
        for message in log:
            value = message.value
            value = value if isinstance(value, dict) else {}
            station = value.get("station")
            frame, t = _frame(value), message.t
            if station is None:  # a listener that cannot tell the sender: the station that sent it first
                heads = [(sent[x][waiting[x][frame][-1]][0], x) for x in stations if waiting[x].get(frame)]
                if not heads:
                    nameless.append((t, frame, previous_sent))
                    continue
                s = min(heads)[1]
            else:
                s = stations[station] if isinstance(station, int) and 0 <= station < len(stations) else None
            queue = waiting[s].get(frame) if s is not None else None
            if queue and t is not None:
                while len(queue) > 1 and sent[s][queue[-1]][0] < t - window \
                        and sent[s][queue[-2]][0] <= t + self.tolerance:
                    queue.pop()  # an older twin that waited past the window never made it
            if not queue or (t is not None and sent[s][queue[-1]][0] > t + self.tolerance):
                strays.append((t, s, frame, station))
                continue
            k = queue.pop()
            taken[s].add(k)
            t_sent = previous_sent = sent[s][k][0]
            if fifo and k < last_taken.get(s, -1):
                self._finding(links[s], "reordered", t_sent, f"frame {_frame_text(frame)} went on the bus at "
                              f"t={t:.6g}, after a frame {s} sent later")
            last_taken[s] = max(k, last_taken.get(s, -1))
            links[s].delivered += 1
            if t is not None:
                links[s].latencies.append((t - t_sent) * self.unit)
        altered: dict[str, set[int]] = {s: set() for s in stations}
        for t, s, frame, station in strays:
            if s is None:
                link = Link(f"can {bus}: station {station!r} -> (bus)", "can", ())
                self.report.links.append(link)
                link.unexplained += 1
                self._finding(link, "unexplained", t, f"the bus carried frame {_frame_text(frame)} from station "
                              f"{station!r}, which is none of {stations}")
                continue
            twin = next((k for k in range(len(sent[s])) if k not in taken[s] and k not in altered[s]
                         and sent[s][k][1][:3] == frame[:3] and (t is None or sent[s][k][0] <= t + self.tolerance)),
                        None)
            if twin is not None:
                altered[s].add(twin)
                links[s].altered += 1
                self._finding(links[s], "altered", sent[s][twin][0], f"{s} sent frame {_frame_text(sent[s][twin][1])},"
                              f" the bus carried {_frame_text(frame)}" + ("" if t is None else f" at t={t:.6g}"))
                continue
            life = self.life.get(s)
            lost_trace = life.untraced_at(t) if life is not None and t is not None else None
            if lost_trace is not None:
                self._finding(links[s], "untraced", t, f"the bus carried frame {_frame_text(frame)} from {s} after "
                              f"{s}'s recorded trace of that run ends (t={lost_trace:.6g}; a killed node loses its "
                              "last trace period)", False)
                continue
            links[s].unexplained += 1
            self._finding(links[s], "unexplained", t, f"the bus carried frame {_frame_text(frame)} from {s}, "
                          f"and {s}'s trace holds no such can_tx")
        for t, frame, floor in nameless:  # heard on a real bus, no station's can_tx: altered, or not a node's
            twins = [(sent[x][k][0], x, k) for x in stations for k in range(len(sent[x]))
                     if k not in taken[x] and k not in altered[x] and sent[x][k][1][:3] == frame[:3]
                     and (t is None or sent[x][k][0] <= t + self.tolerance)]
            if twins:
                # the first one sent after the frame logged before it; else the latest sent by then
                # (earlier ones may predate the logger). Not simply the latest: a real-time log's
                # time is when the logger published, and frames sent after the logger stopped are
                # missing from it too.
                later = [twin for twin in twins if floor is not None and twin[0] >= floor - window]
                _, s, k = min(later) if later else max(twins)
                altered[s].add(k)
                links[s].altered += 1
                self._finding(links[s], "altered", sent[s][k][0], f"{s} sent frame {_frame_text(sent[s][k][1])}, "
                              f"the bus carried {_frame_text(frame)}" + ("" if t is None else f" at t={t:.6g}"))
                continue
            self.report.notes.append(DeliveryFinding(
                "foreign", f"can {bus}: (bus)", t, f"the bus carried frame {_frame_text(frame)}, which no "
                "station's can_tx sent (a device that is not a node, or a station's final frames)", False, ()))
        for s in stations:
            for k, (t_sent, frame) in enumerate(sent[s]):
                if k in taken[s] or k in altered[s]:
                    continue
                down = _logger_down(logger, bus, t_sent, window) if logger is not None else None
                if down is not None:
                    verdict, reason = "unjudged", down
                elif fifo and k < last_taken.get(s, -1):
                    verdict, reason = "lost", f"the bus carried frames {s} sent after it"
                elif logger is not None and logger.seen:
                    verdict, reason = "lost", f"the bus logger {bus} was running"
                elif end is not None and t_sent + window <= end:
                    verdict, reason = "lost", f"the bus logged frames until t={end:.6g}"
                else:
                    verdict, reason = "unjudged", "in flight (queued or on the bus) when the run ended"
                self._unmatched_frame(links[s], verdict, reason, t_sent, frame, "never went on the bus")


def _logger_down(life: _Life, bus: str, t: float, window: float) -> str | None:
    """Why the real-time bus logger `bus` could not have logged a frame sent at `t` (it had not
    started, was down, or the run ended within `window`), or None: it was listening."""
    if not life.seen:
        return f"the bus logger {bus} has no trace in this recording"
    starts = [run[0] for run in life.runs]
    k = _last_at_or_before(starts, t)
    if k < 0:
        return f"sent before the bus logger {bus} started (t={starts[0]:.6g}): it could not hear it"
    last = life.runs[k][1]
    if t + window <= last:
        return None
    if k + 1 < len(life.runs):
        return (f"sent while the bus logger {bus} was down: its last sign of life at t={last:.6g}, "
                f"restarted at t={life.runs[k + 1][0]:.6g}")
    return f"in flight when the run ended: the bus logger {bus}'s last sign of life is at t={last:.6g}"


def _frame_queues(sent: dict[str, list], stations) -> dict[str, dict[tuple, list[int]]]:
    """Per station: each frame it sent -> the indices of its sends of that frame, the earliest
    last (a receiver's or the log's copy is matched to the earliest one not yet taken: `queue[-1]`,
    taken with `queue.pop()`). A list, not a deque: most frames are sent once (their data differ),
    and a deque of one costs 800 bytes, a list of one about 100."""
    waiting: dict[str, dict[tuple, list[int]]] = {s: {} for s in stations}
    for s in stations:
        for k, (_, frame) in enumerate(sent[s]):
            waiting[s].setdefault(frame, []).append(k)
        for queue in waiting[s].values():
            queue.reverse()
    return waiting


def _unheard_before_start(waiting: dict[str, dict[tuple, list[int]]], sent: dict[str, list],
                          got: list[tuple[float, tuple]], life: Any) -> None:
    """Take out of the candidates the frames a receiver cannot have heard: sent before its
    engine started, before its socket was open. A socket opened a little before the engine
    starts hears the last of them, so of the twins (the same frame, sent again and again, as an
    ODrive's heartbeat is) sent before the start it keeps as many as it received beyond those
    sent after; the earlier ones, if left, would be paired with its first receptions, and every
    reception after with a frame sent periods before it (false 'reordered', then 'lost')."""
    received: dict[tuple, int] = {}
    for _, frame in got:
        received[frame] = received.get(frame, 0) + 1
    for sender, queues in waiting.items():
        for frame, queue in queues.items():
            before = sum(1 for k in queue if life.before_start(sent[sender][k][0]))  # the earliest sends
            if not before:
                continue
            keep = max(0, received.get(frame, 0) - (len(queue) - before))
            for _ in range(before - keep):
                queue.pop()


def _frame(value: Any) -> tuple:
    """A canFrame value as CAN compares it: id, extended, rtr, then the dlc valid data bytes."""
    if not isinstance(value, dict):
        return ("?", repr(value))
    data = value.get("data") or []
    dlc = value.get("dlc")
    dlc = dlc if isinstance(dlc, int) else len(data)
    return (value.get("id"), bool(value.get("extended")), bool(value.get("rtr")), dlc, tuple(data[:dlc]))


def _frame_text(frame: tuple) -> str:
    if len(frame) != 5 or not isinstance(frame[0], int):
        return str(frame[-1])
    ident, extended, rtr, dlc, data = frame
    head = f"0x{ident:0{8 if extended else 3}X}"
    return head + (f" RTR dlc {dlc}" if rtr else " [" + " ".join(f"{b:02X}" for b in data if isinstance(b, int)) + "]")


def _align(items: list, candidates: list, t_item, t_candidate, before: float, after: float, same) -> list[tuple]:
    """Pair each of `items` (taken in time order) with the earliest free candidate whose time lies
    in [t - before, t + after], preferring one of the same value; (item, None) when there is none."""
    candidates = sorted(candidates, key=t_candidate)
    used = [False] * len(candidates)
    out = []
    start = 0
    for item in sorted(items, key=t_item):
        t = t_item(item)
        while start < len(candidates) and t_candidate(candidates[start]) < t - before:
            start += 1  # too early for this item, so for every later one too
        first = chosen = None
        k = start
        while k < len(candidates) and t_candidate(candidates[k]) <= t + after:
            if not used[k]:
                first = k if first is None else first
                if same(item, candidates[k]):
                    chosen = k
                    break
            k += 1
        chosen = first if chosen is None else chosen
        if chosen is not None:
            used[chosen] = True
        out.append((item, None if chosen is None else candidates[chosen]))
    return out


_WITNESS = {
    "virtual": "one engine wrote the traces and the wire, deliveries are exact; the check proves "
               "the file consistent",
    "traces": "the wire was rebuilt from the senders' traces, so sender vs wire shows only an "
              "edited or damaged file; sender vs receiver compares two processes' own accounts",
    "direct": "the recorder subscribed to the keys itself, a third witness between sender and receiver",
    "unknown": "recording of unknown origin: the wire is taken as recorded",
}


def check_delivery(recording: Recording, *, tolerance: float = 1e-9, node: str | None = None,
                   grace: float | None = None) -> DeliveryReport:
    """Cross-check every binding (and CAN bus) of the recorded system: see the module docstring.
    `tolerance` is in spec time units; `grace` in seconds (default `GRACE`)."""
    return DeliveryChecker(recording, tolerance, grace).check(node)


def problem_marks(report: DeliveryReport, late: float | None = None) -> list[tuple[float, str, str]]:
    """(t, code, text) of what a timeline may mark: every problem, and with `late` (seconds) every
    delivery slower than that (code 'late')."""
    marks = [(f.t, f.code, f"{f.link}: {f.code}") for f in report.findings if f.problem and f.t is not None]
    if late is not None:
        marks += [(t, "late", f"{label}: {latency * 1e3:.3g} ms") for label, t, latency, _ in report.deliveries
                  if latency > late]
    return sorted(marks, key=lambda m: m[0])


__all__: Iterable[str] = ["DeliveryReport", "DeliveryFinding", "Link", "check_delivery", "problem_marks",
                          "recorded_system", "GRACE"]
