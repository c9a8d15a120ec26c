"""The arm worlds: the robots' joints and limits as the URDFs give them, the holding brake, the
model-joint gripper, and the plain PyBullet facts the controllers rely on."""
import math

import pybullet
import pytest

from sim.worlds import WORLDS, close_world, find_world, make_world, open_world
from sim.worlds.arm import ArmWorld


@pytest.fixture
def xarm():
    world = ArmWorld("xarm6")
    yield world
    world.close()


def test_xarm6_exposes_six_joints_and_the_gripper_with_their_limits(xarm):
    assert xarm.joint_names == ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6", "gripper")
    assert xarm.lower_limits[1] == pytest.approx(-2.059) and xarm.upper_limits[1] == pytest.approx(2.0944)
    assert xarm.lower_limits[-1] == 0.0 and xarm.upper_limits[-1] == 0.85
    assert xarm.effort_limits()[:6] == [50.0, 50.0, 32.0, 32.0, 32.0, 20.0]
    assert all(v == pytest.approx(3.14) for v in xarm.velocity_limits()[:6])
    inertias = xarm.joint_inertias()
    assert len(inertias) == 7 and all(j > 0 for j in inertias) and inertias[1] > inertias[5]


def test_kuka_iiwa_exposes_seven_joints():
    world = make_world("kuka")
    try:
        assert world.joint_names == tuple(f"lbr_iiwa_joint_{k}" for k in range(1, 8))
        assert world.effort_limits() == [300.0] * 7
    finally:
        world.close()


def test_the_brake_holds_the_arm_against_gravity(xarm):
    start, _ = xarm.read_joints()
    for _ in range(480):
        xarm.apply_torques([None] * 7)
        xarm.step()
    held, velocities = xarm.read_joints()
    assert max(abs(a - b) for a, b in zip(start, held)) < 1e-4 and max(map(abs, velocities)) < 1e-3


def test_without_brake_or_torque_the_arm_falls():
    falling = ArmWorld("xarm6", brake_torque=0.0)
    try:
        start, _ = falling.read_joints()
        for _ in range(120):
            falling.apply_torques([None] * 7)
            falling.step()
        assert abs(falling.read_joints()[0][1] - start[1]) > 0.05  # the shoulder sags
    finally:
        falling.close()


def test_a_constant_torque_turns_the_base_joint(xarm):
    torques = [None] * 7
    torques[0] = 2.0
    for _ in range(120):
        xarm.apply_torques(torques)
        xarm.step()
    positions, velocities = xarm.read_joints()
    assert positions[0] > 0.05 and velocities[0] > 0.1
    assert max(abs(v) for v in velocities[1:]) < 1e-2  # the others stay braked


def test_the_gripper_closes_under_torque_and_the_fingers_follow(xarm):
    for _ in range(240):
        xarm.apply_torques([None] * 6 + [0.05])
        xarm.step()
    assert xarm.gripper_closure() == pytest.approx(1.0)
    fingers = [pybullet.getJointState(xarm.body, j, physicsClientId=xarm.client)[0] for j in xarm.finger_joints]
    assert all(f == pytest.approx(0.85, abs=0.02) for f in fingers)


def test_home_pose_points_the_tool_down(xarm):
    position, orientation = xarm.end_effector_pose()
    tool = xarm.tool_point()
    assert tool[2] == pytest.approx(position[2] - 0.15, abs=1e-3)
    assert math.dist(position[:2], tool[:2]) < 1e-3


def test_worlds_by_name_and_the_process_registry():
    assert set(WORLDS) == {"arm", "kuka", "conveyor", "buggy", "urdf"}
    with pytest.raises(ValueError, match="unknown world 'moon'"):
        make_world("moon")
    with pytest.raises(ValueError, match="world 'buggy'"):
        make_world("buggy", wheels=3)
    first = open_world("test-key", "buggy")
    assert find_world("test-key") is first
    second = open_world("test-key", "buggy")  # the same instance built again: it takes the key over
    assert find_world("test-key") is second
    close_world("test-key", first)            # closing the older one leaves the newer registered
    assert find_world("test-key") is second
    close_world("test-key", second)
    assert find_world("test-key") is None


def test_pybullet_steps_are_deterministic():
    runs = []
    for _ in range(2):
        world = ArmWorld("xarm6")
        torques = [1.0, -3.0, 2.0, 0.5, -0.5, 0.1, 0.01]
        for _ in range(240):
            world.apply_torques(torques)
            world.step()
        runs.append(world.read_joints())
        world.close()
    assert runs[0] == runs[1]
