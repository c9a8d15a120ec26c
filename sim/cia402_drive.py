"""One simulated CANopen CiA 402 servo drive, as plain Python: no PyBullet, no IOTA.

The drive speaks CANopen from the device's side, against its EDS (iotad/can/data/cia402_drive.eds,
read by the `canopen` package): `handle(frame, now)` takes every frame of the bus, `update(...)`
runs one control step (position in turns and velocity in turns/s in, motor torque in Nm out, or
None while the power stage is off), and the frames it sends wait in `outbox`.

What it does (docs/simulation.md has the table):
- NMT: boot-up message, PRE-OPERATIONAL, OPERATIONAL, STOPPED; reset node and reset
  communication. SDO (expedited only) in PRE-OPERATIONAL and OPERATIONAL; PDOs in OPERATIONAL.
- SDO server over the object dictionary: reads, writes, aborts with the CiA 301 codes (no such
  object, read-only, wrong length, value range, mapping rules). PDO mappings can be rewritten
  while the PDO is invalid (COB-ID bit 31) and its count is 0, as CiA 301 asks.
- RPDO1 with its transmission type: 0-240 latched until the next SYNC, 254/255 at once. One of
  the wrong length is not processed (EMCY 0x8210). TPDO1 and TPDO2 at every n-th SYNC (type n).
- The CiA 402 state machine, transitions 0-16 of the standard's diagram, driven by the
  controlword; `transitions` lists the numbers taken. Quick stop (option code 0x605A: 2 ends in
  SWITCH ON DISABLED, 6 stays in QUICK STOP ACTIVE and allows transition 16) and the fault
  reaction brake on the quick stop deceleration (0x6085), then the power stage goes off.
- Modes: Profile Position (1, a trapezoidal move at each new set-point, bit 4's rising edge),
  Cyclic Synchronous Position (8) and Cyclic Synchronous Velocity (9), the target taken at SYNC.
- Heartbeat producer (0x1017) and consumer (0x1016): once the master's heartbeat was heard, its
  absence for the consumer time is EMCY 0x8130 and a fault: the fault reaction within the
  consumer time plus one control step, and the error behaviour of 0x1029.1 (CiA 301): by default
  an OPERATIONAL drive enters PRE-OPERATIONAL (no PDOs until an NMT START), 1 keeps its NMT
  state, 2 enters STOPPED. Every fault sends its EMCY.

The control loops are those of the simulated ODrive axis (sim/odrive_axis.py): position P,
velocity PI, torque, with its trapezoidal planner for Profile Position and the stopping ramps.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any

from canopen.objectdictionary import ODVariable

from iotad.can import canopen as co
from iotad.can.frame import Frame, FrameError
from iotad.can.odrive import CONTROL_MODE, INPUT_MODE

from .odrive_axis import IDLE, AxisConfig, OdriveAxis

POSITION, VELOCITY = CONTROL_MODE["POSITION"], CONTROL_MODE["VELOCITY"]
PASSTHROUGH, TRAP_TRAJ = INPUT_MODE["PASSTHROUGH"], INPUT_MODE["TRAP_TRAJ"]
PP, CSP, CSV = co.MODES["PP"], co.MODES["CSP"], co.MODES["CSV"]
NRTSO, SOD, RTSO, SO, OE, QSA, FRA, FAULT = co.STATES
POWERED = (SO, OE, QSA, FRA)
HEARTBEAT_ERROR, PDO_LENGTH_ERROR = 0x8130, 0x8210

ABORT_NO_OBJECT, ABORT_NO_SUBINDEX, ABORT_READ_ONLY = 0x06020000, 0x06090011, 0x06010002
ABORT_WRITE_ONLY, ABORT_LENGTH, ABORT_RANGE = 0x06010001, 0x06070010, 0x06090030
ABORT_ACCESS, ABORT_NOT_MAPPABLE, ABORT_PDO_LENGTH = 0x06010000, 0x06040041, 0x06040042
ABORT_COMMAND, ABORT_STATE = 0x05040001, 0x08000022


class Cia402Drive:
    """One drive at `node_id` (1..127); `servo` is its axis config (gains, limits, inertia) in turns."""

    def __init__(self, node_id: int, servo: AxisConfig | None = None, eds: Any = co.DRIVE_EDS):
        self.node_id = co._node(node_id)
        self.od = co.object_dictionary(eds, node_id)
        self.counts = co.default(self.od, 0x608F, 1) / co.default(self.od, 0x608F, 2)  # increments per turn
        # the drive's own watchdog is the heartbeat consumer: the servo's is off
        self.servo_config = dataclasses.replace(servo or AxisConfig(), watchdog_timeout=0.0)
        self.ignored: list[str] = []
        self.outbox: list[Frame] = []
        self.transitions: list[int] = []
        self.power_up()

    # ------------------------------------------------------------------ power-up and NMT
    def power_up(self) -> None:
        """Power-on (and NMT reset node): the object dictionary at its defaults, boot-up, PRE-OPERATIONAL."""
        self.servo = OdriveAxis(0, self.servo_config)
        self.values: dict[tuple[int, int], Any] = {}
        for obj in self.od.values():
            for var in ([obj] if isinstance(obj, ODVariable) else obj.values()):
                self.values[(var.index, var.subindex)] = var.default
        # the simulated hardware's limits are the drive's: max velocity and torque as its servo has them
        cfg = self.servo_config
        self.values[(0x607F, 0)] = round(cfg.vel_limit * self.counts)
        rated = self.values[(0x6076, 0)] / 1000.0  # Nm
        self.values[(0x6072, 0)] = min(0xFFFF, round(1000.0 * cfg.current_limit * cfg.torque_constant / rated))
        self.state = NRTSO
        self.transitions = [0]
        self._enter(SOD, 1)  # the drive's self-test passed
        self.controlword = 0
        self.latched: dict[int, Any] | None = None
        self.syncs = 0
        self.position = self.velocity = 0.0   # turns, turns/s (from update)
        self.now = 0.0
        self.master_heard: float | None = None
        self.last_heartbeat = -math.inf
        self.ramp = False
        self.new_setpoint = False
        self.transfer: dict | None = None  # the segmented SDO transfer under way
        self.aborts: list[int] = []         # abort codes of the transfers this server ended
        self._boot()

    def _boot(self) -> None:
        self.outbox.append(co.heartbeat(self.node_id, 0))  # the boot-up message
        self.nmt = "PRE_OPERATIONAL"

    def _reset_communication(self) -> None:
        for (index, sub) in list(self.values):
            if 0x1000 <= index < 0x2000:
                self.values[(index, sub)] = co.default(self.od, index, sub)
        self.master_heard = None
        self._boot()

    # ------------------------------------------------------------------ frames in
    def handle(self, frame: Frame, now: float) -> None:
        """Act on one frame of the bus (any frame: those for other nodes are passed over)."""
        self.now = now
        try:
            message = co.decode(frame)
        except FrameError as exc:
            return self._ignore(str(exc))
        kind, node = message.kind, message.node_id
        if kind == "NMT":
            if message.fields["target"] in (0, self.node_id):
                self._nmt(message.fields["command"])
        elif kind == "SYNC":
            self._sync()
        elif kind == "HEARTBEAT":
            if node == self._consumer()[0]:
                self.master_heard = now
        elif kind == "SDO_REQUEST" and node == self.node_id:
            if message.fields["service"] == "abort":
                self.transfer = None  # a client's abort ends its transfer, and needs no answer
            elif self.nmt in ("PRE_OPERATIONAL", "OPERATIONAL"):
                self.outbox.append(self._sdo(message.fields))
        elif frame.id == self._cob(0x1400) and self.nmt == "OPERATIONAL":
            self._rpdo(frame)
        # everything else (other nodes' services, TPDOs of others, EMCY) is not for this drive

    def _ignore(self, why: str) -> None:
        self.ignored.append(why)
        del self.ignored[:-100]

    def _nmt(self, command: str) -> None:
        if command == "START":
            self.nmt = "OPERATIONAL"
        elif command == "STOP":
            self.nmt = "STOPPED"
        elif command == "ENTER_PRE_OPERATIONAL":
            self.nmt = "PRE_OPERATIONAL"
        elif command == "RESET_NODE":
            self.power_up()
        else:
            self._reset_communication()

    def _cob(self, comm_index: int) -> int | None:
        """The COB-ID of a PDO, None while it is invalid (bit 31)."""
        value = self.values[(comm_index, 1)]
        return None if value & 0x80000000 else value & 0x7FF

    def _map(self, map_index: int) -> co.PdoMap:
        count = self.values[(map_index, 0)]
        return co.PdoMap.from_words(self.values[(map_index, k)] for k in range(1, count + 1))

    def _consumer(self) -> tuple[int, float]:
        """(master node id, consumer time in s) of 0x1016.1; (0, 0) when off."""
        value = self.values.get((0x1016, 1), 0)
        node, ms = (value >> 16) & 0x7F, value & 0xFFFF
        return (node, ms / 1000.0) if node and ms else (0, 0.0)

    # ------------------------------------------------------------------ PDOs and SYNC
    def _rpdo(self, frame: Frame) -> None:
        mapping = self._map(0x1600)
        try:
            values = co.unpack_pdo(self.od, mapping, frame.data)
        except FrameError:
            self._emcy(PDO_LENGTH_ERROR, fault=False)  # not processed: CiA 301's PDO length error
            return
        if self.values[(0x1400, 2)] <= 240:
            self.latched = values  # applied at the next SYNC
        else:
            self._apply(values)

    def _sync(self) -> None:
        if self.nmt != "OPERATIONAL":
            return
        self.syncs += 1
        if self.latched is not None:
            values, self.latched = self.latched, None
            self._apply(values)
        for comm in (0x1800, 0x1801):
            cob, kind = self._cob(comm), self.values[(comm, 2)]
            if cob is not None and 1 <= kind <= 240 and self.syncs % kind == 0:
                self.outbox.append(self.tpdo(comm))

    def tpdo(self, comm_index: int) -> Frame:
        mapping = self._map(comm_index + 0x200)
        return co.pack_pdo(self.od, self._cob(comm_index), mapping, {i: self.read(i, s) for i, s, _ in mapping.entries})

    def _apply(self, values: dict[int, Any]) -> None:
        for index, value in values.items():
            if index != 0x6040:
                self.values[(index, 0)] = value
        if 0x6040 in values:
            self.write_controlword(values[0x6040])
        self._follow()

    # ------------------------------------------------------------------ SDO server
    def _sdo(self, fields: dict) -> Frame:
        service = fields["service"]
        if service in ("upload_segment", "download_segment"):
            return self._segment(fields)
        self.transfer = None  # a new initiate ends any transfer under way
        frame = self._initiate(fields)
        if co.decode(frame).fields["service"] == "abort":
            self.aborts.append(co.decode(frame).fields["code"])
        return frame

    def _segment(self, fields: dict) -> Frame:
        """One segment of the segmented transfer under way (CiA 301): the toggle bit alternates,
        starting at 0; an upload sends up to 7 bytes a segment, a download takes them."""
        transfer, node = self.transfer, self.node_id
        if transfer is None or transfer["service"] + "_segment" != fields["service"]:
            where = (transfer["index"], transfer["subindex"]) if transfer else (0, 0)
            self.transfer = None
            self.aborts.append(co.ABORT_COMMAND)
            return co.sdo_abort(node, *where, co.ABORT_COMMAND)
        if fields["toggle"] != transfer["toggle"]:
            self.transfer = None
            self.aborts.append(co.ABORT_TOGGLE)
            return co.sdo_abort(node, transfer["index"], transfer["subindex"], co.ABORT_TOGGLE)
        toggle = transfer["toggle"]
        transfer["toggle"] ^= 1
        if transfer["service"] == "upload":
            data, transfer["data"] = transfer["data"][:7], transfer["data"][7:]
            last = not transfer["data"]
            if last:
                self.transfer = None
            return co.sdo_upload_segment(node, toggle, data, last)
        transfer["data"] += fields["data"]
        if not fields["last"]:
            return co.sdo_download_segment_response(node, toggle)
        self.transfer = None
        index, sub = transfer["index"], transfer["subindex"]
        if transfer["size"] is not None and len(transfer["data"]) != transfer["size"]:
            self.aborts.append(ABORT_LENGTH)
            return co.sdo_abort(node, index, sub, ABORT_LENGTH)
        answer = self._write(index, sub, bytes(transfer["data"]))
        return answer if answer is not None else co.sdo_download_segment_response(node, toggle)

    def _initiate(self, fields: dict) -> Frame:
        index, sub, service = fields["index"], fields["subindex"], fields["service"]
        node = self.node_id
        key = (index, sub)
        if key not in self.values:
            code = ABORT_NO_SUBINDEX if any(i == index for i, _ in self.values) else ABORT_NO_OBJECT
            return co.sdo_abort(node, index, sub, code)
        var = co.variable(self.od, index, sub)
        if service == "upload":
            if not var.readable:
                return co.sdo_abort(node, index, sub, ABORT_WRITE_ONLY)
            data = var.encode_raw(self.read(index, sub))
            if len(data) <= 4:
                return co.sdo_upload_response(node, index, sub, data)
            self.transfer = {"service": "upload", "index": index, "subindex": sub, "toggle": 0, "data": bytes(data)}
            return co.sdo_upload_initiate_response(node, index, sub, len(data))
        if not var.writable:
            return co.sdo_abort(node, index, sub, ABORT_READ_ONLY)
        if fields.get("segmented"):
            self.transfer = {"service": "download", "index": index, "subindex": sub, "toggle": 0,
                             "data": b"", "size": fields["size"]}
            return co.sdo_download_response(node, index, sub)
        answer = self._write(index, sub, fields["data"])
        return answer if answer is not None else co.sdo_download_response(node, index, sub)

    def _write(self, index: int, sub: int, data: bytes) -> Frame | None:
        """Write an object's value from its bytes; the abort frame if refused, else None."""
        node, key = self.node_id, (index, sub)
        var = co.variable(self.od, index, sub)
        if var.fixed_size and len(data) != len(var) // 8:
            return co.sdo_abort(node, index, sub, ABORT_LENGTH)
        value = var.decode_raw(data)
        refused = self._refuse_write(index, sub, value)
        if refused:
            return co.sdo_abort(node, index, sub, refused)
        if index == 0x6040:
            self.write_controlword(value)
        else:
            self.values[key] = value
        self._follow()
        return None

    def _refuse_write(self, index: int, sub: int, value: int) -> int:
        """The abort code a write gets, 0 if allowed."""
        if index in (0x1600, 0x1A00, 0x1A01):
            if sub > 0 and self.values[(index, 0)] != 0:
                return ABORT_ACCESS  # CiA 301: set the count to 0 before changing an entry
            if sub == 0:
                if value > 8:
                    return ABORT_RANGE
                bits = 0
                for k in range(1, value + 1):
                    word = self.values[(index, k)]
                    target = (word >> 16, (word >> 8) & 0xFF)
                    if target not in self.values or not co.variable(self.od, *target).pdo_mappable:
                        return ABORT_NOT_MAPPABLE
                    bits += word & 0xFF
                if bits > 64:
                    return ABORT_PDO_LENGTH
            elif self.values[(index - 0x200, 1)] & 0x80000000 == 0:
                return ABORT_ACCESS  # the PDO is valid: invalidate it first
        if index == 0x6060 and value not in (PP, CSP, CSV):
            return ABORT_RANGE
        if index == 0x605A and value not in (2, 6):
            return ABORT_RANGE
        if index in (0x1400, 0x1800, 0x1801) and sub == 2 and not (value <= 240 or value >= 254):
            return ABORT_RANGE
        return 0

    def read(self, index: int, sub: int = 0) -> Any:
        """An object's value as the drive reports it now (the actual values computed)."""
        if index == 0x6041:
            return self.statusword
        if index == 0x6064:
            return _int32(self.position * self.counts)
        if index == 0x606C:
            return _int32(self.velocity * self.counts)
        if index == 0x6077:
            rated = self.values[(0x6076, 0)] / 1000.0
            return max(-32768, min(32767, round(1000.0 * self.servo.torque_target / rated))) if rated else 0
        if index == 0x6061:
            return self.values[(0x6060, 0)]
        return self.values[(index, sub)]

    # ------------------------------------------------------------------ the 402 state machine
    @property
    def statusword(self) -> int:
        word = co.STATUSWORD[self.state] | co.SW_REMOTE
        if self.state in POWERED:
            word |= co.SW_VOLTAGE_ENABLED
        if self.state == OE:
            mode = self.values[(0x6060, 0)]
            if mode == PP:
                if self.new_setpoint:
                    word |= co.SW_SETPOINT_ACK
                if self.servo.trajectory_done:
                    word |= co.SW_TARGET_REACHED
            else:
                word |= co.SW_SETPOINT_ACK  # CSP/CSV: the drive follows the command value
        return word

    def _enter(self, state: str, transition: int) -> None:
        self.state = state
        self.transitions.append(transition)
        del self.transitions[:-100]

    def write_controlword(self, word: int) -> None:
        """The controlword's device control command, as the standard's state diagram takes it."""
        previous, self.controlword = self.controlword, word
        self.values[(0x6040, 0)] = word
        state, command = self.state, co.command_of(word)
        if state == FAULT:
            if word & 0x80 and not previous & 0x80:
                self._clear_fault()
                self._enter(SOD, 15)
            return
        if state in (NRTSO, FRA) or command == "FAULT RESET":
            return
        if state == SOD and command == "SHUTDOWN":
            self._enter(RTSO, 2)
        elif state == RTSO:
            if command in ("SWITCH ON", "ENABLE OPERATION"):
                self._enter(SO, 3)
                if command == "ENABLE OPERATION":  # switch on + enable operation: 3 then 4
                    self._enable()
            elif command in ("DISABLE VOLTAGE", "QUICK STOP"):
                self._enter(SOD, 7)
        elif state == SO:
            if command == "ENABLE OPERATION":
                self._enable()
            elif command == "SHUTDOWN":
                self._enter(RTSO, 6)
            elif command in ("DISABLE VOLTAGE", "QUICK STOP"):
                self._enter(SOD, 10)
        elif state == OE:
            if command == "SWITCH ON":  # disable operation
                self._power_off(SO, 5)
            elif command == "SHUTDOWN":
                self._power_off(RTSO, 8)
            elif command == "DISABLE VOLTAGE":
                self._power_off(SOD, 9)
            elif command == "QUICK STOP":
                self._enter(QSA, 11)
                self._start_ramp()
            elif word & co.CW_NEW_SETPOINT and not previous & co.CW_NEW_SETPOINT:
                self.new_setpoint = True
            elif not word & co.CW_NEW_SETPOINT:
                self.new_setpoint = False
        elif state == QSA:
            if command == "DISABLE VOLTAGE":
                self._power_off(SOD, 12)
            elif command == "ENABLE OPERATION" and self.values[(0x605A, 0)] in (5, 6, 7, 8):
                self._enable(16)

    def _enable(self, transition: int = 4) -> None:
        self._enter(OE, transition)
        self.ramp = False
        servo = self.servo
        servo.active_errors = servo.disarm_reason = 0
        servo.state = IDLE
        servo._arm(self.now)  # the position input is reset to where the motor is
        self.values[(0x607A, 0)] = _int32(self.position * self.counts)
        self.new_setpoint = False
        self._configure_servo()

    def _configure_servo(self) -> None:
        servo, mode = self.servo, self.values[(0x6060, 0)]
        servo.vel_limit = self.values[(0x607F, 0)] / self.counts
        rated = self.values[(0x6076, 0)] / 1000.0
        servo.current_limit = self.values[(0x6072, 0)] / 1000.0 * rated / (self.servo_config.torque_constant or 1.0)
        if mode == CSV:
            servo.control_mode, servo.input_mode = VELOCITY, PASSTHROUGH
        elif mode == PP:
            servo.control_mode, servo.input_mode = POSITION, TRAP_TRAJ
            servo.traj_limits.update(Traj_Vel_Limit=min(self.values[(0x6081, 0)], self.values[(0x607F, 0)]) / self.counts,
                                     Traj_Accel_Limit=self.values[(0x6083, 0)] / self.counts,
                                     Traj_Decel_Limit=self.values[(0x6084, 0)] / self.counts)
        else:
            servo.control_mode, servo.input_mode = POSITION, PASSTHROUGH

    def _follow(self) -> None:
        """Operation enabled: the servo's input follows the target of the mode."""
        if self.state != OE or self.ramp:
            return
        self._configure_servo()
        servo, mode = self.servo, self.values[(0x6060, 0)]
        if mode == CSP:
            servo.input_pos, servo.input_vel = self.values[(0x607A, 0)] / self.counts, 0.0
        elif mode == CSV:
            servo.input_vel = self.values[(0x60FF, 0)] / self.counts
        elif mode == PP and self.new_setpoint and not getattr(self, "_taken", False):
            servo.input_pos = self.values[(0x607A, 0)] / self.counts
            servo.input_pos_updated = True
        self._taken = mode == PP and self.new_setpoint

    def _power_off(self, state: str, transition: int) -> None:
        self._enter(state, transition)
        self.ramp = False
        self.servo.state = IDLE  # the power stage is off
        self.servo.torque_target = 0.0

    def _start_ramp(self) -> None:
        """Brake on the quick stop deceleration to a standstill (quick stop, fault reaction)."""
        servo = self.servo
        decel = self.values[(0x6085, 0)] / self.counts
        v = self.velocity
        servo.control_mode, servo.input_mode = POSITION, TRAP_TRAJ
        servo.pos_setpoint, servo.vel_setpoint = self.position, v
        servo.traj_limits.update(Traj_Vel_Limit=max(abs(v), 1e-6), Traj_Accel_Limit=decel, Traj_Decel_Limit=decel)
        servo.input_pos = self.position + (v * abs(v) / (2.0 * decel) if decel > 0 else 0.0)
        servo.input_pos_updated = True
        self.ramp = True

    def fault(self, code: int) -> None:
        """A fault: EMCY, then the fault reaction (a braking ramp where the power stage is on), then FAULT."""
        self._emcy(code, fault=True)
        if self.state in (FRA, FAULT):
            return
        powered = self.state in (OE, QSA)
        self._enter(FRA, 13)
        if powered and self.servo.armed:
            self._start_ramp()
        else:
            self._power_off(FRA, 13)
            self.transitions.pop()
            self._enter(FAULT, 14)

    def _communication_error(self) -> None:
        """CiA 301's error behaviour (0x1029.1) on a communication error such as a heartbeat
        event: 0 (the default) an OPERATIONAL node enters PRE-OPERATIONAL, 1 no change, 2 STOPPED."""
        behaviour = self.values.get((0x1029, 1), 0)
        if behaviour == 0 and self.nmt == "OPERATIONAL":
            self.nmt = "PRE_OPERATIONAL"
        elif behaviour == 2:
            self.nmt = "STOPPED"

    def _emcy(self, code: int, fault: bool) -> None:
        register = 0x01 | (0x10 if code & 0xFF00 == 0x8100 else 0)
        if fault:
            self.values[(0x603F, 0)] = code
            self.values[(0x1001, 0)] = register
        self.outbox.append(co.emcy(self.node_id, code, register))

    def _clear_fault(self) -> None:
        self.values[(0x603F, 0)] = 0
        self.values[(0x1001, 0)] = 0
        self.outbox.append(co.emcy(self.node_id, 0x0000, 0))  # error reset

    # ------------------------------------------------------------------ control step
    def update(self, position: float, velocity: float, now: float, dt: float) -> float | None:
        """One control step: the motor's position (turns) and velocity (turns/s) in; torque (Nm)
        out, or None while the power stage is off."""
        self.now = now
        self.position, self.velocity = position, velocity
        period = self.values[(0x1017, 0)] / 1000.0
        if period > 0 and now - self.last_heartbeat >= period - 1e-9 and self.nmt != "INITIALISING":
            self.outbox.append(co.heartbeat(self.node_id, self.nmt))
            self.last_heartbeat = now
        master, timeout = self._consumer()
        if master and self.master_heard is not None and now - self.master_heard > timeout:
            self.master_heard = None  # monitoring starts again with the master's next heartbeat
            self.fault(HEARTBEAT_ERROR)
            self._communication_error()
        if not self.servo.armed:
            self.servo.update(position, velocity, now, dt)
            return None
        torque = self.servo.update(position, velocity, now, dt)
        if self.ramp and self.servo.trajectory_done:  # braked to a standstill: the power stage goes off
            self.ramp = False
            if self.state == FRA:
                self._power_off(FAULT, 14)
            elif self.state == QSA and self.values[(0x605A, 0)] in (0, 1, 2, 3, 4):
                self._power_off(SOD, 12)
        return torque


def _int32(value: float) -> int:
    return max(-0x80000000, min(0x7FFFFFFF, round(value)))
