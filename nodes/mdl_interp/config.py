"""The MDL interpreter's robot and sensor description, checked from its parameters.

`Robot`: joint names, limits and velocity limits, the control period. `SensorLayout`: the names
of the sensor inputs `sensor[0..K-1]` and of the floats each carries, which is what interrupt and
feedback expressions read (`proximity.distance` is sensor `proximity`, field `distance`).
Parameter mistakes raise `ValueError` with a message naming the parameter: a node host then
reports that the node cannot be instantiated, with that message.
"""
from __future__ import annotations

import keyword
import math
import re
from dataclasses import dataclass
from typing import Any

from channels.mdl import SENSOR_WIDTH
from iotad.kernel.types import Array, Float, StructType, Struct, Type

# The xArm6 of sim/ (pybullet_data xarm/xarm6_with_gripper.urdf): its arm joints and their
# URDF limits (radians, rad/s).
XARM6_JOINTS = ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"]
XARM6_LOWER = [-6.28318530718, -2.059, -3.927, -6.28318530718, -1.69297, -6.28318530718]
XARM6_UPPER = [6.28318530718, 2.0944, 0.19198, 6.28318530718, 3.14159265359, 6.28318530718]
XARM6_MAX_VELOCITY = 3.14

# The conveyor arm's sensors (Figure 1) and Buggy's proximity vector; a system names its own.
DEFAULT_SENSORS = {"visual_error": ["x", "y"], "proximity": ["distance", "bearing"], "force": ["x", "y", "z"]}

# Names an expression reads besides the sensors: the measured joint positions.
POSITION = "position"

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_ESPRIT_KEYWORDS = {"struct", "enum", "const", "extern", "iota", "states", "channels", "include", "actions",
                    "when", "after", "within", "do", "if", "else", "for", "int", "float", "bool", "void", "true",
                    "false", "NULL", "inf", "in", "forall", "exists"}


def _name_ok(name: Any) -> bool:
    return (isinstance(name, str) and bool(_NAME.match(name)) and not keyword.iskeyword(name)
            and name not in _ESPRIT_KEYWORDS and not name.startswith("_"))


def _floats(value: Any, count: int, what: str, scalar_ok: bool = False) -> list[float]:
    if scalar_ok and isinstance(value, (int, float)) and not isinstance(value, bool):
        value = [value] * count
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise ValueError(f"{what}: expected {count} numbers (one per joint), got {value!r}")
    out = []
    for item in value:
        if isinstance(item, bool) or not isinstance(item, (int, float)) or math.isnan(item):
            raise ValueError(f"{what}: {item!r} is not a number")
        out.append(float(item))
    return out


@dataclass(frozen=True)
class Robot:
    joints: tuple[str, ...]
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    max_velocity: tuple[float, ...]
    period: float                      # seconds between ticks

    @property
    def size(self) -> int:
        return len(self.joints)

    def joint_index(self, key: str) -> int | None:
        """A program's joint key: a joint name, or a decimal index; None if neither."""
        if key in self.joints:
            return self.joints.index(key)
        if _decimal(key) and int(key) < len(self.joints):
            return int(key)
        return None


def _decimal(text: str) -> bool:
    """ASCII digits only: str.isdigit() also takes '²' (int() then fails) and '٣' (taken as 3)."""
    return text.isascii() and text.isdigit()


MAX_RATE = 100_000.0  # Hz


def robot_from(joints: Any, lower: Any, upper: Any, max_velocity: Any, rate: Any) -> Robot:
    if not isinstance(joints, (list, tuple)) or not joints or not all(isinstance(j, str) and j for j in joints):
        raise ValueError(f"joints: expected a list of joint names, got {joints!r}")
    if len(set(joints)) != len(joints):
        raise ValueError(f"joints: a name appears twice in {list(joints)}")
    if any(_decimal(j) for j in joints):
        raise ValueError("joints: a joint name cannot be a number (programs use numbers as joint indices)")
    n = len(joints)
    low, high = _floats(lower, n, "lower"), _floats(upper, n, "upper")
    for name, lo, hi in zip(joints, low, high):
        if not lo <= hi:
            raise ValueError(f"joint {name}: lower limit {lo} above upper limit {hi}")
    speed = _floats(max_velocity, n, "max_velocity", scalar_ok=True)
    if not all(v > 0 for v in speed):
        raise ValueError(f"max_velocity: every joint's limit must be > 0, got {speed}")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 < rate < math.inf:
        raise ValueError(f"rate: expected a control rate in Hz > 0, got {rate!r}")
    if rate > MAX_RATE:  # its ticks would crowd the engine's time grid (1 ns): a slip of units
        raise ValueError(f"rate: {rate:g} Hz is past {MAX_RATE:g} Hz (a tick every {1e6 / MAX_RATE:g} us); "
                         "no motor controller takes setpoints faster")
    return Robot(tuple(joints), tuple(low), tuple(high), tuple(speed), 1.0 / float(rate))


@dataclass(frozen=True)
class SensorLayout:
    names: tuple[str, ...]                 # sensor[k] is names[k]
    fields: tuple[tuple[str, ...], ...]    # the floats of each, in order of `value`
    types: tuple[StructType, ...]          # the struct an expression sees for each

    def scope(self, joints: int) -> dict[str, Type]:
        """What an expression may read: each sensor's struct, and `position` (float[joints])."""
        names: dict[str, Type] = {name: t for name, t in zip(self.names, self.types)}
        names[POSITION] = Array(Float, joints)
        return names


def sensors_from(sensors: Any) -> SensorLayout:
    if not isinstance(sensors, dict):
        raise ValueError(f"sensors: expected a table of sensor name -> list of field names, got {sensors!r}")
    names, fields, types = [], [], []
    for name, members in sensors.items():
        if not _name_ok(name) or name == POSITION:
            raise ValueError(f"sensors: {name!r} cannot name a sensor (an ESPRIT name, not a keyword, "
                             f"not {POSITION!r})")
        if not isinstance(members, (list, tuple)) or not 1 <= len(members) <= SENSOR_WIDTH:
            raise ValueError(f"sensors.{name}: expected 1 to {SENSOR_WIDTH} field names, got {members!r}")
        if not all(_name_ok(m) for m in members) or len(set(members)) != len(members):
            raise ValueError(f"sensors.{name}: field names must be distinct ESPRIT names, got {list(members)}")
        names.append(name)
        fields.append(tuple(members))
        types.append(Struct(name, **{m: Float for m in members}))
    return SensorLayout(tuple(names), tuple(fields), tuple(types))
