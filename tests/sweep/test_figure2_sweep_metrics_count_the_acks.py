"""The Figure 2 system's sweep metrics (examples/figure2_metrics.py) count the scheduler's acks
by value, as the recording has them."""
from iotad.cli import main
from iotad.kernel.python_loader import load_object
from iotad.launcher.system.system_file import load_system
from iotad.recording.mcap_reader import read_recording

from sweep_iotas import ROOT


def test_commits_aborts_and_rejects_are_the_acks(tmp_path, capsys):
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "30", "--seed", "3",
                 "-o", str(tmp_path / "fig2.mcap")]) == 0
    recording = read_recording(tmp_path / "fig2.mcap")
    acks = [e["value"] for e in recording.trace("scheduler") if e["kind"] == "output" and e["action"] == "ack"]
    metrics = load_object(load_system(ROOT / "examples" / "figure2.toml", check=False).sweep_metrics)(recording)
    counted = {name: metrics[name] for name in ("commits", "aborts", "rejects")}
    assert counted == {"commits": acks.count("COMMIT"), "aborts": acks.count("ABORT"), "rejects": acks.count("REJECT")}
    assert metrics["unanswered"] == len([e for e in recording.trace("scheduler")
                                         if e["kind"] == "input" and e["action"] == "req"]) - len(acks)
    assert metrics["commits"] > 0 and metrics["rejects"] > 0
