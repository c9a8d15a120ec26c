"""`CanMotor`, the CAN motor node: joint setpoints to ODrive CAN Simple frames, CAN feedback to joint states.

One IOTA drives one CAN bus of ODrive axes (firmware 0.6), one axis per joint of its joint map
(`nodes/can_motor/joint_map.py`). docs/can_motor.md is the full description; in short:

- Arming, per axis, at start and on every retry: Clear_Errors, Set_Controller_Mode (the joint's
  mode and input mode), Set_Limits, the optional gain and trajectory settings, Set_Axis_State
  CLOSED_LOOP_CONTROL; armed once a Heartbeat shows CLOSED_LOOP_CONTROL, else ARM_TIMEOUT after
  `arm_timeout` and another try `arm_retry` later.
- Every `setpoints` message sends one frame per armed axis, by the joint's mode: Set_Input_Pos
  (position, velocity and torque feed-forward), Set_Input_Vel (velocity_ff, torque feed-forward)
  or Set_Input_Torque (torque_ff). A value outside the joint's limits is rejected or clamped as
  its `out_of_range` says, and reported on `joint_status`. With `skip_unchanged`, a frame the
  axis was sent last is not sent again: the firmware keeps its input, and `keepalive` repeats
  that frame often enough for its watchdog (an arm holding still then costs the bus a fraction
  of its frames).
- Feedback: Heartbeat, Get_Encoder_Estimates (cyclic), Get_Error and the other axis messages
  (polled with remote frames as `polls` says); `joint_states` every `state_period` once every
  joint has reported a position; `joint_status[i]` at every heartbeat and every event.
- CiA 402 drives (a joint with protocol = "cia402", nodes/can_motor/cia402_link.py): NMT and
  SDO start-up, the controlword toward OPERATION ENABLED (a fault reset first), RPDO setpoints
  taken at the SYNC this node sends every tick, TPDO state, and this node's heartbeat, which the
  drives watch: a silent master is their fault reaction.
- Link watch (`link_timeout` > 0): once setpoints have come, none for `link_timeout` means the
  link to their source (or the source) is lost: every armed or arming axis is commanded IDLE
  (a CiA 402 drive a quick stop), keep-alives stop, and each joint reports LINK_LOST; no axis
  is armed again until setpoints come back (LINK_FOUND), when the axes the watch stopped
  re-arm (an Estop meanwhile holds). Off by default; the launcher turns it on for a node whose
  setpoints come from another host (iotad/launcher/link_watch.py).
- A heartbeat missing for `lost_after` heartbeat periods: LOST. Frames it cannot use go to
  `bad_frame`. `estop = true` (and `final_can_frames`, the node host's shutdown hook) sends
  Estop to every axis; `estop = false` resets ESTOPPED and FAULT axes, which then re-arm.

Times are seconds: run it with time_unit = 1.0.
"""
from __future__ import annotations

import math
from collections import deque
from typing import Any

from channels.joints import joint_setpoints, joint_states
from channels.motor import BAD_FRAME, JOINT_STATUS
from iotad.can import canopen as co
from iotad.can.frame import CAN_FRAME, Frame, FrameError
from iotad.can.odrive import (AXIS_STATE, CONTROL_MODE, INPUT_MODE, MESSAGES, EncodeError, MalformedFrame,
                              UnknownFrame, decode, encode, node_id_of, request, undefined_values)
from iotad.kernel.api import Input, Internal, Iota, Output, Param
from iotad.kernel.code_fault import NodeViolation
from iotad.kernel.types import Bool

from .cia402_link import Cia402Link
from .joint_map import JointConfig, JointMapError, parse_joints

CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]
FF_MAX = 32.767  # Set_Input_Pos carries Vel_FF and Torque_FF as int16 x 0.001
FLOAT_MAX = 1.7976931348623157e308

# Messages an axis sends that the node may poll with a remote frame (the `polls` parameter).
POLLABLE = ("Get_Error", "Get_Encoder_Estimates", "Get_Torques", "Get_Iq", "Get_Temperature",
            "Get_Bus_Voltage_Current", "Get_Powers", "Get_Version")

UNARMED, ARMING, ARMED, FAULT, ESTOPPED = "UNARMED", "ARMING", "ARMED", "FAULT", "ESTOPPED"


class Axis:
    """What the node knows about one axis; plain state, changed only by the node's actions."""

    def __init__(self, node_id: int):
        self.node_id = node_id
        self.phase = UNARMED
        self.retry = False            # the next arming is a retry: it waits arm_retry first
        self.link_stopped = False     # the link watch disarmed it: it re-arms when setpoints return
        self.lost = False
        self.beat = False             # a heartbeat's report is waiting to go out (see `lost`)
        self.heard = False            # any heartbeat ever
        self.axis_state = 0
        self.axis_error = 0
        self.procedure_result = 0
        self.trajectory_done = False
        self.active_errors = 0
        self.disarm_reason = 0
        self.has_position = False
        self.position = 0.0           # joint units
        self.velocity = 0.0
        self.effort = 0.0
        self.command = 0.0            # the joint-unit command the axis follows now
        self.last_sent = 0            # the tick of the last command (or arming) frame
        self.last_frame = None        # the last command frame sent while ARMED (skip_unchanged)
        self.torque_estimate = 0.0    # controller units from here on
        self.iq_measured = 0.0
        self.fet_temperature = 0.0
        self.motor_temperature = 0.0
        self.bus_voltage = 0.0
        self.bus_current = 0.0


