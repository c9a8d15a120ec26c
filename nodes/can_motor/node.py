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
from iotad.can.burst_bus import CAN_FRAMES
from iotad.can.frame import CAN_FRAME, Frame, FrameError
from iotad.can.odrive import EncodeError
from iotad.kernel.api import Input, Internal, Iota, Output, Param
from iotad.kernel.code_fault import NodeViolation
from iotad.kernel.types import Bool

from .cia402_link import Cia402Link
from .drive_link import ARMED, ARMING, ESTOPPED, FAULT, UNARMED, Axis, DriveLink
from .joint_map import JointConfig, JointMapError, parse_joints
from .odrive_link import OdriveLink

# The drive families by the joint map's `protocol`, in the order their shutdown frames go out.
LINKS: dict[str, type[DriveLink]] = {"odrive": OdriveLink, "cia402": Cia402Link}
FLOAT_MAX = 1.7976931348623157e308

# Messages an axis sends that the node may poll with a remote frame (the `polls` parameter).
POLLABLE = ("Get_Error", "Get_Encoder_Estimates", "Get_Torques", "Get_Iq", "Get_Temperature",
            "Get_Bus_Voltage_Current", "Get_Powers", "Get_Version")

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
    rearm_limit = Param(3)          # auto_rearm: re-arms in a row (each after twice the last wait) before FAULT
    rearm_window = Param(10.0)      # s armed after which an axis's re-arms in a row start again from none
    # True: the frames of one instant (a tick's, a setpoints message's) go out as one `can_tx_burst`
    # output, one firing; False: one `can_tx` output each. `iotad run` sets it on a bus that takes
    # bursts (recording format 2's model, a real bus through the node host), where the file does not.
    tx_bursts = Param(False)

    # Sized per joint map (see `_sized`); the declarations here are for six joints.
    setpoints = Input(joint_setpoints(6), switching=0)
    can_rx = Input(CAN_FRAME, switching=0)
    # the frames a real bus's port received together (its node host, in real time), in their order:
    # one input instead of one per frame, taken exactly as each on can_rx at this instant
    can_rx_burst = Input(CAN_FRAMES, switching=0)
    estop = Input(Bool, switching=0)
    can_tx = Output(CAN_FRAME, switching=0)
    can_tx_burst = Output(CAN_FRAMES, switching=0)  # with tx_bursts: an instant's frames, in order
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
        self.period = _check_period("state_period", self.state_period or self.encoder_period)
        self.lost_timeout = _check_period("heartbeat_period", self.heartbeat_period) * _count(self.lost_after)
        self.poll_plan = _poll_plan(self.polls, self.period)
        self.keepalive_ticks = _ticks("keepalive", self.keepalive, self.period)
        if self.skip_unchanged and not self.keepalive_ticks:
            raise ValueError("CanMotor: skip_unchanged needs a keepalive (> 0): an axis holding still would "
                             "get no frame and its watchdog would stop it")
        self.arm_hold_ticks = _ticks("arm_hold", self.arm_hold, self.period)
        self.axes = [Axis(joint.node_id) for joint in self.joint_map]
        self.links: list[DriveLink] = [LINKS[joint.protocol](self, k) for k, joint in enumerate(self.joint_map)]
        # each family's links, in LINKS order (a family with none is not there)
        self.families = [(cls, links) for cls in LINKS.values()
                         if (links := [link for link in self.links if type(link) is cls])]
        self.routes, self.bus_ids = _routes(self.links, self.families)
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
        if isinstance(self.rearm_limit, bool) or not isinstance(self.rearm_limit, int) or self.rearm_limit < 0:
            raise ValueError(f"CanMotor: rearm_limit must be a whole number >= 0, got {self.rearm_limit!r}")
        _ticks("rearm_window", self.rearm_window, self.period)
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

    @can_rx_burst.input
    def on_can_rx_burst(self, frames):
        for value in frames:
            self._receive(value)

    @estop.input
    def on_estop(self, value):
        if value:
            self._estop()
        else:
            self._reset()

    def final_can_frames(self) -> list:
        """The shutdown hook of the node host (iotad/node_host/node_host.py): the frames it sends on the
        bus after the engine stopped, before the bus closes: Estop to every axis."""
        frames = []
        for cls, links in self.families:
            frames += [frame for link in links for frame in link.stop_frames()] + cls.after_stop_frames(links)
        return [frame.to_value() for frame in frames]

    # ------------------------------------------------------------------ arming and timers
    @arm.action(when=lambda self, i: self.axes[i].phase == UNARMED and not self.axes[i].lost and not self.link_lost,
                after=lambda self, i: self._arm_delay(i))
    def send_arming(self, i):
        self._send_arming(i)

    @arm_timeout_expired.action(when=lambda self, i: self.axes[i].phase == ARMING, after="arm_timeout")
    def on_arm_timeout(self, i):
        self.tx.extend(self.links[i].abandon())
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
        for event in self.links[i].heartbeat_lost():
            self.reports[i].append((event, 0.0, 0.0))

    @tick.action(after=lambda self: self.period)
    def on_tick(self):
        self._tick()

    # ------------------------------------------------------------------ outputs
    @can_tx.action(value=lambda self: self.tx[0].to_value(), when=lambda self: bool(self.tx) and not self.tx_bursts,
                   within=(0, "reaction_time"))
    def sent_frame(self):
        self.tx.popleft()

    # The same frames in the same order, all those waiting in one firing: the bus queues them as
    # if posted one by one at this instant (iotad/can/burst_bus.py), so the wire is the same.
    @can_tx_burst.action(value=lambda self: [frame.to_value() for frame in self.tx],
                         when=lambda self: self.tx_bursts and bool(self.tx), within=(0, "reaction_time"))
    def sent_frames(self):
        self.tx.clear()

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
        self.tx.extend(self.links[i].arming_frames())
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
                frame = self.links[i].setpoint_frames(applied, value.velocity_ff[i], value.torque_ff[i])
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
            self.tx.extend(frame)
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
        k = self.routes.get(frame.id)
        if k is not None:
            self.links[k].receive(frame, value)
        elif frame.id in self.bus_ids:  # NMT, SYNC or a master's heartbeat: another master
            self._bad("UNEXPECTED", value)
        else:
            stranger = self.families[0][0].node_id_of(frame.id)  # counted for drive_silent's words
            self.strangers[stranger] = self.strangers.get(stranger, 0) + 1
            self._bad("UNKNOWN_NODE", value)

    def _arm_delay(self, i: int) -> float:
        """0 for a first arming; `arm_retry` for a retry, doubled for each automatic re-arm in a row."""
        axis = self.axes[i]
        if not axis.retry:
            return 0.0
        return self.arm_retry * 2 ** max(0, axis.rearms - 1)

    # ------------------------------------------------------------------ what the links call
    def send(self, frames) -> None:
        self.tx.extend(frames)

    def report(self, i: int, event: str, requested: float = 0.0, applied: float = 0.0) -> None:
        self.reports[i].append((event, requested, applied))

    def reject_frame(self, reason: str, value) -> None:
        self._bad(reason, value)

    def drive_not_enabled(self, i: int, event: str) -> list[str]:
        """The drive says (or shows by its silence) that it is not enabled, whatever the node last
        commanded: an armed or arming axis is safe at once (no setpoint goes to it, what its link
        had under way is dropped). With `auto_rearm` it arms again after its back-off, at most
        `rearm_limit` times in a row (an axis armed for `rearm_window` starts counting again);
        otherwise, and past the limit, it is in FAULT until a reset. Returns the events: `event`
        (and REARM_LIMIT when auto_rearm gives up)."""
        axis = self.axes[i]
        if axis.phase not in (ARMED, ARMING):
            return [event]
        self.tx.extend(self.links[i].abandon())
        if axis.phase == ARMED and (self.ticks - axis.armed_tick) * self.period >= self.rearm_window:
            axis.rearms = 0
        if self.auto_rearm and axis.rearms < self.rearm_limit:
            axis.phase, axis.retry = UNARMED, True
            axis.rearms += 1
        else:
            axis.phase = FAULT
            if self.auto_rearm:
                return [event, "REARM_LIMIT"]
        return [event]

    def drive_enabled(self, i: int, enabled: bool) -> list[str]:
        """The drive's own account of whether it is enabled (in closed loop, in OPERATION
        ENABLED): the phase follows it. Returns the events it makes, if any."""
        axis = self.axes[i]
        if axis.phase == ARMING and enabled:
            axis.phase, axis.armed_tick = ARMED, self.ticks
            # the drive holds where it is on being enabled: its position, or standing still (0
            # velocity or torque) for the other modes, as the arming's hold commands
            axis.command = axis.position if self.joint_map[i].mode == "position" else 0.0
            axis.last_frame = None  # its first command goes out whatever it is
            return ["ARM_DONE"]
        if axis.phase == ARMED and not enabled:
            return self.drive_not_enabled(i, "DISARMED")
        if axis.phase == ESTOPPED and enabled:  # it missed the stop (or came back): again
            link = self.links[i]
            self.tx.extend(link.stop_frames() + type(link).after_stop_frames([link]))
        return []

    def _estop(self) -> None:
        self.estopped = True
        for i, axis in enumerate(self.axes):
            self.tx.extend(self.links[i].stop_frames())
            axis.phase = ESTOPPED
            self.reports[i].append(("ESTOP", 0.0, 0.0))
        self._after_stop()

    def _reset(self) -> None:
        self.estopped = False
        for i, axis in enumerate(self.axes):
            if axis.phase in (ESTOPPED, FAULT):
                axis.phase = UNARMED
                axis.retry = False
                axis.rearms = 0
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
                for link in self.links:
                    if not link.axis.lost:
                        self.tx.extend(link.poll_frames(name))
        for link in self.links:
            self.tx.extend(link.tick_frames())
        for cls, links in self.families:
            self.tx.extend(cls.bus_tick_frames(links, self.ticks))
        if all(axis.has_position for axis in self.axes):
            self.states_due = True

    def _link_lost(self) -> None:
        """No setpoints for `link_timeout`: whoever sends them is cut off (or gone), so nothing
        here knows what the arm should do. Every axis that is (or is becoming) armed is told to go
        IDLE at once, rather than left to the firmware's watchdog, which the keep-alive would feed."""
        self.link_lost = True
        for i, axis in enumerate(self.axes):
            if axis.phase in (ARMED, ARMING):
                self.tx.extend(self.links[i].idle_frames())
                axis.phase, axis.link_stopped = FAULT, True
            self.reports[i].append(("LINK_LOST", 0.0, 0.0))
        self._after_stop()

    def _after_stop(self) -> None:
        """What each family sends once after its axes were stopped (CiA 402: a SYNC, so that the
        quick stops are taken now, not at the next tick)."""
        for cls, links in self.families:
            self.tx.extend(cls.after_stop_frames(links))

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
        for joint, axis, link in zip(self.joint_map, self.axes, self.links):
            if not link.feeds_watchdog:
                continue  # it watches the node another way (CiA 402: its heartbeat consumer)
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
                frame = link.setpoint_frames(axis.command, 0.0, 0.0)
            self.tx.extend(frame)
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


