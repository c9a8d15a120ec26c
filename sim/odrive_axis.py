"""One simulated ODrive axis (firmware 0.6 over CAN Simple), as plain Python: no PyBullet, no IOTA.

The axis speaks the protocol from the controller's side: it takes decoded host messages
(`handle`), runs its cascaded control loop once per control step (`update`: position in turns
and velocity in turns/s in, motor torque in Nm out, or None when the motor is off), and builds
the frames it sends (`heartbeat`, `encoder_estimates`, and the answers to remote requests).

What it models of the firmware, and where it simplifies (docs/simulation.md has the table):
- States: IDLE and CLOSED_LOOP_CONTROL. Calibration requests succeed at once (the simulated
  motor is calibrated); any other state is refused with procedure result INVALID_STATE.
- Errors are 0.6 `ODrive.Error` flags (iotad.can.odrive.AXIS_ERROR). A fault disarms the axis
  (IDLE) and latches in `disarm_reason`; `active_errors` holds the faults not yet cleared.
  Heartbeat.Axis_Error is their OR, as the firmware sends it. Clear_Errors clears both; it does
  not re-arm. Closed loop asked for while an error is latched is refused (procedure DISARMED).
- Watchdog (`watchdog_timeout` > 0): every frame addressed to the axis feeds it, remote requests
  and frames it ignores included, as the firmware's CAN handler does (can_simple.cpp do_command
  feeds it before it looks at the command): a host that polls keeps it fed. Entering closed loop feeds it. No
  command for longer than the timeout while armed: IDLE with WATCHDOG_TIMER_EXPIRED. It is
  checked at every control step, so it trips at most one step after the timeout.
- Controller: input modes INACTIVE, PASSTHROUGH, VEL_RAMP, POS_FILTER, TORQUE_RAMP and TRAP_TRAJ
  (the firmware's trapezoidal planner, sim/trap_traj.py, with the Set_Traj_* limits); control
  modes TORQUE, VELOCITY, POSITION (VOLTAGE, MIRROR... are refused as BAD_CONFIG).
  Position P loop -> velocity PI loop -> torque, the shape of the open 0.5 firmware's
  controller.cpp: velocity limited to vel_limit, torque to current_limit * torque_constant, the
  integrator decays while the torque saturates; torque mode limits torque near vel_limit.
- Remote requests, as ODrive's CAN protocol documents them ("Messages prefixed with Get_ ... can
  be enabled as Cyclic Messages or requested explicitly by the master ... with the RTR bit set,
  and the ODrive responds with the same ID and corresponding payload", docs.odriverobotics.com,
  CAN Protocol, firmware 0.6): the Get_ messages and Address are answered at once; Heartbeat is
  not a Get_ message and is not answered (its state is the cyclic heartbeat's to tell: `iotad
  can` reads it from there). The request still feeds the watchdog, as every frame does.
- Units are the axis's: turns, turns/s, Nm at the motor. Mapping to a joint is the caller's.
"""
from __future__ import annotations

import math
import struct
from dataclasses import dataclass, fields

from iotad.can.frame import Frame
from iotad.can.odrive import (AXIS_ERROR, AXIS_STATE, COMMANDS, CONTROL_MODE, INPUT_MODE, MESSAGES,
                              PROCEDURE_RESULT, Message, encode, frame_id)

from .trap_traj import plan

IDLE = AXIS_STATE["IDLE"]
CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]
CALIBRATION_STATES = frozenset(AXIS_STATE[name] for name in (
    "FULL_CALIBRATION_SEQUENCE", "MOTOR_CALIBRATION", "ENCODER_OFFSET_CALIBRATION", "ENCODER_INDEX_SEARCH",
    "ENCODER_DIR_FIND"))

