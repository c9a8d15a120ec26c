"""The delivery checks of messages, each a function from the accounts (`delivery_accounts.py`)
to report rows: one output key against the wire (`check_wire`), one bound input against the
claims of the outputs bound to it (`check_target`), and inputs from outside, bound to no
output (`check_outside`). docs/checking.md, "Delivery", says what each verdict means.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

from iotad.node_host import wire
from iotad.node_host.can_port import KEY_PREFIX as CAN_KEY_PREFIX
from iotad.kernel.engine import INPUT_REFUSALS
from iotad.kernel.ports import Port
from iotad.recording.delivery_accounts import Accounts, Got, OnWire, Sent, ident_of, same_value, short
from iotad.recording.delivery_report import Link, Rows
from iotad.recording.values import values_equal

REJECTIONS = (*INPUT_REFUSALS, "malformed_payload")  # a receiver saw it and refused it (the engine, or its host)
OVERFLOW = "input_overflow"  # a receiver's full input queue dropped `dropped` inputs between two times
_BETWEEN = re.compile(r"between t=(?P<first>[-+\d.eE]+) and t=(?P<last>[-+\d.eE]+)")


def output_keys(acc: Accounts) -> set[str]:
    """The keys of outputs: claimed on a trace, bound, or recorded where a spec says an output is."""
    system = acc.system
    keys = set(acc.claims)
    keys |= {wire.channel_key(system.name, s.node, s.channel, s.index) for s, _ in system.bindings}
    for topic in acc.wire:
        parsed = wire.parse_key(topic)
        spec = acc.specs.get(parsed[1]) or {}
        for entry in spec.get("channels") or []:
            if isinstance(entry, dict) and entry.get("name") == parsed[2] and entry.get("direction") == "output":
                keys.add(topic)
    return keys


def check_wire(acc: Accounts, key: str) -> Rows:
    """The sender's claims on `key` against the messages the recording holds on it."""
    rows = Rows()
    claims = acc.claims.get(key, [])
    if not acc.covered(key):
        return rows
    messages = acc.on_wire(key)
    parsed = wire.parse_key(key)
    sender = parsed[1] if parsed else "?"
    port = Port(sender, parsed[2], parsed[3]) if parsed else None
    link = rows.link(f"{port} -> (wire)", "wire", (sender,), sent=len(claims))
    by_ident: dict[tuple[int, int], list[OnWire]] = {}
    if any(claim.ident is not None for claim in claims):  # none does in virtual time: no need
        for message in messages:
            by_ident.setdefault(message.ident, []).append(message)
    matched: set[int] = set()
    unkeyed: list[Sent] = []
    for claim in claims:
        if claim.ident is None:
            unkeyed.append(claim)
            continue
        found = next((m for m in by_ident.get(claim.ident, ()) if id(m) not in matched), None)
        if found is None:
            _wire_lost(acc, rows, link, key, claim)
            continue
        matched.add(id(found))
        _compare_wire(rows, link, claim, found)
    if unkeyed:
        rest = [m for m in messages if id(m) not in matched and m.t is not None]
        pairs = _align(unkeyed, rest, lambda c: c.t, lambda m: m.t, acc.tolerance, acc.tolerance + acc.grace,
                       same_value)
        for claim, found in pairs:
            if found is None:
                # on the wire with its value, near its time, and taken by no other claim:
                # that message, mistimed (as a receipt can be, `_check_target`)
                found = acc.mistimed(rest, claim.t, lambda m: id(m) not in matched and same_value(claim, m))
                if found is not None:
                    matched.add(id(found))
                    _mistimed(acc, rows, link, claim, "published", f"is on the wire at t={found.t:.6g}", found.t)
                    continue
                _wire_lost(acc, rows, link, key, claim)
            else:
                matched.add(id(found))
                _compare_wire(rows, link, claim, found)
    taken = {m.ident for m in messages if id(m) in matched}
    for message in messages:
        if id(message) in matched:
            continue
        if message.ident in taken:
            link.duplicated += 1
            rows.finding(link, "duplicated", message.t, f"#{message.ident[0]} is on the wire twice")
            continue
        link.unexplained += 1
        rows.finding(link, "unexplained", message.t,
                      f"#{message.ident[0]} ({short(message.value)}) is on the wire, and {sender}'s trace "
                      f"claims no such message")
    return rows


