"""Bring-up of drives on a real bus: find every drive that answers (ODrive and CiA 402), read its state, and command it, each command read back.

These are synchronous tools over a real-time bus (`iotad.can.bus`), for `iotad can`: nothing here
runs inside an engine. Units at the interface are SI (rad/s at the motor shaft, N.m, A); turns
appear only on the wire (ODrive CAN Simple), increments only in CANopen objects.

- ODrive: Get_Version to every node id 0..63 (a remote frame: harmless to anyone); the state and
  axis error of those that answered from their cyclic Heartbeat, the firmware's own account
  (waited for up to 1.5 heartbeat periods; a remote Heartbeat request only when none comes, and
  `Drive.source` says which); then Get_Error, Get_Bus_Voltage_Current and Get_Temperature.
- CiA 402: an SDO upload of the identity object 0x1018 to every node id 1..127 whose SDO id
  (0x600 + id) is no found ODrive's command id (0x600-0x67F are ODrive nodes 48-51: an SDO
  request there would be an ODrive command), then 0x1018's other entries, 0x1009/0x100A
  (versions), the statusword 0x6041, the error code 0x603F, 0x6079 (DC link voltage) and 0x2001
  (temperature, iotad's drive) where the drive has them, and the device name 0x1008. SDO as CiA
  301 has it: expedited, or segmented for a value over 4 bytes (the strings); a transfer this
  client stops (no answer in time, a wrong toggle bit) is ended with an SDO abort and its code.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Iterable

from . import canopen as co
from . import odrive
from .frame import Frame, FrameError

TAU = 2.0 * math.pi
TIMEOUT = 0.2  # s: how long a scan waits for answers; a command waits `--timeout`
HEARTBEAT_PERIOD = 0.1  # s: an ODrive's cyclic Heartbeat period (the firmware's default)


@dataclass
class Drive:
    protocol: str                      # odrive | cia402
    node_id: int
    firmware: str = "?"
    hardware: str = "?"
    state: str = "?"                   # ODrive axis state, or CiA 402 state
    errors: list[str] = field(default_factory=list)
    bus_voltage: float | None = None   # V
    temperature: float | None = None   # deg C
    detail: dict = field(default_factory=dict)
    source: str = ""                   # where the state came from: heartbeat | remote request | SDO


class CommandFailed(Exception):
    """A command's result, read back, is not what it asked for (or nothing answered in time); the
    message says what the drive reported."""


class Link:
    """Frames out, answers in: `ask` sends and collects the answers `match` picks, until each
    expected key has one or the time is up."""

    def __init__(self, bus, timeout: float = TIMEOUT, clock: Callable[[], float] = time.monotonic,
                 heartbeat_period: float = HEARTBEAT_PERIOD):
        self.bus, self.timeout, self.clock = bus, timeout, clock
        self.heartbeat_period = heartbeat_period

    def drain(self) -> None:
        """Forget what the bus brought before now (a cyclic frame read later must be a fresh one)."""
        while self.bus.recv_frame(timeout=0.0) is not None:
            pass

    def ask(self, frames: Iterable[Frame], match: Callable[[Frame], object], expected: set | None = None,
            timeout: float | None = None) -> dict:
        for frame in frames:
            self.bus.send_frame(frame)
        return self.collect(match, expected, timeout)

    def collect(self, match: Callable[[Frame], object], expected: set | None = None, timeout: float | None = None) -> dict:
        end = self.clock() + (self.timeout if timeout is None else timeout)
        answers: dict = {}
        while True:
            left = end - self.clock()
            if left <= 0 or (expected is not None and expected <= set(answers)):
                return answers
            got = self.bus.recv_frame(timeout=left)
            if got is None:
                continue
            key = match(got[1])
            if key is not None:
                answers[key] = got[1]


# ---------------------------------------------------------------------- ODrive
def odrive_heartbeats(link: Link, nodes: Iterable[int]) -> dict[int, tuple[dict, str]]:
    """{node: (Heartbeat signals, source)}: each axis's next cyclic Heartbeat, waited for up to 1.5
    heartbeat periods (source "heartbeat"); for an axis that sent none, the answer to a remote
    request (source "remote request"), which some peers answer with zeros."""
    nodes = set(nodes)
    match = _odrive_answer("Heartbeat")
    link.drain()
    got = link.collect(match, nodes, 1.5 * link.heartbeat_period)
    beats = {n: (_odrive_signals(frame), "heartbeat") for n, frame in got.items()}
    missing = nodes - set(got)
    if missing:
        asked = link.ask((odrive.request(n, "Heartbeat") for n in sorted(missing)), match, missing)
        beats.update({n: (_odrive_signals(frame), "remote request") for n, frame in asked.items()})
    return {n: beat for n, beat in beats.items() if beat[0]}


def _odrive_answer(name: str) -> Callable[[Frame], int | None]:
    cmd = odrive.COMMANDS[name]

    def match(frame: Frame) -> int | None:
        if frame.extended or frame.rtr or frame.id & 0x1F != cmd:
            return None
        return frame.id >> 5
    return match


def _odrive_signals(frame: Frame) -> dict:
    try:
        return odrive.decode(frame).signals
    except FrameError:
        return {}


def scan_odrives(link: Link, nodes: Iterable[int] = range(64)) -> list[Drive]:
    nodes = list(nodes)
    found = link.ask((odrive.request(n, "Get_Version") for n in nodes), _odrive_answer("Get_Version"), set(nodes))
    beats = odrive_heartbeats(link, found) if found else {}
    return [odrive_status(link, n, found[n], beats.get(n, ({}, ""))) for n in sorted(found)]


def odrive_status(link: Link, node: int, version: Frame | None = None, beat: tuple[dict, str] | None = None) -> Drive:
    drive = Drive("odrive", node)
    if version is None:
        version = link.ask([odrive.request(node, "Get_Version")], _odrive_answer("Get_Version"), {node}).get(node)
    v = _odrive_signals(version) if version is not None else {}
    if v:
        drive.firmware = f"{v['Fw_Version_Major']}.{v['Fw_Version_Minor']}.{v['Fw_Version_Revision']}"
        drive.hardware = f"{v['Hw_Version_Major']}.{v['Hw_Version_Minor']}.{v['Hw_Version_Variant']}"
    beat, drive.source = beat if beat is not None else odrive_heartbeats(link, [node]).get(node, ({}, ""))
    if beat:
        drive.state = _name(odrive.AXIS_STATE, beat["Axis_State"])
        drive.detail.update(axis_error=beat["Axis_Error"], procedure_result=beat["Procedure_Result"])
    errors = _ask_one(link, node, "Get_Error")
    flags = (errors.get("Active_Errors", 0) | errors.get("Disarm_Reason", 0)) if errors else beat.get("Axis_Error", 0) if beat else 0
    drive.errors = odrive.error_names(flags) if flags else []
    bus = _ask_one(link, node, "Get_Bus_Voltage_Current")
    if bus:
        drive.bus_voltage = bus["Bus_Voltage"]
    temperature = _ask_one(link, node, "Get_Temperature")
    if temperature:
        drive.temperature = temperature["FET_Temperature"]
    return drive


def _ask_one(link: Link, node: int, name: str) -> dict:
    frame = link.ask([odrive.request(node, name)], _odrive_answer(name), {node}).get(node)
    return _odrive_signals(frame) if frame is not None else {}


def _name(table: dict[str, int], value: int) -> str:
    return next((name for name, number in table.items() if number == value), str(value))


# ---------------------------------------------------------------------- CiA 402
def _sdo_answer(index: int, subindex: int) -> Callable[[Frame], int | None]:
    def match(frame: Frame) -> int | None:
        if frame.extended or frame.rtr or frame.id & 0x780 != co.TSDO or frame.dlc != 8:
            return None
        try:
            fields = co.decode(frame).fields
        except FrameError:
            return None
        return frame.id & 0x7F if (fields["index"], fields["subindex"]) == (index, subindex) else None
    return match


def _segment_answer(node: int) -> Callable[[Frame], int | None]:
    """A server's segment (or abort) from `node`: segments carry no index, the transfer is the one under way."""
    def match(frame: Frame) -> int | None:
        if frame.extended or frame.rtr or frame.id != co.TSDO + node or frame.dlc != 8:
            return None
        try:
            fields = co.decode(frame).fields
        except FrameError:
            return None
        return node if fields["service"] in ("upload_segment", "download_segment", "abort") else None
    return match


