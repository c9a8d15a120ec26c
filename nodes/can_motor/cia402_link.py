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

import math
from collections import deque

from iotad.can import canopen as co
from iotad.can.frame import Frame
from iotad.can.odrive import EncodeError

from .joint_map import JointConfig

RPDO1_MAP = {"csp": (0x607A, 32), "pp": (0x607A, 32), "csv": (0x60FF, 32)}
TPDO1_MAP = co.PdoMap(((0x6041, 0, 16), (0x6064, 0, 32), (0x6077, 0, 16)))
TPDO2_MAP = co.PdoMap(((0x606C, 0, 32), (0x6061, 0, 8)))
INT32_MAX = 0x7FFFFFFF


class Cia402Link:
    """The host's knowledge of one drive, and the frames that drive it."""

    def __init__(self, joint: JointConfig, master_id: int, master_period: float, lost_after: int,
                 heartbeat_period: float, velocity_every: int = 1):
        self.joint = joint
        self.node = joint.node_id
        self.od = co.object_dictionary(co.DRIVE_EDS, self.node)
        self.mode = joint.operation_mode
        target, bits = RPDO1_MAP[self.mode]
        self.target_index = target
        self.rpdo_map = co.PdoMap(((0x6040, 0, 16), (target, 0, bits)))
        self.rpdo_cob = co.RPDO[0] + self.node
        self.tpdo_maps = {co.TPDO[0] + self.node: TPDO1_MAP, co.TPDO[1] + self.node: TPDO2_MAP}
        self.rated_torque = co.default(self.od, 0x6076) / 1000.0  # Nm
        self.config = self._configuration(master_id, master_period, lost_after, heartbeat_period, velocity_every)
        self.configured = False
        self.queue: deque[tuple[int, int, bytes]] = deque()
        self.waiting: tuple[int, int] | None = None
        self.nmt = ""                 # the drive's NMT state from its heartbeat ("" until heard)
        self.statusword = -1          # -1 until a TPDO1
        self.controlword = 0
        self.error_code = 0           # the last EMCY's code
        self.abort_code = 0           # the last SDO abort's code
        self.new_setpoint = False     # Profile Position: bit 4 was raised in the last RPDO

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

    def arming(self) -> list[Frame]:
        """The frames that start an arming: the start-up sequence if the drive is not configured
        (its first SDO write; the others follow their answers), else none (the controlword does it)."""
        self.new_setpoint = False
        if self.configured:
            return []
        self.queue = deque(self.config)
        return [co.nmt("ENTER_PRE_OPERATIONAL", self.node), self._next_sdo()]

    def abandon(self) -> None:
        """An arming that timed out: what was waiting is forgotten (a retry starts over)."""
        self.queue.clear()
        self.waiting = None

    def _next_sdo(self) -> Frame:
        index, sub, data = self.queue.popleft()
        self.waiting = (index, sub)
        return co.sdo_download(self.node, index, sub, data)

    def on_sdo(self, fields: dict) -> tuple[list[Frame], str]:
        """An SDO response: (frames to send, event or ""). An abort ends the start-up (SDO_ABORT)."""
        where = (fields["index"], fields["subindex"])
        if fields["service"] == "abort":
            self.abort_code = fields["code"]
            self.abandon()
            return [], "SDO_ABORT"
        if self.waiting != where or fields["service"] != "download":
            return [], ""  # an answer to nobody's question here (another master's?): ignored
        self.waiting = None
        if self.queue:
            return [self._next_sdo()], ""
        self.configured = True
        return [co.nmt("START", self.node)], ""

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
            self.configured = False
            self.statusword = -1
            self.abandon()
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
        """Torque actual (per mille of the rated torque) in motor Nm."""
        return per_mille / 1000.0 * self.rated_torque
