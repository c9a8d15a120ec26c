"""The delivery check's report: one row (`Link`) per binding, wire key, outside input or CAN
pair with its counts and latencies, the findings (problems) and notes, and how a report is
printed (`iotad check`, `iotad info`) and marked on a timeline (`problem_marks`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

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

    def add(self, rows: Rows) -> None:
        """The rows of one check, after those of the checks before it."""
        self.links += rows.links
        self.findings += rows.findings
        self.notes += rows.notes
        self.deliveries += rows.deliveries

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


@dataclass
class Rows:
    """What one check adds to the report: links, findings, notes, deliveries (in its order)."""

    links: list[Link] = field(default_factory=list)
    findings: list[DeliveryFinding] = field(default_factory=list)
    notes: list[DeliveryFinding] = field(default_factory=list)
    # (link, t sent, latency in seconds, the nodes it concerns) of every delivery
    deliveries: list[tuple[str, float, float, tuple[str, ...]]] = field(default_factory=list)

    def link(self, label: str, kind: str, nodes: tuple[str, ...], sent: int = 0) -> Link:
        """A new row of the report."""
        link = Link(label, kind, nodes, sent=sent)
        self.links.append(link)
        return link

    def finding(self, link: Link, code: str, t: float | None, message: str, problem: bool = True) -> None:
        finding = DeliveryFinding(code, link.label, t, message, problem, link.nodes)
        (self.findings if problem else self.notes).append(finding)

    def note(self, code: str, label: str, t: float | None, message: str, nodes: tuple[str, ...] = ()) -> None:
        """A note on no link of the report (something from outside, a frame of no station's)."""
        self.notes.append(DeliveryFinding(code, label, t, message, False, nodes))

    def delivered(self, link: Link, t_sent: float, seconds: float) -> None:
        """One delivery on `link`, `seconds` after it was sent."""
        link.delivered += 1
        link.latencies.append(seconds)
        self.deliveries.append((link.label, t_sent, seconds, link.nodes))


WITNESS = {
    "virtual": "one engine wrote the traces and the wire, deliveries are exact; the check proves "
               "the file consistent",
    "traces": "the wire was rebuilt from the senders' traces, so sender vs wire shows only an "
              "edited or damaged file; sender vs receiver compares two processes' own accounts",
    "direct": "the recorder subscribed to the keys itself, a third witness between sender and receiver",
    "unknown": "recording of unknown origin: the wire is taken as recorded",
}


def problem_marks(report: DeliveryReport, late: float | None = None) -> list[tuple[float, str, str]]:
    """(t, code, text) of what a timeline may mark: every problem, and with `late` (seconds) every
    delivery slower than that (code 'late')."""
    marks = [(f.t, f.code, f"{f.link}: {f.code}") for f in report.findings if f.problem and f.t is not None]
    if late is not None:
        marks += [(t, "late", f"{label}: {latency * 1e3:.3g} ms") for label, t, latency, _ in report.deliveries
                  if latency > late]
    return sorted(marks, key=lambda m: m[0])
