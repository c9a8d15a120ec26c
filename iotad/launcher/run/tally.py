"""What crossed a running system's keys, counted for its launcher's summary: the values of each
channel (bounded: past VALUE_LABELS distinct ones, "*"), the violations of each node and the first
distinct violation lines. Filled from zenoh's threads, read by the launcher's: under one lock."""
from __future__ import annotations

import threading
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from iotad.node_host import wire
from iotad.launcher.run.violation_examples import ViolationExamples

VALUE_LABELS = 32             # distinct values counted per channel for the summary; then "*"


@dataclass
class Tally:
    """What crossed the system's keys while it ran: for the summary at the end."""

    values: dict[str, Counter] = field(default_factory=dict)      # channel key -> Counter of values
    violations: Counter = field(default_factory=Counter)           # node path -> count
    examples: ViolationExamples = field(default_factory=ViolationExamples)  # first distinct violation lines
    lock: threading.Lock = field(default_factory=threading.Lock)

    def channel(self, key: str, value: Any) -> None:
        label = value if isinstance(value, (str, bool, int)) and not isinstance(value, float) else "*"
        with self.lock:
            counts = self.values.setdefault(key, Counter())
            if label not in counts and len(counts) >= VALUE_LABELS:
                label = "*"  # a counter, a sequence number...: bounded memory over a long run
            counts[label] += 1

    def trace(self, path: str, event: Any) -> None:
        if isinstance(event, dict) and event.get("kind") == "violation":
            with self.lock:
                self.violations[path] += 1
                value = event.get("value") or {}
                message = value.get("message") if isinstance(value, dict) else value
                self.examples.add(f"{path} t={event.get('t', 0):.3f}: {message}", event.get("index"))


def count_trace(tally: Tally, system_name: str, sample: Any) -> None:
    """A `@trace` sample of any node (a burst, or one event), counted in `tally`. Outputs are
    counted from the nodes' traces, not from their keys: a subscriber to every channel key would
    wake this process for every message, which the nodes pay for."""
    path = wire.node_path(sample.key_expr, system_name, wire.TRACE)
    try:
        events = wire.trace_events(wire.decode(sample.payload.to_bytes()))  # a burst, or one event
    except wire.WireError:
        return
    for event in events:
        tally.trace(path or "?", event)
        if isinstance(event, dict) and event.get("kind") == "output" and isinstance(event.get("key"), str):
            tally.channel(event["key"], event.get("value"))
