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
- Launcher events (node start, exit, restart) go on `iota/<system>/@launcher`; a launcher's start
  gate is a liveliness token on `gate_key(system, host)`.
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


class WireError(ValueError):
    """A payload or attachment that cannot be decoded."""


def channel_key(system: str, path: str, channel: str, index: int | None = None) -> str:
    key = f"{PREFIX}/{system}/{path}/{channel}"
    return key if index is None else f"{key}/{index}"


def trace_key(system: str, path: str) -> str:
    return f"{PREFIX}/{system}/{path}/@trace"


START_KIND = "start"


def start_event(t: float, iota: str, wall: float, pid: int) -> dict:
    """A node's engine-start record on its `@trace` (trace-event shape, kind `start`)."""
    return {"t": t, "iota": iota, "action": "@start", "index": None, "kind": START_KIND,
            "value": {"wall": wall, "pid": pid}}


def gate_key(system: str, host: str | None = None) -> str:
    """The liveliness key of a launcher's start gate: its token says "every node of mine is
    live: start your engines" (docs/internals.md, "Start gate")."""
    return f"{PREFIX}/{system}/@go/{host or 'hub'}"


def launcher_key(system: str) -> str:
    return f"{PREFIX}/{system}/@launcher"


def subscription_keys(system: str) -> list[str]:
    """Key expressions that together match every key of `system`."""
    return [f"{PREFIX}/{system}/**", f"{PREFIX}/{system}/**/@trace", f"{PREFIX}/{system}/@launcher",
            f"{PREFIX}/{system}/**/@heartbeat"]


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


def encode_attachment(sequence: int, send_time_ns: int | None = None) -> bytes:
    return msgpack.packb([sequence, time.time_ns() if send_time_ns is None else send_time_ns])


def decode_attachment(attachment: bytes | None) -> tuple[int, int] | None:
    if not attachment:
        return None
    try:
        sequence, send_ns = msgpack.unpackb(attachment)
        return int(sequence), int(send_ns)
    except Exception:  # noqa: BLE001
        return None