def sdo_abort(link: Link, node: int, index: int, subindex: int, code: int) -> None:
    """End a transfer this client stops, as CiA 301 asks (never leave one open)."""
    link.bus.send_frame(co.sdo_abort(node, index, subindex, code, from_server=False))


MAX_UPLOAD = 4096  # bytes: a longer segmented upload is aborted (a server that never says "last")


def sdo_read(link: Link, nodes: Iterable[int], index: int, subindex: int = 0, timeout: float | None = None) -> dict:
    """{node: fields of its answer} to an upload of index.subindex (an abort's fields say so); a
    segmented answer is read to its end, its bytes in `data`. A single node that does not answer
    in time gets an abort (many nodes: a scan, where silence means no drive)."""
    nodes = list(nodes)
    answers = link.ask((co.sdo_upload(n, index, subindex) for n in nodes), _sdo_answer(index, subindex), set(nodes),
                       timeout)
    if len(nodes) == 1 and nodes[0] not in answers:
        sdo_abort(link, nodes[0], index, subindex, co.ABORT_TIMEOUT)
    out = {}
    for n, frame in answers.items():
        fields = co.decode(frame).fields
        if fields.get("segmented"):
            fields = _upload_segments(link, n, index, subindex, fields, timeout)
        if fields is not None:
            out[n] = fields
    return out


