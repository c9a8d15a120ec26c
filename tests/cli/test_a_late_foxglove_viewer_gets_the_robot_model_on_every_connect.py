"""A viewer of `iotad view` that connects after the arm's model went out still gets it: a client
written here from Foxglove's WebSocket protocol (subprotocol foxglove.sdk.v1: serverInfo,
advertise, subscribe, binary message data) connects once /robot_description and /scene/arm_model
have been logged (it sees them advertised before it subscribes, so they were sent before it
existed), subscribes, and receives the URDF and the meshes; it disconnects, connects again, and
receives them again."""
import json
import struct
import subprocess
import sys
import time
from pathlib import Path

import pybullet_data
import pytest

from launcher_helpers import free_port, launcher, stop_launcher, wait_until

ROOT = Path(__file__).resolve().parents[2]
websockets_client = pytest.importorskip("websockets.sync.client")
pytest.importorskip("foxglove")
LATCHED = ("/robot_description", "/scene/arm_model")


def advertised_channels(ws, wanted, timeout=60.0) -> dict:
    """The channels the server advertises until every `wanted` topic is among them."""
    channels = {}
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not all(t in channels for t in wanted):
        try:
            message = ws.recv(timeout=0.5)
        except TimeoutError:
            continue
        if isinstance(message, str):
            body = json.loads(message)
            if body["op"] == "advertise":
                channels.update({c["topic"]: c for c in body["channels"]})
    return channels


def latched_messages(ws, channels) -> dict:
    """Subscribe to the latched topics; the first message of each (by subscription id)."""
    ids = {number: topic for number, topic in enumerate(LATCHED, 1)}
    ws.send(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": number, "channelId": channels[topic]["id"]} for number, topic in ids.items()]}))
    got = {}
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline and len(got) < len(ids):
        try:
            message = ws.recv(timeout=0.5)
        except TimeoutError:
            continue
        if isinstance(message, bytes) and message[0] == 1:
            subscription, _stamp = struct.unpack_from("<IQ", message, 1)
            got.setdefault(ids[subscription], message[13:])
        elif isinstance(message, str):
            body = json.loads(message)
            assert not (body["op"] == "status" and body.get("level") == 2), body  # a refused subscription
    return got


def test_a_viewer_connecting_late_and_again_receives_the_urdf_and_the_meshes(tmp_path):
    port, ws_port = free_port(), free_port()
    text = (ROOT / "examples" / "arm_ros2.toml").read_text()
    text = text.replace('"../nodes/', f'"{ROOT.as_posix()}/nodes/')
    for name in ("mdl_requester.py:", "mdl_ideal_arm.py:"):
        text = text.replace(f'"{name}', f'"{ROOT.as_posix()}/examples/{name}')
    system = tmp_path / "arm.toml"
    system.write_text(text)
    urdf = (Path(pybullet_data.getDataPath()) / "xarm/xarm6_with_gripper.urdf").read_text()
    received = []
    with launcher(system, "--port", str(port), "--until", "300", "-o", str(tmp_path / "arm.mcap")) as proc:
        # the viewer needs the hub; the arm's joint states flow once the engines start
        assert wait_until(lambda: "start gate open" in proc.output.read_text(), 60), proc.output.read_text()
        view = subprocess.Popen([sys.executable, "-m", "iotad", "view", "--connect", f"tcp/127.0.0.1:{port}",
                                 "--system", "arm_ros2", "--port", str(ws_port), "--until", "300"],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            assert "serving arm_ros2" in view.stdout.readline()
            # a first client only watches for the model's channels: once advertised, the model was
            # logged (a channel is made by its first message), with no one subscribed to it
            with websockets_client.connect(f"ws://127.0.0.1:{ws_port}", subprotocols=["foxglove.sdk.v1"]) as ws:
                first = advertised_channels(ws, LATCHED)
                assert all(t in first for t in LATCHED), proc.output.read_text()[-2000:]
            for _ in range(2):  # the late viewer, then the same viewer reconnecting
                with websockets_client.connect(f"ws://127.0.0.1:{ws_port}", subprotocols=["foxglove.sdk.v1"]) as ws:
                    assert json.loads(ws.recv(timeout=10))["op"] == "serverInfo"
                    channels = advertised_channels(ws, LATCHED)
                    assert all(t in channels for t in LATCHED)  # advertised at once: they exist already
                    received.append(latched_messages(ws, channels))
        finally:
            view.terminate()
            view_said = view.communicate(timeout=10)[0]
        stop_launcher(proc)
    for got in received:
        assert set(got) == set(LATCHED), (got.keys(), view_said[-1500:])
        assert json.loads(got["/robot_description"]) == {"data": urdf}
        # the meshes: a foxglove.SceneUpdate whose models point at the URDF's package:// meshes,
        # which the server answers as assets
        assert got["/scene/arm_model"].count(b"package://xarm_description/meshes/") >= 7


def test_the_arena_and_the_conveyor_are_latched_too_and_the_moving_parts_are_not():
    from iotad.recording.foxglove_latched import LatchedScene
    from iotad.recording.foxglove_scene import SceneTracker

    class Channel:
        def __init__(self):
            self.logged = []

        def log(self, message, log_time=None):
            self.logged.append((message, log_time))

    tracker, latched, channels = SceneTracker(), LatchedScene(), {}
    values = [{"kind": "WALL", "id": 0, "x1": 0.0, "y1": 0.0, "x2": 1.0, "y2": 0.0},
              {"kind": "FOOD", "id": 1, "x1": 0.5, "y1": 0.5, "x2": 0.6, "y2": 0.6},
              {"belt": [0.4, 1.0, 0.2, 0.1], "bin": [0.0, 0.5, 0.3, 0.1], "cube_size": 0.04, "count": 1,
               "x": [0.4], "y": [0.0], "z": [0.12], "colour": [2]},
              {"x": 1.0, "y": 2.0, "yaw": 0.5}]
    for stamp, value in enumerate(values, 1):
        for topic, message in tracker.feed(f"iota/s/n/c{stamp}", value, stamp):
            latched.keep(topic, channels.setdefault(topic, Channel()), message, stamp)
    assert latched.resend("/scene/arena") and latched.resend("/scene/conveyor")
    assert not latched.resend("/scene/pose") and not latched.resend("/scene/path")
    # the latest arena (made from both landmarks, at the second) and the conveyor
    assert channels["/scene/arena"].logged[-1][1] == 2
    assert channels["/scene/conveyor"].logged[-1][1] == 3
