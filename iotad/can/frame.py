"""One CAN frame (`Frame`), and `CAN_FRAME`, the channel type that carries a frame between IOTAs.

A `Frame` is immutable and always valid: an 11-bit id (29-bit when `extended`), at most 8 data
bytes. Its DLC is `len(data)`. A remote (RTR) frame carries no data on the wire but does carry a
DLC; here its `data` holds that many zero bytes, so that the DLC survives every conversion
(python-can message, channel value, recording) and `dlc == len(data)` holds for every frame.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from iotad.kernel.types import Array, Bool, Int, Struct

if TYPE_CHECKING:  # python-can is imported only where a python-can message is made or read
    import can

# The value of a CAN channel: data zero-padded to 8 bytes, dlc = how many are valid.
CAN_FRAME = Struct("canFrame", id=Int(0, 0x1FFFFFFF), extended=Bool, rtr=Bool, dlc=Int(0, 8),
                   data=Array(Int(0, 255), 8))

_FRAME_RECORD = CAN_FRAME.record  # called as CAN_FRAME(...) is, one call fewer (to_value)

STANDARD_ID_MAX = 0x7FF
EXTENDED_ID_MAX = 0x1FFFFFFF


class FrameError(ValueError):
    """A frame that cannot be built or understood; the message says what is wrong and with what."""


@dataclass(frozen=True, slots=True)
class Frame:
    id: int
    data: bytes = b""
    rtr: bool = False
    extended: bool = False

    def __post_init__(self):
        if isinstance(self.id, bool) or not isinstance(self.id, int):
            raise FrameError(f"CAN id must be an int, got {type(self.id).__name__} {self.id!r}")
        limit = EXTENDED_ID_MAX if self.extended else STANDARD_ID_MAX
        if not 0 <= self.id <= limit:
            kind = "29-bit extended" if self.extended else "11-bit standard"
            raise FrameError(f"CAN id 0x{self.id:X} does not fit a {kind} id (0..0x{limit:X})")
        if not isinstance(self.data, bytes):
            try:  # bytearray, list of ints, memoryview: keep the frame immutable and hashable
                object.__setattr__(self, "data", bytes(self.data))
            except (TypeError, ValueError) as exc:
                raise FrameError(f"CAN data must be bytes (0..255 each), got {self.data!r}: {exc}") from None
        if len(self.data) > 8:
            raise FrameError(f"CAN frame 0x{self.id:X} has {len(self.data)} data bytes; classic CAN carries at most 8")
        if self.rtr and any(self.data):
            raise FrameError(f"remote (RTR) frame 0x{self.id:X} carries no data; its data must be {len(self.data)} zero bytes")

    @property
    def dlc(self) -> int:
        return len(self.data)

    @classmethod
    def remote(cls, id: int, dlc: int = 0, extended: bool = False) -> "Frame":
        """A remote (RTR) frame asking for `id`, with the DLC it announces."""
        if not 0 <= dlc <= 8:
            raise FrameError(f"DLC {dlc} out of 0..8")
        return cls(id, bytes(dlc), rtr=True, extended=extended)

    # --- the channel value (CAN_FRAME) ---------------------------------------------------------

    def to_value(self):
        """The CAN_FRAME record of this frame: data zero-padded to 8, dlc the valid bytes."""
        return _FRAME_RECORD(id=self.id, extended=self.extended, rtr=self.rtr, dlc=len(self.data),
                             data=list(self.data) + [0] * (8 - len(self.data)))

    def plain(self) -> dict:
        """The CAN_FRAME value as payloads and traces carry it (a dict; data zero-padded to 8)."""
        return {"id": self.id, "extended": self.extended, "rtr": self.rtr, "dlc": len(self.data),
                "data": list(self.data) + [0] * (8 - len(self.data))}

    @classmethod
    def from_value(cls, value: Any) -> "Frame":
        """The frame of a CAN_FRAME value (a record, or its plain dict as traces and payloads hold it)."""
        kind = value.__class__
        # the usual cases, the checks below in one go (a dict: an output on its way to a bus)
        if kind is _FRAME_RECORD or kind is dict:
            if kind is dict:
                get = value.get
                id, extended, rtr, dlc, data = get("id"), get("extended"), get("rtr"), get("dlc"), get("data")
            else:
                id, extended, rtr, dlc, data = value.id, value.extended, value.rtr, value.dlc, value.data
            if (id is not None and extended is not None and rtr is not None and dlc.__class__ is int
                    and 0 <= dlc <= 8 and data.__class__ is list and len(data) == 8):
                rtr = bool(rtr)
                return cls(int(id), bytes(dlc) if rtr else bytes(data[:dlc]), rtr=rtr, extended=bool(extended))
        get = value.get if isinstance(value, dict) else (lambda name: getattr(value, name, None))
        fields = {name: get(name) for name in CAN_FRAME.field_names}
        missing = [name for name, v in fields.items() if v is None]
        if missing:
            raise FrameError(f"not a canFrame value, missing {missing}: {value!r}")
        dlc, data = fields["dlc"], fields["data"]
        if isinstance(dlc, bool) or not isinstance(dlc, int) or not 0 <= dlc <= 8:
            raise FrameError(f"canFrame dlc must be 0..8, got {dlc!r}")
        if not isinstance(data, (list, tuple, bytes, bytearray)) or len(data) != 8:
            raise FrameError(f"canFrame data must be 8 bytes (zero-padded), got {data!r}")
        rtr = bool(fields["rtr"])
        return cls(int(fields["id"]), bytes(dlc) if rtr else bytes(data[:dlc]), rtr=rtr,
                   extended=bool(fields["extended"]))

    # --- python-can ----------------------------------------------------------------------------

    @classmethod
    def from_can_message(cls, msg: "can.Message") -> "Frame":
        """The frame of a python-can message (error frames and CAN FD are not classic frames)."""
        if getattr(msg, "is_error_frame", False):
            raise FrameError(f"error frame 0x{msg.arbitration_id:X} is not a data frame")
        if getattr(msg, "is_fd", False) and msg.dlc > 8:
            raise FrameError(f"CAN FD frame 0x{msg.arbitration_id:X} with {msg.dlc} bytes is not classic CAN")
        if msg.is_remote_frame:
            return cls.remote(msg.arbitration_id, msg.dlc, extended=msg.is_extended_id)
        return cls(msg.arbitration_id, bytes(msg.data[:msg.dlc]), extended=msg.is_extended_id)

    def to_can_message(self, timestamp: float = 0.0) -> "can.Message":
        import can

        if self.rtr:
            return can.Message(timestamp=timestamp, arbitration_id=self.id, is_extended_id=self.extended,
                               is_remote_frame=True, dlc=len(self.data))
        return can.Message(timestamp=timestamp, arbitration_id=self.id, is_extended_id=self.extended,
                           data=self.data, dlc=len(self.data))

    def __str__(self) -> str:
        ident = f"{self.id:08X}" if self.extended else f"{self.id:03X}"
        body = f"R{len(self.data)}" if self.rtr else self.data.hex(" ").upper()
        return f"{ident} [{len(self.data)}] {body}".rstrip()
