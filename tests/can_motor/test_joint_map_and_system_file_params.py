"""The joint map: its three accepted shapes, clear errors for every bad entry, exact unit
conversions, and the same map written in a system file's TOML (nested tables) reaching the node."""
import math
import textwrap

import pytest
from hypothesis import given, strategies as st

from iotad.launcher.system.system_file import SystemFileError, load_system
from nodes.can_motor import CanMotor, JointMapError, parse_joints

LIST = [{"name": "a", "node_id": 1}, {"name": "b", "node_id": 2, "direction": -1, "gear_ratio": 50.0}]


def test_list_table_and_json_give_the_same_map():
    as_list = parse_joints(LIST)
    as_table = parse_joints({"a": {"node_id": 1}, "b": {"node_id": 2, "direction": -1, "gear_ratio": 50.0}})
    as_json = parse_joints('[{"name": "a", "node_id": 1}, {"name": "b", "node_id": 2, "direction": -1, '
                           '"gear_ratio": 50}]')
    assert as_list == as_table == as_json
    assert [j.name for j in as_list] == ["a", "b"]
    assert (as_list[1].mode, as_list[1].out_of_range, as_list[1].input_mode) == ("position", "reject", "PASSTHROUGH")


@pytest.mark.parametrize("entry,message", [
    ({"name": "e"}, "joint e: needs a node_id"),
    ({"name": "e", "node_id": 64}, "joint e: node_id must be a whole number 0..63, got 64"),
    ({"name": "e", "node_id": 3, "direction": 2}, "joint e: direction must be 1 or -1, got 2"),
    ({"name": "e", "node_id": 3, "gear_ratio": 0}, "joint e: gear_ratio must be > 0, got 0"),
    ({"name": "e", "node_id": 3, "mode": "voltage"}, "joint e: mode must be one of position, velocity, torque"),
    ({"name": "e", "node_id": 3, "out_of_range": "wrap"}, "joint e: out_of_range must be reject or clamp"),
    ({"name": "e", "node_id": 3, "input_mode": "FAST"}, "joint e: input_mode must be an ODrive input mode"),
    ({"name": "e", "node_id": 3, "position_min": 1.0, "position_max": -1.0}, "joint e: position_min (1.0) must be below"),
    ({"name": "e", "node_id": 3, "velocity_limit": math.inf}, "joint e: velocity_limit must be finite"),
    ({"name": "e", "node_id": 3, "offset": "1"}, "joint e: offset must be a number, got '1'"),
    ({"name": "e", "node_id": 3, "vel_gain": 0.1}, "joint e: give vel_gain and vel_integrator_gain together"),
    ({"name": "e", "node_id": 3, "gain": 1}, "joint e: unknown key(s) ['gain']"),
    ({"node_id": 3}, "joints[1]: needs a name"),
])
def test_every_bad_entry_says_which_joint_and_key(entry, message):
    with pytest.raises(JointMapError) as caught:
        parse_joints([{"name": "ok", "node_id": 1}, entry])
    assert message in str(caught.value)


@pytest.mark.parametrize("value,message", [
    ([], "the joint map is empty"),
    ("[{", "joints: not JSON"),
    (42, "joints: expected a list of joint tables"),
    ([{"name": "a", "node_id": 1}, {"name": "a", "node_id": 2}], "two joints named 'a'"),
    ([{"name": "a", "node_id": 1}, {"name": "b", "node_id": 1}], "b and a share node_id 1"),
])
def test_bad_maps(value, message):
    with pytest.raises(JointMapError, match=None) as caught:
        parse_joints(value)
    assert message in str(caught.value)


