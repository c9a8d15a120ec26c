"""A ROS 2 subscriber that joins late still gets the latched state: the robot model a system
declares (`[[ros2]] robot_description`) is published on /robot_description as
std_msgs/msg/String, transient local, and a transient-local subscription made 10 s after the start
by a participant that is not iotad (tests/ros2/ros2_peer.py, asking the publication caches as
rmw_zenoh's querying subscriber does) receives it exactly once, and so does an advanced subscriber (as later rmw_zenoh releases
subscribe transient local); a volatile subscription beside them receives nothing, as in ROS 2."""
import json
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import pybullet_data
import xxhash

from iotad.node_host.transport import free_port

ROOT = Path(__file__).resolve().parents[2]
HERE = Path(__file__).resolve().parent
PEER = str(HERE / "ros2_peer.py")
URDF = "xarm/xarm6_with_gripper.urdf"
LATE = 10.0  # seconds after the launcher started


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


def test_a_subscriber_joining_10_s_late_receives_the_robot_description_once(tmp_path):
    system = tmp_path / "described.toml"
    system.write_text(f'''
[system]
name = "described"
external = ["echo.inp"]

[[node]]
name = "echo"
python = "{(ROOT / 'examples' / 'echo.py').as_posix()}:Echo"

[[ros2]]
robot_description = "{URDF}"
''')
    port = free_port()
    started = time.monotonic()
    launcher = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(system), "--insecure", "--port", str(port),
                                 "--until", "60", "--plain", "-o", str(tmp_path / "described.mcap")],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT)
    try:
        wait_for_hub(port, launcher)
        time.sleep(max(0.0, started + LATE - time.monotonic()))  # the point: to be late
        assert launcher.poll() is None
        topic = "/robot_description=std_msgs/msg/String"
        peer = subprocess.run([sys.executable, PEER, "--connect", f"tcp/127.0.0.1:{port}", "--seconds", "10",
                               "--idle", "2", "--latched", topic, "--latched-advanced", topic, "--listen", topic],
                              capture_output=True, text=True, timeout=60)
        assert peer.returncode == 0, peer.stderr[-3000:]
    finally:
        launcher.send_signal(signal.SIGINT)
        try:
            launcher.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            launcher.kill()
            launcher.communicate()
    lines = [json.loads(line) for line in peer.stdout.splitlines() if line.startswith("{")]
    heard = [line for line in lines if line.get("topic") == "/robot_description"]
    # once to each transient-local subscription: the publication cache's reply to the first
    # rmw_zenoh's query, the advanced publisher's cache to the later one's advanced subscriber;
    # nothing live, nothing to the volatile subscription
    assert sorted(line["via"] for line in heard) == ["advanced", "query"], heard
    latched, advanced = sorted(heard, key=lambda line: line["via"] == "advanced")
    assert (advanced["message"], advanced["attachment"]) == (latched["message"], latched["attachment"])
    assert latched["message"]["data"] == (Path(pybullet_data.getDataPath()) / URDF).read_text()
    assert latched["key"].startswith("0/robot_description/std_msgs::msg::dds_::String_/RIHS01_")
    (tokens,) = [line["tokens"] for line in lines if "tokens" in line]
    (publisher,) = [t for t in tokens if "/MP/" in t and "%robot_description" in t]
    # the token's QoS says so: durability 1 (transient local, rmw_zenoh's default being volatile)
    # and keep last 1, the rest rmw_zenoh's defaults
    assert publisher.endswith("/:1:,1:,:,:,,"), publisher
    high, low = struct.unpack(">QQ", xxhash.xxh3_128(publisher.encode()).digest())
    assert latched["attachment"][2] == struct.pack("<QQ", low, high).hex()
