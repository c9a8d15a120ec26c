"""The CAN motor node's joint map: which ODrive axis drives each joint, and how joint units map to motor units.

A joint's position q (rad), velocity (rad/s) and torque (Nm) map to the axis's turns, turns/s
and motor Nm as

    turns       = direction * gear_ratio * (q - offset) / (2 pi)
    turns/s     = direction * gear_ratio * qdot / (2 pi)
    motor Nm    = direction * tau / gear_ratio                (an ideal gearbox)

so `offset` is the joint angle at which the motor reads 0 turns, `direction` (+1/-1) flips the
motor's sense, and `gear_ratio` is motor turns per joint turn. Feedback maps back by the inverse.

The map is a parameter of the node: a list of tables (each with a `name`), a table keyed by joint
name, or the same as a JSON string. Every problem is a `JointMapError` (a ValueError) whose
message names the joint and the key.
"""
from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass, fields
from typing import Any

from iotad.can.canopen import NODE_ID_MAX as CANOPEN_NODE_ID_MAX
from iotad.can.odrive import INPUT_MODE, NODE_ID_MAX

TAU = 2.0 * math.pi
MODES = ("position", "velocity", "torque")
OUT_OF_RANGE = ("reject", "clamp")
PROTOCOLS = ("odrive", "cia402")
OPERATION_MODES = {"position": ("csp", "pp"), "velocity": ("csv",), "torque": ()}  # CiA 402, by the joint's mode


class JointMapError(ValueError):
    """The joint map parameter is not usable; `str()` says which joint and key, and why."""


@dataclass(frozen=True)
class JointConfig:
    name: str
    node_id: int
    direction: int = 1
    gear_ratio: float = 1.0          # motor turns per joint turn
    offset: float = 0.0              # rad: the joint angle where the motor reads 0 turns
    position_min: float = -math.inf  # rad
    position_max: float = math.inf   # rad
    velocity_limit: float = math.pi  # rad/s at the joint; Set_Limits gets it in motor turns/s
    torque_limit: float = math.inf   # Nm at the joint, for torque commands and feed-forward
    current_limit: float = 10.0      # A, Set_Limits
    mode: str = "position"           # position | velocity | torque
    input_mode: str = "PASSTHROUGH"  # an ODrive INPUT_MODE name
    out_of_range: str = "reject"     # reject | clamp
    # Optional controller settings sent while arming, in the controller's units (None: not sent).
    pos_gain: float | None = None             # (turns/s)/turn, Set_Pos_Gain
    vel_gain: float | None = None             # Nm/(turns/s), Set_Vel_Gains (with the integrator gain)
    vel_integrator_gain: float | None = None  # Nm/turn
    traj_vel_limit: float | None = None       # turns/s, Set_Traj_Vel_Limit
    traj_accel_limit: float | None = None     # turns/s^2, Set_Traj_Accel_Limits (with the decel limit)
    traj_decel_limit: float | None = None     # turns/s^2
    traj_inertia: float | None = None         # Nm/(turns/s^2), Set_Traj_Inertia
    # CiA 402 drives (protocol = "cia402"): docs/can_motor.md, "CiA 402 drives"
    protocol: str = "odrive"                  # odrive (CAN Simple) | cia402 (CANopen)
    operation_mode: str = ""                  # csp | pp (position), csv (velocity); "": csp or csv
    counts_per_turn: float = 65536.0          # the drive's increments per motor turn (its 0x608F)
    acceleration_limit: float = 10.0          # rad/s^2 at the joint: Profile Position's acceleration
    tpdo_timeout: int = 3                     # SYNCs without a statusword (TPDO1) before the drive is LOST
    rated_torque: float | None = None         # Nm, the motor's rated torque if the table states it (0x6076 / 1000)
    explicit: frozenset = frozenset()         # the keys the joint map gave (a scale it states is checked)

    # --- CiA 402: joint units -> drive increments, and back ------------------------------------
    def counts(self, position: float) -> float:
        return self.turns(position) * self.counts_per_turn

    def counts_per_second(self, velocity: float) -> float:
        return self.turns_per_second(velocity) * self.counts_per_turn

    def position_of_counts(self, counts: float) -> float:
        return self.position(counts / self.counts_per_turn)

    def velocity_of_counts(self, counts_per_second: float) -> float:
        return self.velocity(counts_per_second / self.counts_per_turn)

    # --- joint units -> motor units -------------------------------------------------------------
    def turns(self, position: float) -> float:
        return self.direction * self.gear_ratio * (position - self.offset) / TAU

    def turns_per_second(self, velocity: float) -> float:
        return self.direction * self.gear_ratio * velocity / TAU

    def motor_torque(self, torque: float) -> float:
        return self.direction * torque / self.gear_ratio

    # --- motor units -> joint units -------------------------------------------------------------
    def position(self, turns: float) -> float:
        return self.offset + self.direction * turns * TAU / self.gear_ratio

    def velocity(self, turns_per_second: float) -> float:
        return self.direction * turns_per_second * TAU / self.gear_ratio

    def torque(self, motor_torque: float) -> float:
        return self.direction * motor_torque * self.gear_ratio

    @property
    def control_mode(self) -> str:
        """The ODrive CONTROL_MODE name of this joint's mode."""
        return self.mode.upper()

    @property
    def motor_velocity_limit(self) -> float:
        """Set_Limits' Velocity_Limit: the joint's velocity limit in motor turns/s."""
        return self.gear_ratio * self.velocity_limit / TAU


