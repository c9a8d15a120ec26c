"""Every EMCY from a CiA 402 drive is recorded by name, not only as numbers in joint_status: a
`drive_emcy` violation of the motor node on `can_rx` names the joint, the error code (CiA 301/402:
by its own name, else by its class) and the error register's bits (CiA 301 0x1001), and carries
them as fields; one with a nonzero code takes the axis out of ARMED at once; `iotad info` of a
recording lists it. An error reset (code 0) is recorded too, and changes no phase."""
import pytest

from iotad.can import canopen as co
from iotad.cli import main
from iotad.recording.engine_sink import record_run
from motor_bench import Bench
from nodes.can_motor import CanMotor

JOINTS = [{"name": "wrist", "node_id": 3, "protocol": "cia402"}, {"name": "elbow", "node_id": 2}]


@pytest.mark.parametrize("code, register, name, bits", [
    (0x2310, 0x03, "continuous over-current", ["generic", "current"]),
    (0x8130, 0x11, "life guard error or heartbeat error", ["generic", "communication"]),
    (0x8210, 0x11, "PDO not processed due to length error", ["generic", "communication"]),
    (0x4321, 0x09, "temperature (0x4321)", ["generic", "temperature"]),  # no name of its own: its class
    (0xFF42, 0x81, "device specific (0xFF42)", ["generic", "manufacturer specific"]),
    (0x0000, 0x00, "error reset or no error", []),
])
def test_an_emcy_is_a_violation_naming_joint_code_and_register_bits(code, register, name, bits):
    bench = Bench(joints=JOINTS)
    bench.hear(0.02, co.emcy(3, code, register).to_value())
    bench.run(0.05)
    (violation,) = bench.violations()
    value = violation["value"]
    assert (violation["action"], value["violation"]) == ("can_rx", "drive_emcy")
    assert {k: value[k] for k in ("joint", "node_id", "code", "name", "register", "register_bits")} == {
        "joint": "wrist", "node_id": 3, "code": code, "name": name, "register": register, "register_bits": bits}
    assert f"joint 'wrist' (CANopen node id 3): EMCY 0x{code:04X} {name}, error register 0x{register:02X}" \
        in value["message"]
    (status,) = bench.status(0, "EMCY")  # and joint_status still carries the numbers
    assert (status["axis_error"], status["error_register"]) == (code, register)


def test_an_emcy_with_a_code_takes_an_armed_axis_out_at_once_and_the_violation_says_so():
    bench = Bench(joints=JOINTS)
    bench.run(0.01)
    bench.motor.axes[0].phase = "ARMED"  # as if armed: what the EMCY does to it is the point here
    bench.hear(0.02, co.emcy(3, 0x2310, 0x03).to_value())
    bench.run(0.05)
    (violation,) = bench.violations()
    assert violation["value"]["phase"] == "FAULT" and violation["value"]["message"].endswith("the axis is FAULT")
    assert bench.motor.axes[0].phase == "FAULT"


def test_iotad_info_of_a_recording_lists_the_emcy_by_name(tmp_path, capsys):
    out = tmp_path / "emcy.mcap"
    motor = CanMotor("motor", joints=JOINTS, keepalive=0.0, arm_hold=0.0)
    record_run(motor, out, until=0.1, inputs=[{"t": 0.05, "action": "can_rx",
                                               "value": co.emcy(3, 0x8130, 0x11).to_value()}])
    assert main(["info", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "violations: 1" in printed
    assert ("drive_emcy: joint 'wrist' (CANopen node id 3): EMCY 0x8130 life guard error or heartbeat error, "
            "error register 0x11 (generic, communication)") in printed
