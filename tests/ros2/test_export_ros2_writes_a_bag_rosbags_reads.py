"""`iotad export --ros2` writes a rosbag2 bag (MCAP storage, ros2msg schemas, cdr, metadata.yaml)
that rosbags' own reader opens, with one message per recorded value, values equal."""
import math
import subprocess
import sys
from pathlib import Path

import pybullet_data
import pytest
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
IOTAD = str(Path(sys.executable).parent / "iotad")
STORE = get_typestore(Stores.ROS2_JAZZY)


def iotad(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([IOTAD, *args], capture_output=True, text=True, timeout=240, cwd=ROOT)


@pytest.fixture(scope="module")
def arm_recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("arm") / "arm.mcap"
    done = iotad("run", "examples/arm_ros2.toml", "--virtual", "--until", "3", "-o", str(path))
    assert done.returncode == 0 and ", 0 violations" in done.stdout, done.stdout + done.stderr
    return path


def bag_messages(bag: Path) -> dict[str, list]:
    found: dict[str, list] = {}
    with Reader(bag) as reader:
        for connection, stamp, data in reader.messages():
            found.setdefault(connection.topic, []).append((stamp, STORE.deserialize_cdr(data, connection.msgtype)))
    return found


def test_the_mapped_joint_states_are_a_bag_with_every_value(arm_recording, tmp_path):
    bag = tmp_path / "arm_bag"
    done = iotad("export", "--ros2", str(arm_recording), "-o", str(bag))
    assert done.returncode == 0, done.stderr
    assert (bag / "metadata.yaml").is_file()
    recorded = [m for m in read_recording(arm_recording).messages if m.topic == "iota/arm_ros2/arm/joint_states"]
    with Reader(bag) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert reader.message_count == 2 * len(recorded) + 1
    assert types == {"/joint_states": "sensor_msgs/msg/JointState", "/arm/joint1": "std_msgs/msg/Float64",
                     "/robot_description": "std_msgs/msg/String"}
    assert counts == {"/joint_states": len(recorded), "/arm/joint1": len(recorded), "/robot_description": 1}
    assert len(recorded) == 300
    found = bag_messages(bag)
    # the robot model the system declares, once, at the start of the recording
    ((stamp, description),) = found["/robot_description"]
    assert stamp == read_recording(arm_recording).messages[0].log_time
    assert description.data == (Path(pybullet_data.getDataPath()) / "xarm/xarm6_with_gripper.urdf").read_text()
    for message, (stamp, joint_state), (_, joint1) in zip(recorded, found["/joint_states"], found["/arm/joint1"]):
        assert stamp == message.log_time
        assert joint_state.position.tolist() == message.value["position"]
        assert joint_state.name == [f"joint{i}" for i in range(1, 7)] and joint_state.header.frame_id == "link_base"
        assert joint1.data == message.value["position"][0]
    # the storage is rosbag2's MCAP: ros2msg schemas (the .msg text), cdr messages
    (mcap_file,) = bag.glob("*.mcap")
    with open(mcap_file, "rb") as stream:
        summary = make_reader(stream).get_summary()
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
    assert any(s.name == "sensor_msgs/msg/JointState" and b"float64[] position" in s.data
               for s in summary.schemas.values())


def test_a_pose_without_a_mapping_is_exported_too_and_an_existing_bag_is_kept(tmp_path):
    recording = tmp_path / "buggy.mcap"
    done = iotad("run", "examples/buggy.toml", "--virtual", "--until", "3", "-o", str(recording))
    assert done.returncode == 0, done.stdout + done.stderr
    bag = tmp_path / "buggy_bag"
    done = iotad("export", "--ros2", str(recording), "-o", str(bag))
    assert done.returncode == 0, done.stderr
    poses = [m.value for m in read_recording(recording).messages if m.topic == "iota/buggy/body/pose"]
    found = bag_messages(bag)
    assert len(found["/iotad/body/pose"]) == len(poses) > 10
    for pose, (_, message) in zip(poses, found["/iotad/body/pose"]):
        assert (message.pose.position.x, message.pose.position.y) == (pose["x"], pose["y"])
        assert math.isclose(2 * math.atan2(message.pose.orientation.z, message.pose.orientation.w),
                            pose["yaw"], abs_tol=1e-9) or abs(pose["yaw"]) > math.pi - 1e-6
    assert "/iotad/motor/joint_states" in found  # the CAN motor node's joint states
    again = iotad("export", "--ros2", str(recording), "-o", str(bag))
    assert again.returncode != 0 and "exists" in again.stderr and (bag / "metadata.yaml").is_file()
