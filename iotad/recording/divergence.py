"""Where a run's events part from a reference run's (the eager run's, for `iotad stress`): the
outputs whose values differ, the k-th output of a channel against the k-th of the same channel.

Timing alone is no divergence: under another policy every firing may move inside its window
and the run still do the same. What matters is the first output whose value differs, the first
of each node, and the first on a channel of decisions (at most one output a second: a
scheduler's acks, a planner's goals, not a sensor's readings), which say where the run took
another path.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Iterator

from iotad.node_host import wire
from iotad.recording.mcap_reader import iter_messages
from iotad.recording.values import values_equal

NONE = object()  # the other run has no such output

Key = tuple[str, str, Any]  # (iota path, channel, index)


@dataclass(frozen=True)
class Difference:
    """The `count`-th output (from 0) of `action` of `iota` differs: at `t` with `value` in the
    run, at `reference_t` with `reference_value` in the reference (either may be missing)."""

    iota: str
    action: str
    index: Any
    count: int
    t: float | None
    value: Any
    reference_t: float | None
    reference_value: Any
    reference_outputs: int = 0  # how many outputs the reference made on this channel in all

    @property
    def when(self) -> float:
        return self.t if self.t is not None else self.reference_t

    @property
    def channel(self) -> str:
        return self.action if self.index is None else f"{self.action}[{self.index}]"

    def line(self, time_unit: float = 1.0) -> str:
        """`t=2.3000 s vision.look: {...} (output #3; the reference's was {...} at t=2.1000 s)`"""
        t = None if self.t is None else self.t * time_unit
        reference_t = None if self.reference_t is None else self.reference_t * time_unit
        if t is None:
            return (f"t={reference_t:.4f} s {self.iota}.{self.channel}: never output in this run "
                    f"(its output #{self.count + 1}; the reference's was {_short(self.reference_value)})")
        if self.reference_value is NONE:
            return (f"t={t:.4f} s {self.iota}.{self.channel}: {_short(self.value)} (output #{self.count + 1}, "
                    "which the reference never made)")
        return (f"t={t:.4f} s {self.iota}.{self.channel}: {_short(self.value)} (output #{self.count + 1}; "
                f"the reference's was {_short(self.reference_value)} at t={reference_t:.4f} s)")


def outputs(path: str | Path) -> Iterator[tuple[float, Key, Any]]:
    """(t, (iota, action, index), value) of every output event of a recording, in recorded order,
    streamed (a long run's trace is not held)."""
    for message in iter_messages(path):
        if not message.topic.endswith("/" + wire.TRACE):
            continue
        event = message.value
        if isinstance(event, dict) and event.get("kind") == "output":
            yield float(event["t"]), (event["iota"], event["action"], event.get("index")), event.get("value")


def differences(run: str | Path, reference: str | Path) -> list[Difference]:
    """The first differing output of each (iota, channel) of `run` against `reference`, earliest
    first. Both recordings are streamed side by side: the reference's outputs wait in a queue
    per channel until the run's output of the same count comes."""
    waiting: dict[Key, deque] = {}
    counts_run: dict[Key, int] = {}
    counts_ref: dict[Key, int] = {}
    found: dict[Key, Difference] = {}
    ref_stream = outputs(reference)
    ref_done = False

    def pull_reference(until_key: Key, count: int) -> None:
        """Read the reference on until it has `until_key`'s `count`-th output, or ends."""
        nonlocal ref_done
        while not ref_done and counts_ref.get(until_key, 0) <= count:
            try:
                t, key, value = next(ref_stream)
            except StopIteration:
                ref_done = True
                return
            counts_ref[key] = counts_ref.get(key, 0) + 1
            if key not in found:
                waiting.setdefault(key, deque()).append((t, value))

    for t, key, value in outputs(run):
        count = counts_run.get(key, 0)
        counts_run[key] = count + 1
        if key in found:
            continue
        pull_reference(key, count)
        queue = waiting.get(key)
        if queue:
            reference_t, reference_value = queue.popleft()
            if values_equal(value, reference_value):
                continue
        else:
            reference_t, reference_value = None, NONE
        found[key] = Difference(*key, count, t, value, reference_t, reference_value)
        waiting.pop(key, None)
    # the reference's outputs the run never made
    for t, key, value in ref_stream:
        if key not in found:
            waiting.setdefault(key, deque()).append((t, value))
    for key, queue in waiting.items():
        if queue and key not in found:
            reference_t, reference_value = queue[0]
            found[key] = Difference(*key, counts_run.get(key, 0), None, NONE, reference_t, reference_value)
    found = {key: replace(difference, reference_outputs=counts_ref.get(key, 0)) for key, difference in found.items()}
    return sorted(found.values(), key=lambda d: (d.when, d.iota, d.action, str(d.index)))


def first_decision(found: list[Difference], span: float) -> Difference | None:
    """The earliest difference on a channel of decisions, not of streams: one that the reference
    run used at most once a second of its `span` (engine time units) on average, as a scheduler's
    acks and commands, a planner's goals (sensor readings, CAN frames and setpoints, many a
    second, differ as soon as any timing does). Only outputs the run made."""
    return next((d for d in found if d.t is not None and d.reference_outputs <= max(span, 1.0)), None)


def first_per_node(found: list[Difference], root: str = "") -> list[Difference]:
    """The earliest difference of each node (the path's first part under the root), earliest first."""
    seen: dict[str, Difference] = {}
    for difference in found:
        node = node_of(difference.iota, root)
        if node not in seen:
            seen[node] = difference
    return list(seen.values())


def node_of(path: str, root: str = "") -> str:
    inside = path[len(root) + 1:] if root and path.startswith(root + "/") else path
    return inside.split("/")[0]


def _short(value: Any, width: int = 80) -> str:
    if value is NONE:
        return "none"
    text = repr(value)
    return text if len(text) <= width else text[:width - 3] + "..."