def _status(i: int, axis: Axis, report: tuple):
    event, requested, applied = report
    return JOINT_STATUS(joint=i, node_id=axis.node_id, event=event, phase=axis.phase, lost=axis.lost,
                        axis_state=axis.axis_state, axis_error=axis.axis_error,
                        procedure_result=axis.procedure_result, trajectory_done=axis.trajectory_done,
                        active_errors=axis.active_errors, disarm_reason=axis.disarm_reason,
                        error_register=axis.error_register,
                        requested=requested, applied=applied, torque_estimate=axis.torque_estimate,
                        iq_measured=axis.iq_measured, fet_temperature=axis.fet_temperature,
                        motor_temperature=axis.motor_temperature, bus_voltage=axis.bus_voltage,
                        bus_current=axis.bus_current)


def _finite(value: float) -> float:
    """A value a Float channel can carry: +-inf as the largest float (the event says it was bad)."""
    return value if math.isfinite(value) else math.copysign(FLOAT_MAX, value)


def _joint_map(value: Any) -> tuple[JointConfig, ...]:
    if value is None:
        raise JointMapError("CanMotor needs a joint map: joints = [{ name = \"joint1\", node_id = 1 }, ...] "
                            "(docs/can_motor.md)")
    return parse_joints(value)


def _silent_drive(node: CanMotor, i: int) -> str:
    """The drive_silent violation's words: the joint by name, its node id, the bus, and who talks
    on the bus instead (node ids this node has no joint for)."""
    joint = node.joint_map[i]
    bus = f"bus {node.can_bus_name!r}" if node.can_bus_name else "its bus"
    others = ", ".join(f"node id {k} ({n} frames)" for k, n in sorted(node.strangers.items()))
    return (f"joint {joint.name!r}: its drive (CAN node id {joint.node_id}) on {bus} never answered its arming "
            f"in {node.arm_timeout:g} s; " + (f"talking instead: {others}, which no joint of this node uses"
                                               if others else "nothing else on the bus talks either"))


def _routes(links: list[DriveLink], families) -> tuple[dict[int, int], frozenset]:
    """({frame id: joint index} of the frames each drive sends, the ids the families' master side
    sends to the whole bus). Two drives whose ids meet, or a drive on a master's id, are refused."""
    routes: dict[int, int] = {}
    bus_ids = frozenset().union(*(cls.bus_ids(links_of) for cls, links_of in families))
    for k, link in enumerate(links):
        ids = list(link.frame_ids())
        clash = sorted(frame_id for frame_id in ids if frame_id in routes or frame_id in bus_ids)
        if clash:
            other = next((links[routes[c]].joint.name for c in clash if c in routes), None)
            joint = link.joint
            raise JointMapError(
                f"joint {joint.name}: {joint.protocol} node_id {joint.node_id} uses CAN ids "
                f"{', '.join(f'0x{c:03X}' for c in clash[:4])}, which "
                + (f"joint {other} uses too" if other else "this node sends to the whole bus (NMT, SYNC, its heartbeat)")
                + "; choose another node_id")
        routes.update((frame_id, k) for frame_id in ids)
    return routes, bus_ids


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