def _upload_segments(link: Link, node: int, index: int, subindex: int, first: dict, timeout: float | None) -> dict | None:
    """The segments of an upload whose initiate answer was `first`; None (after an abort) when the
    server stops answering or breaks the toggle rule."""
    data, toggle = b"", 0
    while True:
        frame = link.ask([co.sdo_upload_segment_request(node, toggle)], _segment_answer(node), {node}, timeout).get(node)
        if frame is None:
            sdo_abort(link, node, index, subindex, co.ABORT_TIMEOUT)
            return None
        fields = co.decode(frame).fields
        if fields["service"] == "abort":
            return fields
        if fields["service"] != "upload_segment" or fields["toggle"] != toggle or "data" not in fields:
            sdo_abort(link, node, index, subindex, co.ABORT_TOGGLE if fields.get("toggle") != toggle else co.ABORT_COMMAND)
            return None
        data += fields["data"]
        if fields["last"]:
            return {"service": "upload", "index": index, "subindex": subindex, "data": data, "size": first.get("size")}
        if len(data) > MAX_UPLOAD:
            sdo_abort(link, node, index, subindex, co.SDO_ABORT_OUT_OF_MEMORY)
            return None
        toggle ^= 1


def sdo_write(link: Link, node: int, index: int, subindex: int, data: bytes, timeout: float | None = None) -> None:
    """Write one object (expedited up to 4 bytes, segmented beyond); CommandFailed with the
    abort's reason, or when nothing answered in time (the transfer then aborted)."""
    data = bytes(data)
    where = f"0x{index:04X}.{subindex:02X}"
    wait = link.timeout if timeout is None else timeout
    first = co.sdo_download(node, index, subindex, data) if len(data) <= 4 else \
        co.sdo_download_initiate(node, index, subindex, len(data))
    answer = link.ask([first], _sdo_answer(index, subindex), {node}, timeout).get(node)
    if answer is None:
        sdo_abort(link, node, index, subindex, co.ABORT_TIMEOUT)
        raise CommandFailed(f"node {node}: no answer to the SDO write of {where} within {wait:g} s (aborted)")
    fields = co.decode(answer).fields
    if fields["service"] == "abort":
        raise CommandFailed(f"node {node}: the drive refused {where}: {fields['reason']} "
                            f"(SDO abort 0x{fields['code']:08X})")
    if len(data) <= 4:
        return
    chunks = [data[k:k + 7] for k in range(0, len(data), 7)]
    for k, chunk in enumerate(chunks):
        toggle = k & 1
        frame = link.ask([co.sdo_download_segment(node, toggle, chunk, k == len(chunks) - 1)], _segment_answer(node),
                         {node}, timeout).get(node)
        if frame is None:
            sdo_abort(link, node, index, subindex, co.ABORT_TIMEOUT)
            raise CommandFailed(f"node {node}: no answer to segment {k + 1} of the SDO write of {where} within "
                                f"{wait:g} s (aborted)")
        fields = co.decode(frame).fields
        if fields["service"] == "abort":
            raise CommandFailed(f"node {node}: the drive refused {where}: {fields['reason']} "
                                f"(SDO abort 0x{fields['code']:08X})")
        if fields["service"] != "download_segment" or fields["toggle"] != toggle:
            sdo_abort(link, node, index, subindex, co.ABORT_TOGGLE)
            raise CommandFailed(f"node {node}: a wrong answer to segment {k + 1} of the SDO write of {where} (aborted)")


