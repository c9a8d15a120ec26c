"""examples/conveyor.toml with two objects, as `iotad run --virtual` runs it: both are picked off
the belt and placed in the bin; vision and manipulation compete for the arm through the resume
scheduler and the conflicts are resolved on the record (mdl_command, acks); the pick waits for
the object on an interrupt of the interpreter; `iotad check` finds nothing.

One run serves every test (about 20 s of CPU for 19 s of virtual time). The 20-object figure
is a command (docs/conveyor.md): `iotad run examples/conveyor.toml --virtual --until 150`."""
import subprocess

import pytest

pytest.importorskip("pybullet")

from conveyor_variant import IOTAD, system_variant  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402

UNTIL = 19.0  # s: the second object is placed at ~18.1 s and manipulation's request commits at ~18.8 s


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("conveyor")
    system = system_variant(folder, cube_count=2, cube_interval=6.0)
    recording = folder / "conveyor.mcap"
    result = subprocess.run([IOTAD, "run", str(system), "--virtual", "--until", str(UNTIL), "-o", str(recording)],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    loaded = read_recording(recording)
    events = list(loaded.trace())
    return {"path": recording, "events": events, "stdout": result.stdout}


def outputs(run, node, action):
    return [e for e in run["events"] if e["node"] == node and e["kind"] == "output" and e["action"] == action]


def test_both_objects_end_in_the_bin(run):
    final = outputs(run, "sim", "tally")[-1]["value"]
    assert final == {**final, "spawned": 2, "placed": 2, "missed": 0, "dropped": 0, "held": 0}
    grasps = [e["t"] for e in outputs(run, "sim", "tally") if e["value"]["held"] == 1]
    assert len(grasps) == 2


def test_manipulation_preempts_vision_and_vision_is_dropped_on_the_record(run):
    commands = [(e["t"], e["value"]["id"]) for e in outputs(run, "scheduler", "mdl_command")]
    owners = ["pick" if program.startswith("pick") else "look" for _, program in commands]
    assert owners[0] == "look" and owners.count("pick") == 2
    # each pick takes the arm while vision holds it (vision signalled last), and vision gets it back after
    for k, owner in enumerate(owners):
        if owner == "pick":
            assert owners[k - 1] == "look"
    acks = [(e["t"], e["index"], e["value"]) for e in outputs(run, "scheduler", "ack")]
    assert [a for _, i, a in acks if i == 1] == ["COMMIT", "COMMIT"]
    vision_acks = [(t, a) for t, i, a in acks if i == 0]
    assert vision_acks and all(a in ("ABORT", "REJECT") for _, a in vision_acks)
    pick_starts = [t for t, program in commands if program.startswith("pick")]
    # the suspended vision request is aborted after its 1 s timeout, while manipulation holds the arm
    assert any(start < t <= start + 1.5 and a == "ABORT" for start in pick_starts for t, a in vision_acks)


def test_the_hand_waits_for_the_object_on_vision_s_interrupt(run):
    ends = [e["value"] for e in outputs(run, "interpreter", "atom_end") if e["value"]["program"].startswith("pick")]
    waits = [e for e in ends if e["behaviour"] == 0 and e["atom"] == 2]
    assert len(waits) == 2
    assert all(e["end"] == "INTERRUPTED" and e["condition"].startswith("near.dy <") for e in waits)
    programs = [e["value"] for e in outputs(run, "interpreter", "program_end") if e["value"]["program"].startswith("pick")]
    assert [p["end"] for p in programs] == ["DONE", "DONE"]


def test_vision_sees_the_objects_where_they_are(run):
    # planning's pick goals come from vision's sightings; the world puts cube k at y = 0.6 - 0.05 (t - spawn)
    for e in outputs(run, "planning", "pick"):
        goal = e["value"]
        spawn = 1.0 + 6.0 * goal["target"]
        assert goal["y"] == pytest.approx(0.6 - 0.05 * (goal["t"] - spawn), abs=0.02)
        assert goal["x"] == pytest.approx(0.45, abs=0.04)


def test_no_violation_and_iotad_check_passes(run):
    assert " 0 violations" in run["stdout"]
    assert not [e for e in run["events"] if e["kind"] == "violation"]
    result = subprocess.run([IOTAD, "check", str(run["path"])], capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert "every node conforms to its spec" in result.stdout


def test_iotad_plot_draws_the_picks_and_who_held_the_arm(run, tmp_path):
    from sim.worlds.conveyor_plot import conveyor_data, matches
    recording = read_recording(run["path"])
    assert matches(recording)
    data = conveyor_data(recording)
    holders = [who for _, _, who in data["spans"]]
    assert holders[0] == 0 and holders.count(1) == 2  # vision first, then two picks
    result = subprocess.run([IOTAD, "plot", str(run["path"]), "-o", str(tmp_path / "conveyor.png")],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-2000:]
    assert (tmp_path / "conveyor.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_iotad_plot_node_draws_that_schedulers_timeline_and_refuses_one_that_schedules_nothing(run, tmp_path, capsys,
                                                                                              monkeypatch):
    from iotad.cli import main
    from iotad.recording import timeline_plot
    drawn = []
    monkeypatch.setattr(timeline_plot, "plot", lambda recording, output, node, *rest, **kw: drawn.append(node) or output)
    assert main(["plot", str(run["path"]), "-o", str(tmp_path / "timeline.png"), "--node", "scheduler"]) == 0
    assert drawn == ["scheduler"]  # the timeline, not the robot's picture
    monkeypatch.undo()
    assert main(["plot", str(run["path"]), "-o", str(tmp_path / "motor.png"), "--node", "motor"]) == 2
    assert "motor never fired 'schedule': it is no motion scheduler (here: scheduler)" in capsys.readouterr().err
    assert not (tmp_path / "motor.png").exists()


def test_sweep_metrics_count_what_the_world_and_the_scheduler_did(run):
    """examples/conveyor.toml's [sweep] metrics, as `iotad sweep` loads them, on this run."""
    from iotad.kernel.python_loader import load_object
    from iotad.launcher.system.system_file import load_system

    from conveyor_variant import ROOT

    hook = load_object(load_system(ROOT / "examples" / "conveyor.toml", check=False).sweep_metrics)
    metrics = hook(read_recording(run["path"]))
    assert metrics == {"spawned": 2, "placed": 2, "missed": 0, "dropped": 0, "preemptions": metrics["preemptions"]}
    # each pick takes the arm from vision for manipulation: one preemption at least per object placed
    assert metrics["preemptions"] >= 2