class CanMotor(Iota):
    """The CAN motor node. `CanMotor(name, joints=[...])` builds the IOTA sized for its joint map:
    `setpoints` is jointSetpoints<N> and `joint_states` jointStates<N> for N joints."""

    joints = Param(None)            # the joint map (required): see joint_map.py
    heartbeat_period = Param(0.1)   # s, the axes' Heartbeat period
    lost_after = Param(3)           # heartbeat periods without one before LOST
    encoder_period = Param(0.01)    # s, the axes' cyclic Get_Encoder_Estimates period
    state_period = Param(0.0)       # s between joint_states; 0: encoder_period
    polls = Param({"Get_Error": 0.1})  # message name -> s between remote requests (0: off)
    arm_timeout = Param(1.0)        # s from the arming sequence to a closed-loop heartbeat
    arm_retry = Param(0.5)          # s after an ARM_TIMEOUT (or a FAULT with auto_rearm) to try again
    auto_rearm = Param(False)       # re-arm an axis that left closed loop on its own
    keepalive = Param(0.05)         # s without a command before an ARMED axis gets its last one again; 0: off
    skip_unchanged = Param(False)   # a setpoint whose frame is the axis's last is not sent; keepalive repeats it
    arm_hold = Param(0.05)          # s between hold commands to an ARMING axis (feeds its watchdog); 0: off
    reaction_time = Param(0.003)    # s: outputs go out within this of what caused them
    master_node_id = Param(127)     # CiA 402: this node's CANopen node id (its heartbeat's COB-ID 0x700 + id)
    master_heartbeat = Param(0.05)  # CiA 402: s between this node's heartbeats; drives fault after lost_after of them
    velocity_every = Param(1)       # CiA 402: SYNCs between a drive's TPDO2 (velocity actual); 1..240
    link_timeout = Param(0.0)       # s without setpoints (once they came) before the axes go IDLE; 0: off

    # Sized per joint map (see `_sized`); the declarations here are for six joints.
    setpoints = Input(joint_setpoints(6), switching=0)
    can_rx = Input(CAN_FRAME, switching=0)
    estop = Input(Bool, switching=0)
    can_tx = Output(CAN_FRAME, switching=0)
    joint_states = Output(joint_states(6), switching=0)
    joint_status = Output(JOINT_STATUS, size=6, switching=0)
    bad_frame = Output(BAD_FRAME, switching=0)
    arm = Internal(size=6)
    arm_timeout_expired = Internal(size=6)
    heartbeat_lost = Internal(size=6)
    tick = Internal()

    def __new__(cls, name: str | None = None, **params: Any):
        if cls is CanMotor:  # pick the class sized for this joint map
            cls = _sized(len(_joint_map(params.get("joints"))))
        return super().__new__(cls)

    def init(self):
        self.joint_map = _joint_map(self.joints)
        _encodable(self.joint_map)
        self.by_node = {joint.node_id: k for k, joint in enumerate(self.joint_map) if joint.protocol == "odrive"}
        self.period = _check_period("state_period", self.state_period or self.encoder_period)
        self.lost_timeout = _check_period("heartbeat_period", self.heartbeat_period) * _count(self.lost_after)
        self.poll_plan = _poll_plan(self.polls, self.period)
        self.keepalive_ticks = _ticks("keepalive", self.keepalive, self.period)
        if self.skip_unchanged and not self.keepalive_ticks:
            raise ValueError("CanMotor: skip_unchanged needs a keepalive (> 0): an axis holding still would "
                             "get no frame and its watchdog would stop it")
        self.arm_hold_ticks = _ticks("arm_hold", self.arm_hold, self.period)
        self.axes = [Axis(joint.node_id) for joint in self.joint_map]
        if isinstance(self.velocity_every, bool) or not isinstance(self.velocity_every, int) \
                or not 1 <= self.velocity_every <= 240:
            raise ValueError(f"CanMotor: velocity_every must be a whole number of SYNCs 1..240, got {self.velocity_every!r}")
        self.links = {k: Cia402Link(joint, self.master_node_id, self.master_heartbeat, self.lost_after,
                                    self.heartbeat_period, self.velocity_every)
                      for k, joint in enumerate(self.joint_map) if joint.protocol == "cia402"}
        self.co_rx, self.co_host = _canopen_ids(self.joint_map, self.master_node_id) if self.links else ({}, frozenset())
        self.master_ticks = _ticks("master_heartbeat", self.master_heartbeat, self.period) if self.links else 0
        self.reports: list[list[tuple]] = [[] for _ in self.joint_map]  # (event, requested, applied)
        self.tx: deque[Frame] = deque()
        self.bad: list = []
        self.strangers: dict[int, int] = {}  # node id -> frames from it, for no joint of this map
        self.silence_said: set[int] = set()  # axes whose silence was reported (drive_silent)
        self.can_bus_name = getattr(self, "can_bus_name", "")  # set by the launcher, where it knows
        self.estopped = False
        self.ticks = 0
        self.setpoints_tick = -1 << 62  # the tick of the last setpoints message (none yet)
        self.link_ticks = _ticks("link_timeout", self.link_timeout, self.period)
        self.link_lost = False          # the setpoints' source went silent: the axes are held IDLE
        self.states_due = False

    def can_node_ids(self) -> tuple[str, dict[int, str]]:
        """("host", {node id: joint}): the axes this station commands (the system file's check
        refuses two hosts commanding one axis on a bus)."""
        return "host", {joint.node_id: joint.name for joint in self.joint_map}

    # ------------------------------------------------------------------ inputs
    @setpoints.input
    def on_setpoints(self, value):
        if self.link_lost:
            self._link_found()
        if not self.estopped:
            self._command(value)

    @can_rx.input
    def on_can_rx(self, value):
        self._receive(value)

    @estop.input
    def on_estop(self, value):
        if value:
            self._estop()
        else:
            self._reset()

    def final_can_frames(self) -> list:
        """The shutdown hook of the node host (iotad/host/node_host.py): the frames it sends on the
        bus after the engine stopped, before the bus closes: Estop to every axis."""
        frames = [encode(axis.node_id, "Estop") for k, axis in enumerate(self.axes) if k not in self.links]
        if self.links:  # a quick stop, taken at once by the SYNC after it
            frames += [link.quick_stop(self.axes[k].command) for k, link in self.links.items()] + [co.sync()]
        return [frame.to_value() for frame in frames]

    # ------------------------------------------------------------------ arming and timers
    @arm.action(when=lambda self, i: self.axes[i].phase == UNARMED and not self.axes[i].lost and not self.link_lost,
                after=lambda self, i: self.arm_retry if self.axes[i].retry else 0.0)
    def send_arming(self, i):
        self._send_arming(i)

    @arm_timeout_expired.action(when=lambda self, i: self.axes[i].phase == ARMING, after="arm_timeout")
    def on_arm_timeout(self, i):
        if i in self.links:
            self.links[i].abandon()
        self.axes[i].phase = UNARMED
        self.reports[i].append(("ARM_TIMEOUT", 0.0, 0.0))
        if not self.axes[i].heard and i not in self.silence_said:
            self.silence_said.add(i)  # once per axis: a recorded violation, by the joint's name
            raise NodeViolation("drive_silent", _silent_drive(self, i))

    # Restarted by every heartbeat: `beat` is true from a heartbeat until its report is out.
    @heartbeat_lost.action(when=lambda self, i: not self.axes[i].beat and not self.axes[i].lost,
                           after=lambda self, i: self.lost_timeout)
    def on_heartbeat_lost(self, i):
        self.axes[i].lost = True
        self.reports[i].append(("LOST", 0.0, 0.0))

    @tick.action(after=lambda self: self.period)
    def on_tick(self):
        self._tick()

    # ------------------------------------------------------------------ outputs
    @can_tx.action(value=lambda self: self.tx[0].to_value(), when=lambda self: bool(self.tx),
                   within=(0, "reaction_time"))
    def sent_frame(self):
        self.tx.popleft()

    @joint_status.action(value=lambda self, i: _status(i, self.axes[i], self.reports[i][0]),
                         when=lambda self, i: bool(self.reports[i]), within=(0, "reaction_time"))
    def sent_status(self, i):
        self.reports[i].pop(0)
        if not self.reports[i]:
            self.axes[i].beat = False

    @bad_frame.action(value=lambda self: self.bad[0], when=lambda self: bool(self.bad),
                      within=(0, "reaction_time"))
    def sent_bad_frame(self):
        self.bad.pop(0)

    @joint_states.action(value=lambda self: self._joint_states(), when=lambda self: self.states_due,
                         within=(0, "reaction_time"))
    def sent_joint_states(self):
        self.states_due = False

    # ------------------------------------------------------------------ behaviour
    def _send_arming(self, i: int) -> None:
        joint, axis = self.joint_map[i], self.axes[i]
        axis.command = axis.position if joint.mode == "position" else 0.0
        if i in self.links:  # CiA 402: start-up if needed; the controlword follows at every tick
            self.tx.extend(self.links[i].arming())
            axis.phase, axis.retry, axis.last_sent = ARMING, True, self.ticks
            self.reports[i].append(("ARM_SENT", 0.0, 0.0))
            return
        frames = _arming_frames(joint)
        # The hold command before closed loop: the firmware keeps the input velocity and torque it
        # was last given across IDLE (only a position input is reset to where the axis is), so an
        # axis re-armed after a watchdog trip, an estop reset or a restart would resume its last
        # speed or torque until our first setpoint came. A position axis gets one only where it
        # was measured: to an axis still armed (a restarted node) any other position is a move.
        if joint.mode != "position" or axis.has_position:
            frames.insert(-1, _setpoint_frame(joint, axis.command, 0.0, 0.0))
        self.tx.extend(frames)
        axis.phase = ARMING
        axis.retry = True  # until a reset: an axis that fails or drops out is not hammered
        axis.last_sent = self.ticks
        self.reports[i].append(("ARM_SENT", 0.0, 0.0))

    def _command(self, value) -> None:
        self.setpoints_tick = self.ticks
        for i, joint in enumerate(self.joint_map):
            axis = self.axes[i]
            if axis.phase != ARMED:
                continue  # not armed: the firmware would refuse or ignore it
            if joint.mode == "position":
                wanted, low, high = value.position[i], joint.position_min, joint.position_max
            elif joint.mode == "velocity":
                wanted, low, high = value.velocity_ff[i], -joint.velocity_limit, joint.velocity_limit
            else:
                wanted, low, high = value.torque_ff[i], -joint.torque_limit, joint.torque_limit
            applied = wanted
            # the command and its feed-forwards: an infinite one would go out as the frame's
            # largest torque, or as a signal the controller drops with the whole command
            if not (math.isfinite(wanted) and math.isfinite(value.velocity_ff[i])
                    and math.isfinite(value.torque_ff[i])):
                self._report(i, "SETPOINT_REJECTED", wanted, axis.command)
                continue
            if not low <= wanted <= high:
                if joint.out_of_range == "reject":
                    self._report(i, "SETPOINT_REJECTED", wanted, axis.command)
                    continue
                applied = min(max(wanted, low), high)
            try:
                if i in self.links:
                    frame = tuple(self.links[i].setpoint(applied))
                else:
                    frame = _setpoint_frame(joint, applied, value.velocity_ff[i], value.torque_ff[i])
            except EncodeError:  # e.g. a position of 1e300 turns with no limits: no float32 holds it
                self._report(i, "SETPOINT_REJECTED", wanted, axis.command)
                continue
            axis.command = applied
            if applied != wanted:
                self._report(i, "SETPOINT_CLAMPED", wanted, applied)
            if self.skip_unchanged and frame == axis.last_frame and not axis.lost:
                # the axis follows this already; `keepalive` feeds its watchdog (not a LOST
                # axis's: it may still be running, and only the setpoints reach it then)
                continue
            if isinstance(frame, tuple):
                self.tx.extend(frame)
            else:
                self.tx.append(frame)
            axis.last_frame = frame
            axis.last_sent = self.ticks

    def _receive(self, value) -> None:
        try:
            frame = Frame.from_value(value)
        except FrameError:
            self._bad("MALFORMED", value)
            return
        if frame.extended:
            self._bad("EXTENDED_ID", value)
            return
        if self.links:
            k = self.co_rx.get(frame.id)
            if k is not None:
                self._receive_canopen(k, frame, value)
                return
            if frame.id in self.co_host:  # NMT, SYNC or a master's heartbeat: another master
                self._bad("UNEXPECTED", value)
                return
        i = self.by_node.get(node_id_of(frame.id))
        if i is None:
            stranger = node_id_of(frame.id)
            self.strangers[stranger] = self.strangers.get(stranger, 0) + 1
            self._bad("UNKNOWN_NODE", value)
            return
        try:
            message = decode(frame)
        except UnknownFrame:
            self._bad("UNKNOWN_COMMAND", value)
            return
        except MalformedFrame:
            self._bad("WRONG_DLC", value)
            return
        if message.rtr or MESSAGES[message.name].sender == "host":
            self._bad("UNEXPECTED", value)
            return
        signals = message.signals
        if not all(math.isfinite(v) for v in signals.values()) or undefined_values(signals):
            self._bad("BAD_VALUE", value)  # NaN, or an Axis_State no firmware has: not believed
            return
        handler = _HANDLERS.get(message.name)
        if handler is not None:
            handler(self, i, signals)
        # Get_Version, TxSdo, Address, Get_Powers: valid, nothing here uses them

    def _on_heartbeat(self, i: int, signals: dict) -> None:
        axis = self.axes[i]
        previous_error = axis.axis_error
        axis.axis_error = signals["Axis_Error"]
        axis.axis_state = signals["Axis_State"]
        axis.procedure_result = signals["Procedure_Result"]
        axis.trajectory_done = bool(signals["Trajectory_Done_Flag"])
        axis.heard = True
        axis.beat = True
        events = []
        if axis.lost:
            axis.lost = False
            events.append("FOUND")
        closed = axis.axis_state == CLOSED_LOOP
        if axis.phase == ARMING and closed:
            axis.phase = ARMED
            # the firmware holds where it is on entering closed loop: its position, or standing
            # still (0 velocity or torque) for the other modes, as the arming's hold commands
            axis.command = axis.position if self.joint_map[i].mode == "position" else 0.0
            axis.last_frame = None  # its first command goes out whatever it is
            events.append("ARM_DONE")
        elif axis.phase == ARMED and not closed:
            axis.phase = UNARMED if self.auto_rearm else FAULT
            events.append("DISARMED")
        elif axis.phase == ESTOPPED and closed:
            self.tx.append(encode(axis.node_id, "Estop"))  # it missed the Estop (or came back): again
        if axis.axis_error and axis.axis_error != previous_error:
            events.append("AXIS_ERROR")
        for event in events or ["HEARTBEAT"]:
            self.reports[i].append((event, 0.0, 0.0))

    # ------------------------------------------------------------------ CiA 402
    def _receive_canopen(self, i: int, frame: Frame, value) -> None:
        try:
            message = co.decode(frame)
        except co.MalformedFrame:
            self._bad("WRONG_DLC", value)
            return
        except FrameError:
            self._bad("UNKNOWN_COMMAND", value)
            return
        kind, link, axis = message.kind, self.links[i], self.axes[i]
        if kind == "HEARTBEAT":
            self._on_co_heartbeat(i, message.fields["state"])
        elif kind == "EMCY":
            link.error_code = axis.axis_error = message.fields["code"]
            self.reports[i].append(("EMCY", 0.0, 0.0))
        elif kind == "SDO_RESPONSE":
            frames, event = link.on_sdo(message.fields)
            self.tx.extend(frames)
            if event:
                axis.disarm_reason = link.abort_code
                self.reports[i].append((event, 0.0, 0.0))
                if axis.phase == ARMING:  # the start-up failed: another try after arm_retry
                    axis.phase = UNARMED
        elif frame.id in link.tpdo_maps:
            try:
                values = link.unpack(frame)
            except co.MalformedFrame:
                self._bad("WRONG_DLC", value)
                return
            self._on_tpdo(i, values)
        elif kind.startswith("RPDO") or kind == "SDO_REQUEST":
            self._bad("UNEXPECTED", value)  # a master's frame to our drive: another master
        else:
            self._bad("UNKNOWN_COMMAND", value)  # a TPDO this node did not map

    def _on_co_heartbeat(self, i: int, state: str) -> None:
        axis, link = self.axes[i], self.links[i]
        axis.procedure_result = co.NMT_STATE.get(state, 0)
        axis.heard = axis.beat = True
        events = []
        if axis.lost:
            axis.lost = False
            events.append("FOUND")
        if link.on_heartbeat(state):
            events.append("BOOT_UP")
            if axis.phase == ARMED:
                axis.phase = UNARMED if self.auto_rearm else FAULT
                events.append("DISARMED")
            elif axis.phase == ARMING:  # its power-on, or a restart mid-way: start again at once
                axis.phase, axis.retry = UNARMED, False
        for event in events or ["HEARTBEAT"]:
            self.reports[i].append((event, 0.0, 0.0))

    def _on_tpdo(self, i: int, values: dict) -> None:
        joint, axis, link = self.joint_map[i], self.axes[i], self.links[i]
        if 0x6064 in values:
            axis.position = joint.position_of_counts(values[0x6064])
            axis.has_position = True
        if 0x606C in values:
            axis.velocity = joint.velocity_of_counts(values[0x606C])
        if 0x6077 in values:
            axis.torque_estimate = link.torque(values[0x6077])
            axis.effort = joint.torque(axis.torque_estimate)
        if 0x6041 not in values:
            return
        link.statusword = axis.active_errors = values[0x6041]
        axis.axis_state = co.STATE_NUMBER[link.state]
        enabled = link.enabled
        if axis.phase == ARMING and enabled:
            axis.phase = ARMED
            axis.command = axis.position if joint.mode == "position" else 0.0
            axis.last_frame = None
            self.reports[i].append(("ARM_DONE", 0.0, 0.0))
        elif axis.phase == ARMED and not enabled:
            axis.phase = UNARMED if self.auto_rearm else FAULT
            self.reports[i].append(("DISARMED", 0.0, 0.0))
        elif axis.phase == ESTOPPED and enabled:
            self.tx.extend((link.quick_stop(axis.command), co.sync()))  # it missed the quick stop: again

    def _canopen_tick(self) -> None:
        """Each tick: the controlword to every arming drive, this node's heartbeat when due, SYNC."""
        for i, link in self.links.items():
            axis = self.axes[i]
            if axis.phase == ARMING and link.configured and link.statusword >= 0 and not axis.lost:
                hold = axis.position if self.joint_map[i].mode == "position" and axis.has_position else 0.0
                self.tx.append(link.rpdo(link.next_controlword(), hold))
        if self.ticks % self.master_ticks == 0:
            self.tx.append(co.heartbeat(self.master_node_id, "OPERATIONAL"))
        self.tx.append(co.sync())

    def _on_encoder_estimates(self, i: int, signals: dict) -> None:
        joint, axis = self.joint_map[i], self.axes[i]
        axis.position = joint.position(signals["Pos_Estimate"])
        axis.velocity = joint.velocity(signals["Vel_Estimate"])
        axis.has_position = True

    def _on_error(self, i: int, signals: dict) -> None:
        axis = self.axes[i]
        active, reason = signals["Active_Errors"], signals["Disarm_Reason"]
        if (active, reason) != (axis.active_errors, axis.disarm_reason):
            axis.active_errors, axis.disarm_reason = active, reason
            self.reports[i].append(("ERRORS", 0.0, 0.0))

    def _on_torques(self, i: int, signals: dict) -> None:
        axis = self.axes[i]
        axis.torque_estimate = signals["Torque_Estimate"]
        axis.effort = self.joint_map[i].torque(axis.torque_estimate)

    def _on_iq(self, i: int, signals: dict) -> None:
        self.axes[i].iq_measured = signals["Iq_Measured"]

    def _on_temperature(self, i: int, signals: dict) -> None:
        axis = self.axes[i]
        axis.fet_temperature, axis.motor_temperature = signals["FET_Temperature"], signals["Motor_Temperature"]

    def _on_bus(self, i: int, signals: dict) -> None:
        axis = self.axes[i]
        axis.bus_voltage, axis.bus_current = signals["Bus_Voltage"], signals["Bus_Current"]

    def _estop(self) -> None:
        self.estopped = True
        for i, axis in enumerate(self.axes):
            if i in self.links:
                self.tx.append(self.links[i].quick_stop(axis.command))
            else:
                self.tx.append(encode(axis.node_id, "Estop"))
            axis.phase = ESTOPPED
            self.reports[i].append(("ESTOP", 0.0, 0.0))
        if self.links:
            self.tx.append(co.sync())  # the quick stops are taken now, not at the next tick

    def _reset(self) -> None:
        self.estopped = False
        for i, axis in enumerate(self.axes):
            if axis.phase in (ESTOPPED, FAULT):
                axis.phase = UNARMED
                axis.retry = False
                self.reports[i].append(("RESET", 0.0, 0.0))

    def _tick(self) -> None:
        self.ticks += 1
        if self.link_ticks and not self.link_lost and self.ticks - self.setpoints_tick > self.link_ticks \
                and self.setpoints_tick >= 0:
            self._link_lost()
        if self.keepalive_ticks or self.arm_hold_ticks:
            self._keep_alive()
        for name, every in self.poll_plan:
            if self.ticks % every == 0:
                self.tx.extend(request(axis.node_id, name) for k, axis in enumerate(self.axes)
                               if not axis.lost and k not in self.links)
        if self.links:
            self._canopen_tick()
        if all(axis.has_position for axis in self.axes):
            self.states_due = True

    def _link_lost(self) -> None:
        """No setpoints for `link_timeout`: whoever sends them is cut off (or gone), so nothing
        here knows what the arm should do. Every axis that is (or is becoming) armed is told to go
        IDLE at once, rather than left to the firmware's watchdog, which the keep-alive would feed."""
        self.link_lost = True
        for i, axis in enumerate(self.axes):
            if axis.phase in (ARMED, ARMING):
                if i in self.links:
                    self.links[i].abandon()
                    self.tx.append(self.links[i].quick_stop(axis.command))
                else:
                    self.tx.append(encode(axis.node_id, "Set_Axis_State", Axis_Requested_State=AXIS_STATE["IDLE"]))
                axis.phase, axis.link_stopped = FAULT, True
            self.reports[i].append(("LINK_LOST", 0.0, 0.0))
        if self.links:
            self.tx.append(co.sync())  # the quick stops are taken now, not at the next tick

    def _link_found(self) -> None:
        """Setpoints again: the axes the link watch stopped arm again (their arming holds them where
        they are; the first command after it is the setpoint of that moment). Not by `auto_rearm`:
        nothing went wrong with the axis, and the network healing is what the system waits for.
        An axis in FAULT for its own reasons, or estopped meanwhile, stays so until a reset."""
        self.link_lost = False
        for i, axis in enumerate(self.axes):
            if axis.link_stopped and axis.phase == FAULT and not self.estopped:
                axis.phase, axis.retry = UNARMED, False
            axis.link_stopped = False
            self.reports[i].append(("LINK_FOUND", 0.0, 0.0))

    def _keep_alive(self) -> None:
        """Feed the firmware's watchdog. An ARMED axis with no command for `keepalive` gets its last
        command again: without feed-forward if the source went silent (a velocity feed-forward
        would carry the joint on), the very frame it was sent last if it speaks and its setpoint
        is unchanged (`skip_unchanged`). An ARMING axis gets "hold where you are" (the measured
        position, or 0 velocity or torque) every `arm_hold`: the firmware is in closed loop, its
        watchdog running, up to a heartbeat period before its heartbeat says so."""
        for joint, axis in zip(self.joint_map, self.axes):
            if joint.protocol == "cia402":
                continue  # its watchdog is the heartbeat consumer
            every = self.keepalive_ticks if axis.phase == ARMED else self.arm_hold_ticks if axis.phase == ARMING else 0
            if not every or axis.lost or self.ticks - axis.last_sent < every:
                continue
            if axis.phase == ARMING and joint.mode == "position":
                if not axis.has_position:
                    continue
                axis.command = axis.position
            if (axis.phase == ARMED and self.skip_unchanged and axis.last_frame is not None
                    and self.ticks - self.setpoints_tick < every):  # the source speaks, unchanged
                frame = axis.last_frame
            else:
                frame = _setpoint_frame(joint, axis.command, 0.0, 0.0)
            self.tx.append(frame)
            axis.last_frame = frame if axis.phase == ARMED else None
            axis.last_sent = self.ticks

    def _joint_states(self):
        axes = self.axes
        return self.joint_states_type(position=[a.position for a in axes], velocity=[a.velocity for a in axes],
                                      effort=[a.effort for a in axes], stamp=self.ticks * self.period)

    def _report(self, i: int, event: str, requested: float, applied: float) -> None:
        self.reports[i].append((event, _finite(requested), applied))

    def _bad(self, reason: str, value) -> None:
        self.bad.append(BAD_FRAME(reason=reason, frame=value))