def _value(fields: dict | None, od, index: int, subindex: int = 0):
    if not fields or "data" not in fields:
        return None
    try:
        return co.decode_value(od, index, subindex, fields["data"])
    except Exception:  # noqa: BLE001 - an odd length or a type the EDS lacks: not shown
        return None


def scan_cia402(link: Link, nodes: Iterable[int] = range(1, 128), avoid: Iterable[int] = ()) -> list[Drive]:
    """The CiA 402 drives among `nodes`; `avoid` are ODrive node ids found on the bus (whose
    command ids an SDO request must not hit)."""
    busy = {frame_id for n in avoid for frame_id in range(n << 5, (n << 5) + 32)}
    nodes = [n for n in nodes if co.RSDO + n not in busy]
    vendors = sdo_read(link, nodes, 0x1018, 1)
    return [cia402_status(link, n) for n in sorted(vendors) if vendors[n]["service"] == "upload"]


def cia402_status(link: Link, node: int) -> Drive:
    od = co.object_dictionary(co.DRIVE_EDS, node)
    drive = Drive("cia402", node)
    read = {key: sdo_read(link, [node], *key).get(node) for key in
            ((0x1018, 1), (0x1018, 2), (0x1018, 3), (0x1008, 0), (0x1009, 0), (0x100A, 0), (0x6041, 0), (0x603F, 0),
             (0x6079, 0), (0x2001, 0), (0x6061, 0))}
    strings = {key: (bytes(read[key]["data"]).rstrip(b"\0").decode("ascii", "replace") if read[key] and "data" in read[key]
                     else "?") for key in ((0x1008, 0), (0x1009, 0), (0x100A, 0))}
    drive.detail["device"] = strings[(0x1008, 0)]
    revision = _value(read[(0x1018, 3)], od, 0x1018, 3)
    drive.firmware = strings[(0x100A, 0)] + (f" (rev 0x{revision:08X})" if revision is not None else "")
    drive.hardware = strings[(0x1009, 0)]
    drive.detail["vendor"] = _value(read[(0x1018, 1)], od, 0x1018, 1)
    drive.detail["product"] = _value(read[(0x1018, 2)], od, 0x1018, 2)
    status = _value(read[(0x6041, 0)], od, 0x6041)
    if status is not None:
        drive.state = co.state_of(status)
        drive.detail["statusword"] = status
        drive.source = "SDO"
    code = _value(read[(0x603F, 0)], od, 0x603F)
    if code:
        drive.errors = [f"0x{code:04X} {co.emcy_name(code)}"]
    voltage = _value(read[(0x6079, 0)], od, 0x6079)
    drive.bus_voltage = voltage / 1000.0 if voltage is not None else None
    drive.temperature = _value(read[(0x2001, 0)], od, 0x2001)
    mode = _value(read[(0x6061, 0)], od, 0x6061)
    if mode is not None:
        drive.detail["mode"] = co.MODE_NAMES.get(mode, mode)
    return drive


