"""ODrive CAN Simple (firmware 0.6.10): encode and decode every message, byte for byte as its DBC.

The message table below is ODrive's `odrive-cansimple-0.6.10.dbc` written out as code, so that
nodes need no DBC parser at run time (tests/can compares every message with cantools on the DBC).
Names are the DBC's without the "AxisN_" prefix; signals are the DBC's, in physical units
(positions in turns, velocities in turns/s, torques in Nm; Vel_FF and Torque_FF are int16 x 0.001).

Frame id = node_id << 5 | cmd_id, 11-bit standard ids, little-endian signals. Every frame is sent
with the DLC the DBC gives, zero-padded: a real ODrive reads what it needs, strict decoders
(cantools, odrive-can's mock) reject a short Set_Axis_State.

Direction: one id means different things by sender. A remote (RTR) frame from the host asks an
axis for a message (`request(3, "Get_Encoder_Estimates")`); the axis answers with the same id and
data. `decode` of an RTR frame gives a `Message` with `rtr=True` and no signals.

Axis errors (Heartbeat.Axis_Error, Get_Error.Active_Errors/Disarm_Reason) are the 0.6 firmware's
`ODrive.Error` flags, as the DBC lists them: WATCHDOG_TIMER_EXPIRED is 0x01000000. (0x800 was
AXIS_ERROR_WATCHDOG_TIMER_EXPIRED in firmware 0.5; in 0.6 0x800 is DC_BUS_OVER_REGEN_CURRENT.)
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field

from .frame import Frame, FrameError

NODE_ID_MAX = 0x3F  # 6 bits of the 11-bit id
CMD_ID_BITS = 5


class UnknownFrame(FrameError):
    """A frame that is not an ODrive CAN Simple message (unknown command id)."""


class MalformedFrame(FrameError):
    """A frame with an ODrive command id whose shape is wrong (DLC, extended id)."""


class EncodeError(FrameError):
    """Signals that cannot be encoded: unknown name, value out of the signal's range."""


@dataclass(frozen=True)
class Signal:
    name: str
    start: int          # bit position of the least significant bit (little-endian, DBC "@1")
    length: int         # bits
    kind: str           # "u" unsigned int, "i" signed int, "f" IEEE float32
    scale: float = 1
    unit: str = ""

    def to_raw(self, value) -> int:
        """The raw bits of a physical value; EncodeError if it does not fit the signal."""
        if isinstance(value, bool):
            value = int(value)
        if not isinstance(value, (int, float)):
            raise EncodeError(f"signal {self.name} needs a number, got {type(value).__name__} {value!r}")
        if self.kind == "f":
            try:
                return struct.unpack("<I", struct.pack("<f", value))[0]
            except OverflowError:
                raise EncodeError(f"signal {self.name}={value!r} does not fit a float32") from None
        if isinstance(value, float) and not math.isfinite(value):
            raise EncodeError(f"signal {self.name}={value!r} is not a finite number")
        raw = value if self.scale == 1 and isinstance(value, int) else round(value / self.scale)
        low, high = ((-(1 << (self.length - 1)), (1 << (self.length - 1)) - 1) if self.kind == "i"
                     else (0, (1 << self.length) - 1))
        if not low <= raw <= high:
            raise EncodeError(f"signal {self.name}={value!r} is out of range: raw {raw} not in {low}..{high}"
                              f" ({self.length}-bit {'signed' if self.kind == 'i' else 'unsigned'}"
                              f"{f', scale {self.scale}' if self.scale != 1 else ''})")
        return raw & ((1 << self.length) - 1)

    def from_raw(self, raw: int) -> int | float:
        if self.kind == "f":
            return struct.unpack("<f", struct.pack("<I", raw))[0]
        if self.kind == "i" and raw >> (self.length - 1):
            raw -= 1 << self.length
        return raw if self.scale == 1 else raw * self.scale


