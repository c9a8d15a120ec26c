"""CANopen (CiA 301) and the CiA 402 drive profile on frames: COB-IDs, NMT, SYNC, EMCY, SDO, PDOs, heartbeat.

The object dictionary comes from an EDS through the `canopen` package (`object_dictionary`), and
so do its value codecs (`ODVariable.encode_raw`/`decode_raw`), the NMT, SDO-abort and EMCY tables
and the 402 statusword masks. What `canopen` does not give here is its network: its `Network`,
`RemoteNode`, SDO client and PDO maps run on threads against the wall clock, while an IOTA acts
only in its engine's firings, in virtual or real time. So an IOTA builds and reads frames with
the functions below, one frame at a time, and keeps the protocol's state (which SDO is waiting,
which 402 state a drive reports) in its own state (docs/canopen.md says more).

    frame = sdo_download(3, 0x6060, 0, bytes([8]))     # RSDO 0x603: write Modes of operation = 8 (CSP)
    message = decode(frame)                             # Message(kind="SDO_REQUEST", node_id=3, fields={...})
    describe(message)                                   # 'SDO download node=3 0x6060.00 Modes of operation = 8'

Frames are classic 11-bit frames; COB-ID = function code + node id (1..127). `decode` raises
`MalformedFrame` for a frame of a CANopen shape with the wrong length and `UnknownFrame` for an id
no CANopen service uses; both are `FrameError`s (ValueError) with a message that names the frame.
"""
from __future__ import annotations

import functools
import struct
from pathlib import Path
from typing import Any, Iterable, NamedTuple

from canopen.emcy import EmcyError
from canopen.nmt import NMT_COMMANDS, NMT_STATES
from canopen.objectdictionary import ODVariable, ObjectDictionary, import_od
from canopen.profiles.p402 import OperationMode, State402
from canopen.sdo.exceptions import SdoAbortedError

from .frame import Frame, FrameError

DRIVE_EDS = Path(__file__).with_name("data") / "cia402_drive.eds"

NODE_ID_MAX = 127
NMT, SYNC, EMCY, TIME = 0x000, 0x080, 0x080, 0x100
TPDO = (0x180, 0x280, 0x380, 0x480)
RPDO = (0x200, 0x300, 0x400, 0x500)
TSDO, RSDO, HEARTBEAT = 0x580, 0x600, 0x700
SERVICES = {TPDO[k]: f"TPDO{k + 1}" for k in range(4)} | {RPDO[k]: f"RPDO{k + 1}" for k in range(4)} | {
    EMCY: "EMCY", TSDO: "SDO_RESPONSE", RSDO: "SDO_REQUEST", HEARTBEAT: "HEARTBEAT"}

NMT_COMMAND = {"START": 1, "STOP": 2, "ENTER_PRE_OPERATIONAL": 128, "RESET_NODE": 129, "RESET_COMMUNICATION": 130}
NMT_COMMAND_NAMES = {code: name for name, code in NMT_COMMAND.items()}
NMT_STATE = {name.replace("-", "_").replace(" ", "_"): code for code, name in NMT_STATES.items()}
NMT_STATE_NAMES = {code: name for name, code in NMT_STATE.items()}
NMT_STATE_NAMES[0] = "BOOT_UP"  # a heartbeat with state 0 is the boot-up message
assert set(NMT_COMMAND.values()) <= set(NMT_COMMANDS.values())

SDO_ABORTS: dict[int, str] = dict(SdoAbortedError.CODES)
ABORT_TOGGLE, ABORT_TIMEOUT, ABORT_COMMAND = 0x05030000, 0x05040000, 0x05040001  # CiA 301 abort codes
SDO_ABORT_OUT_OF_MEMORY = 0x05040005
SDO_ABORTS.setdefault(0x08000022, "Data cannot be transferred or stored because of the present device state")

# CiA 402: the states by the statusword masks of the `canopen` package (State402.SW_MASK), in the
# order of the standard's state diagram; a number per state for jointStatus.axis_state.
STATES = ("NOT READY TO SWITCH ON", "SWITCH ON DISABLED", "READY TO SWITCH ON", "SWITCHED ON",
          "OPERATION ENABLED", "QUICK STOP ACTIVE", "FAULT REACTION ACTIVE", "FAULT")
