"""The robot in 3D for Foxglove (iotad/recording/foxglove_scene.py, robot_model.py): the xArm6's
frames are where PyBullet puts its links, and every message `iotad export --json` and `iotad view`
make of a run is one that Foxglove's own schema (foxglove-sdk's, protobuf) decodes byte for byte."""
import json
import math
import random
import subprocess
import sys
from pathlib import Path

import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader

from iotad.recording.foxglove_live import Bridge
from iotad.recording import robot_model
from iotad.recording.foxglove_scene import SceneTracker
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
IOTAD = str(Path(sys.executable).parent / "iotad")


def decoder(name: str, encoding: str, data: bytes):
    """The protobuf class a schema record describes (a FileDescriptorSet), built by protobuf itself."""
    assert encoding == "protobuf"
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(data).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def valid(message) -> object:
    """`message` decoded by its schema, which must account for every byte."""
    schema = message.get_schema()
    data = message.encode()
    decoded = decoder(schema.name, schema.encoding, schema.data).FromString(data)
    assert decoded.SerializeToString() == data
    return decoded


def frames(positions: list[float]) -> dict[str, tuple]:
    """World pose of every link, composed from the transforms the scene sends."""
    poses = {robot_model.ROOT_FRAME: ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))}
    named = dict(zip(robot_model.ARM_JOINTS, positions))
    for parent, child, t, r in robot_model.link_transforms(named):
        origin, rotation = poses[parent]
        moved = robot_model.rotate(rotation, t)
        poses[child] = (tuple(a + b for a, b in zip(origin, moved)), robot_model.quaternion_multiply(rotation, r))
    return poses


def test_the_arms_frames_are_where_pybullet_puts_its_links():
    pybullet = pytest.importorskip("pybullet")
    client = pybullet.connect(pybullet.DIRECT)
    try:
        pybullet.setAdditionalSearchPath(str(robot_model.data_root()), physicsClientId=client)
        body = pybullet.loadURDF(robot_model.URDF, useFixedBase=True, physicsClientId=client)
        index = {pybullet.getJointInfo(body, i, physicsClientId=client)[12].decode(): i
                 for i in range(pybullet.getNumJoints(body, physicsClientId=client))}
        joints = {pybullet.getJointInfo(body, i, physicsClientId=client)[1].decode(): i for i in index.values()}
        rng = random.Random(4)
        for _ in range(5):
            positions = [rng.uniform(-1.5, 1.5) for _ in range(6)]
            for name, angle in zip(robot_model.ARM_JOINTS, positions):
                pybullet.resetJointState(body, joints[name], angle, physicsClientId=client)
            ours = frames(positions)
            for link in ("link1", "link3", "link6"):
                state = pybullet.getLinkState(body, index[link], computeForwardKinematics=True, physicsClientId=client)
                assert all(math.isclose(a, b, abs_tol=1e-4) for a, b in zip(ours[link][0], state[4]))
                dot = abs(sum(a * b for a, b in zip(ours[link][1], state[5])))  # q and -q: one rotation
                assert math.isclose(dot, 1.0, abs_tol=1e-4)
    finally:
        pybullet.disconnect(client)


def test_every_scene_message_validates_against_foxglove_schemas():
    tracker = SceneTracker(embed=False)
    made = tracker.feed("iota/s/arm/joint_states", {"position": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6],
                                                    "velocity": [1.0] * 6, "effort": [0.0] * 6}, 3_000_000_001)
    made += tracker.feed("iota/s/body/landmark", {"kind": "WALL", "id": 0, "x1": -2, "y1": -2, "x2": 2, "y2": 2}, 1)
    made += tracker.feed("iota/s/body/landmark", {"kind": "FOOD", "id": 1, "x1": 0.5, "y1": 0.5, "x2": 0.5, "y2": 0.5}, 2)
    made += tracker.feed("iota/s/body/landmark", {"kind": "EATEN", "id": 1, "x1": 0.5, "y1": 0.5, "x2": 0.5, "y2": 0.5}, 3)
    made += tracker.feed("iota/s/body/pose", {"x": 0.5, "y": -0.25, "yaw": math.pi / 2}, 4)
    made += tracker.feed("iota/s/sim/scene", {"t": 1.0, "belt": [0.45, 1.2, 0.16, 0.1], "bin": [0.1, -0.45, 0.3, 0.12],
                                              "cube_size": 0.04, "count": 2, "x": [0.45, 0.1, 0.0], "y": [0.3, -0.45, 0.0],
                                              "z": [0.12, 0.03, 0.0], "colour": [2, 0, 0]}, 5)
    topics = [topic for topic, _ in made]
    assert topics == ["/robot_description", "/scene/arm_model", "/scene/transforms", "/scene/arm_joints",
                      "/scene/arena", "/scene/arena", "/scene/arena", "/scene/path", "/scene/pose", "/scene/conveyor"]
    typed = {topic: valid(message) for topic, message in made if not isinstance(message, dict)}
    model = typed["/scene/arm_model"]
    assert [e.frame_id for e in model.entities] == [v.link for v in robot_model.model()[1]]
    assert all(e.frame_locked and e.models[0].url.startswith("package://") for e in model.entities)
    joints = typed["/scene/arm_joints"]
    assert [j.name for j in joints.joints] == list(robot_model.ARM_JOINTS)
    assert [j.position for j in joints.joints] == [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]
    assert (joints.timestamp.seconds, joints.timestamp.nanos) == (3, 1)
    tf = typed["/scene/transforms"]
    assert {(t.parent_frame_id, t.child_frame_id) for t in tf.transforms} >= {("world", "link_base"), ("link5", "link6")}
    (arena,) = typed["/scene/arena"].entities  # the last: one wall square and the food, eaten (grey)
    assert len(arena.lines) == 1 and len(arena.lines[0].points) == 5 and arena.spheres[0].color.g < 0.7
    pose = typed["/scene/pose"]
    assert pose.frame_id == "world" and math.isclose(pose.pose.orientation.z, math.sqrt(0.5))
    (world,) = typed["/scene/conveyor"].entities  # the belt, the bin's floor and four walls, two cubes
    assert len(world.cubes) == 1 + 5 + 2
    belt, cube = world.cubes[0], world.cubes[6]
    assert (belt.size.x, belt.size.y, belt.pose.position.x) == (0.16, 1.2, 0.45)
    assert (cube.pose.position.x, cube.pose.position.y, cube.size.x, cube.color.b) == (0.45, 0.3, 0.04, 0.9)
    # the URDF is the simulation's, for Foxglove's URDF layer
    assert dict(made)["/robot_description"]["data"] == robot_model.urdf_text()