@dataclass(frozen=True)
class MessageSpec:
    cmd_id: int
    name: str
    dlc: int
    sender: str                       # "axis", "host" or "both" (the DBC's ODrive_AxisN, Master)
    signals: tuple[Signal, ...] = ()
    cycle_time: float | None = None   # seconds, for the axis's cyclic messages

    @property
    def signal_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.signals)


def _u(name, start, length, unit=""):
    return Signal(name, start, length, "u", unit=unit)


def _f(name, start, unit=""):
    return Signal(name, start, 32, "f", unit=unit)


MESSAGES: dict[str, MessageSpec] = {m.name: m for m in (
    MessageSpec(0x00, "Get_Version", 8, "axis", (
        _u("Protocol_Version", 0, 8), _u("Hw_Version_Major", 8, 8), _u("Hw_Version_Minor", 16, 8),
        _u("Hw_Version_Variant", 24, 8), _u("Fw_Version_Major", 32, 8), _u("Fw_Version_Minor", 40, 8),
        _u("Fw_Version_Revision", 48, 8), _u("Fw_Version_Unreleased", 56, 8)), cycle_time=0.1),
    MessageSpec(0x01, "Heartbeat", 8, "axis", (
        _u("Axis_Error", 0, 32), _u("Axis_State", 32, 8), _u("Procedure_Result", 40, 8),
        _u("Trajectory_Done_Flag", 48, 1)), cycle_time=0.1),
    MessageSpec(0x02, "Estop", 0, "host"),
    MessageSpec(0x03, "Get_Error", 8, "axis", (_u("Active_Errors", 0, 32), _u("Disarm_Reason", 32, 32))),
    MessageSpec(0x04, "RxSdo", 8, "host", (
        _u("Opcode", 0, 8), _u("Endpoint_ID", 8, 16), _u("Reserved", 24, 8), _u("Value", 32, 32))),
    MessageSpec(0x05, "TxSdo", 8, "axis", (
        _u("Reserved0", 0, 8), _u("Endpoint_ID", 8, 16), _u("Reserved1", 24, 8), _u("Value", 32, 32))),
    MessageSpec(0x06, "Address", 8, "both", (_u("Node_ID", 0, 8), _u("Serial_Number", 8, 48))),
    MessageSpec(0x07, "Set_Axis_State", 8, "host", (_u("Axis_Requested_State", 0, 32),)),
    MessageSpec(0x09, "Get_Encoder_Estimates", 8, "axis", (
        _f("Pos_Estimate", 0, "rev"), _f("Vel_Estimate", 32, "rev/s")), cycle_time=0.01),
    MessageSpec(0x0B, "Set_Controller_Mode", 8, "host", (_u("Control_Mode", 0, 32), _u("Input_Mode", 32, 32))),
    MessageSpec(0x0C, "Set_Input_Pos", 8, "host", (
        _f("Input_Pos", 0, "rev"), Signal("Vel_FF", 32, 16, "i", 0.001, "rev/s"),
        Signal("Torque_FF", 48, 16, "i", 0.001, "Nm"))),
    MessageSpec(0x0D, "Set_Input_Vel", 8, "host", (_f("Input_Vel", 0, "rev/s"), _f("Input_Torque_FF", 32, "Nm"))),
    MessageSpec(0x0E, "Set_Input_Torque", 8, "host", (_f("Input_Torque", 0, "Nm"),)),
    MessageSpec(0x0F, "Set_Limits", 8, "host", (_f("Velocity_Limit", 0, "rev/s"), _f("Current_Limit", 32, "A"))),
    MessageSpec(0x11, "Set_Traj_Vel_Limit", 8, "host", (_f("Traj_Vel_Limit", 0, "rev/s"),)),
    MessageSpec(0x12, "Set_Traj_Accel_Limits", 8, "host", (
        _f("Traj_Accel_Limit", 0, "rev/s^2"), _f("Traj_Decel_Limit", 32, "rev/s^2"))),
    MessageSpec(0x13, "Set_Traj_Inertia", 8, "host", (_f("Traj_Inertia", 0, "Nm/(rev/s^2)"),)),
    MessageSpec(0x14, "Get_Iq", 8, "axis", (_f("Iq_Setpoint", 0, "A"), _f("Iq_Measured", 32, "A"))),
    MessageSpec(0x15, "Get_Temperature", 8, "axis", (
        _f("FET_Temperature", 0, "deg C"), _f("Motor_Temperature", 32, "deg C"))),
    MessageSpec(0x16, "Reboot", 1, "host", (_u("Action", 0, 8),)),
    MessageSpec(0x17, "Get_Bus_Voltage_Current", 8, "axis", (_f("Bus_Voltage", 0, "V"), _f("Bus_Current", 32, "A"))),
    MessageSpec(0x18, "Clear_Errors", 1, "host", (_u("Identify", 0, 8),)),
    MessageSpec(0x19, "Set_Absolute_Position", 8, "host", (_f("Position", 0, "rev"),)),
    MessageSpec(0x1A, "Set_Pos_Gain", 8, "host", (_f("Pos_Gain", 0, "(rev/s)/rev"),)),
    MessageSpec(0x1B, "Set_Vel_Gains", 8, "host", (_f("Vel_Gain", 0, "Nm/(rev/s)"), _f("Vel_Integrator_Gain", 32, "Nm/rev"))),
    MessageSpec(0x1C, "Get_Torques", 8, "axis", (_f("Torque_Target", 0, "Nm"), _f("Torque_Estimate", 32, "Nm"))),
    MessageSpec(0x1D, "Get_Powers", 8, "axis", (_f("Electrical_Power", 0, "W"), _f("Mechanical_Power", 32, "W"))),
    MessageSpec(0x1F, "Enter_DFU_Mode", 0, "host"),
)}

