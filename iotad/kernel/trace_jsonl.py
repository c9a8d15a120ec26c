"""Trace JSONL (docs/design.md section 5): one event a line, `{"t", "iota", "action", "index", "kind", "value"}`."""
from __future__ import annotations

import json
import math
from typing import IO, Iterable, Iterator

KINDS = ("input", "output", "internal", "violation")
FIELDS = ("t", "iota", "action", "index", "kind", "value")


def _default(value):
    raise TypeError(f"{type(value).__name__} is not plain trace data")


def dumps(event: dict) -> str:
    """One event as one JSON line with fields in the documented order."""
    ordered = {k: event.get(k) for k in FIELDS}
    for k, v in event.items():
        if k not in ordered:
            ordered[k] = v
    t = ordered["t"]
    if isinstance(t, float) and math.isfinite(t) and t == int(t) and abs(t) < 1e15:
        ordered["t"] = float(t)
    try:
        return json.dumps(ordered, default=_default, allow_nan=False, ensure_ascii=False)
    except ValueError:
        # an infinite value (a field declared `in [0, inf]` may be inf): JSON has no token for
        # it; written as `Infinity`, the extension that Python's json (`read` here) reads back
        return json.dumps(ordered, default=_default, allow_nan=True, ensure_ascii=False)


def write(events: Iterable[dict], out: IO[str]) -> int:
    count = 0
    for event in events:
        out.write(dumps(event) + "\n")
        count += 1
    return count


def read(lines: Iterable[str]) -> Iterator[dict]:
    for number, line in enumerate(lines, 1):
        if line.strip():
            try:
                yield json.loads(line)
            except json.JSONDecodeError as exc:
                raise ValueError(f"line {number}: not JSON: {exc.msg}") from None


def violations(events: Iterable[dict]) -> list[dict]:
    return [e for e in events if e["kind"] == "violation"]