TORQUE, VELOCITY, POSITION = CONTROL_MODE["TORQUE"], CONTROL_MODE["VELOCITY"], CONTROL_MODE["POSITION"]
SUPPORTED_CONTROL_MODES = frozenset((TORQUE, VELOCITY, POSITION))
INACTIVE, PASSTHROUGH = INPUT_MODE["INACTIVE"], INPUT_MODE["PASSTHROUGH"]
VEL_RAMP, POS_FILTER, TORQUE_RAMP = INPUT_MODE["VEL_RAMP"], INPUT_MODE["POS_FILTER"], INPUT_MODE["TORQUE_RAMP"]
TRAP_TRAJ = INPUT_MODE["TRAP_TRAJ"]
SUPPORTED_INPUT_MODES = frozenset((INACTIVE, PASSTHROUGH, VEL_RAMP, POS_FILTER, TORQUE_RAMP, TRAP_TRAJ))
# the firmware's defaults of trap_traj.config and controller.config.inertia
TRAJ_DEFAULTS = {"Traj_Vel_Limit": 2.0, "Traj_Accel_Limit": 0.5, "Traj_Decel_Limit": 0.5, "Traj_Inertia": 0.0}

WATCHDOG_TIMER_EXPIRED = AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]
ESTOP_REQUESTED = AXIS_ERROR["ESTOP_REQUESTED"]
BAD_CONFIG = AXIS_ERROR["BAD_CONFIG"]
VELOCITY_LIMIT_VIOLATION = AXIS_ERROR["VELOCITY_LIMIT_VIOLATION"]

SUCCESS, DISARMED, INVALID_STATE = (PROCEDURE_RESULT[name] for name in ("SUCCESS", "DISARMED", "INVALID_STATE"))

# What Get_Version answers: protocol 2, ODrive Pro 4.4.58, firmware 0.6.10 (the DBC's version).
VERSION = dict(Protocol_Version=2, Hw_Version_Major=4, Hw_Version_Minor=4, Hw_Version_Variant=58,
               Fw_Version_Major=0, Fw_Version_Minor=6, Fw_Version_Revision=10, Fw_Version_Unreleased=0)
BUS_VOLTAGE = 24.0  # V, a bench supply: Get_Bus_Voltage_Current answers with it
INTEGRATOR_DECAY = 0.99  # per step while the torque saturates, as the firmware does

# The two cyclic messages packed directly: they are most of an axis's traffic, and `encode` walks
# the signal table. Same bytes as encode() (tests/sim compare them): Heartbeat is Axis_Error u32,
# Axis_State u8, Procedure_Result u8, Trajectory_Done_Flag in bit 48, one padding byte.
_HEARTBEAT = struct.Struct("<IBBBx")
_ENCODER = struct.Struct("<ff")


@dataclass(frozen=True)
class AxisConfig:
    """An axis's configuration (what odrivetool would set), in the firmware's units."""

    pos_gain: float = 20.0               # (turn/s) / turn
    vel_gain: float = 1.0 / 6.0          # Nm / (turn/s)
    vel_integrator_gain: float = 1.0 / 3.0  # Nm / turn, i.e. Nm / (turn/s * s)
    vel_limit: float = 2.0               # turn/s
    current_limit: float = 10.0          # A
    torque_constant: float = 1.0         # Nm/A: with 1, a Current_Limit in A reads as Nm
    watchdog_timeout: float = 0.0        # s; 0 = watchdog off (the firmware's default)
    vel_ramp_rate: float = 1.0           # turn/s^2, INPUT_MODE VEL_RAMP
    torque_ramp_rate: float = 0.01       # Nm/s, INPUT_MODE TORQUE_RAMP
    input_filter_bandwidth: float = 2.0  # 1/s, INPUT_MODE POS_FILTER
    inertia: float = 0.0                 # Nm/(turn/s^2): torque feed-forward of the ramps and filter
    enable_overspeed_error: bool = False  # the firmware's default is on; off here, see docs/simulation.md
    vel_limit_tolerance: float = 1.2     # overspeed trips above this times vel_limit
    control_mode: int = POSITION         # at power-up
    input_mode: int = PASSTHROUGH

    def __post_init__(self):
        for f in fields(self):
            value = getattr(self, f.name)
            if isinstance(value, bool) or f.name in ("control_mode", "input_mode"):
                continue
            if not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"axis config {f.name} must be a finite number >= 0, got {value!r}")
        if self.control_mode not in SUPPORTED_CONTROL_MODES:
            raise ValueError(f"axis config control_mode {self.control_mode!r} is not one of "
                             f"{_names(CONTROL_MODE, SUPPORTED_CONTROL_MODES)}")
        if self.input_mode not in SUPPORTED_INPUT_MODES:
            raise ValueError(f"axis config input_mode {self.input_mode!r} is not one of "
                             f"{_names(INPUT_MODE, SUPPORTED_INPUT_MODES)}")