COMMANDS: dict[str, int] = {name: spec.cmd_id for name, spec in MESSAGES.items()}
_BY_CMD: dict[int, MessageSpec] = {spec.cmd_id: spec for spec in MESSAGES.values()}

# Value tables of the DBC (VAL_), for the signals that carry enums and flags.
AXIS_STATE = {"UNDEFINED": 0, "IDLE": 1, "STARTUP_SEQUENCE": 2, "FULL_CALIBRATION_SEQUENCE": 3,
              "MOTOR_CALIBRATION": 4, "SENSORLESS_CONTROL": 5, "ENCODER_INDEX_SEARCH": 6,
              "ENCODER_OFFSET_CALIBRATION": 7, "CLOSED_LOOP_CONTROL": 8, "LOCKIN_SPIN": 9,
              "ENCODER_DIR_FIND": 10, "HOMING": 11, "ENCODER_HALL_POLARITY_CALIBRATION": 12,
              "ENCODER_HALL_PHASE_CALIBRATION": 13, "ANTICOGGING_CALIBRATION": 14}
# The DBC names them VOLTAGE_CONTROL..POSITION_CONTROL; the short names are the team's interface.
CONTROL_MODE = {"VOLTAGE": 0, "TORQUE": 1, "VELOCITY": 2, "POSITION": 3}
INPUT_MODE = {"INACTIVE": 0, "PASSTHROUGH": 1, "VEL_RAMP": 2, "POS_FILTER": 3, "MIX_CHANNELS": 4,
              "TRAP_TRAJ": 5, "TORQUE_RAMP": 6, "MIRROR": 7, "TUNING": 8}
