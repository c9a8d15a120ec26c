"""The value types of bursts: `canBurst` (the frames a bus carried, with their wire times, as one
event) and `canFrames` (the frames a station queues at one instant, as one output).

A module of their own so that both the modelled bus (`burst_bus`) and the real-time bus's logger
(`frame_log.BusLogger`) can record bursts without importing each other.
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.types import BadValue, Type

from .frame import CAN_FRAME

BURST_FIELDS = ("station", "order", "queued", "start", "end", "duration", "id", "extended", "rtr", "dlc", "data",
                "direction", "message")


class CanBurstType(Type):
    """`canBurst`: a list of the frames a bus carried, each a map of `BURST_FIELDS` (a frame of
    a CAN_BUS_FRAME's fields plus station, order, queued, start and end)."""

    name = "canBurst"

    def check(self, value: Any) -> None:
        if value.__class__ is not list:
            raise BadValue(f"a burst is a list of frames, got {type(value).__name__}")
        for position, frame in enumerate(value):
            if frame.__class__ is not dict or len(frame) != len(BURST_FIELDS):
                raise BadValue(f"[{position}]: a burst's frame is a map of {', '.join(BURST_FIELDS)}")
            for name in BURST_FIELDS:
                if name not in frame:
                    raise BadValue(f"[{position}]: a burst's frame has no {name}")

    def checked_plain(self, value: Any) -> Any:
        self.check(value)
        return value

    def default(self) -> list:
        return []

    def json_schema(self) -> dict:
        number = {"type": "number"}
        integer = {"type": "integer"}
        return {"type": "array", "title": "canBurst", "items": {
            "type": "object", "required": list(BURST_FIELDS),
            "properties": {"station": {"type": ["integer", "null"]}, "order": integer, "queued": number,
                           "start": number, "end": number, "duration": number, "id": integer,
                           "extended": {"type": "boolean"}, "rtr": {"type": "boolean"}, "dlc": integer,
                           "data": {"type": "array", "items": integer, "minItems": 8, "maxItems": 8},
                           "direction": {"type": ["string", "null"]}, "message": {"type": ["string", "null"]}}}}


CAN_BURST = CanBurstType()


class CanFramesType(Type):
    """`canFrames`: the frames a station queues at one instant, in its order (a list of canFrame):
    what a station's `can_tx_burst` output carries to the bus's `tx_burst[k]`."""

    name = "canFrames"

    @staticmethod
    def _each(value: Any, convert) -> list:
        """`convert` applied to each frame of `value`, a bad one named by its position."""
        if not isinstance(value, (list, tuple)):
            raise BadValue(f"frames are a list of canFrame, got {type(value).__name__}")
        out = []
        for position, frame in enumerate(value):
            try:
                out.append(convert(frame))
            except BadValue as exc:
                raise BadValue(f"[{position}]: {exc}") from None
        return out

    def check(self, value: Any) -> None:
        self._each(value, CAN_FRAME.check)

    def checked_plain(self, value: Any) -> Any:
        return self._each(value, CAN_FRAME.checked_plain)

    def to_plain(self, value: Any) -> Any:
        return [CAN_FRAME.to_plain(frame) for frame in value]

    def from_plain(self, plain: Any) -> list:
        return self._each(plain, CAN_FRAME.from_plain)

    def from_checked_plain(self, plain: Any) -> list:
        return [CAN_FRAME.from_checked_plain(frame) for frame in plain]

    def default(self) -> list:
        return []

    def json_schema(self) -> dict:
        return {"type": "array", "title": "canFrames", "items": CAN_FRAME.json_schema()}

    def prepare(self) -> None:
        CAN_FRAME.prepare()


CAN_FRAMES = CanFramesType()
TX_BURST, CAN_TX_BURST = "tx_burst", "can_tx_burst"  # the bus's input and a station's output of frame lists
TX_BURSTS = "tx_bursts"  # the param of a station that can send either way (True: in bursts)
