"""The wire format shared by node hosts, the recorder, replay and the introspection commands.

- Channel keys: `iota/<system>/<instance path>/<channel>[/<index>]`.
- A node's own events (all of them: inputs, outputs, internal actions, violations, as trace
  dicts in the node's clock) go on `iota/<system>/<instance path>/@trace`, in bursts: one sample
  is a msgpack array of event dicts (`encode_burst`), its attachment `[seq, send_time_ns]` where
  `seq` is the node's count of trace events before the burst's first (so the next burst's `seq`
  is `seq + len(burst)`; a receiver that sees a higher one missed events). A sample holding one
  event dict (older node hosts, third-party publishers) is a burst of one: read `@trace` with
  `trace_events`, which takes both.
- On `@trace` a node host adds to each output event the `key`, `seq` and `send_ns` it published
  with, and to each input from outside the `key` it arrived on and the sender's `seq`/`send_ns`
  (when it had the attachment): a trace-sourced recorder rebuilds every message from these.
- The first event a node host puts on `@trace` is `start_event(...)` (kind `start`): the engine's
  start time `t` in the node's clock, when every precondition was first evaluated.
- Each `@trace` burst's attachment also names the process that sent it: `[seq, send_time_ns,
  pid, started_ns]`, `started_ns` the wall time of its `start` event. A node restarted where a
  recorder could not hear it (its host cut off) numbers its trace from 0 again, so its sequence
  numbers may show no jump: the process does (`trace_process`). A two-element attachment (older
  node hosts, third-party publishers) names none.
- Launcher events (node start, exit, restart) go on `iota/<system>/@launcher`; a launcher's start
  gate is a liveliness token on `gate_key(system, host)`; the launcher of a host other than the
  hub's publishes the hub's origin on its clock on `host_origin_key(system, host)`.
- Payload: msgpack of the plain value (None for a channel without a value).
- Attachment: msgpack `[sequence, send_time_ns]`: a per-publisher counter from 0 (a receiver or
  recorder sees gaps) and the sender's wall clock `time.time_ns()` at send.

zenoh treats a chunk starting with '@' as verbatim: `iota/sys/**` does NOT match
`iota/sys/a/@trace`. Subscribe to `subscription_keys(system)` to see everything of a system.
"""
from __future__ import annotations

import time
from typing import Any

import msgpack

PREFIX = "iota"

# The last chunk of a node's (or the system's) keys that are not channels. zenoh matches a chunk
# starting with '@' only verbatim: spell them from here, never by hand.
TRACE = "@trace"          # a node's events, in bursts
ALIVE = "@alive"          # a node's liveliness token
HEARTBEAT = "@heartbeat"  # a node's heartbeats
SPEC = "@spec"            # a node's queryable: its spec, params, start time
LAUNCHER = "@launcher"    # the launchers' events (iota/<system>/@launcher)
ORIGIN = "@origin"        # the hub launcher's queryable: the run's clock origin
GATE = "@go"              # a launcher's start gate (liveliness, iota/<system>/@go/<host>)


class WireError(ValueError):
    """A payload or attachment that cannot be decoded."""


def channel_key(system: str, path: str, channel: str, index: int | None = None) -> str:
    key = f"{PREFIX}/{system}/{path}/{channel}"
    return key if index is None else f"{key}/{index}"


def node_key(system: str, path: str, suffix: str) -> str:
    """`iota/<system>/<path>/<suffix>`: one of a node's `@` keys (`TRACE`, `ALIVE`...)."""
    return f"{PREFIX}/{system}/{path}/{suffix}"


def trace_key(system: str, path: str) -> str:
    return node_key(system, path, TRACE)


def every_node(system: str, suffix: str) -> str:
    """The key expression of that `@` key of every node of `system` (`iota/<system>/**/<suffix>`)."""
    return f"{PREFIX}/{system}/**/{suffix}"


def origin_key(system: str) -> str:
    return f"{PREFIX}/{system}/{ORIGIN}"


def host_origin_key(system: str, host: str) -> str:
    """Where the launcher of `host` publishes the hub's origin on its own clock, each time it
    measures that clock again (msgpack `{"origin": wall seconds}`): its nodes' clocks follow it."""
    return f"{PREFIX}/{system}/{ORIGIN}/{host}"


def node_path(key: str, system: str, suffix: str) -> str | None:
    """The node path of `key` when it is `iota/<system>/<path>/<suffix>`, else None."""
    prefix, end = f"{PREFIX}/{system}/", f"/{suffix}"
    key = str(key)
    if key.startswith(prefix) and key.endswith(end) and len(key) > len(prefix) + len(end):
        return key[len(prefix):-len(end)]
    return None


def keyexpr_matches(expression: str, key: str) -> bool:
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


START_KIND = "start"