def _mistimed(acc: Accounts, rows: Rows, link: Link, claim: Sent, sent: str, found: str, t: float) -> None:
    """`claim` found (on the wire, or received) at `t`, another time than it was sent: altered."""
    link.altered += 1
    rows.finding(link, "altered", claim.t, f"{claim.label} ({short(claim.value)}), {sent} at t={claim.t:.6g}, "
                 f"{found}: {abs(t - claim.t) * acc.unit * 1e3:.3g} ms from its time, beyond the tolerance")


def _wire_lost(acc: Accounts, rows: Rows, link: Link, key: str, claim: Sent) -> None:
    if claim.ident and acc.in_gap(key, claim.ident[0]):
        rows.finding(link, "not recorded", claim.t, f"{claim.label} ({short(claim.value)}): the recorder saw a "
                      "sequence gap here: it missed the message, which says nothing of its delivery", False)
        return
    link.lost += 1
    rows.finding(link, "lost", claim.t, f"{claim.label} ({short(claim.value)}): {claim.node}'s trace says it was "
                  "published; the wire holds no such message")


def _compare_wire(rows: Rows, link: Link, claim: Sent, message: OnWire) -> None:
    if same_value(claim, message):
        link.delivered += 1
        return
    link.altered += 1
    rows.finding(link, "altered", claim.t, f"{claim.label}: {claim.node} sent {short(claim.value)}, the wire "
                  f"carried {short(message.value)}")


def _inputs(acc: Accounts, target: Port, keys: set[str]) -> tuple[list[Got], list[dict]]:
    """The receiver's input events and rejections (whole events) that concern `target`
    (bound from `keys`)."""
    got, rejected = [], []
    several = sum(1 for s, t in acc.system.bindings if t.node == target.node and
                  wire.channel_key(acc.system.name, s.node, s.channel, s.index) in keys) > 1
    for event in acc.events.get(target.node, []):
        kind = event.kind
        here = event.action == target.channel and event.index == target.index
        if kind == "input":
            key = event.key
            if key is not None and key in keys:
                if several and not here:
                    continue  # one key bound to two inputs of this node: the other one's
            elif key is not None or not here:
                continue
            got.append(Got(target.node, key, event.t, event.data, event.start, event.end, event.ident,
                            event.action, event.index))
        elif kind == "violation" and here and (event.raw.get("value") or {}).get("violation") in REJECTIONS + (OVERFLOW,):
            rejected.append(event.raw)
    return got, rejected


@dataclass
class _Target:
    """One bound input and the claims of the outputs bound to it, as they are taken."""

    target: Port
    keys: dict[str, Port]                 # key of a bound output -> the output
    links: dict[str, Link]                # key of a bound output -> its row
    claims: list[Sent]
    by_ident: dict[tuple, Sent] = field(default_factory=dict)      # (key, ident) -> the claim
    taken: dict[int, Got | None] = field(default_factory=dict)    # id(claim) -> the input that took it (None: refused)

    def __post_init__(self) -> None:
        self.by_ident = {(c.key, c.ident): c for c in self.claims if c.ident is not None}


def check_target(acc: Accounts, target: Port, sources: list[Port]) -> Rows:
    """Every claim of the outputs bound to `target` against what `target`'s node took."""
    rows = Rows()
    name = acc.system.name
    keys = {wire.channel_key(name, s.node, s.channel, s.index): s for s in sources}
    got, rejections = _inputs(acc, target, set(keys))
    links = {key: rows.link(f"{source} -> {target}", "binding", (source.node, target.node),
                            sent=len(acc.claims.get(key, []))) for key, source in keys.items()}
    bound = _Target(target, keys, links, [c for key in keys for c in acc.claims.get(key, [])])
    unkeyed = _keyed(acc, rows, bound, got)
    if unkeyed:
        _unkeyed(acc, rows, bound, unkeyed)
    _refused(acc, bound, rejections)
    _untaken(acc, rows, bound)
    return rows


