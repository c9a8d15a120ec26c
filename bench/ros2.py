"""What speaking ROS 2 costs: a JointState published over a `[[ros2]]` mapping against the same
channel without it, and how fast `iotad export --ros2` writes a bag. Prints figures; asserts nothing.

- latency: a joint-states value put on its iotad key, received by a subscriber on that key (the
  channel as it is), against the same value through the bridge's conversion (msgpack decode,
  mapping, CDR via rosbags, rmw_zenoh attachment) put on the ROS 2 key and received there, one
  hop more; three zenoh sessions on loopback in this process, p50/p99 over --samples messages;
- CPU: process CPU seconds per message of each path, and the conversion alone (p50/p99);
- export: a virtual run of examples/arm_ros2.toml for --seconds, exported as a rosbag2 bag:
  messages per second.

    .venv/bin/python bench/ros2.py [--samples 3000] [--seconds 20]
"""
from __future__ import annotations

import argparse
import queue
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from iotad.node_host import wire  # noqa: E402
from iotad.node_host.transport import free_port, open_session  # noqa: E402
from iotad.ros2 import rmw_zenoh  # noqa: E402
from iotad.ros2.mapping import parse  # noqa: E402

KEY = "iota/bench/arm/joint_states"
TABLE = {"channel": "arm.joint_states", "topic": "/joint_states", "type": "sensor_msgs/msg/JointState",
         "direction": "out", "frame_id": "link_base",
         "fields": {"name": {"value": [f"joint{k}" for k in range(1, 7)]}, "position": "position",
                    "velocity": "velocity", "effort": "effort"}}


def quantile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))]


def value(k: int) -> dict:
    return {"position": [0.001 * k + j for j in range(6)], "velocity": [0.1] * 6, "effort": [0.0] * 6,
            "stamp": 0.01 * k}


def measure(bridged: bool, samples: int, warmup: int = 200) -> tuple[list[float], float, list[float]]:
    """(latencies s, CPU s per message, conversion times s) of one path."""
    from channels.joints import JOINT_STATES

    mapping = parse(TABLE, JOINT_STATES, "bench")
    hub = f"tcp/127.0.0.1:{free_port()}"
    sender = open_session([hub], [], credentials=False)
    bridge = open_session(["tcp/127.0.0.1:0"], [hub], credentials=False)
    receiver = open_session(["tcp/127.0.0.1:0"], [hub], credentials=False)
    arrivals: queue.SimpleQueue = queue.SimpleQueue()
    conversions: list[float] = []
    try:
        if bridged:
            ros_out = bridge.declare_publisher(mapping.key)
            gid = rmw_zenoh.gid_of("bench")
            seq = [0]

            def convert(sample):
                start = time.perf_counter()
                plain = wire.decode(sample.payload.to_bytes())
                stamp = time.time_ns()
                data = mapping.to_cdr(plain, stamp)
                attachment = rmw_zenoh.encode_attachment(seq[0], stamp, gid)
                conversions.append(time.perf_counter() - start)
                seq[0] += 1
                ros_out.put(data, attachment=attachment)
            bridge.declare_subscriber(KEY, convert)
            receiver.declare_subscriber(mapping.key, lambda s: arrivals.put(time.perf_counter()))
        else:
            receiver.declare_subscriber(KEY, lambda s: arrivals.put(time.perf_counter()))
        publisher = sender.declare_publisher(KEY, express=True)
        deadline = time.monotonic() + 20
        while True:  # until the path works end to end
            publisher.put(wire.encode(value(0)), attachment=wire.encode_attachment(0, time.time_ns()))
            try:
                arrivals.get(timeout=0.2)
                break
            except queue.Empty:
                if time.monotonic() > deadline:
                    raise RuntimeError("no path") from None
        latencies = []
        cpu_start = time.process_time()
        conversions.clear()
        for k in range(warmup + samples):
            sent = time.perf_counter()
            publisher.put(wire.encode(value(k)), attachment=wire.encode_attachment(k, time.time_ns()))
            latency = arrivals.get(timeout=5) - sent
            if k >= warmup:
                latencies.append(latency)
        cpu = (time.process_time() - cpu_start) / (warmup + samples)
        return latencies, cpu, conversions[warmup:]
    finally:
        for session in (receiver, bridge, sender):
            session.close()


def export_speed(seconds: float) -> tuple[int, float]:
    from iotad.recording.mcap_reader import read_recording
    from iotad.recording.rosbag_export import export_rosbag

    with tempfile.TemporaryDirectory() as folder:
        recording = Path(folder) / "arm.mcap"
        subprocess.run([sys.executable, "-m", "iotad", "run", str(ROOT / "examples" / "arm_ros2.toml"), "--virtual",
                        "--until", str(seconds), "-o", str(recording)], check=True, capture_output=True, cwd=ROOT)
        loaded = read_recording(recording)
        start = time.perf_counter()
        counts = export_rosbag(loaded, Path(folder) / "bag")
        return sum(counts.values()), time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--samples", type=int, default=3000, help="messages per path (default 3000)")
    parser.add_argument("--seconds", type=float, default=20.0, help="virtual seconds of the arm to export (default 20)")
    args = parser.parse_args()
    print(f"JointState over the mapping against the channel alone, {args.samples} messages each, loopback:")
    rows = {}
    for bridged in (False, True, False, True):  # alternating: drift on a shared machine hits both
        latencies, cpu, conversions = measure(bridged, args.samples)
        rows.setdefault(bridged, []).append((latencies, cpu, conversions))
    for bridged, label in ((False, "channel alone (msgpack, iotad key)"), (True, "over the mapping (+bridge hop, CDR)")):
        latencies = [x for run in rows[bridged] for x in run[0]]
        cpu = sum(run[1] for run in rows[bridged]) / len(rows[bridged])
        print(f"  {label:<38} p50 {quantile(latencies, 0.5) * 1e6:7.1f} us  p99 {quantile(latencies, 0.99) * 1e6:7.1f} us"
              f"  CPU {cpu * 1e6:6.1f} us/message (this process: all sessions)")
    conversions = [x for run in rows[True] for x in run[2]]
    print(f"  the conversion alone (decode, map, CDR, attachment): p50 {quantile(conversions, 0.5) * 1e6:.1f} us,"
          f" p99 {quantile(conversions, 0.99) * 1e6:.1f} us")
    count, took = export_speed(args.seconds)
    print(f"iotad export --ros2 of {args.seconds:g} s of examples/arm_ros2.toml: {count} messages in {took:.2f} s, "
          f"{count / took:,.0f} messages/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