PROCEDURE_RESULT = {"SUCCESS": 0, "BUSY": 1, "CANCELLED": 2, "DISARMED": 3, "NO_RESPONSE": 4,
                    "POLE_PAIR_CPR_MISMATCH": 5, "PHASE_RESISTANCE_OUT_OF_RANGE": 6,
                    "PHASE_INDUCTANCE_OUT_OF_RANGE": 7, "UNBALANCED_PHASES": 8, "INVALID_MOTOR_TYPE": 9,
                    "ILLEGAL_HALL_STATE": 10, "TIMEOUT": 11, "HOMING_WITHOUT_ENDSTOP": 12,
                    "INVALID_STATE": 13, "NOT_CALIBRATED": 14, "NOT_CONVERGING": 15}
# ODrive.Error flags of firmware 0.6 (bit values; an axis error is their OR).
AXIS_ERROR = {"NONE": 0, "INITIALIZING": 0x1, "SYSTEM_LEVEL": 0x2, "TIMING_ERROR": 0x4,
              "MISSING_ESTIMATE": 0x8, "BAD_CONFIG": 0x10, "DRV_FAULT": 0x20, "MISSING_INPUT": 0x40,
              "DC_BUS_OVER_VOLTAGE": 0x100, "DC_BUS_UNDER_VOLTAGE": 0x200, "DC_BUS_OVER_CURRENT": 0x400,
              "DC_BUS_OVER_REGEN_CURRENT": 0x800, "CURRENT_LIMIT_VIOLATION": 0x1000,
              "MOTOR_OVER_TEMP": 0x2000, "INVERTER_OVER_TEMP": 0x4000, "VELOCITY_LIMIT_VIOLATION": 0x8000,
              "POSITION_LIMIT_VIOLATION": 0x10000, "WATCHDOG_TIMER_EXPIRED": 0x1000000,
              "ESTOP_REQUESTED": 0x2000000, "SPINOUT_DETECTED": 0x4000000,
              "BRAKE_RESISTOR_DISARMED": 0x8000000, "THERMISTOR_DISCONNECTED": 0x10000000,
              "CALIBRATION_ERROR": 0x40000000}
REBOOT_ACTION = {"reboot": 0, "save_configuration": 1, "erase_configuration": 2, "enter_dfu_mode": 3}


def error_names(flags: int) -> list[str]:
    """The names of the ODrive.Error flags set in `flags` (unknown bits as hex)."""
    names = [name for name, bit in AXIS_ERROR.items() if bit and flags & bit]
    rest = flags & ~sum(AXIS_ERROR.values())
    return names + ([f"0x{rest:X}"] if rest else [])


@dataclass
class Message:
    node_id: int
    name: str
    signals: dict[str, float | int] = field(default_factory=dict)
    rtr: bool = False

    @property
    def cmd_id(self) -> int:
        return COMMANDS[self.name]


def frame_id(node_id: int, name_or_cmd: str | int) -> int:
    """The 11-bit id of a command for an axis: node_id << 5 | cmd_id."""
    cmd = _spec(name_or_cmd).cmd_id if isinstance(name_or_cmd, str) else name_or_cmd
    if isinstance(node_id, bool) or not isinstance(node_id, int) or not 0 <= node_id <= NODE_ID_MAX:
        raise EncodeError(f"ODrive node id must be 0..{NODE_ID_MAX}, got {node_id!r}")
    return node_id << CMD_ID_BITS | cmd


def node_id_of(frame_id: int) -> int:
    return frame_id >> CMD_ID_BITS


def cmd_id_of(frame_id: int) -> int:
    return frame_id & ((1 << CMD_ID_BITS) - 1)


def _spec(name: str) -> MessageSpec:
    try:
        return MESSAGES[name]
    except KeyError:
        raise EncodeError(f"no ODrive CAN Simple message {name!r}; known: {', '.join(MESSAGES)}") from None


