"""A station's can_rx declared external (an input script plays a foreign device) is bound to the
bus and fed from outside at once: `iotad check` of such a virtual run calls the posted frame
external, as it does any external input, not a message that no sender bound sent."""
from pathlib import Path

from iotad.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_a_posted_frame_is_external_and_the_check_passes(tmp_path, capsys):
    text = (ROOT / "examples" / "arm_can.toml").read_text()
    text = text.replace('arm_trajectory.py', str(ROOT / "examples" / "arm_trajectory.py"))
    assert 'external = ["motor.estop"]' in text
    system = tmp_path / "foreign.toml"
    system.write_text(text.replace('external = ["motor.estop"]', 'external = ["motor.estop", "motor.can_rx"]', 1))
    inputs = tmp_path / "foreign.jsonl"
    inputs.write_text('{"t": 0.3, "action": "motor.can_rx", "value": {"id": 1000, "extended": false, "rtr": false, '
                      '"dlc": 8, "data": [1, 2, 3, 4, 5, 6, 7, 8]}}\n')
    out = tmp_path / "foreign.mcap"
    assert main(["run", str(system), "--virtual", "--until", "0.5", "--inputs", str(inputs), "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["check", str(out), "--all"]) == 0
    report = capsys.readouterr().out
    assert "motor received frame 0x3E8 [01 02 03 04 05 06 07 08] from outside (its can_rx is external)" in report
    assert "from outside (motor.can_rx is external)" in report and "[unexplained]" not in report