def _keyed(acc: Accounts, rows: Rows, bound: _Target, got: list[Got]) -> list[Got]:
    """Match the inputs that name their message (key, seq, send time) to its claim exactly;
    returns the inputs that name none (virtual time)."""
    last_ordinal: dict[str, int] = {}
    unkeyed: list[Got] = []
    taken = bound.taken
    for item in got:
        claim = bound.by_ident.get((item.key, item.ident)) if item.ident is not None and item.key else None
        if item.ident is None or item.key is None:
            unkeyed.append(item)
            continue
        link = bound.links[item.key]
        if claim is None:
            _unclaimed(acc, rows, link, item, bound.keys[item.key])
            continue
        if id(claim) in taken:
            link.duplicated += 1
            rows.finding(link, "duplicated", claim.t, f"#{claim.ident[0]} ({short(claim.value)}) received "
                         f"again at t={item.t:.6g} (first at t={taken[id(claim)].t:.6g})")
            continue
        taken[id(claim)] = item
        if claim.ordinal < last_ordinal.get(claim.key, -1):
            rows.finding(link, "reordered", claim.t, f"#{claim.ident[0]} received at t={item.t:.6g}, after a "
                         "message sent later")
        last_ordinal[claim.key] = max(claim.ordinal, last_ordinal.get(claim.key, -1))
        _delivered(acc, rows, link, claim, item)
    return unkeyed


def _unkeyed(acc: Accounts, rows: Rows, bound: _Target, unkeyed: list[Got]) -> None:
    """Match the inputs that name no message to the claims by time and value (virtual time: a
    binding delivers at the instant of the firing); what matches none is a mistimed message,
    a duplicate, an input from outside or unexplained."""
    target, links, claims, taken = bound.target, bound.links, bound.claims, bound.taken
    free = sorted((c for c in claims if id(c) not in taken), key=lambda c: c.t)
    window = acc.tolerance + acc.grace
    pairs = _align(unkeyed, free, lambda g: g.t, lambda c: c.t, window, acc.tolerance, same_value)
    decoded: dict[int, Any] = {}  # id(claim) -> its value: each item below is compared with many

    def value_of(claim: Sent) -> Any:
        if id(claim) not in decoded:
            decoded[id(claim)] = claim.value
        return decoded[id(claim)]

    for item, claim in pairs:
        if claim is not None:
            taken[id(claim)] = item
            _delivered(acc, rows, links[claim.key], claim, item)
            continue
        value = item.value
        # a message sent with this value and taken by no receipt, near in time: the one
        # received, at another time than it was sent (an edited recording, a clock gone
        # wrong). Said as such, once, instead of the claim "lost" and this receipt
        # "duplicated" (of an earlier message with the same value) or "unexplained"
        claim = acc.mistimed(claims, item.t, lambda c: id(c) not in taken and values_equal(value_of(c), value))
        if claim is not None:
            taken[id(claim)] = item
            _mistimed(acc, rows, links[claim.key], claim, "sent", f"was received at t={item.t:.6g}", item.t)
            continue
        # the same value again, after a delivery of it: a duplicate (else nobody sent it)
        twins = [c for c in claims if id(c) in taken and taken[id(c)] is not None
                 and c.t <= item.t + acc.tolerance and values_equal(value_of(c), value)]
        twin = max(twins, key=lambda c: c.t) if twins else None
        link = links[twin.key] if twin else next(iter(links.values()))
        if twin is not None:
            link.duplicated += 1
            rows.finding(link, "duplicated", twin.t, f"{short(item.value)} received again at t={item.t:.6g}")
        elif acc.virtual and target in acc.system.external:
            # bound and declared external: an input script's, posted into it from outside
            rows.note("external", f"(outside) -> {target}", item.t, f"{target.node} took {short(item.value)} at "
                      f"t={item.t:.6g} from outside ({target} is external)", (target.node,))
        else:
            link.unexplained += 1
            rows.finding(link, "unexplained", item.t, f"{target.node} took {short(item.value)} at "
                         f"t={item.t:.6g}, and no sender bound to {target} sent it")


