"""What `iotad new` makes: the robot's joints (names, limits, CAN node ids), its drive family,
its behaviours and their priorities, and its URDF; checked, with one-line errors."""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

FAMILIES = ("odrive", "cia402")
SHIPPED = {"pan_tilt": "sim.robots:pan_tilt.urdf", "kuka": "pybullet_data:kuka_iiwa/model.urdf"}  # by short name
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_FOLDER = re.compile(r"^[A-Za-z_][A-Za-z0-9_-]*$")


class PlanError(ValueError):
    """A choice that cannot make a working robot; `str()` is one line saying which and why."""


@dataclass(frozen=True)
class JointPlan:
    name: str
    lower: float      # rad (or m for a prismatic joint)
    upper: float
    node_id: int      # the CAN node id of its drive


@dataclass(frozen=True)
class BehaviourPlan:
    name: str
    priority: int     # the higher wins the motors (the program scheduler, Figure 2)


@dataclass
class RobotPlan:
    name: str                                   # the folder, and the system's name
    joints: list[JointPlan]
    family: str = "odrive"
    behaviours: list[BehaviourPlan] = field(default_factory=lambda: [BehaviourPlan("sweep", 1)])
    urdf: str | None = None                     # None: a URDF made for the joints; a file; a shipped name

    @property
    def system_name(self) -> str:
        return self.name.replace("-", "_")


DEFAULT_JOINTS = [JointPlan("pan", -2.6, 2.6, 1), JointPlan("tilt", -1.2, 1.2, 2)]


def parse_joint(text: str) -> tuple[str, float | None, float | None]:
    """`NAME` or `NAME:LOWER:UPPER` (radians)."""
    parts = text.split(":")
    name = parts[0].strip()
    if not _NAME.match(name):
        raise PlanError(f"--joint {text!r}: a joint name is letters, digits and _ (not starting with a digit)")
    if len(parts) == 1:
        return name, None, None
    if len(parts) != 3:
        raise PlanError(f"--joint {text!r}: expected NAME or NAME:LOWER:UPPER (radians)")
    try:
        lower, upper = float(parts[1]), float(parts[2])
    except ValueError:
        raise PlanError(f"--joint {text!r}: LOWER and UPPER must be numbers (radians)") from None
    if not lower < upper:
        raise PlanError(f"--joint {text!r}: LOWER must be below UPPER")
    return name, lower, upper


def parse_behaviour(text: str, default_priority: int) -> BehaviourPlan:
    """`NAME` or `NAME:PRIORITY`."""
    name, _, priority = text.partition(":")
    name = name.strip()
    if not _NAME.match(name):
        raise PlanError(f"--behaviour {text!r}: a behaviour name is letters, digits and _ (not starting with a digit)")
    if not priority:
        return BehaviourPlan(name, default_priority)
    try:
        value = int(priority)
    except ValueError:
        raise PlanError(f"--behaviour {text!r}: PRIORITY must be a whole number") from None
    if value < 0:
        raise PlanError(f"--behaviour {text!r}: PRIORITY must be 0 or more")
    return BehaviourPlan(name, value)


def urdf_joints(urdf: str) -> list[tuple[str, float, float]]:
    """The movable joints of a URDF (a file, or a shipped name): (name, lower, upper) in order."""
    path = urdf_path(urdf)
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as exc:
        raise PlanError(f"--urdf {urdf}: cannot read it as a URDF ({exc})") from None
    found = []
    for joint in root.findall("joint"):
        kind = joint.get("type")
        if kind not in ("revolute", "continuous", "prismatic"):
            continue
        limit = joint.find("limit")
        lower = float(limit.get("lower", "-3.14")) if limit is not None and kind != "continuous" else -3.14
        upper = float(limit.get("upper", "3.14")) if limit is not None and kind != "continuous" else 3.14
        name = joint.get("name") or ""
        if not re.fullmatch(r"[A-Za-z0-9_.:-]{1,64}", name):  # a key of MDL targets and of the joint map
            raise PlanError(f"--urdf {urdf}: joint name {name!r} is not usable as a joint's name "
                            "(1..64 letters, digits, _ . : -)")
        found.append((name, lower, upper))
    if not found:
        raise PlanError(f"--urdf {urdf}: it has no revolute, continuous or prismatic joint to drive")
    return found


