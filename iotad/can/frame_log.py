"""`CAN_BUS_FRAME`: one frame as a bus's log records it, decoded as ODrive CAN Simple where it can be.

The modelled bus of virtual time (`virtual_bus.CanBus`) sends one on its `frames` output for every
frame it carries, so a recording has one topic per bus (`iota/<system>/<bus>/frames`) with every
frame in both directions, in bus order. The time is the message's: its log time in the recording
(and its trace event's `t`), the end of the frame, when every other station has it. An IOTA does
not read the clock, so the record itself does not repeat it.

    duration   its bit time on the bus, stuff bits and intermission included (s)
    station    the index of the station that sent it (the [[can]] entry's `stations` order); unset
               (None, null in a recording) where the log cannot tell: a real bus's frames carry
               no sender, so `BusLogger` leaves it unset and `iotad check` takes the station that
               sent such a frame first
    id, extended, rtr, dlc, data   the frame (data zero-padded to 8, `dlc` bytes valid)
    direction  TO_AXIS (a host command, or a remote request for an axis's message), FROM_AXIS
               (an axis's message), EITHER (Address data, which both sides send), or NOT_ODRIVE
    message    the CAN Simple message (Set_Input_Pos, Heartbeat, ...); UNKNOWN for an id CAN Simple
               does not have or an extended id, MALFORMED for a known id of the wrong length

A node's own view stays in its trace (`can_tx` outputs, `can_rx` inputs); this log is the bus's.

In real time nothing models the bus, so `iotad run` runs `BusLogger` as one more node per
`[[can]]` bus, named after it: a listen-only station whose node host opens the same python-can
bus (SocketCAN hands every socket the frames of all the others) and which logs each frame it
hears on `frames`, so the recording has the same topic as a virtual run. Its time is the frame's
arrival in the logger, a little after the frame's end; its `duration` is computed from `bitrate`.
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.api import Input, Iota, Output, Param
from iotad.kernel.types import Array, Bool, Enum, Float, Int, Struct

from . import odrive
from .bit_timing import frame_bits
from .frame import CAN_FRAME, Frame, FrameError

_FRAME_RECORD = CAN_FRAME.record

CAN_DIRECTION = Enum("canDirection", "TO_AXIS", "FROM_AXIS", "EITHER", "NOT_ODRIVE")
CAN_MESSAGE = Enum("canMessage", *odrive.MESSAGES, "UNKNOWN", "MALFORMED")

CAN_BUS_FRAME = Struct("canBusFrame", duration=Float(0, None), station=Int(0, None),
                       id=Int(0, 0x1FFFFFFF), extended=Bool, rtr=Bool, dlc=Int(0, 8),
                       data=Array(Int(0, 255), 8), direction=CAN_DIRECTION, message=CAN_MESSAGE)
_BUS_RECORD = CAN_BUS_FRAME.record  # called as CAN_BUS_FRAME(...) is, one call fewer (bus_frame)


def classify(frame: Frame) -> tuple[str, str]:
    """(direction, name) of a frame under CAN Simple."""
    if frame.extended:
        return "NOT_ODRIVE", "UNKNOWN"  # CAN Simple uses 11-bit ids: another protocol shares the bus
    if frame.__class__ is not Frame:
        return _classify(frame)
    # The answer depends on the id, RTR and DLC only (decoding the signals never fails), so a
    # standard frame's is remembered: at most 2048 ids x 2 x 9 answers.
    key = (frame.id, frame.rtr, len(frame.data))
    found = _CLASSES.get(key)
    if found is None:
        found = _CLASSES[key] = _classify(frame)
    return found


_CLASSES: dict[tuple[int, bool, int], tuple[str, str]] = {}


def _classify(frame: Frame) -> tuple[str, str]:
    try:
        name = odrive.decode(frame).name
    except odrive.UnknownFrame:
        return "NOT_ODRIVE", "UNKNOWN"
    except FrameError:  # a known command id with the wrong length
        spec = odrive.spec_of(frame)
        return _direction(spec.sender, frame.rtr) if spec else "NOT_ODRIVE", "MALFORMED"
    return _direction(odrive.MESSAGES[name].sender, frame.rtr), name


def _direction(sender: str, rtr: bool) -> str:
    if rtr or sender == "host":
        return "TO_AXIS"  # a remote frame always asks the axis for its message
    return "FROM_AXIS" if sender == "axis" else "EITHER"


def bus_frame(value: Any, station: int | None, duration: float):
    """The CAN_BUS_FRAME record of a CAN_FRAME value the bus carried."""
    if value.__class__ is _FRAME_RECORD and value.extended is False and value.dlc.__class__ is int:
        # the bus's usual case, a record its input checked: no Frame built (classify's answer
        # depends on the id, RTR and DLC only); data past the DLC, and a remote frame's, zeroed
        rtr, dlc = value.rtr, value.dlc
        found = _CLASSES.get((value.id, rtr, dlc))
        if found is not None and value.data.__class__ is list and len(value.data) == 8:
            data = [0] * 8 if rtr else value.data[:dlc] + [0] * (8 - dlc)
            return _BUS_RECORD(duration=duration, station=station, id=value.id, extended=False, rtr=rtr,
                               dlc=dlc, data=data, direction=found[0], message=found[1])
    frame = Frame.from_value(value)
    direction, name = classify(frame)
    return CAN_BUS_FRAME(duration=duration, station=station, id=frame.id, extended=frame.extended,
                         rtr=frame.rtr, dlc=frame.dlc, data=list(frame.data) + [0] * (8 - len(frame.data)),
                         direction=direction, message=name)


class BusLogger(Iota):
    """The log of a real-time bus: every frame heard on `can_rx` goes out on `frames` as a
    CAN_BUS_FRAME with no station (a real bus does not say who sent a frame), in arrival order."""

    bitrate = Param(1_000_000)  # bit/s of the bus, for each frame's `duration`
    lag = Param(0.1)            # s: a frame logged later than this after it arrived is a deadline miss

    can_rx = Input(CAN_FRAME, switching=0)
    frames = Output(CAN_BUS_FRAME, switching=0)

    def init(self):
        if not 0 < self.bitrate:
            raise ValueError(f"BusLogger bitrate must be positive, got {self.bitrate!r}")
        self.log = []  # records of frames heard, not yet out

    @can_rx.input
    def heard(self, value):
        frame = Frame.from_value(value)
        bits = frame_bits(frame.id, frame.extended, frame.rtr, frame.data, dlc=frame.dlc)
        self.log.append(bus_frame(value, None, bits / self.bitrate))

    # Logged at once; the window only bounds how stale the log's times may get on a busy machine.
    @frames.action(value=lambda self: self.log[0], when=lambda self: bool(self.log), within=(0, "lag"))
    def logged(self):
        self.log.pop(0)