def _silent_drive(node: CanMotor, i: int) -> str:
    """The drive_silent violation's words: the joint by name, its node id, the bus, and who talks
    on the bus instead (node ids this node has no joint for)."""
    joint = node.joint_map[i]
    bus = f"bus {node.can_bus_name!r}" if node.can_bus_name else "its bus"
    others = ", ".join(f"node id {k} ({n} frames)" for k, n in sorted(node.strangers.items()))
    return (f"joint {joint.name!r}: its drive (CAN node id {joint.node_id}) on {bus} never answered its arming "
            f"in {node.arm_timeout:g} s; " + (f"talking instead: {others}, which no joint of this node uses"
                                               if others else "nothing else on the bus talks either"))


_HANDLERS = {"Heartbeat": CanMotor._on_heartbeat, "Get_Encoder_Estimates": CanMotor._on_encoder_estimates,
             "Get_Error": CanMotor._on_error, "Get_Torques": CanMotor._on_torques, "Get_Iq": CanMotor._on_iq,
             "Get_Temperature": CanMotor._on_temperature, "Get_Bus_Voltage_Current": CanMotor._on_bus}


def _setpoint_frame(joint: JointConfig, command: float, velocity_ff: float, torque_ff: float) -> Frame:
    """The frame that commands `command` (joint units, in the joint's mode) with feed-forward.
    Feed-forward is limited to the joint's limits and to what the frame can carry, silently."""
    node = joint.node_id
    torque_ff = _saturate(torque_ff, joint.torque_limit)
    if joint.mode == "position":
        velocity_ff = _saturate(velocity_ff, joint.velocity_limit)
        return encode(node, "Set_Input_Pos", Input_Pos=joint.turns(command),
                      Vel_FF=_saturate(joint.turns_per_second(velocity_ff), FF_MAX),
                      Torque_FF=_saturate(joint.motor_torque(torque_ff), FF_MAX))
    if joint.mode == "velocity":
        return encode(node, "Set_Input_Vel", Input_Vel=joint.turns_per_second(command),
                      Input_Torque_FF=joint.motor_torque(torque_ff))
    return encode(node, "Set_Input_Torque", Input_Torque=joint.motor_torque(command))