_FIELDS = {f.name: f for f in fields(JointConfig) if f.name != "explicit"}
_OPTIONAL = {"pos_gain", "vel_gain", "vel_integrator_gain", "traj_vel_limit", "traj_accel_limit",
             "traj_decel_limit", "traj_inertia"}


def parse_joints(value: Any) -> tuple[JointConfig, ...]:
    """The joint map from the `joints` parameter: a list of tables with `name`, a table keyed by
    joint name, or either as a JSON string. Order is joint order (index in jointSetpoints)."""
    if isinstance(value, str):
        try:
            value = json.loads(value)
        except json.JSONDecodeError as exc:
            raise JointMapError(f"joints: not JSON: {exc.msg} at column {exc.colno}") from None
    if isinstance(value, dict):
        entries = []
        for name, table in value.items():
            if not isinstance(table, dict):
                raise JointMapError(f"joints.{name}: expected a table of settings, got {table!r}")
            if "name" in table and table["name"] != name:
                raise JointMapError(f"joints.{name}: its name key says {table['name']!r}")
            entries.append({**table, "name": name})
    elif isinstance(value, (list, tuple)):
        entries = list(value)
    else:
        raise JointMapError("joints: expected a list of joint tables (each with name and node_id), "
                            f"a table keyed by joint name, or JSON of either; got {type(value).__name__}")
    if not entries:
        raise JointMapError("joints: the joint map is empty; give at least one joint")
    joints = tuple(_joint(k, entry) for k, entry in enumerate(entries))
    seen_names: dict[str, int] = {}
    seen_ids: dict[int, str] = {}
    for joint in joints:
        if joint.name in seen_names:
            raise JointMapError(f"joints: two joints named {joint.name!r}")
        seen_names[joint.name] = 1
        if joint.node_id in seen_ids:
            raise JointMapError(f"joints: {joint.name} and {seen_ids[joint.node_id]} share node_id {joint.node_id}")
        seen_ids[joint.node_id] = joint.name
    return joints


def _joint(k: int, entry: Any) -> JointConfig:
    if not isinstance(entry, dict):
        raise JointMapError(f"joints[{k}]: expected a table with name and node_id, got {entry!r}")
    name = entry.get("name")
    if not isinstance(name, str) or not name:
        raise JointMapError(f"joints[{k}]: needs a name (a non-empty string)")
    where = f"joint {name}"
    unknown = sorted(set(entry) - set(_FIELDS))
    if unknown:
        raise JointMapError(f"{where}: unknown key(s) {unknown}; known: {sorted(_FIELDS)}")
    protocol = entry.get("protocol", "odrive")
    if protocol not in PROTOCOLS:
        raise JointMapError(f"{where}: protocol must be odrive or cia402, got {protocol!r}")
    low, high = (1, CANOPEN_NODE_ID_MAX) if protocol == "cia402" else (0, NODE_ID_MAX)
    if "node_id" not in entry:
        raise JointMapError(f"{where}: needs a node_id ({low}..{high})")
    node_id = entry["node_id"]
    if isinstance(node_id, bool) or not isinstance(node_id, int) or not low <= node_id <= high:
        kind = " (a cia402 axis: CANopen)" if protocol == "cia402" else ""
        raise JointMapError(f"{where}: node_id must be a whole number {low}..{high}, got {node_id!r}{kind}")
    settings: dict[str, Any] = {"name": name, "node_id": node_id, "explicit": frozenset(entry)}
    for key, raw in entry.items():
        if key in ("name", "node_id"):
            continue
        settings[key] = _setting(where, key, raw)
    joint = JointConfig(**settings)
    if joint.protocol == "cia402":
        joint = _cia402(where, joint)
    elif joint.operation_mode:
        raise JointMapError(f"{where}: operation_mode is for a cia402 axis; an ODrive's is mode and input_mode")
    else:
        for key in ("tpdo_timeout", "rated_torque"):
            if key in entry:
                raise JointMapError(f"{where}: {key} is for a cia402 axis")
    if not joint.position_min < joint.position_max:
        raise JointMapError(f"{where}: position_min ({joint.position_min}) must be below position_max "
                            f"({joint.position_max})")
    if (joint.vel_gain is None) != (joint.vel_integrator_gain is None):
        raise JointMapError(f"{where}: give vel_gain and vel_integrator_gain together (one Set_Vel_Gains frame)")
    if (joint.traj_accel_limit is None) != (joint.traj_decel_limit is None):
        raise JointMapError(f"{where}: give traj_accel_limit and traj_decel_limit together "
                            "(one Set_Traj_Accel_Limits frame)")
    return joint


