"""`[[ros2]]` tables are checked with the system file, before anything starts: each one that
cannot work is one error naming the table and why, never a traceback."""
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.launcher.system.system_file import SystemFileError, load_system

ROOT = Path(__file__).resolve().parents[2]
ARM = (ROOT / "examples" / "mdl_ideal_arm.py").as_posix()
HEAD = f'''
[system]
name = "t"
external = ["arm.setpoints"]

[[node]]
name = "arm"
python = "{ARM}:IdealArm"
'''
GOOD = '''
[[ros2]]
channel = "arm.joint_states"
topic = "/joint_states"
type = "sensor_msgs/msg/JointState"
direction = "out"
fields = { position = "position" }
'''


def check(tmp_path, text: str) -> list[str]:
    path = tmp_path / "t.toml"
    path.write_text(HEAD + text)
    with pytest.raises(SystemFileError) as caught:
        load_system(path)
    return caught.value.errors


def test_a_good_table_adds_the_bridge_bound_to_the_channel(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text(HEAD + GOOD)
    system = load_system(path)
    assert [(str(b.source), str(b.target)) for b in system.bindings] == [("arm.joint_states", "ros2.out_0")]
    assert system.nodes["ros2"].params["ros_node"] == "iotad_t"


@pytest.mark.parametrize("change, said", [
    (('channel = "arm.joint_states"', 'channel = "arm.nope"'), "node 'arm' has no external channel 'nope'"),
    (('channel = "arm.joint_states"', 'channel = "arm.setpoints"'), "is an input channel; expected an output"),
    (('type = "sensor_msgs/msg/JointState"', 'type = "sensor_msgs/msg/JointStat"'), "unknown ROS 2 message type"),
    (('topic = "/joint_states"', 'topic = "/joint states"'), "is not a ROS 2 name token"),
    (('fields = { position = "position" }', 'fields = { position = "stamp" }'), "one value (float[0..None]) against a sequence of float64"),
    (('direction = "out"', 'direction = "in"'), "is an output channel; expected an input"),
])
def test_a_table_that_cannot_work_is_one_error_naming_it(tmp_path, change, said):
    errors = check(tmp_path, GOOD.replace(*change))
    assert len(errors) == 1 and "[[ros2]] #1" in errors[0] and said in errors[0], errors


def test_a_message_into_an_input_it_does_not_fit_and_a_node_named_ros2_are_refused(tmp_path):
    twice = GOOD + '''
[[ros2]]
channel = "arm.setpoints"
topic = "/setpoints"
type = "std_msgs/msg/Float64"
direction = "in"
'''
    errors = check(tmp_path, twice.replace('external = ["arm.setpoints"]', ""))
    assert len(errors) == 1 and "[[ros2]] #2" in errors[0] and "do not fit" in errors[0], errors
    named = HEAD + f'''
[[node]]
name = "ros2"
python = "{ARM}:IdealArm"
''' + GOOD
    path = tmp_path / "n.toml"
    path.write_text(named.replace('external = ["arm.setpoints"]', 'external = ["arm.setpoints", "ros2.setpoints"]'))
    with pytest.raises(SystemFileError) as caught:
        load_system(path)
    assert any("is the ROS 2 bridge's" in e for e in caught.value.errors), caught.value.errors


def test_the_check_command_says_it_in_one_line(tmp_path):
    path = tmp_path / "t.toml"
    path.write_text(HEAD + GOOD.replace('topic = "/joint_states"', 'topic = "joint_states"'))
    done = subprocess.run([sys.executable, "-m", "iotad", "run", str(path), "--check"], capture_output=True, text=True,
                          timeout=60)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert "[[ros2]] #1" in done.stderr and "fully qualified" in done.stderr


def test_an_input_that_a_bind_feeds_already_takes_no_topic(tmp_path):
    text = (ROOT / "examples" / "arm_ros2.toml").read_text()
    text = text.replace('"../nodes/', f'"{ROOT.as_posix()}/nodes/').replace('"mdl_requester.py:', f'"{ROOT.as_posix()}/examples/mdl_requester.py:')
    text = text.replace('"mdl_ideal_arm.py:', f'"{ROOT.as_posix()}/examples/mdl_ideal_arm.py:')
    path = tmp_path / "arm.toml"
    path.write_text(text + '''
[[ros2]]
channel = "arm.setpoints"
topic = "/arm/setpoints"
type = "sensor_msgs/msg/JointState"
direction = "in"
fields = { position = "position" }
''')
    with pytest.raises(SystemFileError) as caught:
        load_system(path)
    (error,) = caught.value.errors
    assert "[[ros2]] #4" in error and "arm.setpoints is already bound ([[bind]]" in error


@pytest.mark.parametrize("table, said", [
    ('robot_description = "nope.urdf"', "robot_description 'nope.urdf': no such file beside the system file"),
    ('robot_description = "t.toml"', "is not a URDF (no <robot> element)"),
    ('robot_description = "xarm/xarm6_with_gripper.urdf"\nchannel = "arm.joint_states"',
     "unknown key(s) channel for a robot_description table"),
    ('robot_description = "xarm/xarm6_with_gripper.urdf"\ndurability = "forever"',
     'durability must be "volatile" or "transient_local"'),
])
def test_a_robot_description_that_cannot_work_is_one_error_naming_it(tmp_path, table, said):
    errors = check(tmp_path, GOOD + "\n[[ros2]]\n" + table + "\n")
    assert len(errors) == 1 and "[[ros2]] #2" in errors[0] and said in errors[0], errors


def test_durability_defaults_to_transient_local_for_latched_topics_only(tmp_path):
    path = tmp_path / "t.toml"
    beside = tmp_path / "robot.urdf"
    beside.write_text('<robot name="r"><link name="base"/></robot>')
    path.write_text(HEAD + GOOD + GOOD.replace("/joint_states", "/robot1/tf_static")
                    + GOOD.replace("/joint_states", "/latched_joints").replace('direction = "out"', 'direction = "out"\ndurability = "transient_local"')
                    + '\n[[ros2]]\nrobot_description = "robot.urdf"\n')
    mappings = load_system(path).nodes["ros2"].params["mappings"]
    assert [(m["topic"], m["durability"]) for m in mappings] == [
        ("/joint_states", "volatile"), ("/robot1/tf_static", "transient_local"), ("/latched_joints", "transient_local"),
        ("/robot_description", "transient_local")]
    assert mappings[3]["channel"] is None and mappings[3]["fields"] == {"data": {"value": beside.read_text()}}
