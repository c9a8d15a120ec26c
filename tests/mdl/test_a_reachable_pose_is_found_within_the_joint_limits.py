"""A pose the arm reaches with its joints within their limits is a motion, not a fault: the
inverse-kinematics solver knows no limits, so where its first solution leaves them, the
interpreter asks again within them (PyBullet's null-space solver, from where the arm is and
from the middle of every range). Of 40 such poses, 6 were refused; one still is (below)."""
import random

import pybullet

from nodes.mdl_interp.config import XARM6_LOWER, XARM6_UPPER
from nodes.mdl_interp.kinematics import Kinematics, KinematicsError
from channels.mdl import Pose

JOINTS = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")


def test_poses_of_configurations_within_the_limits_are_solved_within_them():
    solver = Kinematics("xarm/xarm6_with_gripper.urdf", JOINTS, "link6", 0.01)
    solver.load()
    rng = random.Random(1)
    solved, refused = 0, []
    try:
        for _ in range(40):
            q = [rng.uniform(max(lo, -2.0), min(hi, 2.0)) for lo, hi in zip(XARM6_LOWER, XARM6_UPPER)]
            for joint, value in zip(solver._joint_ids, q):
                pybullet.resetJointState(solver._body, joint, value, physicsClientId=solver._client)
            where = pybullet.getLinkState(solver._body, solver._ee, computeForwardKinematics=True,
                                          physicsClientId=solver._client)[4]
            try:
                goal = solver.solve(Pose(position=tuple(where), orientation=None), [0.0] * 6, XARM6_LOWER, XARM6_UPPER)
            except KinematicsError:
                refused.append(q)
                continue
            if all(lo <= v <= hi for v, lo, hi in zip(goal, XARM6_LOWER, XARM6_UPPER)):
                solved += 1
            else:
                refused.append(q)
    finally:
        solver.close()
    assert solved >= 39, f"{solved} of 40 solved within the limits; refused: {refused}"