STATE_NUMBER = {name: k for k, name in enumerate(STATES)}
STATUSWORD = {name: State402.SW_MASK[name][1] for name in STATES}  # the bits each state sets
SW_VOLTAGE_ENABLED, SW_WARNING, SW_REMOTE = 1 << 4, 1 << 7, 1 << 9
SW_TARGET_REACHED, SW_SETPOINT_ACK, SW_FOLLOWING_ERROR = 1 << 10, 1 << 12, 1 << 13
# Controlword commands (CiA 402 table "device control commands"); fault reset is bit 7's rising edge.
CW_SHUTDOWN, CW_SWITCH_ON, CW_ENABLE_OPERATION = 0x06, 0x07, 0x0F
CW_DISABLE_VOLTAGE, CW_QUICK_STOP, CW_FAULT_RESET = 0x00, 0x02, 0x80
CW_NEW_SETPOINT, CW_CHANGE_IMMEDIATELY = 1 << 4, 1 << 5
MODES = {"PP": OperationMode.PROFILED_POSITION, "CSP": OperationMode.CYCLIC_SYNCHRONOUS_POSITION,
         "CSV": OperationMode.CYCLIC_SYNCHRONOUS_VELOCITY}
MODE_NAMES = dict(OperationMode.CODE2NAME)

# EMCY error codes (CiA 301 and CiA 402) by name; other codes are named by their class.
EMCY_CODES = {
    0x0000: "error reset or no error", 0x1000: "generic error", 0x2310: "continuous over-current",
    0x2320: "short circuit at outputs", 0x3210: "DC link over-voltage", 0x3220: "DC link under-voltage",
    0x4210: "excess temperature device", 0x4310: "excess temperature drive", 0x5530: "EEPROM",
    0x6100: "internal software", 0x6320: "parameter error", 0x7305: "incremental sensor 1 fault",
    0x8110: "CAN overrun (objects lost)", 0x8120: "CAN in error passive mode",
    0x8130: "life guard error or heartbeat error", 0x8140: "recovered from bus off",
    0x8210: "PDO not processed due to length error", 0x8220: "PDO length exceeded",
    0x8400: "velocity speed control error", 0x8611: "following error", 0xFF00: "device specific"}

_SDO = struct.Struct("<BHB")
_EMCY = struct.Struct("<HB5s")


class UnknownFrame(FrameError):
    """An id that no CANopen service uses (or a node id out of range)."""


class MalformedFrame(FrameError):
    """A CANopen service's frame of the wrong shape (length, RTR, extended id, SDO command)."""


class UnknownValue(MalformedFrame):
    """A CANopen frame of the right shape whose value no state or command has (a heartbeat of state 99)."""


class Message(NamedTuple):
    kind: str         # NMT SYNC EMCY HEARTBEAT SDO_REQUEST SDO_RESPONSE TPDO1..4 RPDO1..4 TIME
    node_id: int      # 0 for NMT (the target is in fields), SYNC and TIME
    fields: dict
    frame: Frame


# ---------------------------------------------------------------------- the object dictionary
@functools.lru_cache(maxsize=32)
def object_dictionary(path: str | Path = DRIVE_EDS, node_id: int = 1) -> ObjectDictionary:
    """The object dictionary of an EDS for a node id (`$NODEID` resolved), by the `canopen`
    package; cached, so treat it as read-only."""
    try:
        return import_od(str(path), node_id)
    except (OSError, ValueError, KeyError) as exc:
        raise ValueError(f"{path}: not a readable EDS: {exc}") from None


def variable(od: ObjectDictionary, index: int, subindex: int = 0) -> ODVariable:
    """The object `index`.`subindex` of `od`; KeyError names it when the EDS lacks it."""
    try:
        entry = od[index]
        return entry if isinstance(entry, ODVariable) else entry[subindex]
    except KeyError:
        raise KeyError(f"object 0x{index:04X}.{subindex:02X} is not in the object dictionary") from None


def default(od: ObjectDictionary, index: int, subindex: int = 0) -> Any:
    return variable(od, index, subindex).default


def encode_value(od: ObjectDictionary, index: int, subindex: int, value: Any) -> bytes:
    """`value` in the object's data type, little-endian (raises ValueError if it does not fit)."""
    return variable(od, index, subindex).encode_raw(value)


def decode_value(od: ObjectDictionary, index: int, subindex: int, data: bytes) -> Any:
    var = variable(od, index, subindex)
    size = len(var) // 8 if var.fixed_size else len(data)
    return var.decode_raw(bytes(data[:size]))