def _refused(acc: Accounts, bound: _Target, rejections: list[dict]) -> None:
    """The messages the receiver saw and refused (a recorded rejection): no loss."""
    claims, taken = bound.claims, bound.taken
    for event in rejections:
        t = float(event["t"])
        value = event.get("value") or {}
        if value.get("violation") == OVERFLOW:
            _overflowed(acc, bound.links, claims, taken, t, value)
            continue
        # a node host names the message it refused (key, seq, send_ns): that claim exactly;
        # else the latest untaken claim sent by then
        ident, key = ident_of(event), event.get("key")
        exact = bound.by_ident.get((key, ident)) if ident is not None and key else None
        candidates = [exact] if exact is not None and id(exact) not in taken else \
            [c for c in claims if id(c) not in taken and t - acc.tolerance - acc.grace <= c.t <= t + acc.tolerance]
        if not candidates:
            continue
        claim = max(candidates, key=lambda c: c.t)
        taken[id(claim)] = None
        bound.links[claim.key].rejected += 1


def _untaken(acc: Accounts, rows: Rows, bound: _Target) -> None:
    """Every claim the receiver never took: lost, or not judged (it was not running)."""
    target = bound.target
    for claim in bound.claims:
        if id(claim) in bound.taken:
            continue
        link = bound.links[claim.key]
        verdict, reason = acc.life[target.node].judge(claim.t, acc.grace, target.node) \
            if target.node in acc.life else ("unjudged", f"{target.node} is not in this recording")
        unheard = acc.unheard(target.node, claim.t)
        if verdict == "lost" and unheard is not None:
            # the receiver's events of then never reached the recording: it may have taken it
            verdict, reason = "unjudged", (f"sent while {target.node}'s trace misses events this recording never "
                                           f"heard (t={unheard[0]:.6g}..{unheard[1]:.6g}: {unheard[2]}): it may "
                                           f"have taken it then")
        if verdict == "lost":
            link.lost += 1
            rows.finding(link, "lost", claim.t, f"{claim.label} ({short(claim.value)}) sent at t={claim.t:.6g} "
                         f"never reached {target}; {reason}")
        else:
            link.unjudged += 1
            rows.finding(link, "not judged", claim.t, f"{claim.label}: {reason}", False)


def _overflowed(acc: Accounts, links: dict[str, Link], claims: list[Sent], taken: dict, t: float, value: dict) -> None:
    """An `input_overflow` the receiver recorded: it dropped `dropped` inputs received between
    two times (its message says which): so many untaken claims sent by then were refused."""
    count = value.get("dropped")
    count = count if isinstance(count, int) and not isinstance(count, bool) else 1
    match = _BETWEEN.search(str(value.get("message") or ""))
    first, last = (float(match["first"]), float(match["last"])) if match else (-math.inf, t)
    window = acc.tolerance + acc.grace
    candidates = [c for c in claims if id(c) not in taken and first - window <= c.t <= last + acc.tolerance]
    for claim in sorted(candidates, key=lambda c: c.t)[:count]:
        taken[id(claim)] = None
        links[claim.key].rejected += 1