def test_the_live_server_answers_the_meshes_and_nothing_else():
    (visual, *_) = robot_model.model()[1]
    assert Bridge.asset(visual.mesh) == robot_model.mesh_path(visual.mesh).read_bytes()
    assert Bridge.asset("package://xarm_description/../../../../etc/passwd") is None
    assert Bridge.asset("file:///etc/passwd") is None


@pytest.mark.parametrize("system, seconds", [("arm_ros2.toml", "2"), ("buggy.toml", "4"), ("conveyor.toml", "3")])
def test_an_exported_run_carries_the_robot_in_foxglove_schemas(tmp_path, system, seconds):
    recording, exported = tmp_path / "run.mcap", tmp_path / "run-foxglove.mcap"
    done = subprocess.run([IOTAD, "run", f"examples/{system}", "--virtual", "--until", seconds, "-o", str(recording)],
                          capture_output=True, text=True, timeout=240, cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    done = subprocess.run([IOTAD, "export", str(recording), "-o", str(exported), "--json"],
                          capture_output=True, text=True, timeout=240, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    found: dict[str, list] = {}
    with open(exported, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            if not channel.topic.startswith(("/scene/", "/robot_description")):
                continue
            if channel.message_encoding == "protobuf":
                decoded = decoder(schema.name, schema.encoding, schema.data).FromString(message.data)
                assert decoded.SerializeToString() == message.data
            else:
                decoded = json.loads(message.data)
            found.setdefault(channel.topic, []).append((message.log_time, decoded))
    values = read_recording(recording).messages
    if system == "arm_ros2.toml":
        recorded = [m for m in values if m.topic == "iota/arm_ros2/arm/joint_states"]
        assert len(found["/scene/arm_joints"]) == len(found["/scene/transforms"]) == len(recorded) > 100
        for message, (stamp, joints) in zip(recorded, found["/scene/arm_joints"]):
            assert stamp == message.log_time
            assert [j.position for j in joints.joints] == message.value["position"]
        (_, model), = found["/scene/arm_model"]
        assert all(e.models[0].media_type == "model/stl" and len(e.models[0].data) > 1000 for e in model.entities)
        assert found["/robot_description"][0][1]["data"] == robot_model.urdf_text()
    elif system == "conveyor.toml":
        scenes = [m.value for m in values if m.topic == "iota/conveyor/sim/scene"]
        assert len(found["/scene/conveyor"]) == len(scenes) > 10
        (entity,) = found["/scene/conveyor"][-1][1].entities
        assert len(entity.cubes) == 6 + scenes[-1]["count"] and scenes[-1]["count"] >= 1  # the first cube is out
        arm = [m.value for m in values if m.topic == "iota/conveyor/motor/joint_states"]
        assert len(found["/scene/arm_joints"]) == len(arm) and len(arm[0]["position"]) == 7  # the gripper, left out
        assert [j.position for j in found["/scene/arm_joints"][-1][1].joints] == arm[-1]["position"][:6]
    else:
        poses = [m.value for m in values if m.topic == "iota/buggy/body/pose"]
        assert len(found["/scene/pose"]) == len(poses) > 10
        last_path = found["/scene/path"][-1][1].entities[0].lines[0].points
        assert (last_path[-1].x, last_path[-1].y) == pytest.approx((poses[-1]["x"], poses[-1]["y"]), abs=0.011)
        arena = found["/scene/arena"][-1][1].entities[0]
        landmarks = [m.value for m in values if m.topic == "iota/buggy/body/landmark"]
        assert len(arena.lines) == sum(v["kind"] in ("WALL", "CRACK") for v in landmarks)
        assert len(arena.spheres) == len({v["id"] for v in landmarks if v["kind"] == "FOOD"})


def test_the_layout_in_the_repository_opens_the_scene_topics():
    from iotad.recording.foxglove_layout import LOG_TOPIC, layout_json
    from iotad.recording.foxglove_scene import TOPICS

    committed = json.loads((ROOT / "docs" / "foxglove-layout.json").read_text())
    assert committed == json.loads(layout_json())  # regenerate it with layout_json() when the scene changes
    panels = {}

    def walk(node):
        if node.get("type") == "panel":
            panels[node["panelType"]] = node["config"]
        for item in node.get("items", []):
            walk(item["content"])
    walk(committed["content"])
    assert set(panels) == {"ThreeDee", "Plot", "Log"}
    assert set(panels["ThreeDee"]["topics"]) <= set(TOPICS) and panels["ThreeDee"]["fixedFrame"] == "world"
    assert all(p["value"].split(".")[0] in TOPICS for p in panels["Plot"]["paths"])
    assert panels["Log"]["topicToRender"] == LOG_TOPIC