# ---------------------------------------------------------------------- building frames
def _node(node_id: int, low: int = 1) -> int:
    if isinstance(node_id, bool) or not isinstance(node_id, int) or not low <= node_id <= NODE_ID_MAX:
        raise ValueError(f"CANopen node id must be {low}..{NODE_ID_MAX}, got {node_id!r}")
    return node_id


def nmt(command: str | int, node_id: int = 0) -> Frame:
    """An NMT command (START, STOP, ENTER_PRE_OPERATIONAL, RESET_NODE, RESET_COMMUNICATION) to a
    node, or to every node (0)."""
    code = NMT_COMMAND[command] if isinstance(command, str) else command
    if code not in NMT_COMMAND_NAMES:
        raise ValueError(f"NMT command {command!r} is not one of {', '.join(NMT_COMMAND)}")
    return Frame(NMT, bytes((code, _node(node_id, 0))))


def sync() -> Frame:
    return Frame(SYNC, b"")


def heartbeat(node_id: int, state: str | int) -> Frame:
    code = NMT_STATE[state] if isinstance(state, str) else state
    return Frame(HEARTBEAT + _node(node_id), bytes((code,)))


def emcy(node_id: int, code: int, register: int = 0, data: bytes = b"") -> Frame:
    return Frame(EMCY + _node(node_id), _EMCY.pack(code, register, bytes(data)))


def sdo_download(node_id: int, index: int, subindex: int, data: bytes) -> Frame:
    """Client to server: an expedited download (write) of 1 to 4 bytes."""
    n = len(data)
    if not 1 <= n <= 4:
        raise ValueError(f"an expedited SDO download carries 1 to 4 bytes, got {n}")
    command = 0x20 | ((4 - n) << 2) | 0x3
    return Frame(RSDO + _node(node_id), _SDO.pack(command, index, subindex) + bytes(data).ljust(4, b"\0"))


def sdo_upload(node_id: int, index: int, subindex: int) -> Frame:
    """Client to server: initiate an upload (read)."""
    return Frame(RSDO + _node(node_id), _SDO.pack(0x40, index, subindex) + bytes(4))


def sdo_download_initiate(node_id: int, index: int, subindex: int, size: int) -> Frame:
    """Client to server: initiate a segmented download (write) of `size` bytes (more than 4)."""
    return Frame(RSDO + _node(node_id), _SDO.pack(0x21, index, subindex) + struct.pack("<I", size))


def sdo_download_segment(node_id: int, toggle: int, data: bytes, last: bool) -> Frame:
    """Client to server: one segment of a download, 1 to 7 bytes; `last` ends the transfer."""
    n = len(data)
    if not 1 <= n <= 7:
        raise ValueError(f"an SDO segment carries 1 to 7 bytes, got {n}")
    command = (toggle & 1) << 4 | (7 - n) << 1 | int(last)
    return Frame(RSDO + _node(node_id), bytes((command,)) + bytes(data).ljust(7, b"\0"))


def sdo_upload_segment_request(node_id: int, toggle: int) -> Frame:
    """Client to server: the next segment of an upload, please."""
    return Frame(RSDO + _node(node_id), bytes((0x60 | (toggle & 1) << 4,)) + bytes(7))


def sdo_upload_initiate_response(node_id: int, index: int, subindex: int, size: int) -> Frame:
    """Server to client: a segmented upload of `size` bytes begins (the segments follow on request)."""
    return Frame(TSDO + _node(node_id), _SDO.pack(0x41, index, subindex) + struct.pack("<I", size))


def sdo_upload_segment(node_id: int, toggle: int, data: bytes, last: bool) -> Frame:
    """Server to client: one segment of an upload, 0 to 7 bytes; `last` ends the transfer."""
    n = len(data)
    if not 0 <= n <= 7:
        raise ValueError(f"an SDO segment carries 0 to 7 bytes, got {n}")
    command = (toggle & 1) << 4 | (7 - n) << 1 | int(last)
    return Frame(TSDO + _node(node_id), bytes((command,)) + bytes(data).ljust(7, b"\0"))


def sdo_download_segment_response(node_id: int, toggle: int) -> Frame:
    return Frame(TSDO + _node(node_id), bytes((0x20 | (toggle & 1) << 4,)) + bytes(7))


