"""`iotad replay --node`: a recorded node re-run from its stored spec agrees with its recording;
a changed recording diverges, and the first divergence is shown with the events around it."""
import pytest

from iotad.cli import main
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node
from recorded_systems import find, mutate
from recorded_systems import figure2


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "fig2.mcap"
    record_run(figure2(), path, until=30)
    return path


@pytest.mark.parametrize("node", ["scheduler", "vision", "manipulation"])
def test_replay_is_identical(recorded, node, capsys):
    recording = read_recording(recorded)
    result = replay_node(recording, node, tolerance=0.0, kinds=("output", "internal"))
    assert result.ok, result.lines()
    assert result.max_time_error == 0.0 and len(result.recorded) == len(result.replayed) > 0
    assert main(["replay", str(recorded), "--node", node, "--internal"]) == 0
    assert "replay agrees" in capsys.readouterr().out


def test_divergence_names_the_event(recorded, tmp_path, capsys):
    def wrong(events):
        k = find(events, action="mdl_command", kind="output")
        events[k] = dict(events[k], value={"w": 9.0, "k": 1.0})
        return events
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", wrong)
    assert main(["replay", str(path), "--node", "scheduler"]) == 1
    out = capsys.readouterr().out
    assert "diverges at output event #0: recorded output mdl_command={'w': 9.0, 'k': 1.0} at t=0" in out
    assert "replayed output mdl_command={'w': 0.2, 'k': 1.0} at t=0" in out
    assert ">> #0" in out and "#1" in out  # the events around it


def test_time_beyond_tolerance_diverges(recorded, tmp_path, capsys):
    def later(events):
        k = find(events, action="ack", value="COMMIT", index=1)
        events[k] = dict(events[k], t=events[k]["t"] + 0.2)
        return events
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", later)
    assert main(["replay", str(path), "--node", "scheduler", "--tolerance", "0.1"]) == 1
    assert "0.2 apart, beyond the tolerance 0.1" in capsys.readouterr().out
    assert main(["replay", str(path), "--node", "scheduler", "--tolerance", "0.3"]) == 0


def test_unknown_node_is_exit_2(recorded, capsys):
    assert main(["replay", str(recorded), "--node", "nosuch"]) == 2
    assert capsys.readouterr().err.startswith("iotad: error: node 'nosuch'")


FIGURE2_FILE = __import__("pathlib").Path(__file__).resolve().parents[2] / "examples" / "figure2.toml"


def test_a_node_cut_short_before_the_runs_end_diverges(tmp_path, capsys):
    # a virtual run records how far every node ran: what the replay makes between the node's
    # last recorded event and then is an event the recording lacks (it "agreed" before)
    source = tmp_path / "fig2.mcap"
    assert main(["run", str(FIGURE2_FILE), "--virtual", "--until", "20", "-o", str(source)]) == 0
    path = mutate(source, tmp_path / "m.mcap", "scheduler", lambda events: [e for e in events if e["t"] <= 5.0])
    capsys.readouterr()
    assert main(["replay", str(path), "--node", "scheduler"]) == 1
    assert "the replay has an extra event: output ack[0]=COMMIT at t=7" in capsys.readouterr().out
    assert main(["replay", str(source), "--node", "scheduler"]) == 0  # the whole recording agrees
