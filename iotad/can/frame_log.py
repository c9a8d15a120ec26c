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

A bus whose stations name CiA 402 node ids logs `canopen_frame_log.CANOPEN_BUS_FRAME` records
instead, each frame named by its family (CANopen service or CAN Simple message).

In real time nothing models the bus, so `iotad run` runs `BusLogger` as one more node per
`[[can]]` bus, named after it: a listen-only station whose node host opens the same python-can
bus (SocketCAN hands every socket the frames of all the others) and which logs the frames it
hears in bursts (recording format 2), as the modelled bus of virtual time does: the frames heard
within `batch` of the first go out as one `burst` event, each with its arrival in the logger as
its wire end (a little after the frame's real end), its `duration` computed from `bitrate`, and no
station. Readers expand a burst into the `frames` log of format 1 (iotad/recording/bursts.py), so
the recording has the same frames on the same topic as a virtual run.
"""
from __future__ import annotations

from typing import Any

from iotad.esprit.runtime import esprit_now
from iotad.kernel.api import Input, Iota, Output, Param
from iotad.kernel.types import Array, Bool, Enum, Float, Int, Struct

from . import odrive
from .bit_timing import frame_bits
from .burst_types import CAN_BURST, CAN_FRAMES
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
    """The log of a real-time bus: the frames heard on `can_rx` go out in bursts on `burst`
    (`canBurst`: each frame with no station, as a real bus does not say who sent it, its arrival
    as its wire end, in arrival order), one burst per `batch` while frames come."""

    bitrate = Param(1_000_000)  # bit/s of the bus, for each frame's `duration`
    lag = Param(0.1)            # s: a frame logged later than this after it arrived is a deadline miss
    # s: the frames heard within this of the first go out as one burst (at 500 Hz, six joints: 30
    # frames an event instead of one); it bounds how late the log's last frames are published
    batch = Param(0.005)

    can_rx = Input(CAN_FRAME, switching=0)
    can_rx_burst = Input(CAN_FRAMES, switching=0)  # the frames its port received together, in order
    frames = Output(CAN_BUS_FRAME, switching=0)  # format 1's log, a record per frame: not sent any more
    burst = Output(CAN_BURST, switching=0)

    def init(self):
        if not 0 < self.bitrate:
            raise ValueError(f"BusLogger bitrate must be positive, got {self.bitrate!r}")
        if not 0 <= self.batch <= self.lag:
            raise ValueError(f"BusLogger batch must be 0 to lag ({self.lag!r}) s, got {self.batch!r}")
        self.log = []    # burst entries of frames heard, not yet out
        self.order = 0   # the order on the bus of the next frame heard (arrival order)

    @can_rx.input
    def heard(self, value):
        frame = Frame.from_value(value)
        duration = frame_bits(frame.id, frame.extended, frame.rtr, frame.data, dlc=frame.dlc) / self.bitrate
        record = self.logged_frame(bus_frame(value, None, duration))
        now = esprit_now()
        self.log.append({"station": None, "order": self.order, "queued": now - duration, "start": now - duration,
                         "end": now, "duration": duration, "id": record.id, "extended": record.extended,
                         "rtr": record.rtr, "dlc": record.dlc, "data": list(record.data),
                         "direction": record.direction, "message": record.message})
        self.order += 1

    @can_rx_burst.input
    def heard_together(self, frames):
        for value in frames:
            self.heard(value)

    def logged_frame(self, record):
        """The record logged for a frame heard (a bus with CANopen stations names its frames by
        family: `canopen_frame_log.CanopenBusLogger`)."""
        return record

    # The window opens as the first frame of a burst is heard; the burst takes every frame heard by
    # the time it fires.
    @burst.action(value=lambda self: list(self.log), when=lambda self: bool(self.log), within=("batch", "lag"))
    def logged(self):
        self.log = []