def sdo_download_response(node_id: int, index: int, subindex: int) -> Frame:
    return Frame(TSDO + _node(node_id), _SDO.pack(0x60, index, subindex) + bytes(4))


def sdo_upload_response(node_id: int, index: int, subindex: int, data: bytes) -> Frame:
    """Server to client: an expedited upload response (1 to 4 bytes; longer values are cut to 4)."""
    data = bytes(data)[:4] or b"\0"
    command = 0x40 | ((4 - len(data)) << 2) | 0x3
    return Frame(TSDO + _node(node_id), _SDO.pack(command, index, subindex) + data.ljust(4, b"\0"))


def sdo_abort(node_id: int, index: int, subindex: int, code: int, from_server: bool = True) -> Frame:
    base = TSDO if from_server else RSDO
    return Frame(base + _node(node_id), _SDO.pack(0x80, index, subindex) + struct.pack("<I", code))


# ---------------------------------------------------------------------- PDOs
class PdoMap(NamedTuple):
    """One PDO's mapping: (index, subindex, bits) per mapped object, in frame order."""

    entries: tuple[tuple[int, int, int], ...]

    @classmethod
    def from_words(cls, words: Iterable[int]) -> "PdoMap":
        return cls(tuple((w >> 16, (w >> 8) & 0xFF, w & 0xFF) for w in words))

    def words(self) -> list[int]:
        return [index << 16 | sub << 8 | bits for index, sub, bits in self.entries]

    @property
    def size(self) -> int:
        return sum(bits for _, _, bits in self.entries) // 8


def pdo_map(od: ObjectDictionary, mapping_index: int) -> PdoMap:
    """The default mapping the EDS gives a PDO (0x1600.. RPDOs, 0x1A00.. TPDOs)."""
    record = od[mapping_index]
    count = record[0].default
    return PdoMap.from_words(record[k].default for k in range(1, count + 1))


def pack_pdo(od: ObjectDictionary, cob_id: int, mapping: PdoMap, values: dict[int, Any]) -> Frame:
    """A PDO frame: the mapped objects' values (keyed by index) in their data types, in order;
    a mapped object missing from `values` is sent as 0."""
    data = b"".join(encode_value(od, index, sub, values.get(index, 0)) for index, sub, _ in mapping.entries)
    return Frame(cob_id, data)


def unpack_pdo(od: ObjectDictionary, mapping: PdoMap, data: bytes) -> dict[int, Any]:
    """The mapped objects' values (keyed by index); MalformedFrame when the length differs."""
    if len(data) != mapping.size:
        raise MalformedFrame(f"PDO of {len(data)} bytes; its mapping is {mapping.size} bytes")
    values, at = {}, 0
    for index, sub, bits in mapping.entries:
        size = bits // 8
        values[index] = decode_value(od, index, sub, data[at:at + size])
        at += size
    return values


# ---------------------------------------------------------------------- decoding
def cob_node(frame_id: int) -> tuple[int, int]:
    """(function code, node id) of an 11-bit COB-ID."""
    return frame_id & 0x780, frame_id & 0x7F


def service_of(frame_id: int) -> str | None:
    """The CANopen service an 11-bit id belongs to, whatever its frame holds (NMT, SYNC, TIME,
    TPDO1, SDO_REQUEST, HEARTBEAT...); None for an id that none uses."""
    if frame_id in _BROADCASTS:
        return _BROADCASTS[frame_id]
    function, node = cob_node(frame_id)
    return SERVICES.get(function) if node else None


_BROADCASTS = {NMT: "NMT", SYNC: "SYNC", TIME: "TIME"}


def claims(frame: Frame, nodes: frozenset | set) -> bool:
    """Whether a frame is CANopen on a bus whose CANopen node ids are `nodes`: NMT, SYNC, a
    heartbeat, or a service of one of the nodes (the ids an ODrive of a mixed bus must not use,
    nodes/can_motor checks that). Every frame of a bus with no CANopen node is not."""
    if frame.extended or not nodes:
        return False
    if frame.id in (NMT, SYNC) or frame.id & 0x780 == HEARTBEAT:
        return True
    return frame.id & 0x7F in nodes and frame.id & 0x780 in SERVICES


