"""A joint commanded on a CAN node id that no drive serves: `iotad run --check` refuses it where
the bus's drives are simulated stations of the system (it knows every id they serve), and at run
time, where the check cannot know the drives (real ones, or a station that does not declare its
ids), the silence is a recorded `drive_silent` violation naming the joint, its node id, the bus
and who talks on the bus instead, printed in the run's summary."""
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]

UNDECLARED = '''from sim.odrive_sim import SimulatedOdrives


class UndeclaredOdrives(SimulatedOdrives):
    """Simulated ODrives the check cannot see, as it cannot see real ones."""
    can_node_ids = None
'''


def arm_with_joint6_on(tmp_path: Path, node_id: int, undeclared: bool = False) -> Path:
    """examples/mdl_arm.toml with joint6 commanded on `node_id` (the simulated drives serve 1..6)."""
    text = (ROOT / "examples/mdl_arm.toml").read_text()
    text = text.replace('"../nodes/scheduler/', f'"{ROOT}/nodes/scheduler/')
    text = text.replace('python = "mdl_requester.py:', f'python = "{ROOT}/examples/mdl_requester.py:')
    before = 'name = "joint6"\nnode_id = 6\n'
    assert before in text
    text = text.replace(before, f'name = "joint6"\nnode_id = {node_id}\n')
    if undeclared:
        (tmp_path / "undeclared_odrives.py").write_text(UNDECLARED)
        text = text.replace('python = "sim.odrive_sim:SimulatedOdrives"',
                            'python = "undeclared_odrives.py:UndeclaredOdrives"')
    path = tmp_path / "arm.toml"
    path.write_text(text)
    return path


def test_the_check_refuses_a_joint_whose_node_id_no_simulated_drive_serves(tmp_path, capsys):
    system = arm_with_joint6_on(tmp_path, 9)
    assert main(["run", "--check", str(system)]) == 2
    err = capsys.readouterr().err
    assert "joint 'joint6' is commanded on CAN node id 9, which no simulated drive on bus 'can0' serves" in err
    assert "served: 1, 2, 3, 4, 5, 6" in err


def test_the_shipped_arm_with_every_id_served_passes_the_check(tmp_path, capsys):
    assert main(["run", "--check", str(arm_with_joint6_on(tmp_path, 6))]) == 0


def test_a_drive_that_never_answers_is_a_recorded_violation_naming_joint_id_bus_and_who_talks(tmp_path, capsys):
    system = arm_with_joint6_on(tmp_path, 9, undeclared=True)
    assert main(["run", "--check", str(system)]) == 0  # the check cannot know these drives
    out = tmp_path / "arm.mcap"
    assert main(["run", str(system), "--virtual", "--until", "2", "-o", str(out), "--plain"]) == 0
    printed = capsys.readouterr().out
    said = ("joint 'joint6': its drive (CAN node id 9) on bus 'can0' never answered its arming in 1 s; "
            "talking instead: node id 6")
    assert said in printed, printed
    recording = read_recording(out)
    silent = [e for e in recording.trace() if e["kind"] == "violation"
              and e["value"]["violation"] == "drive_silent"]
    assert len(silent) == 1, silent  # once, not at every arming retry
    assert silent[0]["iota"].endswith("motor") and silent[0]["index"] == 5
    assert said in silent[0]["value"]["message"]
    assert main(["info", str(out)]) == 0  # and iotad info names the joint, not only its index
    assert "joint(s) 5 (joint6) UNARMED and LOST" in capsys.readouterr().out


@pytest.mark.parametrize("strict", ["--strict", "file"])
def test_strict_ends_that_run_non_zero(tmp_path, capsys, strict):
    system = arm_with_joint6_on(tmp_path, 9, undeclared=True)
    argv = ["run", str(system), "--virtual", "--until", "2", "--no-record", "--plain"]
    if strict == "file":
        system.write_text(system.read_text().replace("[system]\n", "[system]\nstrict = true\n", 1))
    else:
        argv.append("--strict")
    assert main(argv) == 1
    assert "strict: 1 violation(s)" in capsys.readouterr().out
