"""Any robot from its URDF in its own PyBullet client: its movable joints, by the URDF's names,
driven by simulated drives as the xArm is (torque control, a holding brake while an axis is off).

`world = "urdf"` with `world_options = { urdf = "robot.urdf" }` in a simulated drives node
(`SimulatedOdrives`, `SimulatedCia402Drives`): the joints are the URDF's revolute, continuous and
prismatic joints in URDF order, named as the URDF names them, so `node_ids = { pan = 1, tilt = 2 }`
puts an axis on each by name. The file is an absolute path, `package:file` (the shipped
`sim.robots:pan_tilt.urdf`, or `pybullet_data:kuka_iiwa/model.urdf`), or, in a system file, a
path relative to it (the launcher makes it absolute). Options: `home` (joint positions at reset,
default all 0), `fixed_base`, `floor`, `gravity`, `time_step`, and the arm world's
`brake_torque`, `joint_damping`, `solver_iterations`, `brake_solver_iterations`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import pybullet

from . import physics
from .arm import ArmWorld, RobotModel

MOVABLE = (pybullet.JOINT_REVOLUTE, pybullet.JOINT_PRISMATIC)  # a continuous joint is revolute here
DEFAULT_EFFORT = 10.0    # Nm (N) for a joint whose URDF gives no effort limit
DEFAULT_VELOCITY = 3.0   # rad/s (m/s) for one that gives no velocity limit


def urdf_file(urdf: str) -> Path:
    """The URDF `urdf` names: an absolute or working-folder path, or `package:file`."""
    from iotad.kernel.package_files import is_package_ref, package_file

    if not isinstance(urdf, str) or not urdf:
        raise ValueError("world 'urdf' needs the option urdf = \"path/to/robot.urdf\" (or \"package:file.urdf\")")
    if is_package_ref(urdf):
        return package_file(urdf)
    path = Path(urdf).expanduser().resolve()
    if not path.is_file():
        raise ValueError(f"world 'urdf': no URDF file {urdf!r} (looked at {path})")
    return path


class UrdfWorld(ArmWorld):
    """A robot loaded from any URDF, in its own DIRECT client, stepped by whoever owns it."""

    POSITIVE_OPTIONS = ("time_step",)

    def __init__(self, urdf: str = "", time_step: float = 1.0 / 240.0, gravity: float = -9.81,
                 home: Sequence[float] | None = None, fixed_base: bool = True, floor: bool = True,
                 brake_torque: float = 2.0, joint_damping: float = 0.05, solver_iterations: int = 10,
                 brake_solver_iterations: int = 50):
        path = urdf_file(urdf)
        self.urdf = str(path)
        self.robot = path.stem
        self.time_step = float(time_step)
        self.client = client = physics.connect(self.time_step, gravity)
        self.solver_iterations = (int(solver_iterations), int(brake_solver_iterations))
        if floor:
            self.floor = physics.box(client, (2.0, 2.0, 0.005), (0, 0, -0.005), rgba=(0.8, 0.8, 0.78, 1))
        try:
            self.body = pybullet.loadURDF(str(path), useFixedBase=bool(fixed_base), physicsClientId=client)
        except pybullet.error as exc:
            physics.disconnect(client)
            raise ValueError(f"world 'urdf': PyBullet cannot load {path}: {exc}") from None
        joints = [pybullet.getJointInfo(self.body, j, physicsClientId=client)
                  for j in range(pybullet.getNumJoints(self.body, physicsClientId=client))]
        movable = [info for info in joints if info[2] in MOVABLE]
        if not movable:
            physics.disconnect(client)
            raise ValueError(f"world 'urdf': {path.name} has no revolute, continuous or prismatic joint to drive")
        self.links = {info[12].decode(): info[0] for info in joints}
        end = movable[-1][12].decode()  # the last driven joint's child: what a tool would hang on
        self.model = RobotModel(str(path), end, tuple(0.0 for _ in movable))
        self.arm_joints = [info[0] for info in movable]
        self.arm_joint_names = tuple(info[1].decode() for info in movable)
        self.finger_joints = []
        self.movable = [info[0] for info in joints if info[2] != pybullet.JOINT_FIXED]
        self.joint_names = self.arm_joint_names
        self.lower_limits = [info[8] for info in movable]
        self.upper_limits = [info[9] for info in movable]
        self._efforts = [info[10] if info[10] > 0 else DEFAULT_EFFORT for info in movable]
        self._velocities = [info[11] if info[11] > 0 else DEFAULT_VELOCITY for info in movable]
        self.end_effector_link = self.links[end]
        self.brake_torque = float(brake_torque)
        self.gripper = None
        self._gripper_torque = None
        for j in self.arm_joints:
            pybullet.changeDynamics(self.body, j, jointDamping=joint_damping, physicsClientId=client)
        self._finger_target = None
        self._braked = None
        if home is not None and len(home) != len(self.arm_joints):
            physics.disconnect(client)
            raise ValueError(f"world 'urdf': home needs {len(self.arm_joints)} joint positions "
                             f"({', '.join(self.arm_joint_names)}), got {len(home)}")
        self.reset(home)
