"""An end-effector pose as a ramp's or minimum-jerk's target: PyBullet's inverse kinematics on
the robot's URDF gives the joint goal when the atom starts, from the arm's current command; the
arm ends at the pose; an unreachable pose stops the program and holds the motors."""
import math

import pytest

pybullet = pytest.importorskip("pybullet")
import pybullet_data  # noqa: E402

from channels.mdl import minimum_jerk, program  # noqa: E402

JOINTS = [0.3, -0.4, -0.8, 0.2, 1.0, 0.0]


@pytest.fixture(scope="module")
def arm_model():
    """The xArm6 in a PyBullet client of this test's own: forward kinematics of link6."""
    client = pybullet.connect(pybullet.DIRECT)
    body = pybullet.loadURDF(pybullet_data.getDataPath() + "/xarm/xarm6_with_gripper.urdf", useFixedBase=True,
                             physicsClientId=client)
    link = [j for j in range(pybullet.getNumJoints(body, physicsClientId=client))
            if pybullet.getJointInfo(body, j, physicsClientId=client)[12].decode() == "link6"][0]

    def forward(positions):
        for joint, value in enumerate(positions, start=1):  # joint1..joint6 are the URDF's joints 1..6
            pybullet.resetJointState(body, joint, value, physicsClientId=client)
        return pybullet.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=client)[4]
    try:
        names = [pybullet.getJointInfo(body, j, physicsClientId=client)[1].decode() for j in range(1, 7)]
        assert names == [f"joint{k}" for k in range(1, 7)]
        yield forward
    finally:
        pybullet.disconnect(client)


def test_a_pose_target_puts_the_end_effector_there(make_run, arm_model):
    target = list(arm_model(JOINTS))
    run = make_run(start=[0.0, -0.3, -0.6, 0.0, 0.9, 0.0])
    run.command(program("to-pose", minimum_jerk(pose={"position": target}, T=1.0)), t=0.0)
    run.run(until=1.5)
    [end] = run.values("atom_end")
    assert (end["end"], end["tick"]) == ("DONE", 100)
    final = run.of("setpoints", "output")[-1]["value"]["position"]
    assert math.dist(arm_model(final), target) < 0.01
    assert not run.values("fault")


def test_an_unreachable_pose_stops_the_program_and_holds(make_run):
    run = make_run()
    run.command(program("far", minimum_jerk(pose={"position": [3.0, 0.0, 0.5]}, T=1.0)), t=0.0)
    run.run(until=0.2)
    [fault] = run.values("fault")
    assert "behaviours[0].atoms[0].u.pose: pose [3.0, 0.0, 0.5] is out of reach" in fault["message"]
    assert [v["end"] for v in run.values("program_end")] == ["FAULT"]
    assert {tuple(e["value"]["position"]) for e in run.of("setpoints", "output")} == {(0.0,) * 6}
