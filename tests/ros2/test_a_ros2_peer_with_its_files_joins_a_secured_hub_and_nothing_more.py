"""A ROS 2 machine inside the trust boundary: `iotad certs ros2 rviz` writes its certificate and
rmw_zenoh's session configuration (TLS to the hub, its own user and password), and the hub of
`iotad run --certs` (access control on) admits it with the rights the [[ros2]] tables give: a
participant that is not iotad (tests/ros2/ros2_peer.py, opening its session from that file as
rmw_zenoh does from ZENOH_SESSION_CONFIG_URI) receives /joint_states and its Twist drives Buggy.
The same participant is refused without the files; what it puts on an out topic, an unmapped
topic or an `iota/...` key reaches no one (a tools session subscribed to every key hears none of
it) and the recording holds none of it."""
import json
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

from iotad.node_host.transport import PeerUnreachable, free_port, open_tool_session
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
PEER = str(HERE / "ros2_peer.py")
MARK = 777.25  # what the peer tries to slip in where it may not


def iotad(*args, cwd):
    return subprocess.run([sys.executable, "-m", "iotad", *args], capture_output=True, text=True, timeout=60, cwd=cwd)


def peer(*args, timeout=90):
    done = subprocess.run([sys.executable, PEER, *args], capture_output=True, text=True, timeout=timeout)
    lines = [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]
    return done.returncode, lines, done.stderr


def wait_for_hub(port, process, timeout=60.0):
    import socket
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.communicate()[0][-3000:]
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return
        except OSError:
            time.sleep(0.05)
    raise AssertionError(f"no hub on port {port} after {timeout} s")


def tools_session(endpoint, process, timeout=30.0):
    """A session with the tools' rights, once the run has written where their credentials are
    (just after its hub listens)."""
    deadline = time.monotonic() + timeout
    while True:
        assert process.poll() is None
        try:
            return open_tool_session([endpoint], timeout=1.0)
        except PeerUnreachable:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)


def test_a_ros2_peer_with_its_files_reads_and_drives_and_nothing_else(tmp_path):
    tcp, tls = free_port(), free_port()
    certs = tmp_path / "certs"
    for step in (["init", str(certs), "--name", "teleop"], ["host", "hub", "--dir", str(certs)],
                 ["ros2", "rviz", "--dir", str(certs), "--connect", f"tls/127.0.0.1:{tls}"]):
        made = iotad("certs", *step, cwd=tmp_path)
        assert made.returncode == 0, made.stderr
    config = certs / "ros2-rviz.json5"
    buggy = (ROOT / "examples" / "buggy" / "buggy.iota").as_posix()
    system = tmp_path / "teleop.toml"
    system.write_text(f'''
[system]
name = "teleop"
external = ["buggy.subconscious", "buggy.proximity", "buggy.food", "arm.setpoints"]

[system.endpoints]
listen = ["tcp/127.0.0.1:{tcp}", "tls/127.0.0.1:{tls}"]

[[node]]
name = "buggy"
spec = "{buggy}"
iota = "buggy"
params = {{ DT = 0.1 }}

[[node]]
name = "arm"
python = "{(ROOT / 'examples' / 'mdl_ideal_arm.py').as_posix()}:IdealArm"

[[ros2]]
channel = "buggy.conscious"
topic = "/cmd_vel"
type = "geometry_msgs/msg/Twist"
direction = "in"
fields = {{ speed = "linear.x", turn = "angular.z", why = {{ value = "WANDER" }} }}

[[ros2]]
channel = "arm.joint_states"
topic = "/joint_states"
type = "sensor_msgs/msg/JointState"
direction = "out"
fields = {{ name = {{ value = ["joint1", "joint2", "joint3", "joint4", "joint5", "joint6"] }}, position = "position" }}

[[ros2]]
robot_description = "xarm/xarm6_with_gripper.urdf"
''')
    recording = tmp_path / "teleop.mcap"
    launcher = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(system), "--certs", str(certs),
                                 "--until", "120", "--after-live", "-o", str(recording), "--plain"],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
    heard = []
    try:
        wait_for_hub(tcp, launcher)
        # a witness with the tools' rights (every key): what the hub lets through, it hears
        witness = tools_session(f"tcp/127.0.0.1:{tcp}", launcher)
        witness.declare_subscriber("**", lambda s: heard.append((str(s.key_expr), s.payload.to_bytes())))
        try:
            # without the files: no certificate for the TLS link, no password for the plain one
            for endpoint in (f"tls/127.0.0.1:{tls}", f"tcp/127.0.0.1:{tcp}"):
                code, lines, err = peer("--connect", endpoint, "--seconds", "3")
                assert code == 3 and "refused" in lines[-1], (endpoint, code, lines, err[-2000:])
            rogue = ["--publish", f'/joint_states=sensor_msgs/msg/JointState={{"position": [{MARK}]}}',
                     "--publish", f'/nope=std_msgs/msg/Float64={{"data": {MARK}}}',
                     "--put", f"iota/teleop/buggy/conscious={MARK}", "--put", f"iota/teleop/arm/joint_states={MARK}"]
            code, lines, err = peer("--config", str(config), "--seconds", "5", "--idle", "10", "--every", "0.25",
                                    "--listen", "/joint_states=sensor_msgs/msg/JointState",
                                    "--latched", "/robot_description=std_msgs/msg/String",
                                    "--latched-advanced", "/robot_description=std_msgs/msg/String",
                                    "--publish", '/cmd_vel=geometry_msgs/msg/Twist={"linear": {"x": 0.2}, "angular": {"z": 0.5}}')
            assert code == 0, (lines[-3:], err[-3000:])
            # the same peer, with the same files, now tries what it may not (a session of its own:
            # zenoh hands a session's own puts to its own subscribers, hub or no hub)
            code, tried, err = peer("--config", str(config), "--seconds", "3", "--every", "0.25", *rogue)
            assert code == 0 and tried[0] == {"ready": True}, (tried, err[-3000:])
        finally:
            witness.close()
        launcher.send_signal(signal.SIGINT)  # done: a clean stop, the recording closed with all it holds
        out, _ = launcher.communicate(timeout=120)
        assert launcher.returncode in (0, 130), out[-3000:]
    finally:
        if launcher.poll() is None:
            launcher.kill()
            launcher.communicate()
    assert "access control: on" in out and "ROS 2 machines admitted: ros2-rviz" in out, out[-3000:]
    joints = [line["message"] for line in lines if line.get("topic") == "/joint_states"]
    assert len(joints) > 50 and all(j["name"][0] == "joint1" for j in joints)  # 100 a second from the arm
    # the latched robot model, from the bridge's caches: the queries of both kinds of rmw_zenoh
    # transient-local subscription and their replies pass too
    models = [line for line in lines if line.get("topic") == "/robot_description"]
    assert sorted(m["via"] for m in models) == ["advanced", "query"], models
    assert all(m["message"]["data"].startswith("<?xml") for m in models)
    trace = read_recording(recording).trace()
    commands = [e["value"] for e in trace if e["node"] == "buggy" and e["kind"] == "input" and e["action"] == "conscious"]
    assert commands and all(c == {"speed": 0.2, "turn": 0.5, "why": "WANDER"} for c in commands)
    # what it may not do reached no one: neither the tools' witness nor the recording
    mark = struct.pack("<d", MARK)
    assert heard and not [key for key, payload in heard if mark in payload or str(MARK).encode() in payload]
    assert not [m.topic for m in read_recording(recording).messages
                if str(MARK) in json.dumps(m.value, default=str)]
    assert not [k for k, _ in heard if k.startswith("0/nope")]