def start_event(t: float, iota: str, wall: float, pid: int) -> dict:
    """A node's engine-start record on its `@trace` (trace-event shape, kind `start`)."""
    return {"t": t, "iota": iota, "action": "@start", "index": None, "kind": START_KIND,
            "value": {"wall": wall, "pid": pid}}


def gate_key(system: str, host: str | None = None) -> str:
    """The liveliness key of a launcher's start gate: its token says "every node of mine is
    live: start your engines" (docs/internals.md, "Start gate")."""
    return f"{PREFIX}/{system}/{GATE}/{host or 'hub'}"


def launcher_key(system: str) -> str:
    return f"{PREFIX}/{system}/{LAUNCHER}"


def subscription_keys(system: str) -> list[str]:
    """Key expressions that together match every key of `system`."""
    return [f"{PREFIX}/{system}/**", every_node(system, TRACE), launcher_key(system), every_node(system, HEARTBEAT)]


def parse_key(key: str) -> tuple[str, str, str, int | None] | None:
    """(system, path, channel, index) of a channel key, or None if it is not one.

    The last chunk is an index when it is all digits; `@`-chunks keep their '@'. A recording
    has a few hundred keys and a million messages that the tools parse again and again (`iotad
    check` parsed 6.5 million): answers are remembered, a few thousand keys at most."""
    if key.__class__ is str:
        try:
            return _PARSED[key]
        except KeyError:
            pass
        if len(_PARSED) >= _PARSED_MAX:
            _PARSED.clear()
        parsed = _PARSED[key] = _parse_key(key)
        return parsed
    return _parse_key(key)


_PARSED: dict[str, tuple[str, str, str, int | None] | None] = {}
_PARSED_MAX = 4096


def _parse_key(key: str) -> tuple[str, str, str, int | None] | None:
    parts = key.split("/")
    if len(parts) < 4 or parts[0] != PREFIX:
        return None
    index = None
    if parts[-1].isdigit() and len(parts) >= 5:
        index = int(parts[-1])
        parts = parts[:-1]
    return parts[1], "/".join(parts[2:-1]), parts[-1], index


def encode(value: Any) -> bytes:
    return msgpack.packb(value, use_bin_type=True)


def decode(payload: bytes) -> Any:
    try:
        return msgpack.unpackb(payload, raw=False, strict_map_key=False)
    except Exception as exc:  # noqa: BLE001 - msgpack raises several unrelated types
        detail = str(exc) or f"starts {payload[:16].hex(' ')}"  # some msgpack errors say nothing
        raise WireError(f"malformed msgpack payload ({len(payload)} bytes): {type(exc).__name__}: {detail}") from None


def encode_burst(events: list) -> bytes:
    """One `@trace` sample: the events of a burst, oldest first."""
    return msgpack.packb(events, use_bin_type=True)


def trace_events(value: Any) -> list:
    """The events of a decoded `@trace` payload: a burst (list) or one event (dict, the old form).
    Elements are returned as they are: a consumer must skip (and report) what is not a dict."""
    if isinstance(value, list):
        return value
    if isinstance(value, dict):
        return [value]
    raise WireError(f"malformed @trace payload: {type(value).__name__}, neither an event dict nor a burst (list)")


def encode_attachment(sequence: int, send_time_ns: int | None = None,
                      process: tuple[int, int] | None = None) -> bytes:
    """`[sequence, send_time_ns]`; with `process` (a `@trace` burst's: pid, started_ns) four elements."""
    fields = [sequence, time.time_ns() if send_time_ns is None else send_time_ns]
    return msgpack.packb(fields if process is None else [*fields, *process])


def decode_attachment(attachment: bytes | None) -> tuple[int, int] | None:
    """(sequence, send_time_ns) of an attachment, whatever follows them; None if it has none."""
    if not attachment:
        return None
    try:
        fields = msgpack.unpackb(attachment)
        return int(fields[0]), int(fields[1])
    except Exception:  # noqa: BLE001
        return None


def trace_process(fields: Any) -> tuple[int, int] | None:
    """(pid, started_ns) of the process that sent a `@trace` burst, from its decoded attachment's
    fields; None where it names none (an older node host)."""
    if isinstance(fields, (list, tuple)) and len(fields) >= 4 and all(isinstance(f, int) for f in fields[2:4]):
        return int(fields[2]), int(fields[3])
    return None


def restart_note(key: str, expected: int, got: int, process: tuple[int, int]) -> dict:
    """A recorder's note (on its gaps topic) that a new process began sending on the `@trace` key
    `key`: its first burst heard has `seq` `got`, so its first `got` events (its `start` record
    first) were not heard; `expected` is the `seq` the process before would have sent next."""
    return {"key": key, "expected": 0, "got": got, "missing": got, "after": expected,
            "process": {"pid": process[0], "started_ns": process[1]}}
