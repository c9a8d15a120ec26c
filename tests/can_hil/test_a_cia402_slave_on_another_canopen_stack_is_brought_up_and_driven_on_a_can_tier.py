"""A CiA 402 drive on a CANopen stack other than the master's: tests/can_hil/canopen_slave.py, the
`canopen` package's LocalNode (its NMT slave, SDO server with segmented transfers, EMCY producer)
with a CiA 402 layer written from the standards' texts. iotad's master speaks CANopen with its
own frame-level code (iotad/can/canopen.py; `canopen` only reads the EDS there), so this is a
second implementation of both CiA 301 and CiA 402, on a real CAN tier (vcan, else udp_multicast
in a private network namespace), node 5:

- `iotad can scan` finds it, with the strings its SDO server sends segmented (0x1008, 0x1009,
  0x100A), in SWITCH ON DISABLED;
- `arm` enables it (OPERATION ENABLED); `clear-errors` then sends nothing and it stays enabled;
  after its own fault (EMCY 0x2310) `clear-errors` brings it to SWITCH ON DISABLED through the
  fault reset (transition 15), and `idle` leaves it READY TO SWITCH ON or SWITCH ON DISABLED;
- the motor node (`iotad run`, one joint) starts it (NMT, SDO, PDO mapping), enables it through
  the 402 state machine, and the joint follows its setpoint by RPDO at SYNC to 0.01 rad.
"""
import json
import sys
from pathlib import Path

import pytest

from iotad.can import canopen as co
from iotad.recording.mcap_reader import read_recording

HERE = Path(__file__).resolve().parent

SYSTEM = """
[system]
name = "slave_joint"
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
encoder_period = 0.02
polls = {{}}

[[node.params.joints]]
name = "j"
node_id = 5
protocol = "cia402"
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

SCRIPT = r'''
import json, os, signal, subprocess, sys, time
folder, system, recording, slave_py, eds = sys.argv[1:6]
slave = subprocess.Popen([sys.executable, slave_py, "5", eds], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
results = {}
try:
    assert slave.stdout.readline().strip() == "slave ready", slave.stderr.read()
    def can(*args):
        done = subprocess.run([sys.executable, "-m", "iotad", "can", *args, "--hub-timeout", "0"],
                              capture_output=True, text=True, timeout=60)
        return [done.returncode, done.stdout, done.stderr[-2000:]]
    results["scan"] = can("scan", "--protocol", "cia402")
    results["arm"] = can("arm", "--node", "5", "--protocol", "cia402")
    results["clear_enabled"] = can("clear-errors", "--node", "5", "--protocol", "cia402")
    results["status_enabled"] = can("status", "--node", "5", "--protocol", "cia402")
    slave.send_signal(signal.SIGUSR1)
    time.sleep(0.2)
    results["status_fault"] = can("status", "--node", "5", "--protocol", "cia402")
    results["clear_fault"] = can("clear-errors", "--node", "5", "--protocol", "cia402")
    results["idle"] = can("idle", "--node", "5", "--protocol", "cia402")
    run = subprocess.run([sys.executable, "-m", "iotad", "run", system, "--until", "4", "--after-live", "--plain",
                          "--port", "0", "-o", recording, "--log-dir", os.path.join(folder, "logs")],
                         capture_output=True, text=True, timeout=240, cwd=folder)
    results["run"] = [run.returncode, run.stdout[-3000:], run.stderr[-3000:]]
finally:
    slave.terminate()
    try:
        slave.wait(5)
    except subprocess.TimeoutExpired:
        slave.kill()
        slave.wait()
    results["slave_stderr"] = slave.stderr.read()[-2000:]
print("RESULT " + json.dumps(results))
'''


@pytest.fixture(scope="module")
def results(system_can_tier, tmp_path_factory):
    folder = tmp_path_factory.mktemp("canopen_slave")
    system = folder / "slave_joint.toml"
    system.write_text(SYSTEM.format(sweep=HERE / "one_joint_sweep.py"))
    recording = folder / "slave.mcap"
    run = system_can_tier.run_python(SCRIPT, str(folder), str(system), str(recording), str(HERE / "canopen_slave.py"),
                                     str(co.DRIVE_EDS), timeout=400, cwd=str(folder)).check()
    line = next(line for line in run.output.splitlines() if line.startswith("RESULT "))
    return json.loads(line[len("RESULT "):]), recording


def test_scan_shows_the_slaves_strings_read_by_segmented_sdo(results):
    out, _ = results
    rc, stdout, stderr = out["scan"]
    assert rc == 0, (stderr, out["slave_stderr"])
    (row,) = stdout.splitlines()[1:]
    assert row.split()[:2] == ["cia402", "5"] and "SWITCH ON DISABLED" in row
    assert "iotad-drive 0.2.0" in row and "sim-board 1.0" in row and row.endswith("iotad simulated CiA 402 drive")


def test_clear_errors_leaves_an_enabled_slave_enabled_and_resets_a_faulted_one(results):
    out, _ = results
    assert out["arm"][0] == 0 and "arm done: OPERATION ENABLED" in out["arm"][1], out["arm"]
    assert out["clear_enabled"][0] == 0 and "no fault, nothing sent; it reports OPERATION ENABLED" in out["clear_enabled"][1]
    assert "OPERATION ENABLED" in out["status_enabled"][1]
    assert "FAULT" in out["status_fault"][1] and "0x2310 continuous over-current" in out["status_fault"][1]
    assert out["clear_fault"][0] == 0 and "clear-errors done: SWITCH ON DISABLED" in out["clear_fault"][1], out["clear_fault"]
    assert out["idle"][0] == 0, out["idle"]


def test_the_motor_node_starts_enables_and_drives_the_slave(results):
    out, recording = results
    assert out["run"][0] == 0, out["run"]
    trace = read_recording(recording).trace()
    status = [e for e in trace if e.get("node") == "motor" and e.get("action") == "joint_status" and e.get("kind") == "output"]
    events = [e["value"]["event"] for e in status]
    assert "ARM_DONE" in events and "DISARMED" not in events and "SCALE_MISMATCH" not in events
    states = [e["value"]["position"][0] for e in trace if e.get("node") == "motor" and e.get("action") == "joint_states"
              and e.get("kind") == "output"]
    assert states and states[-1] - states[0] == pytest.approx(1.0, abs=0.01)