def decode(frame: Frame) -> Message:
    """The CANopen service a frame carries, with its fields; PDO data stays raw bytes
    (`unpack_pdo` reads it against a mapping)."""
    if frame.extended:
        raise MalformedFrame(f"frame 0x{frame.id:08X}: CANopen uses 11-bit ids")
    data = frame.data
    if frame.id == NMT:
        _length(frame, "NMT", 2)
        command, target = data[0], data[1]
        if command not in NMT_COMMAND_NAMES:
            raise MalformedFrame(f"NMT frame with command {command}, not a CiA 301 NMT command")
        if target > NODE_ID_MAX:
            raise MalformedFrame(f"NMT frame for node {target}, beyond {NODE_ID_MAX}")
        return Message("NMT", 0, {"command": NMT_COMMAND_NAMES[command], "target": target}, frame)
    if frame.id == SYNC:
        if frame.rtr or frame.dlc > 1:
            raise MalformedFrame(f"SYNC with {frame.dlc} bytes (0, or 1 with a counter)")
        return Message("SYNC", 0, {"counter": data[0]} if data else {}, frame)
    if frame.id == TIME:
        _length(frame, "TIME", 6)
        return Message("TIME", 0, {}, frame)
    function, node = cob_node(frame.id)
    kind = SERVICES.get(function)
    if kind is None or node == 0:
        raise UnknownFrame(f"frame 0x{frame.id:03X} is no CANopen service of a node 1..127")
    if frame.rtr:
        raise MalformedFrame(f"{kind} 0x{frame.id:03X} as a remote frame (CANopen services here send data)")
    if kind == "HEARTBEAT":
        _length(frame, kind, 1)
        state = data[0] & 0x7F
        if state not in NMT_STATE_NAMES:
            raise UnknownValue(f"heartbeat of node {node} with state {state}, not an NMT state")
        return Message(kind, node, {"state": NMT_STATE_NAMES[state]}, frame)
    if kind == "EMCY":
        _length(frame, kind, 8)
        code, register, vendor = _EMCY.unpack(data)
        return Message(kind, node, {"code": code, "name": emcy_name(code), "register": register,
                                    "data": vendor}, frame)
    if kind in ("SDO_REQUEST", "SDO_RESPONSE"):
        _length(frame, kind, 8)
        return Message(kind, node, _sdo_fields(kind, data), frame)
    return Message(kind, node, {"data": bytes(data)}, frame)  # a PDO: its mapping says what it holds


def _length(frame: Frame, kind: str, dlc: int) -> None:
    if frame.rtr or frame.dlc != dlc:
        what = "a remote frame" if frame.rtr else f"{frame.dlc} bytes"
        raise MalformedFrame(f"{kind} 0x{frame.id:03X} with {what}; it has {dlc}")


def _sdo_fields(kind: str, data: bytes) -> dict:
    """The fields of an SDO frame (CiA 301 7.2.4.3): initiate (expedited or segmented), segment
    (index and subindex None: a segment belongs to the transfer under way), abort."""
    command, index, subindex = _SDO.unpack(data[:4])
    payload = bytes(data[4:8])
    ccs = command >> 5
    if ccs == 4:
        code = struct.unpack("<I", payload)[0]
        return {"service": "abort", "index": index, "subindex": subindex, "code": code,
                "reason": SDO_ABORTS.get(code, "unknown abort code")}
    request = kind == "SDO_REQUEST"
    segment = {0: "download_segment", 3: "upload_segment"} if request else {0: "upload_segment",
                                                                           1: "download_segment"}
    if ccs in segment:
        fields = {"service": segment[ccs], "index": None, "subindex": None, "toggle": command >> 4 & 1}
        if ccs == 0:  # a segment that carries data (download request, upload response)
            fields["data"] = bytes(data[1:8 - (command >> 1 & 0x7)])
            fields["last"] = bool(command & 1)
        return fields
    services = {1: "download", 2: "upload"} if request else {3: "download", 2: "upload"}
    service = services.get(ccs)
    if service is None:
        raise MalformedFrame(f"{kind} with command 0x{command:02X}: a block transfer or no SDO command "
                             "(expedited and segmented transfers and aborts are spoken here)")
    fields = {"service": service, "index": index, "subindex": subindex}
    expedited, sized = command & 0x2, command & 0x1
    if (request and service == "download") or (not request and service == "upload"):
        if expedited:
            fields["data"] = payload[:4 - ((command >> 2) & 0x3)] if sized else payload
        else:  # segmented: the size (if indicated), the data follows in segments
            fields["segmented"] = True
            fields["size"] = struct.unpack("<I", payload)[0] if sized else None
    return fields