def encode(node_id: int, name: str, **signals) -> Frame:
    """The data frame of message `name` for axis `node_id`; signals by DBC name in physical units,
    missing ones 0. `encode(3, "Set_Input_Pos", Input_Pos=1.5, Vel_FF=0.2, Torque_FF=0.0)`."""
    fast = _PACKERS.get(name)
    if fast is not None:  # whole-byte signals: one struct.pack (a motor node sends thousands a second)
        pack, cmd_id, known, layout = fast
        if signals.keys() <= known and node_id.__class__ is int and 0 <= node_id <= NODE_ID_MAX:
            try:
                raw = [value if kind == "f" or scale == 1 and value.__class__ is int else round(value / scale)
                       for value, kind, scale in ((signals.get(n, 0), kind, scale) for n, kind, scale in layout)]
                return Frame(node_id << CMD_ID_BITS | cmd_id, pack(*raw))
            except (struct.error, TypeError, ValueError, OverflowError):
                pass  # out of range, not a number, NaN: the signal by signal way says what, in its words
    return encode_by_signals(node_id, name, **signals)


def encode_by_signals(node_id: int, name: str, **signals) -> Frame:
    """`encode`, signal by signal (`Signal.to_raw`): for every message, and what says why a value
    cannot be sent."""
    spec = _spec(name)
    unknown = set(signals) - set(spec.signal_names)
    if unknown:
        raise EncodeError(f"{name} has no signal(s) {sorted(unknown)}; its signals: {list(spec.signal_names) or 'none'}")
    bits = 0
    for signal in spec.signals:
        bits |= signal.to_raw(signals.get(signal.name, 0)) << signal.start
    return Frame(frame_id(node_id, spec.cmd_id), bits.to_bytes(8, "little")[:spec.dlc])


def request(node_id: int, name: str) -> Frame:
    """The remote (RTR) frame that asks axis `node_id` for message `name` (e.g. a Get_Error poll).
    DLC 0, as ODrive's own examples send it; the firmware answers any DLC."""
    return Frame.remote(frame_id(node_id, _spec(name).cmd_id))


def spec_of(frame: Frame) -> MessageSpec | None:
    """The message spec of a frame's command id, or None (no checks on its shape)."""
    return None if frame.extended else _BY_CMD.get(cmd_id_of(frame.id))


def decode(frame: Frame, as_axis: bool = False) -> Message:
    """The ODrive message a frame carries. UnknownFrame for a command id CAN Simple does not have,
    MalformedFrame for an extended id or a DLC other than the DBC's (remote frames: any DLC).

    `as_axis`: read it as the firmware's CAN handler does (the simulated axes do): a data frame
    with no data for a message the axis sends is a request, as a remote frame is ("a message with
    RTR=0 and an empty payload can also be used"), and a command whose DLC is not the DBC's is
    read from the bytes it has, the missing ones 0 (the firmware reads its signals unchecked)."""
    if not isinstance(frame, Frame):
        raise MalformedFrame(f"expected a Frame, got {type(frame).__name__} {frame!r}")
    if frame.extended:
        raise MalformedFrame(f"frame 0x{frame.id:08X} has an extended (29-bit) id; ODrive CAN Simple uses 11-bit ids")
    node, cmd = node_id_of(frame.id), cmd_id_of(frame.id)
    spec = _BY_CMD.get(cmd)
    if spec is None:
        raise UnknownFrame(f"frame 0x{frame.id:03X} (node {node}, cmd 0x{cmd:02X}): no ODrive CAN Simple "
                           f"command has id 0x{cmd:02X}")
    if frame.rtr or as_axis and frame.dlc == 0 and spec.sender in ("axis", "both"):
        return Message(node, spec.name, {}, rtr=True)
    if as_axis and frame.dlc != spec.dlc:
        frame = Frame(frame.id, (frame.data + bytes(8))[:spec.dlc])
    if frame.dlc != spec.dlc:
        raise MalformedFrame(f"{spec.name} frame 0x{frame.id:03X} (node {node}) has DLC {frame.dlc}, "
                             f"the protocol gives {spec.dlc}: {frame.data.hex(' ') or 'no data'}")
    fast = _UNPACKERS.get(spec.cmd_id)
    if fast is not None:  # byte-aligned signals: one struct.unpack, the same values as from_raw's
        unpack, names, scales = fast
        raw = unpack(frame.data)
        values = dict(zip(names, raw)) if scales is None else \
            {n: (r if k == 1 else r * k) for n, r, k in zip(names, raw, scales)}
        return Message(node, spec.name, values)
    bits = int.from_bytes(frame.data, "little")
    values = {s.name: s.from_raw((bits >> s.start) & ((1 << s.length) - 1)) for s in spec.signals}
    return Message(node, spec.name, values)