def _names(table: dict[str, int], numbers) -> str:
    return ", ".join(f"{name} ({n})" for name, n in table.items() if n in numbers)


def _float32(value: float) -> float:
    """What a float32 signal can carry: huge values saturate instead of failing to pack."""
    return value if -3.4e38 < value < 3.4e38 else math.copysign(3.4e38, value) if value == value else value


def _clamp(value: float, low: float, high: float) -> float:
    return low if value < low else high if value > high else value


class OdriveAxis:
    """One axis: its state machine, controller and CAN answers. `now` is the caller's clock (s)."""

    def __init__(self, node_id: int, config: AxisConfig | None = None):
        if isinstance(node_id, bool) or not isinstance(node_id, int) or not 0 <= node_id <= 0x3F:
            raise ValueError(f"ODrive node id must be 0..63, got {node_id!r}")
        self.node_id = node_id
        self._heartbeat_id = frame_id(node_id, COMMANDS["Heartbeat"])
        self._encoder_id = frame_id(node_id, COMMANDS["Get_Encoder_Estimates"])
        self.initial_config = config or AxisConfig()
        self.ignored: list[str] = []   # why frames were ignored (kept short: the last 100)
        self._power_up()

    def _power_up(self) -> None:
        config = self.initial_config
        self.config = config
        self.state = IDLE
        self.active_errors = 0
        self.disarm_reason = 0
        self.procedure_result = SUCCESS
        self.control_mode = config.control_mode
        self.input_mode = config.input_mode
        self.pos_gain, self.vel_gain = config.pos_gain, config.vel_gain
        self.vel_integrator_gain = config.vel_integrator_gain
        self.vel_limit, self.current_limit = config.vel_limit, config.current_limit
        self.input_pos = self.input_vel = self.input_torque = 0.0
        self.pos_setpoint = self.vel_setpoint = self.torque_setpoint = 0.0
        self.integrator = 0.0
        self.torque_target = 0.0
        self.pos_estimate = self.vel_estimate = 0.0
        self.position_offset = 0.0     # Set_Absolute_Position: estimate = measured + offset
        self.traj_limits = dict(TRAJ_DEFAULTS)
        self.inertia = config.inertia  # controller.config.inertia: Set_Traj_Inertia sets it
        self.trajectory = None         # TRAP_TRAJ: the move planned at the last Set_Input_Pos
        self.trajectory_time = 0.0
        self.trajectory_done = True    # Heartbeat's Trajectory_Done_Flag, as the firmware starts
        self.input_pos_updated = False
        self.last_command = -math.inf  # when the watchdog was last fed

    # ------------------------------------------------------------------ state
    @property
    def armed(self) -> bool:
        return self.state == CLOSED_LOOP

    @property
    def axis_error(self) -> int:
        """What Heartbeat.Axis_Error carries: active errors | disarm reason."""
        return self.active_errors | self.disarm_reason

    def fault(self, error: int) -> None:
        """A fault: the error is set and latched, and an armed axis disarms (goes IDLE)."""
        self.active_errors |= error
        self.disarm_reason |= error
        self.state = IDLE
        self.torque_target = 0.0

    def _ignore(self, why: str) -> list[Frame]:
        self.ignored.append(why)
        del self.ignored[:-100]
        return []

    # ------------------------------------------------------------------ CAN in
    def handle(self, message: Message, now: float) -> list[Frame]:
        """Act on one decoded message addressed to this axis; return the frames it answers with."""
        self.last_command = now  # any frame to the axis feeds the watchdog, as the firmware's CAN handler does
        spec = MESSAGES[message.name]
        if message.rtr:
            if message.name == "Heartbeat":  # cyclic only: the protocol's requestable messages are Get_*
                return self._ignore("remote request for Heartbeat, which the firmware sends only cyclically")
            if spec.sender in ("axis", "both"):
                return [self.reply(message.name)]
            return self._ignore(f"remote request for {message.name}, a host command")
        if spec.sender == "axis":
            # the same id with data is another device's answer (a node id clash), not for us
            return self._ignore(f"{message.name} with data: an axis's message, not a command")
        values = message.signals
        for name, value in values.items():
            if isinstance(value, float) and not math.isfinite(value):
                return self._ignore(f"{message.name}: {name}={value} is not a finite number")
        handler = getattr(self, "_on_" + message.name, None)
        if handler is None:
            return self._ignore(f"{message.name} is not simulated")
        return handler(values, now) or []

    def _on_Set_Axis_State(self, values: dict, now: float) -> None:
        requested = values["Axis_Requested_State"]
        if requested == IDLE:
            self.state = IDLE
            self.torque_target = 0.0
            self.procedure_result = SUCCESS
        elif requested == CLOSED_LOOP:
            if self.axis_error:
                self.procedure_result = DISARMED  # refused: errors must be cleared first
                return
            if not self.armed:
                self._arm(now)
            self.procedure_result = SUCCESS
        elif requested in CALIBRATION_STATES and not self.armed:
            self.procedure_result = SUCCESS  # the simulated motor and encoder are calibrated
        else:
            self.procedure_result = INVALID_STATE

    def _arm(self, now: float) -> None:
        # As the firmware does on entering closed loop (axis.cpp start_closed_loop_control,
        # controller.cpp control_mode_updated): a position input is reset to where the axis is and
        # the integrator cleared; the input velocity and torque it was last given are kept, and
        # drive it (a host re-arming an axis sends its hold command first: nodes/can_motor does)
        self.state = CLOSED_LOOP
        if self.control_mode == POSITION:
            self.input_pos = self.pos_setpoint = self.pos_estimate
            self.input_pos_updated = True  # in TRAP_TRAJ: a move of no length, to where it is
        self.integrator = 0.0
        self.last_command = now

    def _on_Estop(self, values: dict, now: float) -> None:
        self.fault(ESTOP_REQUESTED)

    def _on_Clear_Errors(self, values: dict, now: float) -> None:
        self.active_errors = 0
        self.disarm_reason = 0
        self.procedure_result = SUCCESS

    def _on_Set_Controller_Mode(self, values: dict, now: float) -> None:
        control, input_mode = values["Control_Mode"], values["Input_Mode"]
        if control not in SUPPORTED_CONTROL_MODES or input_mode not in SUPPORTED_INPUT_MODES:
            self._ignore(f"Set_Controller_Mode: unsupported Control_Mode={control} Input_Mode={input_mode}")
            self.fault(BAD_CONFIG)
            return
        self.control_mode, self.input_mode = control, input_mode

    def _on_Set_Input_Pos(self, values: dict, now: float) -> None:
        self.input_pos = values["Input_Pos"]
        self.input_pos_updated = True  # TRAP_TRAJ plans a move to it at the next control step
        self.input_vel = values["Vel_FF"]
        self.input_torque = values["Torque_FF"]

    def _on_Set_Input_Vel(self, values: dict, now: float) -> None:
        self.input_vel = values["Input_Vel"]
        self.input_torque = values["Input_Torque_FF"]

    def _on_Set_Input_Torque(self, values: dict, now: float) -> None:
        self.input_torque = values["Input_Torque"]

    def _on_Set_Limits(self, values: dict, now: float) -> list[Frame]:
        vel_limit, current_limit = values["Velocity_Limit"], values["Current_Limit"]
        if vel_limit < 0 or current_limit < 0:
            return self._ignore(f"Set_Limits: negative limit (Velocity_Limit={vel_limit}, Current_Limit={current_limit})")
        self.vel_limit, self.current_limit = vel_limit, current_limit
        return []

    def _on_Set_Pos_Gain(self, values: dict, now: float) -> None:
        self.pos_gain = values["Pos_Gain"]

    def _on_Set_Vel_Gains(self, values: dict, now: float) -> None:
        self.vel_gain, self.vel_integrator_gain = values["Vel_Gain"], values["Vel_Integrator_Gain"]

    def _on_Set_Absolute_Position(self, values: dict, now: float) -> None:
        shift = values["Position"] - self.pos_estimate
        self.position_offset += shift
        self.pos_estimate += shift
        # the setpoints move with the frame of reference, so an armed axis does not jump
        self.input_pos += shift
        self.pos_setpoint += shift

    def _traj(self, values: dict, now: float) -> None:
        self.traj_limits.update(values)  # the next move planned uses them, as the firmware's
        self.inertia = self.traj_limits["Traj_Inertia"] if "Traj_Inertia" in values else self.inertia

    _on_Set_Traj_Vel_Limit = _on_Set_Traj_Accel_Limits = _on_Set_Traj_Inertia = _traj

    def _on_Reboot(self, values: dict, now: float) -> list[Frame]:
        if values["Action"] != 0:
            return self._ignore(f"Reboot Action={values['Action']}: only a plain reboot (0) is simulated")
        self._power_up()
        return []

    # ------------------------------------------------------------------ control
    def update(self, position: float, velocity: float, now: float, dt: float) -> float | None:
        """One control step: the measured position (turns) and velocity (turns/s) in; the motor
        torque (Nm) out, or None when the motor is off (IDLE)."""
        self.pos_estimate = position + self.position_offset
        self.vel_estimate = velocity
        if not self.armed:
            self.torque_target = 0.0
            return None
        config = self.config
        if config.watchdog_timeout > 0 and now - self.last_command > config.watchdog_timeout:
            self.fault(WATCHDOG_TIMER_EXPIRED)
            return None
        if config.enable_overspeed_error and abs(velocity) > config.vel_limit_tolerance * self.vel_limit:
            self.fault(VELOCITY_LIMIT_VIOLATION)
            return None
        self._update_setpoints(dt)
        mode = self.control_mode
        vel_wanted = self.vel_setpoint
        if mode == POSITION:
            vel_wanted += self.pos_gain * (self.pos_setpoint - self.pos_estimate)
        torque = self.torque_setpoint
        vel_error = 0.0
        if mode >= VELOCITY:
            vel_wanted = _clamp(vel_wanted, -self.vel_limit, self.vel_limit)
            vel_error = vel_wanted - velocity
            torque += self.vel_gain * vel_error + self.integrator
        else:
            # torque mode: the firmware cuts torque that would drive the motor past vel_limit
            torque = _clamp(torque, (-self.vel_limit - velocity) * self.vel_gain,
                            (self.vel_limit - velocity) * self.vel_gain)
        limit = self.current_limit * config.torque_constant
        limited = not -limit <= torque <= limit
        if limited:
            torque = _clamp(torque, -limit, limit)
        if mode < VELOCITY:
            self.integrator = 0.0
        elif limited:
            self.integrator *= INTEGRATOR_DECAY
        else:
            self.integrator += self.vel_integrator_gain * dt * vel_error
        self.torque_target = torque
        return torque

    def _update_setpoints(self, dt: float) -> None:
        mode = self.input_mode
        if mode == PASSTHROUGH:
            self.pos_setpoint, self.vel_setpoint = self.input_pos, self.input_vel
            self.torque_setpoint = self.input_torque
        elif mode == VEL_RAMP:
            most = self.config.vel_ramp_rate * dt
            step = _clamp(self.input_vel - self.vel_setpoint, -most, most)
            self.vel_setpoint += step
            self.torque_setpoint = self.input_torque + step / dt * self.inertia
        elif mode == POS_FILTER:
            # a critically damped second-order filter toward input_pos (the firmware's gains)
            ki = 2.0 * self.config.input_filter_bandwidth
            kp = 0.25 * ki * ki
            accel = kp * (self.input_pos - self.pos_setpoint) + ki * (self.input_vel - self.vel_setpoint)
            self.torque_setpoint = self.input_torque + accel * self.inertia
            self.vel_setpoint += dt * accel
            self.pos_setpoint += dt * self.vel_setpoint
        elif mode == TORQUE_RAMP:
            most = self.config.torque_ramp_rate * dt
            self.torque_setpoint += _clamp(self.input_torque - self.torque_setpoint, -most, most)
        elif mode == TRAP_TRAJ:
            self._follow_trajectory(dt)
        # INACTIVE: the setpoints stay as they are

    def _follow_trajectory(self, dt: float) -> None:
        # as the firmware's controller does in TRAP_TRAJ: a new input position plans a move from
        # where the setpoint is (position and velocity); the setpoints follow it, with the
        # acceleration times the inertia as torque feed-forward; at its end it holds the goal
        if self.input_pos_updated:
            limits = self.traj_limits
            self.trajectory = plan(self.input_pos, self.pos_setpoint, self.vel_setpoint, limits["Traj_Vel_Limit"],
                                   limits["Traj_Accel_Limit"], limits["Traj_Decel_Limit"])
            self.trajectory_time = 0.0
            self.trajectory_done = False
            self.input_pos_updated = False
        if self.trajectory_done or self.trajectory is None:
            return
        if self.trajectory_time > self.trajectory.tf:
            self.pos_setpoint, self.vel_setpoint, self.torque_setpoint = self.trajectory.xf, 0.0, 0.0
            self.trajectory_done = True
            return
        position, velocity, acceleration = self.trajectory.eval(self.trajectory_time)
        self.pos_setpoint, self.vel_setpoint = position, velocity
        self.torque_setpoint = acceleration * self.inertia
        self.trajectory_time += dt

    # ------------------------------------------------------------------ CAN out
    def heartbeat(self) -> Frame:
        return Frame(self._heartbeat_id, _HEARTBEAT.pack(self.axis_error, self.state, self.procedure_result,
                                                         int(self.trajectory_done)))

    def encoder_estimates(self) -> Frame:
        return Frame(self._encoder_id, _ENCODER.pack(_float32(self.pos_estimate), _float32(self.vel_estimate)))

    def reply(self, name: str) -> Frame:
        """The data frame answering a remote request for message `name` (an axis's message)."""
        node = self.node_id
        torque_constant = self.config.torque_constant or 1.0
        mechanical = self.torque_target * self.vel_estimate * 2 * math.pi
        if name == "Heartbeat":
            return self.heartbeat()
        if name == "Get_Encoder_Estimates":
            return self.encoder_estimates()
        if name == "Get_Error":
            return encode(node, name, Active_Errors=self.active_errors, Disarm_Reason=self.disarm_reason)
        if name == "Get_Version":
            return encode(node, name, **VERSION)
        if name == "Get_Iq":
            current = self.torque_target / torque_constant
            return encode(node, name, Iq_Setpoint=current, Iq_Measured=current)
        if name == "Get_Torques":
            return encode(node, name, Torque_Target=self.torque_target, Torque_Estimate=self.torque_target)
        if name == "Get_Powers":  # a lossless motor
            return encode(node, name, Electrical_Power=mechanical, Mechanical_Power=mechanical)
        if name == "Get_Bus_Voltage_Current":
            return encode(node, name, Bus_Voltage=BUS_VOLTAGE, Bus_Current=mechanical / BUS_VOLTAGE)
        if name == "Get_Temperature":
            return encode(node, name, FET_Temperature=25.0, Motor_Temperature=25.0)
        if name == "Address":
            return encode(node, name, Node_ID=node, Serial_Number=0x5100_0000 + node)
        # TxSdo: arbitrary endpoints are not simulated; answer with a zero value
        return encode(node, name)