def _arming_frames(joint: JointConfig) -> list[Frame]:
    """Clear_Errors, the controller mode, the limits, the optional gains, then closed loop."""
    node = joint.node_id
    frames = [encode(node, "Clear_Errors", Identify=0),
              encode(node, "Set_Controller_Mode", Control_Mode=CONTROL_MODE[joint.control_mode],
                     Input_Mode=INPUT_MODE[joint.input_mode]),
              encode(node, "Set_Limits", Velocity_Limit=joint.motor_velocity_limit, Current_Limit=joint.current_limit)]
    if joint.pos_gain is not None:
        frames.append(encode(node, "Set_Pos_Gain", Pos_Gain=joint.pos_gain))
    if joint.vel_gain is not None:
        frames.append(encode(node, "Set_Vel_Gains", Vel_Gain=joint.vel_gain,
                             Vel_Integrator_Gain=joint.vel_integrator_gain))
    if joint.traj_vel_limit is not None:
        frames.append(encode(node, "Set_Traj_Vel_Limit", Traj_Vel_Limit=joint.traj_vel_limit))
    if joint.traj_accel_limit is not None:
        frames.append(encode(node, "Set_Traj_Accel_Limits", Traj_Accel_Limit=joint.traj_accel_limit,
                             Traj_Decel_Limit=joint.traj_decel_limit))
    if joint.traj_inertia is not None:
        frames.append(encode(node, "Set_Traj_Inertia", Traj_Inertia=joint.traj_inertia))
    frames.append(encode(node, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP))
    return frames


