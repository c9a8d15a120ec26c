"""A third party's ODrive: the `odrive-can` package's own mock (odrive_can.mock.ODriveCANMock, its
simulator of an ODrive on CAN Simple, not iotad's), as a process on a real CAN tier (vcan, else
udp_multicast in a private network namespace), axis 1:

- `iotad can scan` finds it and reads its state from its cyclic Heartbeat (the mock answers a
  remote Heartbeat request with zeros, which would read UNDEFINED): IDLE, "heartbeat";
- `status`, `clear-errors` (nothing to clear: nothing sent), `arm` (CLOSED_LOOP_CONTROL, read
  back) and `idle` (IDLE) each say what the mock reports;
- the motor node (`iotad run`, one joint) arms it, drives it by Set_Input_Pos and the joint
  follows its setpoint: the recording ends with the joint 1 rad from where it began, to 0.01 rad.

Skipped where the package is not installed (it is a test dependency: pyproject's `test` extra).
"""
import json
import sys
from pathlib import Path

import pytest

pytest.importorskip("odrive_can")

from iotad.recording.mcap_reader import read_recording  # noqa: E402

HERE = Path(__file__).resolve().parent

SYSTEM = """
[system]
name = "mock_joint"
time_unit = 1.0
start_timeout = 60.0
heartbeat_timeout = 10.0
external = ["motor.estop"]

[system.endpoints]
listen = ["tcp/127.0.0.1:7447"]

[[node]]
name = "sweep"
python = "{sweep}:Sweep"

[[node]]
name = "motor"
python = "nodes.can_motor:CanMotor"

[node.params]
heartbeat_period = 0.2     # the mock's cyclic heartbeat
encoder_period = 0.1       # its cyclic encoder estimates
polls = {{}}

[[node.params.joints]]
name = "j"
node_id = 1
velocity_limit = 20.0

[[can]]
name = "bus"
interface = "env"
stations = ["motor"]

[[bind]]
from = "sweep.setpoints"
to = "motor.setpoints"

[[bind]]
from = "motor.joint_states"
to = "sweep.joint_states"
"""

# Runs inside the tier: the mock as its own process, the tools, then the system.
SCRIPT = r'''
import json, os, subprocess, sys, time
from iotad.can.bus import open_env_bus

interface, channel = os.environ["IOTAD_CAN_INTERFACE"], os.environ["IOTAD_CAN_CHANNEL"]
extra = ", port=43113, hop_limit=1, fd=False" if interface == "udp_multicast" else ""
mock_source = ("import can, logging; logging.disable(logging.CRITICAL); from odrive_can.mock import ODriveCANMock; "
               f"ODriveCANMock(axis_id=1, can_bus=can.Bus(interface={interface!r}, channel={channel!r}{extra})).start()")
folder, system, recording = sys.argv[1], sys.argv[2], sys.argv[3]
mock = subprocess.Popen([sys.executable, "-c", mock_source], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
results = {}
try:
    with open_env_bus() as bus:  # wait for the mock's first heartbeat (id 0x21)
        end = time.monotonic() + 20
        while time.monotonic() < end:
            got = bus.recv_frame(timeout=0.5)
            if got is not None and got[1].id == 0x21 and not got[1].rtr:
                break
    def can(*args):
        done = subprocess.run([sys.executable, "-m", "iotad", "can", *args, "--hub-timeout", "0",
                               "--heartbeat-period", "0.2"], capture_output=True, text=True, timeout=60)
        return [done.returncode, done.stdout, done.stderr[-2000:]]
    results["scan"] = can("scan", "--protocol", "odrive")
    results["status"] = can("status", "--node", "1", "--protocol", "odrive")
    results["clear"] = can("clear-errors", "--node", "1", "--protocol", "odrive")
    results["arm"] = can("arm", "--node", "1", "--protocol", "odrive", "--timeout", "3")
    results["idle"] = can("idle", "--node", "1", "--protocol", "odrive", "--timeout", "3")
    run = subprocess.run([sys.executable, "-m", "iotad", "run", system, "--until", "5", "--after-live", "--plain",
                          "--port", "0", "-o", recording, "--log-dir", os.path.join(folder, "logs")],
                         capture_output=True, text=True, timeout=240, cwd=folder)
    results["run"] = [run.returncode, run.stdout[-3000:], run.stderr[-3000:]]
finally:
    mock.terminate()
    try:
        mock.wait(5)
    except subprocess.TimeoutExpired:
        mock.kill()
        mock.wait()
print("RESULT " + json.dumps(results))
'''


@pytest.fixture(scope="module")
def results(system_can_tier, tmp_path_factory):
    folder = tmp_path_factory.mktemp("odrive_mock")
    system = folder / "mock_joint.toml"
    system.write_text(SYSTEM.format(sweep=HERE / "one_joint_sweep.py"))
    recording = folder / "mock.mcap"
    run = system_can_tier.run_python(SCRIPT, str(folder), str(system), str(recording), timeout=400, cwd=str(folder)).check()
    line = next(line for line in run.output.splitlines() if line.startswith("RESULT "))
    return json.loads(line[len("RESULT "):]), recording


def test_scan_and_status_read_the_mocks_state_from_its_heartbeat(results):
    out, _ = results
    rc, stdout, stderr = out["scan"]
    assert rc == 0, stderr
    rows = [line.split() for line in stdout.splitlines()[1:]]
    assert [(r[0], r[1]) for r in rows] == [("odrive", "1")]
    assert "IDLE" in rows[0] and "heartbeat" in rows[0] and "UNDEFINED" not in rows[0]
    rc, stdout, _ = out["status"]
    assert rc == 0 and "IDLE" in stdout and "heartbeat" in stdout


def test_the_tools_say_what_the_mock_reports(results):
    out, _ = results
    assert out["clear"][0] == 0 and "clear-errors: no fault, nothing sent; it reports IDLE (from its heartbeat)" in out["clear"][1]
    assert out["arm"][0] == 0 and "arm done: CLOSED_LOOP_CONTROL, errors: none (from its heartbeat)" in out["arm"][1], out["arm"]
    assert out["idle"][0] == 0 and "idle done: IDLE" in out["idle"][1], out["idle"]


def test_the_motor_node_arms_the_mock_and_the_joint_follows_its_setpoint(results):
    out, recording = results
    assert out["run"][0] == 0, out["run"]
    trace = read_recording(recording).trace()
    status = [e["value"] for e in trace if e.get("node") == "motor" and e.get("action") == "joint_status"
              and e.get("kind") == "output"]
    events = [s["event"] for s in status]
    assert "ARM_DONE" in events and "DISARMED" not in events and "LOST" not in events
    states = [e["value"]["position"][0] for e in trace if e.get("node") == "motor" and e.get("action") == "joint_states"
              and e.get("kind") == "output"]
    assert states and states[-1] - states[0] == pytest.approx(1.0, abs=0.01)