def test_the_node_without_a_map_or_with_bad_params_says_why():
    with pytest.raises(JointMapError, match="CanMotor needs a joint map"):
        CanMotor("m")
    with pytest.raises(ValueError, match="polls: 'Get_Nothing' cannot be polled"):
        CanMotor("m", joints=LIST, polls={"Get_Nothing": 1.0})
    with pytest.raises(ValueError, match="lost_after must be a whole number"):
        CanMotor("m", joints=LIST, lost_after=0)
    with pytest.raises(ValueError, match=r"state_period 1e-300 s is below 1e-05 s"):
        CanMotor("m", joints=LIST, state_period=1e-300)


@pytest.mark.parametrize("key, value, signal", [("current_limit", 1e39, "Current_Limit"),
                                                ("pos_gain", 1e39, "Pos_Gain"),
                                                ("traj_inertia", 1e39, "Traj_Inertia"),
                                                ("velocity_limit", 1e40, "Velocity_Limit")])
def test_a_setting_no_frame_can_carry_is_refused_when_the_node_is_built(key, value, signal):
    """It passed the joint map's checks, then failed at every arming attempt, a runtime error
    each, until the engine halted (zeno) at t=0: a float32 holds at most 3.4e38."""
    joints = [{"name": "a", "node_id": 1}, {"name": "b", "node_id": 2, key: value}]
    with pytest.raises(JointMapError, match=rf"joint b: signal {signal}=.* does not fit a float32 \(in the frames "
                                            r"that arm its axis\)"):
        CanMotor("m", joints=joints)


@given(q=st.floats(-10, 10), direction=st.sampled_from([1, -1]), gear=st.floats(0.1, 200),
       offset=st.floats(-3, 3))
def test_conversions_invert_each_other(q, direction, gear, offset):
    (joint,) = parse_joints([{"name": "j", "node_id": 1, "direction": direction, "gear_ratio": gear,
                              "offset": offset}])
    assert joint.position(joint.turns(q)) == pytest.approx(q, abs=1e-9)
    assert joint.velocity(joint.turns_per_second(q)) == pytest.approx(q, abs=1e-9)
    assert joint.torque(joint.motor_torque(q)) == pytest.approx(q, abs=1e-9)
    assert joint.turns(offset) == 0.0


SYSTEM = textwrap.dedent('''
    [system]
    name = "motors"
    external = ["motor.setpoints", "motor.estop", "motor.can_rx"]

    [[node]]
    name = "motor"
    python = "nodes.can_motor:CanMotor"

    [node.params]
    heartbeat_period = 0.1
    polls = { Get_Error = 0.1, Get_Torques = 0.02 }

    [[node.params.joints]]
    name = "shoulder"
    node_id = 1
    position_min = -3.0
    position_max = 3.0

    [[node.params.joints]]
    name = "elbow"
    node_id = 2
    direction = -1
    gear_ratio = 9.0
    offset = 0.5
    mode = "velocity"
    out_of_range = "clamp"
''')


def test_a_system_file_gives_the_joint_map_as_nested_tables(tmp_path):
    path = tmp_path / "motors.toml"
    path.write_text(SYSTEM)
    system = load_system(path)
    channels = system.nodes["motor"].channels
    assert channels["setpoints"].type.name == "jointSetpoints2"
    assert channels["joint_states"].type.name == "jointStates2"
    assert channels["joint_status"].size == 2
    params = system.node_config("motor", 0.0, ["tcp/127.0.0.1:7447"])["params"]
    motor = CanMotor("motor", **params)  # what the node host builds from the JSON config
    assert [(j.name, j.node_id, j.mode, j.gear_ratio) for j in motor.joint_map] == [
        ("shoulder", 1, "position", 1.0), ("elbow", 2, "velocity", 9.0)]


def test_a_bad_joint_in_a_system_file_is_one_clear_line(tmp_path):
    path = tmp_path / "motors.toml"
    path.write_text(SYSTEM.replace("direction = -1", "direction = 2"))
    with pytest.raises(SystemFileError) as caught:
        load_system(path)
    assert "joint elbow: direction must be 1 or -1, got 2" in str(caught.value)