def _encodable(joints: tuple[JointConfig, ...]) -> None:
    """Every joint's arming frames can be built: a limit or gain no float32 holds (1e39) is a
    JointMapError when the node is built, not a runtime error at every arming attempt."""
    for joint in joints:
        if joint.protocol == "cia402":
            continue
        try:
            _arming_frames(joint)
        except EncodeError as exc:
            raise JointMapError(f"joint {joint.name}: {exc} (in the frames that arm its axis)") from None


def _status(i: int, axis: Axis, report: tuple):
    event, requested, applied = report
    return JOINT_STATUS(joint=i, node_id=axis.node_id, event=event, phase=axis.phase, lost=axis.lost,
                        axis_state=axis.axis_state, axis_error=axis.axis_error,
                        procedure_result=axis.procedure_result, trajectory_done=axis.trajectory_done,
                        active_errors=axis.active_errors, disarm_reason=axis.disarm_reason,
                        requested=requested, applied=applied, torque_estimate=axis.torque_estimate,
                        iq_measured=axis.iq_measured, fet_temperature=axis.fet_temperature,
                        motor_temperature=axis.motor_temperature, bus_voltage=axis.bus_voltage,
                        bus_current=axis.bus_current)


def _saturate(value: float, limit: float) -> float:
    return value if -limit <= value <= limit else math.copysign(limit, value)


