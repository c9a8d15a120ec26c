"""A CAN bus's stations claim node ids: each simulated ODrive axis answers to one, each motor
node's joint commands one. Two devices answering one id garble each other's replies, and two
motor nodes commanding one axis bypass the scheduler; on a real bus both are well-formed frames,
so the system file's check is where they are caught."""
from __future__ import annotations

from pathlib import Path

import pytest

from iotad.launcher.system.system_file import SystemFileError, load_system

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _arm_can(tmp_path: Path, extra: str, stations: str) -> Path:
    text = (EXAMPLES / "arm_can.toml").read_text()
    text = text.replace('python = "arm_trajectory.py:', f'python = "{EXAMPLES / "arm_trajectory.py"}:')
    text = text.replace('stations = ["motor", "odrives"]', f"stations = {stations}")
    text = text.replace('external = ["motor.estop"]', 'external = ["motor.estop", "motor2.estop"]'
                        if "motor2" in extra else 'external = ["motor.estop"]')
    path = tmp_path / "arm_can.toml"
    path.write_text(text + extra)
    return path


SECOND_SIM = """
[[node]]
name = "spare"
python = "sim.odrive_sim:SimulatedOdrives"
params = {{ world = "arm", node_ids = {{ joint1 = {first}, joint2 = 12, joint3 = 13, joint4 = 14, joint5 = 15, joint6 = 16 }} }}
"""

SECOND_MOTOR = """
[[node]]
name = "motor2"
python = "nodes.can_motor:CanMotor"
[node.params]
joints = [{ name = "a", node_id = 3 }, { name = "b", node_id = 22 }, { name = "c", node_id = 23 },
          { name = "d", node_id = 24 }, { name = "e", node_id = 25 }, { name = "f", node_id = 26 }]

[[bind]]
from = "trajectory.setpoints"
to = "motor2.setpoints"
"""


@pytest.mark.parametrize("extra, stations, said", [
    (SECOND_SIM.format(first=4), '["motor", "odrives", "spare"]',
     "CAN node id 4 is answered by two devices: odrives (joint4) and spare (joint1)"),
    (SECOND_MOTOR, '["motor", "odrives", "motor2"]',
     "CAN node id 3 is commanded by two hosts: motor (joint3) and motor2 (a)"),
])
def test_two_stations_claiming_one_node_id_are_refused(tmp_path, extra, stations, said):
    with pytest.raises(SystemFileError) as caught:
        load_system(_arm_can(tmp_path, extra, stations))
    first, *others = caught.value.errors
    assert first == f"arm_can.toml: [[can]] #1 (name=\"arm_bus\"): {said}; every axis on a bus needs a node id of its own"
    # motor2's other joints (ids 22..26) are served by no simulated drive: refused too, each by name
    assert others == ([] if "motor2" not in stations else [
        f"arm_can.toml: [[can]] #1 (name=\"arm_bus\"): motor2: joint {name!r} is commanded on CAN node id {i}, "
        "which no simulated drive on bus 'arm_bus' serves (served: 1, 2, 3, 4, 5, 6)"
        for name, i in zip("bcdef", range(22, 27))])


def test_stations_with_ids_of_their_own_share_a_bus(tmp_path):
    path = _arm_can(tmp_path, SECOND_SIM.format(first=11), '["motor", "odrives", "spare"]')
    system = load_system(path)
    assert system.buses["arm_bus"].stations == ["motor", "odrives", "spare"]