# The error register's bits (CiA 301 0x1001, the second byte of an EMCY), bit 0 first; bit 6 is reserved.
ERROR_REGISTER_BITS = ("generic", "current", "voltage", "temperature", "communication", "device profile",
                       "reserved", "manufacturer specific")


def error_register_names(register: int) -> list[str]:
    """The names of the bits set in an error register (CiA 301 0x1001), bit 0 first."""
    return [name for bit, name in enumerate(ERROR_REGISTER_BITS) if register >> bit & 1]


def emcy_name(code: int) -> str:
    """An EMCY error code by name: its own (CiA 301, CiA 402) where EMCY_CODES has it, else its class's."""
    if code in EMCY_CODES:
        return EMCY_CODES[code]
    described = EmcyError(code, 0, b"", 0.0).get_desc()
    return f"{described.lower()} (0x{code:04X})" if described else f"0x{code:04X}"


def state_of(statusword: int) -> str:
    """The CiA 402 state a statusword reports (canopen's State402.SW_MASK)."""
    for name in STATES:
        mask, value = State402.SW_MASK[name]
        if statusword & mask == value:
            return name
    return "NOT READY TO SWITCH ON"


def command_of(controlword: int) -> str:
    """The device control command of a controlword (fault reset: bit 7, acted on at its rising edge)."""
    if controlword & 0x80:
        return "FAULT RESET"
    if controlword & 0x02 == 0:
        return "DISABLE VOLTAGE"
    if controlword & 0x06 == 0x02:
        return "QUICK STOP"
    if controlword & 0x0F == 0x06 or controlword & 0x07 == 0x06:
        return "SHUTDOWN"
    if controlword & 0x0F == 0x07:
        return "SWITCH ON"
    return "ENABLE OPERATION"


def describe(message: Message, od: ObjectDictionary | None = None, maps: dict[int, PdoMap] | None = None) -> str:
    """A message in words; a PDO by its mapping (`maps`: COB-ID -> PdoMap, with the `od` that
    types it), otherwise as its bytes."""
    f, node = message.fields, message.node_id
    kind = message.kind
    if kind == "NMT":
        return f"NMT {f['command']} node={f['target'] or 'all'}"
    if kind == "SYNC":
        return "SYNC" + (f" counter={f['counter']}" if "counter" in f else "")
    if kind == "HEARTBEAT":
        return f"Heartbeat node={node} {f['state']}"
    if kind == "EMCY":
        return f"EMCY node={node} 0x{f['code']:04X} {f['name']} register=0x{f['register']:02X}"
    if kind in ("SDO_REQUEST", "SDO_RESPONSE") and f["index"] is None:
        side = "SDO" if kind == "SDO_REQUEST" else "SDO response"
        what = f" {len(f['data'])} bytes {f['data'].hex(' ').upper()}" if "data" in f else ""
        return f"{side} {f['service'].replace('_', ' ')} node={node} toggle={f['toggle']}{what}" + (
            " last" if f.get("last") else "")
    if kind in ("SDO_REQUEST", "SDO_RESPONSE"):
        where = f"0x{f['index']:04X}.{f['subindex']:02X}"
        name = _object_name(od, f["index"], f["subindex"])
        side = "SDO" if kind == "SDO_REQUEST" else "SDO response"
        if f["service"] == "abort":
            return f"{side} abort node={node} {where}{name} 0x{f['code']:08X} {f['reason']}"
        value = ""
        if f.get("segmented"):
            value = f" (segmented, {f['size']} bytes)" if f.get("size") is not None else " (segmented)"
        if "data" in f:
            value = " = " + _value_text(od, f["index"], f["subindex"], f["data"])
        return f"{side} {f['service']} node={node} {where}{name}{value}"
    if kind == "TIME":
        return "TIME"
    mapping = (maps or {}).get(message.frame.id)
    if od is not None and mapping is not None:
        try:
            values = unpack_pdo(od, mapping, message.fields["data"])
        except (FrameError, ValueError, KeyError) as exc:
            return f"{kind} node={node} malformed: {exc}"
        return f"{kind} node={node} " + " ".join(_pdo_value(od, index, value) for index, value in values.items())
    return f"{kind} node={node} " + message.fields["data"].hex(" ").upper()