def _finite(value: float) -> float:
    """A value a Float channel can carry: +-inf as the largest float (the event says it was bad)."""
    return value if math.isfinite(value) else math.copysign(FLOAT_MAX, value)


def _joint_map(value: Any) -> tuple[JointConfig, ...]:
    if value is None:
        raise JointMapError("CanMotor needs a joint map: joints = [{ name = \"joint1\", node_id = 1 }, ...] "
                            "(docs/can_motor.md)")
    return parse_joints(value)


def _canopen_ids(joints: tuple[JointConfig, ...], master: int) -> tuple[dict[int, int], frozenset]:
    """({COB-ID: joint index} of every CiA 402 drive's services, the host-side ids: NMT, SYNC, the
    master's heartbeat). An ODrive whose ids (node_id << 5 .. + 31) meet one of them is refused."""
    if isinstance(master, bool) or not isinstance(master, int) or not 1 <= master <= co.NODE_ID_MAX:
        raise ValueError(f"CanMotor: master_node_id must be 1..{co.NODE_ID_MAX}, got {master!r}")
    rx: dict[int, int] = {}
    for k, joint in enumerate(joints):
        if joint.protocol != "cia402":
            continue
        if joint.node_id == master:
            raise JointMapError(f"joint {joint.name}: node_id {master} is this node's own CANopen id "
                                "(master_node_id)")
        rx.update({function + joint.node_id: k for function in co.SERVICES})
    host = frozenset((co.NMT, co.SYNC, co.HEARTBEAT + master))
    for joint in joints:
        if joint.protocol == "odrive":
            ids = set(range(joint.node_id << 5, (joint.node_id << 5) + 32))
            clash = sorted(ids & (set(rx) | host))
            if clash:
                raise JointMapError(f"joint {joint.name}: ODrive node_id {joint.node_id} uses CAN ids "
                                    f"0x{joint.node_id << 5:03X}-0x{(joint.node_id << 5) + 31:03X}, which meet the "
                                    f"CANopen id(s) {', '.join(f'0x{c:03X}' for c in clash[:4])} of this bus's "
                                    "CiA 402 drives (NMT, SYNC, heartbeats, PDOs, SDOs); choose another")
    return rx, host


