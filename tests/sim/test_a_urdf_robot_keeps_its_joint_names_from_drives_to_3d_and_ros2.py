"""Any URDF, end to end: `world = "urdf"` loads it into PyBullet with a simulated drive on each
of its joints by name; the 3D scene (`iotad export --json`, what `iotad view` sends) draws that
URDF with the joint map's names, its links where PyBullet puts them; `iotad export --ros2` names
the joints as the joint map does, and writes the `/iotad/...` joint states beside mapped topics.
With the shipped pan-tilt head (2 joints) and pybullet_data's KUKA iiwa (7)."""
import json
import re
import math
import random
from pathlib import Path

import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

import iotad
from iotad.cli import main
from iotad.kernel.package_files import package_file
from iotad.recording import robot_model
from iotad.recording.urdf_robot import load_urdf

ROBOTS = {"pan_tilt": ("sim.robots:pan_tilt.urdf", ["pan", "tilt"]),
          "kuka": ("pybullet_data:kuka_iiwa/model.urdf", [f"lbr_iiwa_joint_{k}" for k in range(1, 8)])}


@pytest.fixture(scope="module", params=list(ROBOTS))
def robot(request, tmp_path_factory):
    """(URDF file, joint names, recording of 3 s of the robot `iotad new --urdf NAME` makes)."""
    urdf, names = ROBOTS[request.param]
    where = tmp_path_factory.mktemp(request.param)
    assert main(["new", "robot", "--urdf", request.param, "--in", str(where)]) == 0
    recording = where / "run.mcap"
    assert main(["run", str(where / "robot" / "robot.toml"), "--virtual", "--until", "3", "--strict",
                 "-o", str(recording), "--plain"]) == 0
    return package_file(urdf), names, recording


def test_the_drives_drive_the_urdfs_joints_by_name(robot):
    urdf, names, recording = robot
    opened = iotad.open_recording(recording)
    drives = opened.raw.specs["drives"]["params"]
    assert list(drives["node_ids"]) == names and drives["world"] == "urdf"
    states = [s.value["position"] for s in opened.values("iota/robot/motor/joint_states")]
    for k, name in enumerate(names):  # the sweep's first leg moves every joint a quarter of its range
        assert max(p[k] for p in states) - min(p[k] for p in states) > 0.05, name


def decoded(schema, data: bytes):
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name)).FromString(data)


def test_the_3d_scene_draws_the_urdf_with_the_joint_maps_names(robot, tmp_path):
    urdf, names, recording = robot
    out = tmp_path / "fox.mcap"
    assert main(["export", "--json", str(recording), "-o", str(out)]) == 0
    found: dict[str, list] = {}
    with open(out, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(
                topics=["/robot_description", "/scene/arm_joints", "/scene/transforms", "/scene/arm_model"]):
            value = message.data if channel.message_encoding == "json" else decoded(schema, message.data)
            found.setdefault(channel.topic, []).append(value)
    assert len(found["/robot_description"]) == 1
    assert json.loads(found["/robot_description"][0])["data"] == urdf.read_text()
    last = found["/scene/arm_joints"][-1]
    assert [j.name for j in last.joints] == names
    recorded = [s.value["position"] for s in iotad.open_recording(recording).values("iota/robot/motor/joint_states")]
    assert [j.position for j in last.joints] == pytest.approx(recorded[-1])
    links = {t.child_frame_id for t in found["/scene/transforms"][-1].transforms}
    assert {j.child for j in load_urdf(str(urdf)).joints} <= links
    assert found["/scene/arm_model"][0].entities  # its shapes or meshes, each locked to a link


def test_the_scenes_frames_are_where_pybullet_puts_the_links(robot):
    from sim.worlds.urdf_world import UrdfWorld

    urdf, names, _ = robot
    world = UrdfWorld(str(urdf), floor=False)
    try:
        import pybullet

        rng = random.Random(7)
        positions = {name: rng.uniform(max(lo, -1.0), min(hi, 1.0))
                     for name, lo, hi in zip(world.joint_names, world.lower_limits, world.upper_limits)}
        for j, name in zip(world.arm_joints, world.joint_names):
            pybullet.resetJointState(world.body, j, positions[name], physicsClientId=world.client)
        robot_frames = load_urdf(str(urdf))
        poses = {robot_frames.root_link(): ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))}
        for parent, child, t, r in robot_frames.link_transforms(positions):
            origin, rotation = poses[parent]
            moved = robot_model.rotate(rotation, t)
            poses[child] = (tuple(a + b for a, b in zip(origin, moved)), robot_model.quaternion_multiply(rotation, r))
        for link, index in world.links.items():
            state = pybullet.getLinkState(world.body, index, computeForwardKinematics=True, physicsClientId=world.client)
            assert poses[link][0] == pytest.approx(state[4], abs=1e-6), link
            dot = abs(sum(a * b for a, b in zip(poses[link][1], state[5])))
            assert math.isclose(dot, 1.0, abs_tol=1e-6), link
    finally:
        world.close()


def test_the_ros2_export_names_the_joints_as_the_joint_map_does(robot, tmp_path):
    _, names, recording = robot
    bag = tmp_path / "bag"
    assert main(["export", "--ros2", str(recording), "-o", str(bag)]) == 0
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        states = [store.deserialize_cdr(data, c.msgtype) for c, _, data in reader.messages()
                  if c.topic == "/iotad/motor/joint_states"]
    assert states and all(list(s.name) == names for s in states)


def test_the_live_view_draws_the_same_robot_from_the_nodes_specs(robot):
    """`iotad view`'s bridge learns the robot from each node's @spec (as the recording keeps
    them) and sends the URDF and the named joints for each joint-states message."""
    from iotad.recording.foxglove_live import Bridge

    urdf, names, recording = robot
    opened = iotad.open_recording(recording)
    bridge = Bridge()
    sent: dict[str, list] = {}

    class Channel:
        def __init__(self, topic):
            self.topic = topic

        def log(self, message, log_time=None):
            sent.setdefault(self.topic, []).append(message)

    bridge._scene_channel = lambda topic, message: Channel(topic)
    # the channel's own joint-states view too
    bridge._kinds["joints"] = (bridge._joints, lambda topic: Channel(topic))
    for spec in opened.raw.specs.values():
        bridge.describe(spec)
    states = opened.values("iota/robot/motor/joint_states")
    for sample in states[:5]:
        bridge.message(sample.key, sample.value, sample.send_ns)
    assert sent["/robot_description"] == [{"data": urdf.read_text()}]
    shown = [decoded(m.get_schema(), m.encode()) for m in sent["/scene/arm_joints"]]
    assert [[j.name for j in m.joints] for m in shown] == [names] * 5
    plain = [decoded(m.get_schema(), m.encode()) for m in sent["/motor/joint_states/joints"]]
    assert [[j.name for j in m.joints] for m in plain] == [names] * 5
    assert [[j.position for j in m.joints] for m in shown] == [s.value["position"] for s in states[:5]]


@pytest.mark.parametrize("options, said", [
    ({}, "needs the option urdf"),
    ({"urdf": "/no/such/robot.urdf"}, "no URDF file '/no/such/robot.urdf'"),
    ({"urdf": "sim.robots:nothing.urdf"}, "has no file 'nothing.urdf'"),
    ({"urdf": "sim.robots:pan_tilt.urdf", "home": [0.1]}, "home needs 2 joint positions (pan, tilt), got 1"),
])
def test_a_urdf_world_that_cannot_be_built_says_why(options, said):
    from sim.worlds import make_world

    with pytest.raises(ValueError, match=re.escape(said)):
        make_world("urdf", **options)
