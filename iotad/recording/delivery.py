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

The check is three parts: `delivery_accounts.py` reads the recording once into frozen accounts;
`delivery_messages.py` (bindings, wire, outside inputs) and `delivery_can.py` (buses, bus logs)
are the checks, each a function from the accounts to report rows; `delivery_report.py` holds
the rows and prints them. This module runs them in order and filters the report by node.
"""
from __future__ import annotations

from typing import Iterable

from iotad.kernel.ports import Port
from iotad.recording.delivery_accounts import GRACE, Accounts, read_accounts
from iotad.recording.delivery_can import check_bus, check_bus_log, sent_frames
from iotad.recording.delivery_messages import check_outside, check_target, check_wire, output_keys
from iotad.recording.delivery_report import (WITNESS, DeliveryFinding, DeliveryReport, Link, Rows,  # noqa: F401
                                             problem_marks)
from iotad.recording.mcap_reader import Recording
from iotad.recording.recorded_system import recorded_system

PROBLEMS = ("lost", "altered", "duplicated", "unexplained", "reordered", "causality")


def check_delivery(recording: Recording, *, tolerance: float = 1e-9, node: str | None = None,
                   grace: float | None = None) -> DeliveryReport:
    """Cross-check every binding (and CAN bus) of the recorded system: see the module docstring.
    `tolerance` is in spec time units; `grace` in seconds (default `GRACE`)."""
    info = recording.info
    mode = "virtual" if info.get("clock") == "virtual" else str(info.get("source") or "unknown")
    report = DeliveryReport(mode, WITNESS.get(mode, WITNESS["unknown"]))
    system = recorded_system(recording)
    if isinstance(system, str):
        report.checked, report.reason = False, system
        return report
    accounts = read_accounts(recording, system, tolerance, grace)
    for rows in _checks(accounts):
        report.add(rows)
    order = {"binding": 0, "external": 1, "can": 2, "wire": 3}
    report.links.sort(key=lambda link: (order.get(link.kind, 4), link.label))
    if node is not None:
        report.links = [link for link in report.links if node in link.nodes]
        report.findings = [f for f in report.findings if node in f.nodes]
        report.notes = [f for f in report.notes if node in f.nodes]
        report.deliveries = [d for d in report.deliveries if node in d[3]]
    return report


def _checks(accounts: Accounts) -> Iterable[Rows]:
    """Every check's rows, in the report's order: the wire, bindings, outside inputs, buses."""
    system = accounts.system
    sources_of: dict[Port, list[Port]] = {}
    for source, target in system.bindings:
        sources_of.setdefault(target, []).append(source)
    keys = output_keys(accounts)
    for key in sorted(keys):
        yield check_wire(accounts, key)
    for target in sorted(sources_of, key=str):
        yield check_target(accounts, target, sources_of[target])
    yield check_outside(accounts, sources_of, keys)
    for bus, stations in system.buses.items():
        sent = sent_frames(accounts, stations)
        yield check_bus_log(accounts, bus, stations, sent)
        yield check_bus(accounts, bus, stations, sent)


__all__: Iterable[str] = ["DeliveryReport", "DeliveryFinding", "Link", "check_delivery", "problem_marks",
                          "recorded_system", "GRACE"]
