"""`CAN_BUS_FRAME`: one frame as a bus's log records it, decoded as ODrive CAN Simple where it can be.

The modelled bus of virtual time (`virtual_bus.CanBus`) sends one on its `frames` output for every
frame it carries, so a recording has one topic per bus (`iota/<system>/<bus>/frames`) with every
frame in both directions, in bus order. The time is the message's: its log time in the recording
(and its trace event's `t`), the end of the frame, when every other station has it. An IOTA does
not read the clock, so the record itself does not repeat it.

    duration   its bit time on the bus, stuff bits and intermission included (s)
    station    the index of the station that sent it (the [[can]] entry's `stations` order)
    id, extended, rtr, dlc, data   the frame (data zero-padded to 8, `dlc` bytes valid)
    direction  TO_AXIS (a host command, or a remote request for an axis's message), FROM_AXIS
               (an axis's message), EITHER (Address data, which both sides send), or NOT_ODRIVE
    message    the CAN Simple message (Set_Input_Pos, Heartbeat, ...); UNKNOWN for an id CAN Simple
               does not have or an extended id, MALFORMED for a known id of the wrong length

A node's own view stays in its trace (`can_tx` outputs, `can_rx` inputs); this log is the bus's.
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.types import Array, Bool, Enum, Float, Int, Struct

from . import odrive
from .frame import Frame, FrameError

CAN_DIRECTION = Enum("canDirection", "TO_AXIS", "FROM_AXIS", "EITHER", "NOT_ODRIVE")
CAN_MESSAGE = Enum("canMessage", *odrive.MESSAGES, "UNKNOWN", "MALFORMED")

CAN_BUS_FRAME = Struct("canBusFrame", duration=Float(0, None), station=Int(0, None),
                       id=Int(0, 0x1FFFFFFF), extended=Bool, rtr=Bool, dlc=Int(0, 8),
                       data=Array(Int(0, 255), 8), direction=CAN_DIRECTION, message=CAN_MESSAGE)


def classify(frame: Frame) -> tuple[str, str]:
    """(direction, name) of a frame under CAN Simple."""
    if frame.extended:
        return "NOT_ODRIVE", "UNKNOWN"  # CAN Simple uses 11-bit ids: another protocol shares the bus
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


def bus_frame(value: Any, station: int, duration: float):
    """The CAN_BUS_FRAME record of a CAN_FRAME value the bus carried."""
    frame = Frame.from_value(value)
    direction, name = classify(frame)
    return CAN_BUS_FRAME(duration=duration, station=station, id=frame.id, extended=frame.extended,
                         rtr=frame.rtr, dlc=frame.dlc, data=list(frame.data) + [0] * (8 - len(frame.data)),
                         direction=direction, message=name)