def _cia402(where: str, joint: JointConfig) -> JointConfig:
    """A CiA 402 joint with its operation mode resolved: csp for position, csv for velocity."""
    allowed = OPERATION_MODES[joint.mode]
    if not allowed:
        raise JointMapError(f"{where}: a cia402 axis runs position (csp, pp) or velocity (csv), not torque")
    mode = joint.operation_mode or allowed[0]
    if mode not in allowed:
        raise JointMapError(f"{where}: operation_mode {mode!r} does not drive a {joint.mode} joint; "
                            f"one of {', '.join(allowed)}")
    return dataclasses.replace(joint, operation_mode=mode)


def _number(where: str, key: str, raw: Any, *, positive: bool = False, infinite: bool = False) -> float:
    if isinstance(raw, bool) or not isinstance(raw, (int, float)) or math.isnan(raw):
        raise JointMapError(f"{where}: {key} must be a number, got {raw!r}")
    if math.isinf(raw) and not infinite:
        raise JointMapError(f"{where}: {key} must be finite, got {raw!r}")
    if positive and not raw > 0:
        raise JointMapError(f"{where}: {key} must be > 0, got {raw!r}")
    return float(raw)


def _setting(where: str, key: str, raw: Any) -> Any:
    if key == "direction":
        if isinstance(raw, bool) or raw not in (1, -1):
            raise JointMapError(f"{where}: direction must be 1 or -1, got {raw!r}")
        return int(raw)
    if key == "mode":
        if raw not in MODES:
            raise JointMapError(f"{where}: mode must be one of {', '.join(MODES)}, got {raw!r}")
        return raw
    if key == "out_of_range":
        if raw not in OUT_OF_RANGE:
            raise JointMapError(f"{where}: out_of_range must be reject or clamp, got {raw!r}")
        return raw
    if key == "protocol":
        return raw
    if key == "operation_mode":
        if raw not in ("csp", "pp", "csv"):
            raise JointMapError(f"{where}: operation_mode must be csp, pp or csv, got {raw!r}")
        return raw
    if key in ("counts_per_turn", "acceleration_limit", "rated_torque"):
        return _number(where, key, raw, positive=True)
    if key == "tpdo_timeout":
        if isinstance(raw, bool) or not isinstance(raw, int) or not 1 <= raw <= 240:
            raise JointMapError(f"{where}: tpdo_timeout must be a whole number of SYNCs 1..240, got {raw!r}")
        return raw
    if key == "input_mode":
        if raw not in INPUT_MODE:
            raise JointMapError(f"{where}: input_mode must be an ODrive input mode "
                                f"({', '.join(INPUT_MODE)}), got {raw!r}")
        return raw
    if key in ("position_min", "position_max"):
        return _number(where, key, raw, infinite=True)
    if key in ("gear_ratio", "velocity_limit", "current_limit"):
        return _number(where, key, raw, positive=True)
    if key == "torque_limit":
        return _number(where, key, raw, positive=True, infinite=True)
    if key == "offset":
        return _number(where, key, raw)
    if key in _OPTIONAL:
        if raw is None:
            return None
        if key == "traj_inertia":
            value = _number(where, key, raw)
            if value < 0:
                raise JointMapError(f"{where}: traj_inertia must be >= 0, got {raw!r}")
            return value
        return _number(where, key, raw, positive=True)
    raise JointMapError(f"{where}: unknown key {key!r}")  # pragma: no cover - checked by the caller