def scan(link: Link, protocols: Iterable[str] = ("odrive", "cia402")) -> list[Drive]:
    odrives = scan_odrives(link) if "odrive" in protocols else []
    drives = scan_cia402(link, avoid=[d.node_id for d in odrives]) if "cia402" in protocols else []
    return odrives + drives


def status(link: Link, protocol: str, node: int) -> Drive:
    return odrive_status(link, node) if protocol == "odrive" else cia402_status(link, node)


# ---------------------------------------------------------------------- commands, read back
def _wait_for(link: Link, read: Callable[[], Drive], done: Callable[[Drive], bool], timeout: float) -> Drive:
    end = link.clock() + timeout
    drive = read()
    while not done(drive) and link.clock() < end:
        drive = read()
    return drive


def _controlword(link: Link, node: int, word: int) -> None:
    sdo_write(link, node, 0x6040, 0, word.to_bytes(2, "little"))


def clear_errors(link: Link, protocol: str, node: int, timeout: float = 1.0) -> Drive:
    """Clear a drive's errors and read its state back. A drive with no fault gets nothing (its
    `detail["unchanged"]` says so). An ODrive gets Clear_Errors; a CiA 402 drive in FAULT a fault
    reset, the rising edge of controlword bit 7 with the other command bits as they are (never
    "disable voltage" on the way: 0x0000 would switch an enabled drive's power stage off)."""
    drive = status(link, protocol, node)
    faulted = drive.state == "FAULT" if protocol == "cia402" else bool(drive.errors or drive.detail.get("axis_error"))
    if not faulted and drive.state not in ("?", "FAULT REACTION ACTIVE"):
        drive.detail["unchanged"] = True
        return drive
    if protocol == "odrive":
        link.bus.send_frame(odrive.encode(node, "Clear_Errors", Identify=0))
    else:
        od = co.object_dictionary(co.DRIVE_EDS, node)
        word = _value(sdo_read(link, [node], 0x6040).get(node), od, 0x6040)
        if word is None:
            raise CommandFailed(f"node {node}: no answer to the SDO read of its controlword 0x6040")
        if word & co.CW_FAULT_RESET:  # bit 7 is high already: lower it first, or there is no edge
            _controlword(link, node, word & ~co.CW_FAULT_RESET)
        _controlword(link, node, word | co.CW_FAULT_RESET)
    drive = _wait_for(link, lambda: status(link, protocol, node), lambda d: not d.errors and d.state != "FAULT", timeout)
    if drive.errors or drive.state == "FAULT":
        raise CommandFailed(f"node {node}: still in error after clear-errors: {', '.join(drive.errors) or drive.state}")
    return drive


def arm(link: Link, protocol: str, node: int, timeout: float = 1.0) -> Drive:
    if protocol == "odrive":
        link.bus.send_frame(odrive.encode(node, "Set_Axis_State", Axis_Requested_State=odrive.AXIS_STATE["CLOSED_LOOP_CONTROL"]))
        want = "CLOSED_LOOP_CONTROL"
    else:
        drive = cia402_status(link, node)
        if drive.state == "FAULT":
            raise CommandFailed(f"node {node}: in FAULT ({', '.join(drive.errors) or 'no error code'}); "
                                "run clear-errors first")
        for word in (co.CW_SHUTDOWN, co.CW_SWITCH_ON, co.CW_ENABLE_OPERATION):
            _controlword(link, node, word)
        want = "OPERATION ENABLED"
    drive = _wait_for(link, lambda: status(link, protocol, node), lambda d: d.state == want, timeout)
    if drive.state != want:
        why = ", ".join(drive.errors) or drive.detail.get("procedure_result", "")
        raise CommandFailed(f"node {node}: did not arm within {timeout:g} s: it reports {drive.state}"
                            + (f" ({why})" if why != "" else ""))
    return drive


