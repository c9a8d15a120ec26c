"""A round trip through a ROS 2 participant that is not iotad (tests/ros2/ros2_peer.py: plain
zenoh and rosbags): it sees the bridge node and its publishers in the graph, receives the arm's
JointState from a running system with the values the recording holds, and its Twist drives Buggy's
arbiter, while a topic published faster than its input's switching time is refused and recorded."""
import json
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

import xxhash

from iotad.node_host.transport import free_port
from iotad.launcher.system.system_file import load_system
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
IOTAD = str(Path(sys.executable).parent / "iotad")
PEER = str(HERE / "ros2_peer.py")
REACHED = [0.8, 0.3, -0.6, 0.0, 1.3, 0.0]  # examples/arm_ros2.toml: the reach program's target, then hold


def wait_for_hub(port: int, process: subprocess.Popen, timeout: float = 60.0) -> None:
    """Until the launcher's hub accepts connections (or the launcher ended: the test fails)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()[0][-3000:]
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.05)
    raise AssertionError(f"no hub on port {port} after {timeout} s")


def run_with_peer(system: Path, recording: Path, seconds: float, *peer_args: str) -> list[dict]:
    """Run `system` under `iotad run` and the peer beside it; the peer's lines, parsed."""
    port = free_port()
    launcher = subprocess.Popen([IOTAD, "run", str(system), "--insecure", "--port", str(port), "--until", str(seconds),
                                 "--after-live", "-o", str(recording), "--plain"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                text=True, cwd=ROOT)
    try:
        wait_for_hub(port, launcher)
        # the peer goes on until the system's messages stop (it ended), within a generous bound
        peer = subprocess.run([sys.executable, PEER, "--connect", f"tcp/127.0.0.1:{port}", "--seconds",
                               str(seconds + 60), *peer_args], capture_output=True, text=True, timeout=seconds + 120)
        assert peer.returncode == 0, peer.stderr[-3000:]
        out, _ = launcher.communicate(timeout=120)
        assert launcher.returncode == 0, out[-3000:]
    finally:
        if launcher.poll() is None:
            launcher.kill()
            launcher.communicate()
    return [json.loads(line) for line in peer.stdout.splitlines() if line.startswith("{")]


def test_the_peer_receives_the_arms_joint_states_as_recorded(tmp_path):
    recording = tmp_path / "arm.mcap"
    lines = run_with_peer(ROOT / "examples" / "arm_ros2.toml", recording, 6.0,
                          "--listen", "/joint_states=sensor_msgs/msg/JointState")
    heard = [line for line in lines if line.get("topic") == "/joint_states"]
    assert len(heard) > 50, lines[-3:]  # 100 a second once the arm is up
    (tokens,) = [line["tokens"] for line in lines if "tokens" in line]
    node = [t for t in tokens if "/NN/" in t]
    assert len(node) == 1 and node[0].endswith("/0/0/NN/%/%/iotad_arm_ros2"), tokens
    session = node[0].split("/")[2]
    assert any(t.startswith(f"@ros2_lv/0/{session}/0/1/MP/%/%/iotad_arm_ros2/%joint_states/"
                            "sensor_msgs::msg::dds_::JointState_/RIHS01_") for t in tokens), tokens
    # each message is the value the bridge took, by sequence number: the recording's own copy
    taken = [e["value"] for e in read_recording(recording).trace()
             if e["node"] == "ros2" and e["kind"] == "input" and e["action"] == "out_0"]
    gids = set()
    for line in heard:
        seq, stamp, gid = line["attachment"]
        gids.add(gid)
        message = line["message"]
        assert line["header"] == "00010000"
        assert message["name"] == ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"]
        assert message["position"] == taken[seq]["position"]
        assert message["velocity"] == taken[seq]["velocity"]
        assert message["header"]["frame_id"] == "link_base"
        assert message["header"]["stamp"]["sec"] * 10**9 + message["header"]["stamp"]["nanosec"] == stamp
    # the GID in each attachment is the graph's GID of the publisher: XXH3-128 of its token, the
    # low 64 bits then the high 64 bits, each little-endian (rmw_zenoh's Entity; the test of the
    # wire quotes its code)
    (publisher,) = [t for t in tokens if "/MP/" in t and "%joint_states" in t]
    high, low = struct.unpack(">QQ", xxhash.xxh3_128(publisher.encode()).digest())
    assert gids == {struct.pack("<QQ", low, high).hex()}
    seqs = [line["attachment"][0] for line in heard]
    assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
    assert heard[-1]["message"]["position"] == REACHED  # it moved, and the peer saw where to


def test_a_ros2_twist_drives_buggy_and_a_too_fast_topic_is_refused(tmp_path):
    buggy = (ROOT / "examples" / "buggy" / "buggy.iota").as_posix()
    system = tmp_path / "teleop.toml"
    system.write_text(f'''
[system]
name = "teleop"
external = ["buggy.subconscious", "buggy.proximity", "buggy.food"]

[[node]]
name = "buggy"
spec = "{buggy}"
iota = "buggy"
params = {{ DT = 0.1 }}

[[node]]
name = "slow"
python = "{(HERE / 'slow_input.py').as_posix()}:SlowInput"

[[ros2]]
channel = "buggy.conscious"
topic = "/cmd_vel"
type = "geometry_msgs/msg/Twist"
direction = "in"
fields = {{ speed = "linear.x", turn = "angular.z", why = {{ value = "WANDER" }} }}

[[ros2]]
channel = "slow.level"
topic = "/level"
type = "std_msgs/msg/Float64"
direction = "in"

[[ros2]]
channel = "buggy.setpoints"
topic = "/buggy/wheels"
type = "sensor_msgs/msg/JointState"
direction = "out"
fields = {{ name = {{ value = ["drive", "turn"] }}, velocity = "velocity_ff" }}
''')
    recording = tmp_path / "teleop.mcap"
    lines = run_with_peer(system, recording, 5.0, "--every", "0.2",
                          "--publish", '/cmd_vel=geometry_msgs/msg/Twist={"linear": {"x": 0.2}, "angular": {"z": 0.5}}',
                          "--publish", '/level=std_msgs/msg/Float64={"data": 0.75}',
                          "--listen", "/buggy/wheels=sensor_msgs/msg/JointState")
    wheels = [line["message"] for line in lines if line.get("topic") == "/buggy/wheels"]
    assert wheels and wheels[-1] == {**wheels[-1], "name": ["drive", "turn"], "velocity": [0.2, 0.5]}
    trace = read_recording(recording).trace()
    commands = [e["value"] for e in trace if e["node"] == "buggy" and e["kind"] == "input" and e["action"] == "conscious"]
    assert commands and all(c == {"speed": 0.2, "turn": 0.5, "why": "WANDER"} for c in commands)
    setpoints = [e["value"] for e in trace if e["node"] == "buggy" and e["kind"] == "output" and e["action"] == "setpoints"]
    assert setpoints[-1]["velocity_ff"] == [0.2, 0.5]
    first = next(e["t"] for e in trace if e["node"] == "buggy" and e["action"] == "conscious")
    assert all(e["value"]["velocity_ff"] == [0.0, 0.0] for e in trace if e["node"] == "buggy"
               and e["action"] == "setpoints" and e["t"] < first)  # standing until the first Twist
    # /level every 0.2 s into an input that takes one a second: most are refused at the bridge,
    # each one recorded as a switching_time violation; the bridge forwards the others a second
    # apart or more, and each reaches slow.level
    refused = [e for e in trace if e["node"] == "ros2" and e["kind"] == "violation" and e["action"] == "ros_1"]
    assert refused and all(e["value"]["violation"] == "switching_time" for e in refused)
    forwarded = [e["t"] for e in trace if e["node"] == "ros2" and e["kind"] == "output" and e["action"] == "in_1"]
    assert forwarded and all(b - a >= 1.0 - 1e-9 for a, b in zip(forwarded, forwarded[1:])), forwarded
    taken = [e for e in trace if e["node"] == "slow" and e["kind"] == "input" and e["action"] == "level"]
    assert taken and all(e["value"] == 0.75 for e in taken)
    # slow judges the second by when each arrives: a forward held up on a loaded machine more
    # than its successor (over 2 ms, the system's arrival_tolerance) arrives sooner than a
    # second after it, and is refused there and recorded as such; none is lost (the last may
    # still be on its way as the run ends)
    early = [e for e in trace if e["node"] == "slow" and e["kind"] == "violation"]
    assert all(e["value"]["violation"] == "switching_time" for e in early), early
    assert len(forwarded) - 1 <= len(taken) + len(early) <= len(forwarded), (forwarded, taken, early)
    assert len(refused) > len(taken)


def test_the_buggy_example_on_ros2_checks():
    system = load_system(ROOT / "examples" / "buggy_ros2.toml")
    bridge = system.nodes["ros2"]
    assert [m["topic"] for m in bridge.params["mappings"]] == ["/cmd_vel", "/buggy/pose", "/buggy/wheels"]
    assert {str(b.source): str(b.target) for b in system.bindings if "ros2" in (b.source.node, b.target.node)} == {
        "ros2.in_0": "buggy.conscious", "body.pose": "ros2.out_1", "buggy.setpoints": "ros2.out_2"}
