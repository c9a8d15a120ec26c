"""The CAN motor node's side of one CiA 402 drive: start-up over NMT and SDO, the controlword toward OPERATION ENABLED, RPDO setpoints, TPDO state.

Plain state, changed only by the node's actions (nodes/can_motor/node.py); frames come from
`iotad.can.canopen`, against the drive's EDS. The sequence (docs/can_motor.md, "CiA 402 drives"):

1. NMT ENTER_PRE_OPERATIONAL, then one SDO write at a time, each sent when the last was answered:
   the heartbeat consumer (0x1016: the master's node id, `lost_after` master heartbeats) and
   producer (0x1017), the mode of operation (0x6060), the mappings of RPDO1 (controlword and
   target) and of TPDO1/TPDO2 (statusword, position, torque; velocity, mode display), their
   transmission types (at every SYNC; RPDO1 at once in Profile Position), the velocity limit
   (0x607F) and, for Profile Position, the profile velocity and acceleration; then NMT START.
2. At every tick (each SYNC), an arming axis gets an RPDO: controlword toward OPERATION
   ENABLED from the state its last TPDO reported (fault reset, shutdown, switch on, enable
   operation) and as target where it is (position modes) or 0 (velocity).
3. Armed, every setpoint is an RPDO (enable operation + target), taken by the drive at SYNC.
"""
from __future__ import annotations

import dataclasses
import math
import sys
from collections import deque

from typing import Any, Sequence

from iotad.can import canopen as co
from iotad.can.frame import Frame, FrameError
from iotad.can.odrive import EncodeError
from iotad.kernel.code_fault import NodeViolation

from .drive_link import ARMED, ARMING, FAULT, UNARMED, DriveLink
from .joint_map import JointMapError

# What the node reads from each drive at start-up: rated torque, position encoder resolution,
# gear ratio, feed constant (CiA 402's factor group; the last three where the drive has them).
SCALING = ((0x6076, 0), (0x608F, 1), (0x608F, 2), (0x6091, 1), (0x6091, 2), (0x6092, 1), (0x6092, 2))
RPDO1_MAP = {"csp": (0x607A, 32), "pp": (0x607A, 32), "csv": (0x60FF, 32)}
TPDO1_MAP = co.PdoMap(((0x6041, 0, 16), (0x6064, 0, 32), (0x6077, 0, 16)))
TPDO2_MAP = co.PdoMap(((0x606C, 0, 32), (0x6061, 0, 8)))
INT32_MAX = 0x7FFFFFFF