def idle(link: Link, protocol: str, node: int, timeout: float = 1.0) -> Drive:
    if protocol == "odrive":
        link.bus.send_frame(odrive.encode(node, "Set_Axis_State", Axis_Requested_State=odrive.AXIS_STATE["IDLE"]))
        wanted = ("IDLE",)
    else:
        _controlword(link, node, co.CW_SHUTDOWN)  # the power stage off, ready to switch on again
        wanted = ("READY TO SWITCH ON", "SWITCH ON DISABLED")
    drive = _wait_for(link, lambda: status(link, protocol, node), lambda d: d.state in wanted, timeout)
    if drive.state not in wanted:
        raise CommandFailed(f"node {node}: still {drive.state} after idle")
    return drive


def estop(link: Link, protocol: str, node: int, timeout: float = 1.0) -> Drive:
    if protocol == "odrive":
        link.bus.send_frame(odrive.encode(node, "Estop"))
        wanted = ("IDLE",)
    else:
        _controlword(link, node, co.CW_QUICK_STOP)
        wanted = ("QUICK STOP ACTIVE", "SWITCH ON DISABLED")
    drive = _wait_for(link, lambda: status(link, protocol, node), lambda d: d.state in wanted, timeout)
    if drive.state not in wanted:
        raise CommandFailed(f"node {node}: still {drive.state} after estop")
    return drive


def set_limits(link: Link, protocol: str, node: int, velocity: float | None, current: float | None,
               torque: float | None) -> dict:
    """Velocity in rad/s at the motor shaft, current in A (ODrive), torque in N.m (CiA 402, its max
    torque). Returns what the drive holds now, read back where the protocol can."""
    if protocol == "odrive":
        if velocity is None or current is None:
            raise CommandFailed("an ODrive takes both limits in one Set_Limits frame: give --velocity and --current")
        link.bus.send_frame(odrive.encode(node, "Set_Limits", Velocity_Limit=velocity / TAU, Current_Limit=current))
        drive = odrive_status(link, node)  # CAN Simple cannot read the limits back: it must still answer, error-free
        if drive.state == "?":
            raise CommandFailed(f"node {node}: no heartbeat after Set_Limits")
        return {"velocity_limit_turns_per_s": velocity / TAU, "current_limit_a": current, "errors": drive.errors}
    od = co.object_dictionary(co.DRIVE_EDS, node)
    done = {}
    if velocity is not None:
        counts = sdo_read(link, [node], 0x608F, 1).get(node)
        per_turn = _value(counts, od, 0x608F, 1) or co.default(od, 0x608F, 1)
        sdo_write(link, node, 0x607F, 0, co.encode_value(od, 0x607F, 0, round(abs(velocity) / TAU * per_turn)))
        done["velocity_limit_rad_s"] = _value(sdo_read(link, [node], 0x607F).get(node), od, 0x607F) / per_turn * TAU
    if torque is not None:
        rated = _value(sdo_read(link, [node], 0x6076).get(node), od, 0x6076) or co.default(od, 0x6076)
        sdo_write(link, node, 0x6072, 0, co.encode_value(od, 0x6072, 0, min(0xFFFF, round(1000.0 * abs(torque) * 1000.0 / rated))))
        done["torque_limit_nm"] = _value(sdo_read(link, [node], 0x6072).get(node), od, 0x6072) / 1000.0 * rated / 1000.0
    if current is not None:
        raise CommandFailed("a CiA 402 drive here takes its limit as --torque (N.m), not --current")
    return done
