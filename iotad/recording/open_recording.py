"""`iotad.open_recording(path)`: a recording read for people and scripts: its channels' values,
its nodes' events and traces, by channel and time, in seconds (docs/recordings.md)."""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterator

from iotad.node_host import wire
from iotad.recording.mcap_reader import Recording, read_recording


@dataclass(frozen=True)
class Sample:
    """One message on one key, as `iotad echo` shows it live: the key, the sender's sequence
    number, its send time (ns since the epoch, or the run's virtual ns), the time `t` in seconds
    of the run, and the value."""

    key: str
    seq: int | None
    send_ns: int | None
    t: float
    value: Any


class OpenRecording:
    """A recording opened with `iotad.open_recording(path)`.

    - `channels()`: the value keys it holds (`iota/<system>/<node>/<channel>[/<index>]`) with
      how many messages each;
    - `values(keyexpr, since=None, until=None)`: the `Sample`s on every key the key expression
      matches (`*` one chunk, `**` any number; neither matches an `@` chunk, as in zenoh), in
      recorded order; `@trace` keys give one sample per event of a burst, as `iotad echo` does;
    - `series(key)`: `(t, value)` pairs of one channel, for a plot;
    - `events(node=None, kind=None)`: trace events (`t` in spec time units, as recorded) of one
      node or all, optionally of one kind (input, output, internal, violation);
    - `trace(node)`: the node's events, and `violations()`: every violation of the run;
    - `nodes`, `system`, `time_unit`, `info`, `path`, and `raw`: the full reader's `Recording`.
    """

    def __init__(self, recording: Recording):
        from iotad.recording.recorded_clock import run_info

        self.raw = recording
        # a real-time run's messages are logged in wall-clock ns: `t` counts from its origin
        # (the t = 0 of every node); a virtual run's are its virtual ns already
        origin = run_info(recording).get("origin")
        self.origin_ns = round(origin * 1e9) if isinstance(origin, (int, float)) and not isinstance(origin, bool) else 0

    # -- what it is
    @property
    def path(self) -> str:
        return self.raw.path

    @property
    def system(self) -> str | None:
        return self.raw.system

    @property
    def time_unit(self) -> float:
        return self.raw.time_unit

    @property
    def info(self) -> dict[str, Any]:
        return self.raw.info

    @property
    def nodes(self) -> list[str]:
        return self.raw.nodes()

    def channels(self) -> dict[str, int]:
        """Value keys (no `@` chunk: not traces, heartbeats or the launcher's) and their message counts."""
        return {key: n for key, n in self.raw.topics().items()
                if key.startswith(wire.PREFIX + "/") and "/@" not in key}

    # -- values
    def values(self, keyexpr: str = "**", since: float | None = None, until: float | None = None) -> list[Sample]:
        """Every sample on the keys `keyexpr` matches with `since <= t <= until` (seconds)."""
        return list(self.iter_values(keyexpr, since, until))

    def iter_values(self, keyexpr: str = "**", since: float | None = None,
                    until: float | None = None) -> Iterator[Sample]:
        match = key_matcher(keyexpr)
        for message in self.raw.messages:
            if not match(message.topic):
                continue
            t = (message.log_time - self.origin_ns) / 1e9
            if (since is not None and t < since) or (until is not None and t > until):
                continue
            value = message.value
            seq = message.sequence
            if message.topic.endswith("/" + wire.TRACE) and isinstance(value, list):
                for k, event in enumerate(value):  # a burst: one sample per event, numbered on
                    yield Sample(message.topic, seq + k, message.publish_time, t, event)
                continue
            yield Sample(message.topic, seq, message.publish_time, t, value)

    def series(self, key: str) -> list[tuple[float, Any]]:
        """`(t in seconds, value)` of one key, in order: what to plot."""
        if key not in self.raw.topics():
            known = ", ".join(sorted(self.channels())[:8])
            raise KeyError(f"{self.path} has no key {key!r} (some it has: {known})")
        return [(s.t, s.value) for s in self.iter_values(key)]

    # -- events
    def events(self, node: str | None = None, kind: str | None = None) -> list[dict]:
        """Trace events of `node` (its name, e.g. "scheduler") or of every node, of one `kind` or all."""
        if node is not None and node not in self.nodes:
            raise KeyError(f"{self.path} has no node {node!r} (nodes: {', '.join(self.nodes)})")
        return [e for e in self.raw.trace(node) if kind is None or e.get("kind") == kind]

    def trace(self, node: str | None = None) -> list[dict]:
        return self.events(node)

    def violations(self) -> list[dict]:
        return self.events(kind="violation")

    def __repr__(self) -> str:
        return f"<recording {self.path}: system {self.system}, {len(self.raw.messages)} messages>"


def open_recording(path: str | Path) -> OpenRecording:
    """Open the recording at `path` (a split one by its `-o` file): `RecordingError` with one line
    saying why when it is no recording or damaged."""
    return OpenRecording(read_recording(path))


def key_matcher(keyexpr: str):
    """A test of a key against a key expression as zenoh reads it: `*` is one chunk, `**` any
    number of chunks (none included), and neither matches a chunk that starts with `@`."""
    chunks = keyexpr.strip("/").split("/")
    pattern = "/".join(_chunk(c) for c in chunks)
    pattern = pattern.replace("/(?:ANY)", "(?:/[^@/][^/]*)*").replace("(?:ANY)/", "(?:[^@/][^/]*/)*")
    pattern = pattern.replace("(?:ANY)", "(?:[^@/][^/]*(?:/[^@/][^/]*)*)?")
    compiled = re.compile(f"^{pattern}$")
    return lambda key: compiled.match(key) is not None


def _chunk(chunk: str) -> str:
    if chunk == "**":
        return "(?:ANY)"
    if chunk == "*":
        return "[^@/][^/]*"
    return re.escape(chunk)