MIN_PERIOD = 1e-5  # s: 100 kHz, past any CAN bus's frame rate (about 8,000 frames/s at 1 Mbit/s)


def _check_period(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
        raise ValueError(f"CanMotor: {name} must be a positive number of seconds, got {value!r}")
    if value < MIN_PERIOD:  # ticks that crowd the engine's 1 ns grid: a slip of units
        raise ValueError(f"CanMotor: {name} {value!r} s is below {MIN_PERIOD:g} s; no CAN bus carries that")
    return float(value)


def _count(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"CanMotor: lost_after must be a whole number of heartbeat periods >= 1, got {value!r}")
    return value


def _ticks(name: str, seconds: Any, period: float) -> int:
    """Seconds as whole ticks, at least one (0: off)."""
    if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not 0 <= seconds < math.inf:
        raise ValueError(f"CanMotor: {name} must be seconds >= 0 (0: off), got {seconds!r}")
    return max(1, round(seconds / period)) if seconds > 0 else 0


def _poll_plan(polls: Any, period: float) -> tuple[tuple[str, int], ...]:
    """(message, every how many ticks) for each poll; a period rounds to whole ticks, at least one."""
    if not isinstance(polls, dict):
        raise ValueError(f"CanMotor: polls must be a table of message name -> seconds, got {polls!r}")
    plan = []
    for name, seconds in polls.items():
        if name not in POLLABLE:
            raise ValueError(f"CanMotor: polls: {name!r} cannot be polled; one of {', '.join(POLLABLE)}")
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not 0 <= seconds < math.inf:
            raise ValueError(f"CanMotor: polls.{name} must be seconds >= 0 (0: off), got {seconds!r}")
        if seconds > 0:
            plan.append((name, max(1, round(seconds / period))))
    return tuple(plan)


_CLASSES: dict[int, type] = {}


def _sized(joints: int) -> type:
    """The CanMotor class for `joints` joints: its channels typed and sized for that count (a
    spec's channel types are fixed per class, so each joint count gets one class, cached)."""
    cls = _CLASSES.get(joints)
    if cls is None:
        cls = type("CanMotor", (CanMotor,), {
            "__module__": CanMotor.__module__, "__qualname__": "CanMotor", "__doc__": CanMotor.__doc__,
            "joint_states_type": joint_states(joints),
            "setpoints": Input(joint_setpoints(joints), switching=0),
            "joint_states": Output(joint_states(joints), switching=0),
            "joint_status": Output(JOINT_STATUS, size=joints, switching=0),
            "arm": Internal(size=joints), "arm_timeout_expired": Internal(size=joints),
            "heartbeat_lost": Internal(size=joints)})
        _CLASSES[joints] = cls
    return cls