def _object_name(od: ObjectDictionary | None, index: int, subindex: int) -> str:
    if od is None:
        return ""
    try:
        return " " + variable(od, index, subindex).name
    except KeyError:
        return ""


def _value_text(od: ObjectDictionary | None, index: int, subindex: int, data: bytes) -> str:
    if od is not None:
        try:
            value = decode_value(od, index, subindex, data)
            cob_or_map = (0x1600 <= index < 0x1800 or 0x1A00 <= index < 0x1C00) and subindex or \
                ((0x1400 <= index < 0x1600 or 0x1800 <= index < 0x1A00) and subindex == 1)
            return f"0x{value:08X}" if cob_or_map else str(value)
        except (KeyError, ValueError, struct.error, Exception):  # an odd length: show the bytes
            pass
    return bytes(data).hex(" ").upper()


def _pdo_value(od: ObjectDictionary, index: int, value: Any) -> str:
    name = _object_name(od, index, 0).strip().replace(" ", "_")
    if index == 0x6041:
        return f"{name}=0x{value:04X}({state_of(value)})"
    if index == 0x6040:
        return f"{name}=0x{value:04X}({command_of(value)})"
    if index in (0x6060, 0x6061):
        return f"{name}={MODE_NAMES.get(value, value)}"
    return f"{name}={value}"


class PdoTracker:
    """The PDO mappings of a bus as its frames show them: the EDS's defaults for the given nodes,
    changed by every SDO download to a PDO's mapping or communication parameters (0x1400-0x1BFF),
    as a master configures its drives. `describe(frame)` names what each frame carries."""

    def __init__(self, nodes: Iterable[int] = (), eds: str | Path = DRIVE_EDS):
        self.eds = eds
        self.nodes = set(nodes)
        self.maps: dict[int, PdoMap] = {}    # COB-ID -> mapping
        self.words: dict[tuple[int, int], dict[int, int]] = {}  # (node, mapping index) -> sub -> word
        self.cobs: dict[tuple[int, int], int] = {}  # (node, communication index) -> COB-ID
        for node in self.nodes:
            self._defaults(node)

    def _defaults(self, node: int) -> None:
        od = object_dictionary(self.eds, node)
        for comm in (0x1400, 0x1401, 0x1402, 0x1403, 0x1800, 0x1801, 0x1802, 0x1803):
            if comm in od:
                cob = od[comm][1].default & 0x7FF
                self.cobs[(node, comm)] = cob
                self.maps[cob] = pdo_map(od, comm + 0x200)

    def od(self, node: int) -> ObjectDictionary:
        return object_dictionary(self.eds, node)

    def feed(self, message: Message) -> None:
        f = message.fields
        if message.kind != "SDO_REQUEST" or f.get("service") != "download" or "data" not in f \
                or message.node_id not in self.nodes:
            return
        node, index, sub = message.node_id, f["index"], f["subindex"]
        value = int.from_bytes(f["data"], "little")
        if 0x1400 <= index < 0x1600 or 0x1800 <= index < 0x1A00:
            if sub == 1:
                self.cobs[(node, index)] = value & 0x7FF
                self._rebuild(node, index)
        elif 0x1600 <= index < 0x1800 or 0x1A00 <= index < 0x1C00:
            entry = self.words.setdefault((node, index), {0: 0})
            entry[sub] = value
            self._rebuild(node, index - 0x200)

    def _rebuild(self, node: int, comm: int) -> None:
        cob = self.cobs.get((node, comm))
        words = self.words.get((node, comm + 0x200))
        if cob is None or words is None:
            return
        count = words.get(0, 0)
        self.maps[cob] = PdoMap.from_words(words.get(k, 0) for k in range(1, count + 1))

    def claims(self, frame: Frame) -> bool:
        """Whether a frame is CANopen on this bus (`claims` of the tracker's nodes)."""
        return claims(frame, self.nodes)

    def describe(self, frame: Frame) -> str:
        """The frame in words (`decode` and `describe`); raises FrameError if it is not CANopen."""
        message = decode(frame)
        self.feed(message)
        node = message.node_id or (message.fields.get("target") if message.kind == "NMT" else 0)
        od = self.od(node) if node in self.nodes else (self.od(next(iter(self.nodes))) if self.nodes else None)
        return describe(message, od, self.maps)