def _delivered(acc: Accounts, rows: Rows, link: Link, claim: Sent, item: Got) -> None:
    latency = item.t - claim.t
    if not same_value(claim, item):
        link.altered += 1
        rows.finding(link, "altered", claim.t, f"{claim.label}: {claim.node} sent {short(claim.value)}, "
                      f"{item.node} received {short(item.value)} at t={item.t:.6g}")
        return
    # each end's time is on the hub's timeline only within its host's clock bound (a host's
    # offset to the hub is measured, not known): received before sent by less than the two
    # bounds is within what the clocks can tell (a merge of hosts on one machine showed 0.03 ms)
    if latency < -(acc.tolerance + acc.clock_bound(claim.node, claim.t) + acc.clock_bound(item.node, item.t)):
        rows.finding(link, "causality", claim.t, f"received at t={item.t:.6g}, {-latency * acc.unit * 1e3:.3g} ms "
                      f"before it was sent")
    rows.delivered(link, claim.t, latency * acc.unit)


def _unclaimed(acc: Accounts, rows: Rows, link: Link, item: Got, source: Port) -> None:
    """A received message (key, seq, send time) that the sender's trace does not hold."""
    seq = item.ident[0]
    sender = source.node
    sent_t = acc.node_t(sender, item.ident[1])
    last = max((c.t for c in acc.claims.get(item.key, [])), default=None)
    trace_end = acc.life[sender].trace_end if sender in acc.life else None
    if acc.trace_not_held(sender):
        rows.finding(link, "untraced", item.t, f"#{seq} received at t={item.t:.6g}; {sender}'s trace is not in this "
                      "recording, which was made to hold other nodes' (merge the hosts' recordings to judge it)", False)
        return
    if acc.in_gap(item.key, seq) or acc.trace_gap(sender):
        rows.finding(link, "untraced", item.t, f"#{seq} received at t={item.t:.6g}; {sender}'s trace lost "
                      "events there (a sequence gap), so it may have claimed it", False)
        return
    if sent_t is not None and trace_end is not None and sent_t > trace_end and (last is None or sent_t > last):
        rows.finding(link, "untraced", item.t, f"#{seq} received at t={item.t:.6g} was sent at t={sent_t:.6g}, "
                      f"after {sender}'s recorded trace ends (t={trace_end:.6g}; a killed node loses its "
                      "last trace period)", False)
        return
    link.unexplained += 1
    rows.finding(link, "unexplained", item.t, f"{item.node} took #{seq} ({short(item.value)}) on {item.key} at "
                  f"t={item.t:.6g}, and {sender}'s trace claims no such message")


def check_outside(acc: Accounts, sources_of: dict[Port, list[Port]], output_keys: set[str]) -> Rows:
    """Inputs from keys that no binding names (`iotad pub`, a foreign publisher): fine into an
    input that is external (declared, or bound to nothing); unexplained into a bound one. In a
    direct recording, also messages on input keys that no node took."""
    rows = Rows()
    system = acc.system
    name = system.name
    bound_keys = {t: {wire.channel_key(name, s.node, s.channel, s.index) for s in sources}
                  for t, sources in sources_of.items()}
    links: dict[Port, Link] = {}
    received: set[tuple[str, tuple[int, int]]] = set()
    for node, events in acc.events.items():
        for event in events:
            if event.kind != "input":
                continue
            key = event.key
            port = Port(node, event.action, event.index)
            if key is None:
                if port in sources_of:
                    continue  # a bound input without a key (virtual time): the binding's
                if acc.inside_composite(node, event.iota):
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
                rows.finding(link, "unexplained", t, f"{node} took {short(event.value)} from {key}, "
                              f"which the system file does not bind to {port} (nor declares it external)")
            else:
                link.delivered += 1
    rows.links += [links[p] for p in sorted(links, key=str)]
    if acc.mode != "direct":
        return rows  # elsewhere such messages are on the file only because a node took them
    for key in acc.wire:
        if key in output_keys:
            continue
        for message in acc.on_wire(key):
            if (key, message.ident) in received:
                continue
            parsed = wire.parse_key(key)
            link = Link(f"(outside) -> {key}", "external", (parsed[1],))
            rows.links.append(link)
            link.unexplained += 1
            rows.finding(link, "unexplained", message.t, f"#{message.ident[0]} ({short(message.value)}) on "
                          f"{key}: no node's output, and no node took it")
    return rows


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