def _unpacker(spec: MessageSpec):
    """(unpack, names, scales or None) of a message whose signals are whole bytes, little-endian,
    8, 16 or 32 bits, in order and apart; None for any other (bit fields, 48-bit numbers)."""
    codes = {("u", 8): "B", ("u", 16): "H", ("u", 32): "I", ("i", 8): "b", ("i", 16): "h", ("i", 32): "i",
             ("f", 32): "f"}
    layout, at = "<", 0
    for signal in spec.signals:
        code = codes.get((signal.kind, signal.length))
        if code is None or signal.start % 8 or signal.start < at or (signal.kind == "f" and signal.scale != 1):
            return None
        layout += "x" * ((signal.start - at) // 8) + code
        at = signal.start + signal.length
    if not spec.signals or at > 8 * spec.dlc:
        return None
    layout += "x" * ((8 * spec.dlc - at) // 8)
    scales = tuple(signal.scale for signal in spec.signals)
    return (struct.Struct(layout).unpack, tuple(s.name for s in spec.signals),
            None if all(k == 1 for k in scales) else scales)


_UNPACKERS = {spec.cmd_id: found for spec in MESSAGES.values() if (found := _unpacker(spec)) is not None}


def _packer(spec: MessageSpec):
    """(pack, cmd_id, signal names, (name, kind, scale) per signal) of a message `_unpacker` reads
    with one struct (whole-byte signals), for `encode`; None for any other."""
    if spec.cmd_id not in _UNPACKERS:
        return None
    layout = _UNPACKERS[spec.cmd_id][0].__self__  # the struct that reads the message writes it
    return (layout.pack, spec.cmd_id, frozenset(spec.signal_names),
            tuple((signal.name, signal.kind, signal.scale) for signal in spec.signals))


_PACKERS = {spec.name: found for spec in MESSAGES.values() if (found := _packer(spec)) is not None}


def describe(message: Message) -> str:
    """One short line: `Heartbeat node=3 Axis_Error=0 Axis_State=CLOSED_LOOP_CONTROL ...`."""
    if message.rtr:
        return f"{message.name} node={message.node_id} request"
    parts = [f"{message.name} node={message.node_id}"]
    for name, value in message.signals.items():
        parts.append(f"{name}={_show(name, value)}")
    return " ".join(parts)


_NAMED = {"Axis_State": AXIS_STATE, "Axis_Requested_State": AXIS_STATE, "Procedure_Result": PROCEDURE_RESULT,
          "Input_Mode": INPUT_MODE, "Control_Mode": CONTROL_MODE, "Action": REBOOT_ACTION}
_FLAGS = {"Axis_Error", "Active_Errors", "Disarm_Reason"}


def undefined_values(signals: dict) -> list[str]:
    """The signals of a decoded message whose value names no member of their enumeration (an
    Axis_State of 99): `name=value` each. A controller never sends one; a forged or corrupted
    frame may."""
    return [f"{name}={value}" for name, value in signals.items()
            if name in _NAMED and value not in _NAMED[name].values()]


def _show(name: str, value: float | int) -> str:
    if name in _FLAGS:
        return "|".join(error_names(int(value))) if value else "0"
    if name in _NAMED:
        for label, number in _NAMED[name].items():
            if number == value:
                return label
        return str(value)
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)
