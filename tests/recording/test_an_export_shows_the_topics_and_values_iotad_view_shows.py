"""`iotad export --json` writes a recording through the mapping `iotad view` serves live
(iotad/recording/foxglove_mapping.py): every channel on `/<node path>/<channel>[/<k>]` with the
values the mapping gives (bare values wrapped, CAN frames with their `decoded` name), joint
states and planar poses in Foxglove's own schemas beside them, the nodes' acks, commands and
violations on `/log`; protobuf messages decoded by the schema the file carries."""
import json
from pathlib import Path

import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader

from iotad.cli import main
from iotad.node_host import wire
from iotad.recording.foxglove_scene import SceneTracker
from iotad.recording.foxglove_mapping import LOG_TOPIC, can_decoded, log_lines, topic_of, views
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]


def decoder(name: str, data: bytes):
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(data).file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def exported(tmp_path, example: str, seconds: str) -> tuple:
    recording, out = tmp_path / "run.mcap", tmp_path / "run-foxglove.mcap"
    assert main(["run", str(ROOT / "examples" / example), "--virtual", "--until", seconds, "-o", str(recording),
                 "--plain"]) == 0
    assert main(["export", "--json", str(recording), "-o", str(out)]) == 0
    found: dict[str, list] = {}
    with open(out, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages(log_time_order=False):
            if channel.message_encoding == "json":
                value = json.loads(message.data)
            else:
                value = decoder(schema.name, schema.data).FromString(message.data)
            found.setdefault(channel.topic, []).append((schema.name, value))
    return read_recording(recording), found


def test_figure2_exports_each_channel_on_the_view_topic_with_the_view_values_and_its_log(tmp_path):
    recording, found = exported(tmp_path, "figure2.toml", "10")
    expected: dict[str, list] = {}
    for message in recording.messages:
        parsed = wire.parse_key(message.topic)
        if parsed is not None and not parsed[2].startswith("@"):
            for topic, kind, value in views(message.topic, None, message.value):
                expected.setdefault(topic, []).append(value)
    assert {"/scheduler/ack/0", "/scheduler/ack/1", "/vision/req", "/manipulation/req"} <= set(expected)
    for topic, values in expected.items():
        assert [value for _, value in found[topic]] == values, topic
        assert topic not in recording.topics()  # the recording's key is not exported a second time
    assert found["/scheduler/ack/0"][0] == ("ack", {"value": "ABORT"})  # the channel's type names its schema
    assert found["/vision/req"][0][1]["priority"] == 1
    # /log: the mapping's lines from the nodes' traces, as foxglove.Log
    lines = [line for node in recording.nodes() for _, _, line in log_lines(node, recording.trace(node))]
    logged = found[LOG_TOPIC]
    assert {name for name, _ in logged} == {"foxglove.Log"}
    assert sorted(log.message for _, log in logged) == sorted(lines) and lines
    assert any(line.startswith("scheduler.ack[0] = ") for line in lines)
    # what is no channel (the traces) stays on its own key
    assert len(found["iota/figure2/scheduler/@trace"]) == len(recording.trace("scheduler", starts=True))


def test_joint_states_can_frames_and_poses_show_in_foxglove_schemas(tmp_path):
    recording, found = exported(tmp_path, "buggy.toml", "1")
    states = [m.value for m in recording.messages if m.topic == "iota/buggy/motor/joint_states"]
    joints = found["/motor/joint_states/joints"]
    assert states and len(joints) == len(states) and {name for name, _ in joints} == {"foxglove.JointStates"}
    tracker = SceneTracker(embed=True)  # the joint map's names, as the live view names them
    for spec in recording.specs.values():
        tracker.learn(spec)
    names = tracker.robots.names_for("motor", len(states[0]["position"])) or \
        [f"j{k}" for k in range(len(states[0]["position"]))]
    for state, (_, message) in zip(states, joints):
        assert [j.position for j in message.joints] == pytest.approx(state["position"])
        assert [j.name for j in message.joints] == names
    poses = [m.value for m in recording.messages if m.topic == "iota/buggy/body/pose"]
    shown = found["/body/pose/pose"]
    assert poses and len(shown) == len(poses) and {name for name, _ in shown} == {"foxglove.PoseInFrame"}
    assert [c for _, p in shown for c in (p.pose.position.x, p.pose.position.y)] == pytest.approx(
        [c for p in poses for c in (p["x"], p["y"])])
    assert all(p.frame_id == "world" for _, p in shown)
    frames = [m.value for m in recording.messages if m.topic == "iota/buggy/motor/can_tx"]
    sent = found[topic_of("iota/buggy/motor/can_tx")]
    assert frames and [value["decoded"] for _, value in sent] == [can_decoded(f) for f in frames]
    assert all(name == "canFrame" for name, _ in sent) and not sent[0][1]["decoded"].startswith("not ")
