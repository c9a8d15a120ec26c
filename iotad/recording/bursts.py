"""Bursts of recording format 2, read as format 1's per-frame events: each frame of a modelled
bus's `burst` becomes the bus's `frames` log entry and its `rx[k]` output for every other station,
at the frame's wire end, as the format 1 bus (`iotad.can.virtual_bus.CanBus`) recorded them.

A station's `can_tx_burst` (its frames of one instant in one output) becomes a `can_tx` output
per frame, at its time, and the bus's `tx_burst[k]` input that took it a `tx[k]` input per frame;
a real-time station's `can_rx_burst` (what its CAN port received together) a `can_rx` input per frame. `expand(recording)` adds those events to a format 2 recording as it is read (`mcap_reader`), as
messages marked `derived`: the delivery check, candump, exports and plots see every frame as
before, while a node's own check and replay (`Recording.process_trace`) see the bus's events as
it fired them (its bursts). `wire_frames` gives a bus's frames with their wire times from a
recording of either format, for comparisons of the two.
"""
from __future__ import annotations

from typing import Any

from iotad.node_host import wire
from iotad.recording.mcap_format import packb, unpackb

BURST = "burst"
CAN_TX_BURST = "can_tx_burst"  # a station's frames of one instant, one output (iotad.can.burst_bus)
TX_BURST = "tx_burst"  # the bus's input they arrive on
CAN_RX_BURST = "can_rx_burst"  # a real-time station's frames received together, one input (iotad.node_host.can_port)
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


_PER_FRAME = {(CAN_TX_BURST, "output"): "can_tx", (TX_BURST, "input"): "tx", (CAN_RX_BURST, "input"): "can_rx"}


def is_station_burst(event: Any) -> bool:
    """A station's `can_tx_burst` output, the bus's `tx_burst[k]` input that took it, or a real-time
    station's `can_rx_burst` input (the frames its CAN port received together)."""
    return (isinstance(event, dict) and isinstance(event.get("value"), list)
            and (event.get("action"), event.get("kind")) in _PER_FRAME)


def sent_events(event: dict) -> list[dict]:
    """The format 1 events of a station's `can_tx_burst` output (a `can_tx` output per frame), of
    the bus's `tx_burst[k]` input (a `tx[k]` input per frame) or of a station's `can_rx_burst` input
    (a `can_rx` input per frame, from where the burst came: its `key`), in order, at its time."""
    kind = event["kind"]
    action = _PER_FRAME[(event["action"], kind)]
    extra = {"key": event["key"]} if kind == "input" and "key" in event else {}
    return [{"t": event["t"], "iota": event.get("iota"), "action": action, "index": event.get("index"), "kind": kind,
             "value": frame, **extra} for frame in event["value"] if isinstance(frame, dict)]


def _stations(recording: Any, node: str) -> int:
    """The stations of the modelled bus `node`, whose `rx[k]` a burst stands for; 0 for a real
    bus's logger (iotad.can.frame_log.BusLogger), which has no `stations` and no `rx`: its bursts
    are its log alone."""
    spec = recording.specs.get(node) or {}
    params = spec.get("params") if isinstance(spec, dict) else None
    stations = params.get("stations") if isinstance(params, dict) else None
    return stations if isinstance(stations, int) and stations > 0 else 0


def expand(recording: Any, message_type: type) -> int:
    """Add the per-frame events of every burst in `recording` (format 2) to its messages, each
    marked `derived`, in log-time order; returns how many frames it expanded. `message_type` is
    the reader's RecordedMessage, passed in so that this module stays below the reader."""
    markers = (packb(BURST), packb(CAN_TX_BURST), packb(TX_BURST), packb(CAN_RX_BURST))  # (cheap tests first)
    derived: list = []
    sequences: dict[str, int] = {}
    stations: dict[str, int] = {}
    floors: dict[str, int] = {}  # per bus's trace topic: the log time of the last frame expanded
    real_time = (getattr(recording, "info", None) or {}).get("clock") != "virtual"
    frames = 0
    for position, message in enumerate(recording.messages):
        if not message.topic.endswith("/" + wire.TRACE) or not any(m in message.data for m in markers):
            continue
        try:
            event = unpackb(message.data)
        except Exception:  # noqa: BLE001 - damage is the reader's to report, not the expansion's
            continue
        parsed = wire.parse_key(message.topic)
        if not parsed:
            continue
        system, node = parsed[0], parsed[1]
        if is_burst(event):
            if node not in stations:
                stations[node] = _stations(recording, node)
            events = frame_events(event, stations[node])
            # a bus's frames at their own wire times, ahead of what was logged at the same time
            place = (0, 0)
        elif is_station_burst(event):
            events = sent_events(event)
            # a station's frames stand for the one event that carried them: right after it, in
            # its node's order (a real-time trace burst logs many events at one receipt time,
            # and frames placed ahead of them read as taken before events the engine took first)
            place = (1, position)
        else:
            continue
        origin = message.log_time - round(float(event["t"]) * _unit(recording) * 1e9)
        # a bus's frames in the order it carried them: in real time each burst's log time carries
        # its own publishing delay, so frames of two bursts timed from each could swap places
        floor = floors.get(message.topic, 0) if real_time and is_burst(event) else None
        for derived_event in events:
            t = derived_event["t"]
            if not isinstance(t, (int, float)):
                continue
            ns = origin + round(t * _unit(recording) * 1e9)
            if floor is not None:
                ns = floor = max(ns, floor)
            derived.append((place, _message(message_type, message.topic, ns, sequences,
                                            dict(derived_event, iota=event.get("iota")))))
            if derived_event["kind"] == "output":  # an output is on its channel's key too
                key = wire.channel_key(system, node, derived_event["action"], derived_event["index"])
                derived.append((place, _message(message_type, key, ns, sequences, derived_event["value"])))
            if derived_event["action"] == "frames":
                frames += 1
        if floor is not None:
            floors[message.topic] = floor
    if derived:
        merged = [(m.log_time, *place, 1, k, m) for k, (place, m) in enumerate(derived)]
        merged += [(m.log_time, 1, k, 0, 0, m) for k, m in enumerate(recording.messages)]
        merged.sort(key=lambda item: item[:5])
        recording.messages = [item[5] for item in merged]
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
