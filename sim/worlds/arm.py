"""An arm from pybullet_data in its own PyBullet client: the xArm6 with its gripper, or the KUKA iiwa.

`ArmWorld` is a `Plant` (sim/worlds/plant.py): its joints are the arm's revolute joints in
URDF order, plus "gripper" on the xArm6. How each is driven:
- Arm joints: PyBullet TORQUE_CONTROL with the torque the simulated ODrive computes; their
  velocity motors are switched off first (force 0), as PyBullet requires. While an axis is off
  (IDLE) a holding brake acts instead, as the xArm's own joint brakes do when its servos are
  disabled: a PyBullet position motor holding the angle where the brake engaged, limited to
  `brake_torque` times the joint's effort limit (more solver iterations while any joint is
  braked: with 10 the chain creeps under gravity). A brake twice as strong as the drive (the
  default 2) stops the heaviest joint braked at 0.9 rad/s within 3 mrad; as strong as the drive,
  it overshot 12 mrad, 21 mrad in a slowed real-time run, before it pulled back. The
  URDF's joint damping (1 Nm s/rad) is replaced by `joint_damping`: PyBullet applies damping
  explicitly, and 1 Nm s/rad on the 1.6e-3 kg m^2 wrist is unstable at 240 Hz.
- The gripper: its six finger joints are mimic joints of `drive_joint` (PyBullet ignores
  <mimic>), and the knuckles are far too light for an explicit torque loop at 240 Hz. So the
  gripper axis drives a `ModelJoint` (0..0.85 rad, closed at 0.85) integrated here, and the six
  finger joints follow it with PyBullet position motors.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import pybullet

from . import physics
from .model_joint import ModelJoint


@dataclass(frozen=True)
class RobotModel:
    urdf: str
    end_effector: str                    # the link whose pose is the end effector's
    home: tuple[float, ...]              # arm joint positions at reset (rad)
    tool_offset: float = 0.0             # from the end-effector link to the grasp point, along its z (m)
    gripper_joints: tuple[str, ...] = ()  # finger joints driven together by the "gripper" joint
    gripper_range: tuple[float, float] = (0.0, 0.0)


ROBOTS = {
    # home: the gripper 0.44 m above the floor, pointing down, 0.39 m in front of the base
    "xarm6": RobotModel("xarm/xarm6_with_gripper.urdf", "link6", (0.0, -0.3, -1.0, 0.0, 1.3, 0.0),
                        tool_offset=0.15,
                        gripper_joints=("drive_joint", "left_finger_joint", "left_inner_knuckle_joint",
                                        "right_outer_knuckle_joint", "right_finger_joint",
                                        "right_inner_knuckle_joint"),
                        gripper_range=(0.0, 0.85)),
    "kuka_iiwa": RobotModel("kuka_iiwa/model.urdf", "lbr_iiwa_link_7", (0.0, 0.5, 0.0, -1.2, 0.0, 1.4, 0.0),
                            tool_offset=0.05),
}
GRIPPER = "gripper"
GRIPPER_INERTIA = 2e-4     # kg m^2 at the drive joint: fingers and the linkage as one
GRIPPER_FRICTION = 2e-3    # Nm s/rad
GRIPPER_EFFORT = 1.0       # Nm: what its axis may give by default
GRIPPER_VELOCITY = 2.0     # rad/s, the URDF's limit


class ArmWorld:
    """An arm on the floor in its own DIRECT client, stepped by whoever owns it."""

    def __init__(self, robot: str = "xarm6", time_step: float = 1.0 / 240.0, gravity: float = -9.81,
                 home: Sequence[float] | None = None, brake_torque: float = 2.0, joint_damping: float = 0.05,
                 floor: bool = True, solver_iterations: int = 10,
                 brake_solver_iterations: int = 50):
        if robot not in ROBOTS:
            raise ValueError(f"unknown robot {robot!r}; known: {', '.join(ROBOTS)}")
        self.robot = robot
        self.model = model = ROBOTS[robot]
        self.time_step = float(time_step)
        self.client = client = physics.connect(self.time_step, gravity)
        # PyBullet's default 50 solver iterations cost a third more per step than 10, which is
        # enough while every joint is torque-driven; a brake (a velocity motor holding the arm
        # against gravity) creeps with 10, so braking switches to `brake_solver_iterations`
        self.solver_iterations = (int(solver_iterations), int(brake_solver_iterations))
        if floor:  # a plain box: plane.urdf's textured plane costs a camera image ~1 ms more
            self.floor = physics.box(client, (2.0, 2.0, 0.005), (0, 0, -0.005), rgba=(0.8, 0.8, 0.78, 1))
        self.body = pybullet.loadURDF(model.urdf, useFixedBase=True, physicsClientId=client)
        joints = [pybullet.getJointInfo(self.body, j, physicsClientId=client)
                  for j in range(pybullet.getNumJoints(self.body, physicsClientId=client))]
        by_name = {info[1].decode(): info for info in joints}
        self.links = {info[12].decode(): info[0] for info in joints}
        finger_names = set(model.gripper_joints)
        arm = [info for info in joints if info[2] == pybullet.JOINT_REVOLUTE and info[1].decode() not in finger_names]
        self.arm_joints = [info[0] for info in arm]
        self.arm_joint_names = tuple(info[1].decode() for info in arm)
        self.finger_joints = [by_name[name][0] for name in model.gripper_joints]
        self.movable = [info[0] for info in joints if info[2] != pybullet.JOINT_FIXED]
        self.joint_names = self.arm_joint_names + ((GRIPPER,) if self.finger_joints else ())
        self.lower_limits = [info[8] for info in arm]
        self.upper_limits = [info[9] for info in arm]
        self._efforts = [info[10] for info in arm]
        self._velocities = [info[11] for info in arm]
        self.end_effector_link = self.links[model.end_effector]
        self.brake_torque = float(brake_torque)
        self.gripper = None
        self._gripper_torque = None
        if self.finger_joints:
            low, high = model.gripper_range
            self.lower_limits.append(low)
            self.upper_limits.append(high)
            self._efforts.append(GRIPPER_EFFORT)
            self._velocities.append(GRIPPER_VELOCITY)
            self.gripper = ModelJoint(GRIPPER_INERTIA, GRIPPER_FRICTION, low, high,
                                      brake_torque=GRIPPER_EFFORT, position=low)
        for j in self.arm_joints:
            pybullet.changeDynamics(self.body, j, jointDamping=joint_damping, physicsClientId=client)
        self._finger_target = None
        self._braked = None  # which arm joints are braked now (position motor on)
        self.reset(home)

    # ------------------------------------------------------------------ set-up
    def reset(self, home: Sequence[float] | None = None) -> None:
        """Put the arm at `home` (default: the robot's), at rest, braked, the gripper open."""
        home = list(self.model.home if home is None else home)
        if len(home) != len(self.arm_joints):
            raise ValueError(f"{self.robot} home needs {len(self.arm_joints)} joint positions, got {len(home)}")
        for j, q in zip(self.arm_joints, home):
            pybullet.resetJointState(self.body, j, q, 0.0, physicsClientId=self.client)
        if self.gripper is not None:
            self.gripper.position, self.gripper.velocity = self.model.gripper_range[0], 0.0
            for j in self.finger_joints:
                pybullet.resetJointState(self.body, j, self.gripper.position, 0.0, physicsClientId=self.client)
            self._drive_fingers()
        self._braked = None
        self.apply_torques([None] * len(self.joint_names))

    # ------------------------------------------------------------------ Plant
    def joint_inertias(self) -> list[float]:
        positions = [s[0] for s in pybullet.getJointStates(self.body, self.movable, physicsClientId=self.client)]
        mass = pybullet.calculateMassMatrix(self.body, positions, physicsClientId=self.client)
        column = {j: k for k, j in enumerate(self.movable)}
        inertias = [mass[column[j]][column[j]] for j in self.arm_joints]
        if self.gripper is not None:
            inertias.append(self.gripper.inertia)
        return inertias

    def effort_limits(self) -> list[float]:
        return list(self._efforts)

    def velocity_limits(self) -> list[float]:
        return list(self._velocities)

    def read_joints(self) -> tuple[list[float], list[float]]:
        states = pybullet.getJointStates(self.body, self.arm_joints, physicsClientId=self.client)
        positions = [s[0] for s in states]
        velocities = [s[1] for s in states]
        if self.gripper is not None:
            positions.append(self.gripper.position)
            velocities.append(self.gripper.velocity)
        return positions, velocities

    def apply_torques(self, torques: Sequence[float | None]) -> None:
        n = len(self.arm_joints)
        arm = torques[:n]
        braked = tuple(t is None for t in arm)
        client, body = self.client, self.body
        if braked != self._braked:
            # the brake: a position motor holding where the joint was when it engaged, limited to
            # brake_torque x effort; a joint being driven has its motors off (force 0)
            held = [s[0] for s in pybullet.getJointStates(body, self.arm_joints, physicsClientId=client)]
            forces = [self.brake_torque * effort if b else 0.0 for b, effort in zip(braked, self._efforts)]
            pybullet.setJointMotorControlArray(body, self.arm_joints, pybullet.POSITION_CONTROL,
                                               targetPositions=held, targetVelocities=[0.0] * n, forces=forces,
                                               physicsClientId=client)
            pybullet.setPhysicsEngineParameter(numSolverIterations=self.solver_iterations[any(braked)],
                                               physicsClientId=client)
            self._braked = braked
        if not all(braked):
            driven = [j for j, b in zip(self.arm_joints, braked) if not b]
            forces = [t for t in arm if t is not None]
            pybullet.setJointMotorControlArray(body, driven, pybullet.TORQUE_CONTROL, forces=forces,
                                               physicsClientId=client)
        if self.gripper is not None:
            self._gripper_torque = torques[n]

    def step(self) -> None:
        if self.gripper is not None:
            self.gripper.step(self._gripper_torque, self.time_step)
            self._drive_fingers()
        pybullet.stepSimulation(physicsClientId=self.client)

    def close(self) -> None:
        physics.disconnect(self.client)

    # ------------------------------------------------------------------ views
    def end_effector_pose(self) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        """World position and orientation (x, y, z, w) of the end-effector link."""
        state = pybullet.getLinkState(self.body, self.end_effector_link, computeForwardKinematics=True,
                                      physicsClientId=self.client)
        return tuple(state[4]), tuple(state[5])

    def tool_point(self) -> tuple[float, float, float]:
        """The grasp point: `tool_offset` along the end-effector link's z axis."""
        position, orientation = self.end_effector_pose()
        m = pybullet.getMatrixFromQuaternion(orientation)
        d = self.model.tool_offset
        return (position[0] + m[2] * d, position[1] + m[5] * d, position[2] + m[8] * d)

    def gripper_closure(self) -> float:
        """0 open .. 1 closed (0 for an arm without gripper)."""
        if self.gripper is None:
            return 0.0
        low, high = self.model.gripper_range
        return (self.gripper.position - low) / (high - low)

    def inverse_kinematics(self, position, orientation=None) -> list[float]:
        """Arm joint positions (rad) putting the end-effector link at `position` (a helper for tests
        and examples; controllers reach a pose through CAN, not through this)."""
        solution = pybullet.calculateInverseKinematics(
            self.body, self.end_effector_link, position, orientation, maxNumIterations=200,
            residualThreshold=1e-5, physicsClientId=self.client)
        column = {j: k for k, j in enumerate(self.movable)}
        return [solution[column[j]] for j in self.arm_joints]

    def _drive_fingers(self) -> None:
        target = self.gripper.position
        if self._finger_target is not None and abs(target - self._finger_target) < 1e-4:
            return  # the finger motors already hold this
        self._finger_target = target
        n = len(self.finger_joints)
        pybullet.setJointMotorControlArray(self.body, self.finger_joints, pybullet.POSITION_CONTROL,
                                           targetPositions=[target] * n, forces=[20.0] * n,
                                           physicsClientId=self.client)

