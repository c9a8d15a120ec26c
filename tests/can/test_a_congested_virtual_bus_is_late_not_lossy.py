"""The modelled bus of virtual time loses nothing and queues without bound. At 50 kbit/s the
arm's frames wait seconds for the bus, each station's in its order: `iotad check` must call that
latency, not loss (it paired receptions with a frame's later twin once the first had waited
past the real-time grace of 0.1 s: hundreds of 'lost', 'altered' and 'reordered')."""
from pathlib import Path

from iotad.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_a_congested_virtual_bus_checks_clean(tmp_path, capsys):
    text = (ROOT / "examples" / "arm_can.toml").read_text()
    text = text.replace('arm_trajectory.py', str(ROOT / "examples" / "arm_trajectory.py"))
    assert "bitrate = 1000000" in text
    text = text.replace("bitrate = 1000000", "bitrate = 50000", 1)
    system = tmp_path / "slow_bus.toml"
    system.write_text(text)
    out = tmp_path / "slow_bus.mcap"
    assert main(["run", str(system), "--virtual", "--until", "3", "-o", str(out)]) == 0
    capsys.readouterr()
    assert main(["check", str(out)]) == 0
    report = capsys.readouterr().out
    assert "cut at the end: queued when the run ended at t=3" in report  # the queue it ended with
    assert "[lost]" not in report and "[reordered]" not in report and "[altered]" not in report
