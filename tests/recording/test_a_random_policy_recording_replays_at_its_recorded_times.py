"""`iotad run --virtual --seed N` picks firing times at random within the windows; those times
are in the recording alone, so replay follows them (as for a real-time recording) instead of
re-running the node at the eager policy's times, which would diverge at once."""
from pathlib import Path

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node

ROOT = Path(__file__).resolve().parents[2]


def test_a_seeded_virtual_run_replays_every_node(tmp_path, capsys):
    out = tmp_path / "seeded.mcap"
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "10", "--seed", "3",
                 "-o", str(out)]) == 0
    recording = read_recording(str(out))
    assert (recording.info["policy"], recording.info["seed"]) == ("random", 3)
    for node in recording.specs:
        result = replay_node(recording, node)
        assert result.ok and result.guided and result.recorded, "\n".join(result.lines())
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    assert "policy: random (seed 3)" in capsys.readouterr().out


def test_an_eager_virtual_run_still_replays_freely(tmp_path):
    out = tmp_path / "eager.mcap"
    assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--virtual", "--until", "10", "-o", str(out)]) == 0
    recording = read_recording(str(out))
    assert recording.info["policy"] == "eager"
    result = replay_node(recording, "scheduler")
    assert result.ok and not result.guided and result.recorded
