"""The log of a bus with CiA 402 (CANopen) stations: each frame named by its family, CANopen or ODrive CAN Simple.

`frame_log.CAN_BUS_FRAME` names every frame as CAN Simple, which is right for a bus of ODrives
only: there a CANopen SYNC (0x080) would be an ODrive's Get_Version. A bus whose stations declare
CiA 402 node ids (`canopen_ids.canopen_nodes` of their params) logs `CANOPEN_BUS_FRAME` records
instead, the same fields with `message` wider by the CANopen services:

    message    NMT, SYNC, TIME, EMCY, HEARTBEAT, SDO_REQUEST, SDO_RESPONSE, TPDO1..4, RPDO1..4 for a
               frame CANopen claims on the bus (`canopen.claims`: NMT, SYNC, every heartbeat, and the
               services of the CANopen node ids), by `canopen.decode` as `iotad candump` decodes it
               (MALFORMED where it refuses it); the CAN Simple name otherwise, as on an ODrive bus
    direction  TO_AXIS for what a master sends its drives (NMT, SYNC, TIME, RPDOs, SDO requests, the
               heartbeat of a node that is not one of the drives), FROM_AXIS for what a drive sends
               (TPDOs, SDO responses, EMCY, its heartbeat); a CAN Simple frame's as on an ODrive bus

`CanopenCanBus` (virtual time) and `CanopenBusLogger` (real time) are the modelled bus and the bus
logger with that log, taking the node ids as `canopen`; a bus with no CANopen station keeps
`CanBus` and `BusLogger`, so its recording is what it was.
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.api import Output, Param
from iotad.kernel.types import Enum, Struct

from . import canopen as co
from . import odrive
from .frame import Frame, FrameError
from .frame_log import CAN_BUS_FRAME, BusLogger, classify
from .virtual_bus import CanBus

CANOPEN_MESSAGES = ("NMT", "SYNC", "TIME", *co.SERVICES.values())
assert not set(CANOPEN_MESSAGES) & set(odrive.MESSAGES)  # "HEARTBEAT" is CANopen's, "Heartbeat" an ODrive's
CANOPEN_BUS_MESSAGE = Enum("canopenBusMessage", *odrive.MESSAGES, *CANOPEN_MESSAGES, "UNKNOWN", "MALFORMED")
CANOPEN_BUS_FRAME = Struct("canopenBusFrame", **dict(CAN_BUS_FRAME.fields, message=CANOPEN_BUS_MESSAGE))
_RECORD = CANOPEN_BUS_FRAME.record

_FROM_DRIVE = frozenset({"EMCY", "SDO_RESPONSE", *(f"TPDO{k}" for k in range(1, 5))})


def canopen_classify(frame: Frame, nodes: frozenset) -> tuple[str, str]:
    """(direction, name) of a frame on a bus whose CANopen node ids are `nodes`: its CANopen
    service where CANopen claims it, its CAN Simple message otherwise (`frame_log.classify`)."""
    if not co.claims(frame, nodes):
        return classify(frame)
    kind = co.service_of(frame.id)
    if kind is None:  # claimed but of no node (a heartbeat id of node 0)
        return "NOT_ODRIVE", "UNKNOWN"
    drive = kind in _FROM_DRIVE or (kind == "HEARTBEAT" and frame.id & 0x7F in nodes)
    direction = "FROM_AXIS" if drive else "TO_AXIS"
    try:
        return direction, co.decode(frame).kind
    except FrameError:  # a CANopen service's frame of the wrong shape
        return direction, "MALFORMED"


def renamed(record: Any, nodes: frozenset):
    """The CANOPEN_BUS_FRAME record of a CAN_BUS_FRAME record (`frame_log.bus_frame`'s), its frame
    named by family."""
    frame = Frame(record.id, bytes(record.dlc) if record.rtr else bytes(record.data[:record.dlc]),
                  rtr=record.rtr, extended=record.extended)
    direction, message = canopen_classify(frame, nodes)
    return _RECORD(duration=record.duration, station=record.station, id=record.id, extended=record.extended,
                   rtr=record.rtr, dlc=record.dlc, data=record.data, direction=direction, message=message)


def _node_ids(nodes: Any, what: str) -> frozenset:
    if isinstance(nodes, (str, bytes)) or not all(isinstance(n, int) and not isinstance(n, bool)
                                                  and 1 <= n <= co.NODE_ID_MAX for n in nodes):
        raise ValueError(f"{what} canopen must be CANopen node ids 1..{co.NODE_ID_MAX}, got {nodes!r}")
    return frozenset(nodes)


class CanopenCanBus(CanBus):
    """The modelled bus (`virtual_bus.CanBus`) of a bus with CANopen stations: its log names each
    frame by family, the CANopen node ids being `canopen`."""

    canopen = Param(())
    frames = Output(CANOPEN_BUS_FRAME, switching=0)  # the log's actions are CanBus's: only the type differs

    def init(self):
        super().init()
        self.canopen_ids = _node_ids(self.canopen, "CanopenCanBus")

    def _free(self):
        logged = len(self.log)
        super()._free()
        if len(self.log) > logged:  # the frame that ended, logged as CanBus logs it: named again
            self.log[logged] = renamed(self.log[logged], self.canopen_ids)


class CanopenBusLogger(BusLogger):
    """The logger of a real-time bus with CANopen stations (`frame_log.BusLogger`): each frame
    named by family, the CANopen node ids being `canopen`."""

    canopen = Param(())
    frames = Output(CANOPEN_BUS_FRAME, switching=0)

    def init(self):
        super().init()
        self.canopen_ids = _node_ids(self.canopen, "CanopenBusLogger")

    def logged_frame(self, record):
        return renamed(record, self.canopen_ids)
