"""Bursts of recording format 2, read as format 1's per-frame events: each frame of a modelled
bus's `burst` becomes the bus's `frames` log entry and its `rx[k]` output for every other station,
at the frame's wire end, as the format 1 bus (`iotad.can.virtual_bus.CanBus`) recorded them.

`expand(recording)` adds those events to a format 2 recording as it is read (`mcap_reader`), as
messages marked `derived`: the delivery check, candump, exports and plots see every frame as
before, while a node's own check and replay (`Recording.process_trace`) see the bus's events as
it fired them (its bursts). `wire_frames` gives a bus's frames with their wire times from a
recording of either format, for comparisons of the two.
"""
from __future__ import annotations

from typing import Any

from iotad.host import wire
from iotad.recording.mcap_format import packb, unpackb

BURST = "burst"
_FRAME_FIELDS = ("id", "extended", "rtr", "dlc", "data")
_LOG_FIELDS = ("duration", "station", "id", "extended", "rtr", "dlc", "data", "direction", "message")


def is_burst(event: Any) -> bool:
    return (isinstance(event, dict) and event.get("action") == BURST and event.get("kind") == "output"
            and isinstance(event.get("value"), list))


def frame_events(event: dict, stations: int) -> list[dict]:
    """The format 1 events of a burst event: per frame, its `frames` log entry (none where the
    bus keeps no log), then its `rx[k]` for each other station, at its wire end."""
    out = []
    iota = event.get("iota")
    for frame in event["value"]:
        if not isinstance(frame, dict):
            continue
        end = frame.get("end")
        if frame.get("message") is not None:  # None: a bus without a log ([[can]] log = false)
            out.append({"t": end, "iota": iota, "action": "frames", "index": None, "kind": "output",
                        "value": {k: frame.get(k) for k in _LOG_FIELDS}})
        value = {k: frame.get(k) for k in _FRAME_FIELDS}
        for k in range(stations):
            if k != frame.get("station"):
                out.append({"t": end, "iota": iota, "action": "rx", "index": k, "kind": "output", "value": value})
    return out


def _stations(recording: Any, node: str) -> int:
    spec = recording.specs.get(node) or {}
    params = spec.get("params") if isinstance(spec, dict) else None
    stations = params.get("stations") if isinstance(params, dict) else None
    return stations if isinstance(stations, int) and stations > 0 else 2


def expand(recording: Any) -> int:
    """Add the per-frame events of every burst in `recording` (format 2) to its messages, each
    marked `derived`, in log-time order; returns how many frames it expanded."""
    from iotad.recording.mcap_reader import RecordedMessage
    marker = packb(BURST)
    derived: list = []
    sequences: dict[str, int] = {}
    stations: dict[str, int] = {}
    frames = 0
    for message in recording.messages:
        if not message.topic.endswith("/" + wire.TRACE) or marker not in message.data:
            continue
        try:
            event = unpackb(message.data)
        except Exception:  # noqa: BLE001 - damage is the reader's to report, not the expansion's
            continue
        if not is_burst(event):
            continue
        parsed = wire.parse_key(message.topic)
        if not parsed:
            continue
        system, node = parsed[0], parsed[1]
        if node not in stations:
            stations[node] = _stations(recording, node)
        origin = message.log_time - round(float(event["t"]) * _unit(recording) * 1e9)
        for derived_event in frame_events(event, stations[node]):
            t = derived_event["t"]
            if not isinstance(t, (int, float)):
                continue
            ns = origin + round(t * _unit(recording) * 1e9)
            derived.append(_message(RecordedMessage, message.topic, ns, sequences, dict(derived_event, iota=event.get("iota"))))
            key = wire.channel_key(system, node, derived_event["action"], derived_event["index"])
            derived.append(_message(RecordedMessage, key, ns, sequences, derived_event["value"]))
            if derived_event["action"] == "frames":
                frames += 1
    if derived:
        merged = [(m.log_time, 0, k, m) for k, m in enumerate(derived)]
        merged += [(m.log_time, 1, k, m) for k, m in enumerate(recording.messages)]
        merged.sort(key=lambda item: item[:3])
        recording.messages = [item[3] for item in merged]
    return frames


def _unit(recording: Any) -> float:
    cached = recording.__dict__.get("_burst_unit")
    if cached is None:
        cached = recording.__dict__["_burst_unit"] = recording.time_unit
    return cached


def _message(cls: Any, topic: str, ns: int, sequences: dict[str, int], value: Any) -> Any:
    sequence = sequences.get(topic, 0)
    sequences[topic] = sequence + 1
    message = cls(topic, ns, ns, sequence, packb(value))
    message.derived = True
    return message


def wire_frames(recording: Any, bus: str) -> list[dict]:
    """Every frame bus `bus` carried, in the order they ended: station, id, extended, rtr, dlc,
    data and wire end (`end`) and start (`start`), from the bursts of a format 2 recording or
    the `frames` log of a format 1 one (start = end - duration)."""
    out = []
    for event in recording.trace(bus, derived=False):
        if is_burst(event):
            for frame in event["value"]:
                out.append({k: frame[k] for k in ("station", "id", "extended", "rtr", "dlc", "data", "start", "end")})
        elif event.get("action") == "frames" and event.get("kind") == "output":
            value = event["value"]
            out.append({"station": value["station"], "id": value["id"], "extended": value["extended"],
                        "rtr": value["rtr"], "dlc": value["dlc"], "data": value["data"],
                        "start": event["t"] - value["duration"], "end": event["t"]})
    return out