def urdf_path(urdf: str) -> Path:
    """The file of a URDF choice: a shipped name (`pan_tilt`) or a file."""
    from iotad.kernel.package_files import package_file

    from iotad.kernel.package_files import is_package_ref

    if urdf in SHIPPED:
        return package_file(SHIPPED[urdf])
    if is_package_ref(urdf):  # "pybullet_data:kuka_iiwa/model.urdf"
        try:
            return package_file(urdf)
        except ValueError as exc:
            raise PlanError(f"--urdf {urdf}: {exc}") from None
    path = Path(urdf).expanduser()
    if not path.is_file():
        shipped = ", ".join(SHIPPED)
        raise PlanError(f"--urdf {urdf}: no such file (or a shipped robot: {shipped}, or package:file.urdf)")
    return path.resolve()


def make_plan(name: str, joints: list[str] | None = None, family: str = "odrive", node_ids: list[int] | None = None,
              behaviours: list[str] | None = None, urdf: str | None = None) -> RobotPlan:
    """The robot the choices describe; `PlanError` for one that would not work."""
    if not _FOLDER.match(name):
        raise PlanError(f"{name!r}: a robot's name is letters, digits, _ and - (it names its folder and system)")
    if family not in FAMILIES:
        raise PlanError(f"--drives {family!r}: one of {', '.join(FAMILIES)}")
    if urdf is None and not joints:
        urdf = "pan_tilt"  # the default robot: the shipped pan-tilt head
    from_urdf = urdf_joints(urdf) if urdf is not None else []
    chosen: list[tuple[str, float | None, float | None]] = [parse_joint(j) for j in joints or []]
    if not chosen:
        chosen = [(n, lo, hi) for n, lo, hi in from_urdf]
    by_name = {n: (lo, hi) for n, lo, hi in from_urdf}
    if from_urdf:
        unknown = [n for n, _, _ in chosen if n not in by_name]
        if unknown:
            raise PlanError(f"joint(s) {', '.join(unknown)} not in the URDF (its joints: {', '.join(by_name)})")
    names = [n for n, _, _ in chosen]
    if len(set(names)) != len(names):
        raise PlanError(f"joint names must differ: {', '.join(names)}")
    ids = node_ids or list(range(1, len(chosen) + 1))
    if len(ids) != len(chosen):
        raise PlanError(f"--node-ids gives {len(ids)} ids for {len(chosen)} joints")
    top = 63 if family == "odrive" else 127
    if len(set(ids)) != len(ids) or not all(1 <= i <= top for i in ids):
        raise PlanError(f"--node-ids {','.join(map(str, ids))}: one id per joint, all different, 1..{top} "
                        f"({'ODrive CAN Simple' if family == 'odrive' else 'CANopen'})")
    planned = []
    for (joint, lower, upper), node_id in zip(chosen, ids):
        if lower is None:
            lower, upper = by_name.get(joint, (-1.5, 1.5))
        planned.append(JointPlan(joint, float(lower), float(upper), int(node_id)))
    made = [parse_behaviour(b, k + 1) for k, b in enumerate(behaviours or ["sweep"])]
    if len({b.name for b in made}) != len(made):
        raise PlanError("behaviour names must differ")
    clash = {b.name for b in made} & {"scheduler", "mdl", "motor", "drives", "can0"}
    if clash:
        raise PlanError(f"behaviour name {sorted(clash)[0]!r} is taken by one of the robot's own nodes")
    return RobotPlan(name, planned, family, made, urdf)