class Cia402Link(DriveLink):
    """The host's knowledge of one drive, and the frames that drive it. The node's settings it
    takes: master_node_id, master_heartbeat, lost_after, heartbeat_period, velocity_every."""

    family = "cia402"
    feeds_watchdog = False  # its watchdog is the heartbeat consumer (0x1016): it watches the node's heartbeat

    def __init__(self, node, index: int):
        super().__init__(node, index)
        joint = self.joint
        master_id, velocity_every = node.master_node_id, node.velocity_every
        if isinstance(master_id, bool) or not isinstance(master_id, int) or not 1 <= master_id <= co.NODE_ID_MAX:
            raise ValueError(f"CanMotor: master_node_id must be 1..{co.NODE_ID_MAX}, got {master_id!r}")
        if joint.node_id == master_id:
            raise JointMapError(f"joint {joint.name}: node_id {master_id} is this node's own CANopen id "
                                "(master_node_id)")
        if isinstance(velocity_every, bool) or not isinstance(velocity_every, int) or not 1 <= velocity_every <= 240:
            raise ValueError(f"CanMotor: velocity_every must be a whole number of SYNCs 1..240, got {velocity_every!r}")
        master_period = node.master_heartbeat
        if isinstance(master_period, bool) or not isinstance(master_period, (int, float)) \
                or not 0 < master_period < math.inf:
            raise ValueError(f"CanMotor: master_heartbeat must be a positive number of seconds, got {master_period!r}")
        self.master_id = master_id
        self.master_ticks = max(1, round(master_period / node.period))
        self.node_id = joint.node_id
        self.od = co.object_dictionary(co.DRIVE_EDS, self.node_id)
        self.mode = joint.operation_mode
        target, bits = RPDO1_MAP[self.mode]
        self.target_index = target
        self.rpdo_map = co.PdoMap(((0x6040, 0, 16), (target, 0, bits)))
        self.rpdo_cob = co.RPDO[0] + self.node_id
        self.tpdo_maps = {co.TPDO[0] + self.node_id: TPDO1_MAP, co.TPDO[1] + self.node_id: TPDO2_MAP}
        self.rated_torque = joint.rated_torque  # Nm: the drive's 0x6076 once read (None: not known)
        self.table_joint = joint                # the joint as the table states it (scale checked against the drive's)
        self.settings = (master_id, master_period, node.lost_after, node.heartbeat_period, velocity_every)
        self.config = self._configuration(*self.settings)  # checked now: every value fits its object
        self.configured = False
        self.queue: deque[tuple[int, int, bytes | None]] = deque()  # None: a read (upload)
        self.scale: dict[tuple[int, int], int | None] = {}  # what the drive said of its scaling objects
        self.mismatch: tuple[int, float, float] | None = None  # (object, table value, drive value)
        self.waiting: tuple[int, int] | None = None
        self.nmt = ""                 # the drive's NMT state from its heartbeat ("" until heard)
        self.statusword = -1          # -1 until a TPDO1
        self.controlword = 0
        self.error_code = 0           # the last EMCY's code
        self.abort_code = 0           # the last SDO abort's code
        self.new_setpoint = False     # Profile Position: bit 4 was raised in the last RPDO
        self.started = False          # NMT START went out in this arming: its TPDOs are due
        self.operational_seen = False  # since then, a TPDO or an OPERATIONAL heartbeat came
        self.unanswered = 0           # SYNCs since the last statusword while one is due
        self.stop_sent = False        # a quick stop went out for an enabled drive held in FAULT (UNCOMMANDED_STATE)

    # ------------------------------------------------------------------ start-up
    def _configuration(self, master_id: int, master_period: float, lost_after: int,
                       heartbeat_period: float, velocity_every: int) -> tuple[tuple[int, int, bytes], ...]:
        joint, od = self.joint, self.od

        def u(index: int, sub: int, value: int) -> tuple[int, int, bytes]:
            return index, sub, co.encode_value(od, index, sub, value)

        consumer_ms = max(1, round(1000.0 * master_period * lost_after))
        writes = [u(0x1016, 1, master_id << 16 | min(consumer_ms, 0xFFFF)),
                  u(0x1017, 0, max(1, round(1000.0 * heartbeat_period))),
                  u(0x6060, 0, co.MODES[self.mode.upper()])]
        sync_type = 255 if self.mode == "pp" else 1  # Profile Position takes a new set-point at once
        for comm, mapping, kind in ((0x1400, self.rpdo_map, sync_type), (0x1800, TPDO1_MAP, 1),
                                     (0x1801, TPDO2_MAP, velocity_every)):
            cob = co.default(od, comm, 1) & 0x7FF
            writes.append(u(comm, 1, cob | 0x80000000))           # invalid while it changes
            writes.append(u(comm + 0x200, 0, 0))
            writes += [u(comm + 0x200, k, word) for k, word in enumerate(mapping.words(), 1)]
            writes.append(u(comm + 0x200, 0, len(mapping.entries)))
            writes.append(u(comm, 2, kind))
            writes.append(u(comm, 1, cob))
        velocity = round(abs(joint.counts_per_second(joint.velocity_limit)))
        writes.append(u(0x607F, 0, min(velocity, 0xFFFFFFFF)))
        if self.mode == "pp":
            acceleration = min(round(abs(joint.counts_per_second(joint.acceleration_limit))), 0xFFFFFFFF)
            writes += [u(0x6081, 0, min(velocity, 0xFFFFFFFF)), u(0x6083, 0, acceleration), u(0x6084, 0, acceleration)]
        return tuple(writes)

    def arming_frames(self) -> list[Frame]:
        """The frames that start an arming: the start-up sequence if the drive is not configured
        (its first SDO write; the others follow their answers), else none (the controlword does it)."""
        self.new_setpoint = False
        self.statusword = -1  # unknown until its next TPDO: no controlword from an old state
        self.operational_seen = False
        self.unanswered = 0
        if self.configured:  # configured already: NMT START if it is not OPERATIONAL (a recovery)
            self.started = True
            return [] if self.nmt == "OPERATIONAL" else [co.nmt("START", self.node_id)]
        self.started = False
        self.scale = {}
        self.queue = deque((index, sub, None) for index, sub in SCALING)  # first what the drive says of its units
        return [co.nmt("ENTER_PRE_OPERATIONAL", self.node_id), self._next_sdo()]

    def abandon(self) -> list[Frame]:
        """An arming given up (timed out, or the drive is not enabled): the start-up starts over at
        the next arming; an SDO write still waiting for its answer is ended with an SDO abort
        (CiA 301: a transfer the client stops is never left open)."""
        frames = [co.sdo_abort(self.node_id, *self.waiting, co.ABORT_TIMEOUT, from_server=False)] if self.waiting else []
        self._forget()
        return frames

    def _forget(self) -> None:
        self.queue.clear()
        self.waiting = None

    def _next_sdo(self) -> Frame:
        index, sub, data = self.queue.popleft()
        self.waiting = (index, sub)
        if data is None:
            return co.sdo_upload(self.node_id, index, sub)
        return co.sdo_download(self.node_id, index, sub, data)

    def on_sdo(self, fields: dict) -> tuple[list[Frame], str]:
        """An SDO response: (frames to send, event or ""). An abort of a write ends the start-up
        (SDO_ABORT); of a read, the drive lacks that optional object. Scaling that contradicts the
        joint table's ends it too (SCALE_MISMATCH)."""
        where = (fields["index"], fields["subindex"])
        reading = where in SCALING
        if self.waiting != where:
            return [], ""  # an answer to nobody's question here (another master's?): ignored
        if fields["service"] == "abort" and not reading:
            self.abort_code = fields["code"]
            self._forget()  # the server ended the transfer
            return [], "SDO_ABORT"
        if fields["service"] not in (("upload", "abort") if reading else ("download",)):
            return [], ""
        self.waiting = None
        if reading:
            data = fields.get("data")
            self.scale[where] = int.from_bytes(data, "little") if fields["service"] == "upload" and data else None
            if not self.queue:  # every scaling object read: check them, then configure
                self.mismatch = self._take_scale()
                if self.mismatch:
                    return [], "SCALE_MISMATCH"
                self.queue.extend(self._configuration(*self.settings))
        if self.queue:
            return [self._next_sdo()], ""
        self.configured = self.started = True
        return [co.nmt("START", self.node_id)], ""

    def _take_scale(self) -> tuple[int, float, float] | None:
        """The drive's units (CiA 402's factor group): position units per motor turn are the feed
        constant over the gear ratio (0x6092, 0x6091) where it has them, else its encoder
        increments per turn (0x608F); the rated torque (0x6076, mNm) scales torque actual. A value
        the joint table states explicitly must agree; one it does not state is taken from the
        drive. The gear ratio (0x6091: motor revolutions per driving shaft revolution) is the
        table's `gear_ratio` (motor turns per joint turn): stated in both, they must agree; stated
        by the drive only, the drive's is taken (positions and efforts through the table's 1.0
        would be off by the drive's ratio). Returns (object, table's, drive's) of the first
        contradiction, else None."""
        def ratio(index: int) -> float | None:
            top, bottom = self.scale.get((index, 1)), self.scale.get((index, 2))
            return top / bottom if top and bottom else None

        table = self.table_joint
        drive_gear, feed, resolution = ratio(0x6091), ratio(0x6092), ratio(0x608F)
        gear = drive_gear or 1.0
        units, index = (feed / gear, 0x6092) if feed else (resolution, 0x608F)
        rated = self.scale.get((0x6076, 0))
        rated = rated / 1000.0 if rated else None
        if units and "counts_per_turn" in table.explicit and not math.isclose(units, table.counts_per_turn, rel_tol=1e-9):
            return index, table.counts_per_turn, units
        if drive_gear and "gear_ratio" in table.explicit and not math.isclose(drive_gear, table.gear_ratio,
                                                                               rel_tol=1e-9):
            return 0x6091, table.gear_ratio, drive_gear
        if rated and table.rated_torque is not None and not math.isclose(rated, table.rated_torque, rel_tol=1e-6):
            return 0x6076, table.rated_torque, rated
        if rated is None and table.rated_torque is None:
            return 0x6076, 0.0, 0.0  # no rated torque anywhere: its torque actual means nothing
        self.joint = dataclasses.replace(table, counts_per_turn=units or table.counts_per_turn,
                                         gear_ratio=drive_gear if drive_gear and "gear_ratio" not in table.explicit
                                         else table.gear_ratio)
        self.rated_torque = rated or table.rated_torque
        return None

    def scale_reason(self) -> str:
        """The one line that says why the drive is refused (after SCALE_MISMATCH)."""
        index, table, drive = self.mismatch
        name = {0x6076: "rated torque (0x6076, N.m)", 0x608F: "increments per motor turn (0x608F)",
                0x6092: "position units per motor turn (0x6092 / 0x6091)",
                0x6091: "gear ratio (0x6091, motor revolutions per shaft revolution)"}[index]
        if index == 0x6076 and not drive:
            return (f"joint {self.joint.name}: the drive gives no rated torque (0x6076) and the joint table none "
                    "(rated_torque): its torque actual cannot be scaled; not armed")
        key = {0x6076: "rated_torque", 0x6091: "gear_ratio"}.get(index, "counts_per_turn")
        return (f"joint {self.joint.name}: the joint table's {key} = {table:g} contradicts the drive's {name} = "
                f"{drive:g}; not armed (fix the table or the drive)")

    def emcy_violation(self, code: int, register: int) -> NodeViolation:
        """The recorded `drive_emcy` violation of one EMCY: the joint by name, the error code by
        name and the error register's bits by name (joint_status carries the numbers only)."""
        name, bits = co.emcy_name(code), co.error_register_names(register)
        message = (f"joint {self.joint.name!r} (CANopen node id {self.node_id}): EMCY 0x{code:04X} {name}, "
                   f"error register 0x{register:02X} ({', '.join(bits) or 'no error'}); the axis is "
                   f"{self.axis.phase}")
        return NodeViolation("drive_emcy", message, joint=self.joint.name, node_id=self.node_id, code=code,
                             name=name, register=register, register_bits=bits, phase=self.axis.phase)

    # ------------------------------------------------------------------ state from the drive
    @property
    def state(self) -> str:
        return co.state_of(self.statusword) if self.statusword >= 0 else "NOT READY TO SWITCH ON"

    @property
    def enabled(self) -> bool:
        return self.statusword >= 0 and self.state == "OPERATION ENABLED"

    def unpack(self, frame: Frame) -> dict:
        """A TPDO's values by object index (MalformedFrame for the wrong length)."""
        return co.unpack_pdo(self.od, self.tpdo_maps[frame.id], frame.data)

    def on_heartbeat(self, state: str) -> bool:
        """A heartbeat; True when it is a boot-up (the drive restarted and lost its configuration)."""
        self.nmt = state
        if state == "BOOT_UP":
            self.configured = self.started = False
            self.statusword = -1
            self._forget()  # a booted drive holds no transfer
            return True
        return False

    # ------------------------------------------------------------------ frames to the drive
    def next_controlword(self) -> int:
        """The controlword one step toward OPERATION ENABLED from the reported state; a fault is
        reset on bit 7's rising edge (so 0x80 follows a word without it)."""
        state = self.state
        if state == "FAULT":
            word = 0x00 if self.controlword & co.CW_FAULT_RESET else co.CW_FAULT_RESET
        elif state in ("SWITCH ON DISABLED", "NOT READY TO SWITCH ON"):
            word = co.CW_SHUTDOWN
        elif state == "READY TO SWITCH ON":
            word = co.CW_SWITCH_ON
        elif state in ("SWITCHED ON", "OPERATION ENABLED"):
            word = co.CW_ENABLE_OPERATION
        else:  # QUICK STOP ACTIVE, FAULT REACTION ACTIVE: disable voltage, then start again
            word = co.CW_DISABLE_VOLTAGE
        return word

    def rpdo(self, controlword: int, command: float) -> Frame:
        """RPDO1: the controlword and the target (joint units: rad, or rad/s in csv)."""
        joint = self.joint
        value = joint.counts_per_second(command) if self.mode == "csv" else joint.counts(command)
        if not math.isfinite(value) or abs(value) > INT32_MAX:
            raise EncodeError(f"joint {joint.name}: {command!r} is {value:g} increments; an INTEGER32 target "
                              f"holds +-{INT32_MAX}")
        self.controlword = controlword
        return co.pack_pdo(self.od, self.rpdo_cob, self.rpdo_map, {0x6040: controlword, self.target_index: round(value)})

    def setpoint(self, command: float) -> list[Frame]:
        """The frames of one setpoint while armed: an RPDO taken at SYNC (csp, csv); in Profile
        Position a new set-point (bit 4 raised, change immediately) then bit 4 lowered again."""
        if self.mode != "pp":
            return [self.rpdo(co.CW_ENABLE_OPERATION, command)]
        raised = co.CW_ENABLE_OPERATION | co.CW_NEW_SETPOINT | co.CW_CHANGE_IMMEDIATELY
        return [self.rpdo(raised, command), self.rpdo(co.CW_ENABLE_OPERATION | co.CW_CHANGE_IMMEDIATELY, command)]

    def quick_stop(self, command: float) -> Frame:
        return self.rpdo(co.CW_QUICK_STOP, command)

    def torque(self, per_mille: int) -> float:
        """Torque actual (per mille of the rated torque the drive gave) in motor Nm."""
        return per_mille / 1000.0 * (self.rated_torque or 0.0)

    # ------------------------------------------------------------------ the node's hooks
    @staticmethod
    def node_id_of(frame_id: int) -> int:
        return frame_id & 0x7F  # CiA 301's predefined connection set: function code + node id

    def frame_ids(self):
        return [function + self.node_id for function in co.SERVICES]

    @classmethod
    def bus_ids(cls, links: Sequence["Cia402Link"]) -> frozenset:
        """NMT, SYNC and this node's heartbeat: heard from the bus, another master sends them."""
        return frozenset((co.NMT, co.SYNC, co.HEARTBEAT + links[0].master_id))

    def setpoint_frames(self, command: float, velocity_ff: float, torque_ff: float) -> tuple[Frame, ...]:
        return tuple(self.setpoint(command))

    def heartbeat_lost(self) -> list[str]:
        """A drive silent for its heartbeat timeout is not enabled, whatever it last said."""
        return self.node.drive_not_enabled(self.index, "LOST")

    def stop_frames(self) -> list[Frame]:
        return [self.quick_stop(self.axis.command)]

    def idle_frames(self) -> list[Frame]:
        return self.abandon() + [self.quick_stop(self.axis.command)]

    @classmethod
    def after_stop_frames(cls, links: Sequence["Cia402Link"]) -> list[Frame]:
        return [co.sync()]  # the quick stops are taken now, not at the next tick

    def tick_frames(self) -> list[Frame]:
        """The TPDO timeout (a statusword is due at every SYNC once NMT START went out: none for
        `tpdo_timeout` SYNCs is LOST, and a quick stop in case it still runs), then an arming
        drive's controlword, one step toward OPERATION ENABLED, holding where it is."""
        axis = self.axis
        if self.started and axis.phase in (ARMED, ARMING) and not axis.lost:
            if self.unanswered >= self.joint.tpdo_timeout:
                axis.lost = True
                frames = self.stop_frames() + self.after_stop_frames([self])
                for event in self.node.drive_not_enabled(self.index, "TPDO_TIMEOUT"):
                    self.node.report(self.index, event)
                return frames
            self.unanswered += 1
        else:
            self.unanswered = 0
        if axis.phase == ARMING and self.configured and self.statusword >= 0 and not axis.lost:
            hold = axis.position if self.joint.mode == "position" and axis.has_position else 0.0
            return [self.rpdo(self.next_controlword(), hold)]
        return []

    @classmethod
    def bus_tick_frames(cls, links: Sequence["Cia402Link"], ticks: int) -> list[Frame]:
        """This node's heartbeat when due (the drives' consumers watch it), then SYNC."""
        first = links[0]
        frames = [co.heartbeat(first.master_id, "OPERATIONAL")] if ticks % first.master_ticks == 0 else []
        return frames + [co.sync()]

    def receive(self, frame: Frame, value: Any) -> None:
        node, axis = self.node, self.axis
        try:
            message = co.decode(frame)
        except co.UnknownValue:  # e.g. a heartbeat of no NMT state: not believed (its timeout runs on)
            node.reject_frame("BAD_VALUE", value)
            return
        except co.MalformedFrame:
            node.reject_frame("WRONG_DLC", value)
            return
        except FrameError:
            node.reject_frame("UNKNOWN_COMMAND", value)
            return
        kind = message.kind
        if kind == "HEARTBEAT":
            self._on_heartbeat(message.fields["state"])
        elif kind == "EMCY":
            # every EMCY is recorded (code, register); one with a code is a fault, whatever the statusword says
            code = message.fields["code"]
            self.error_code = axis.axis_error = code
            axis.error_register = message.fields["register"]
            for event in node.drive_not_enabled(self.index, "EMCY") if code else ["EMCY"]:
                node.report(self.index, event)
            raise self.emcy_violation(code, axis.error_register)  # recorded by name; the node goes on
        elif kind == "SDO_RESPONSE":
            frames, event = self.on_sdo(message.fields)
            node.send(frames)
            if event == "SCALE_MISMATCH":  # a contradiction no retry mends: FAULT until a reset
                index, table, drive = self.mismatch
                axis.disarm_reason = index
                print(f"CanMotor: {self.scale_reason()}", file=sys.stderr, flush=True)
                if axis.phase == ARMING:
                    axis.phase = FAULT
                node.report(self.index, event, table, drive)
            elif event:
                axis.disarm_reason = self.abort_code
                node.report(self.index, event)
                if axis.phase == ARMING:  # the start-up failed: another try after arm_retry
                    axis.phase = UNARMED
        elif frame.id in self.tpdo_maps:
            try:
                values = self.unpack(frame)
            except co.MalformedFrame:
                node.reject_frame("WRONG_DLC", value)
                return
            self._on_tpdo(values)
        elif kind.startswith("RPDO") or kind == "SDO_REQUEST":
            node.reject_frame("UNEXPECTED", value)  # a master's frame to our drive: another master
        else:
            node.reject_frame("UNKNOWN_COMMAND", value)  # a TPDO this node did not map

    def _on_heartbeat(self, state: str) -> None:
        axis, node = self.axis, self.node
        axis.procedure_result = co.NMT_STATE.get(state, 0)
        axis.heard = axis.beat = True
        events = []
        if axis.lost:
            axis.lost = False
            events.append("FOUND")
        if state == "OPERATIONAL" and self.started:
            self.operational_seen = True
        elif state in ("PRE_OPERATIONAL", "STOPPED") and self.started and (
                axis.phase == ARMED or (axis.phase == ARMING and self.operational_seen)):
            # the drive left OPERATIONAL (its heartbeat consumer or an NMT command from elsewhere):
            # it takes no PDO, so it is not enabled whatever its last statusword said
            self.statusword = -1
            events += self.node.drive_not_enabled(self.index, "NMT_" + state)
        if self.on_heartbeat(state):
            events.append("BOOT_UP")
            if axis.phase == ARMED:
                events += node.drive_not_enabled(self.index, "DISARMED")
            elif axis.phase == ARMING:  # its power-on, or a restart mid-way: start again at once
                axis.phase, axis.retry = UNARMED, False
        for event in events or ["HEARTBEAT"]:
            node.report(self.index, event)

    def _on_tpdo(self, values: dict) -> None:
        joint, axis = self.joint, self.axis
        if 0x6064 in values:
            axis.position = joint.position_of_counts(values[0x6064])
            axis.has_position = True
        if 0x606C in values:
            axis.velocity = joint.velocity_of_counts(values[0x606C])
        if 0x6077 in values:
            axis.torque_estimate = self.torque(values[0x6077])
            axis.effort = joint.torque(axis.torque_estimate)
        if 0x6041 not in values:
            return
        self.statusword = axis.active_errors = values[0x6041]
        self.unanswered = 0
        self.operational_seen = True
        axis.axis_state = co.STATE_NUMBER[self.state]
        events = []
        if axis.lost:  # the TPDO timeout's LOST (the heartbeat's clears with a heartbeat)
            axis.lost = False
            events.append("FOUND")
        events += self.node.drive_enabled(self.index, self.enabled)
        if self.enabled and axis.phase == FAULT and not axis.link_stopped and not self.stop_sent:
            # enabled while the node holds it in FAULT: another master (`iotad can arm`) enabled
            # it; only the node's reset (estop = false) clears a held FAULT, so it is stopped
            # again (a quick stop, once per episode), as an ODrive in closed loop is sent IDLE
            self.node.send(self.stop_frames() + self.after_stop_frames([self]))
            self.stop_sent = True
            events.append("UNCOMMANDED_STATE")
        elif not self.enabled:
            self.stop_sent = False
        for event in events:
            self.node.report(self.index, event)
