"""Buggy's sweep metrics (examples/buggy/metrics.py) say what its recording shows: the food it
ate and the bumps its pose counted, seconds in each behaviour that add up to the run, and mean
hunger and fear within the range the moods took; the hungrier, bolder Buggy is hungrier."""
from buggy_runs import ROOT
from iotad.kernel.python_loader import load_object
from iotad.launcher.system.system_file import load_system
from iotad.recording.mcap_reader import read_recording


def test_metrics_of_the_timid_and_the_bold_buggy(buggy_run, hungry_run):
    hook = load_system(ROOT / "examples" / "buggy.toml", check=False).sweep_metrics  # as `iotad sweep` finds it
    assert hook == load_system(ROOT / "examples" / "buggy-hungry.toml", check=False).sweep_metrics
    buggy_metrics = load_object(hook)
    measured = []
    for run in (buggy_run, hungry_run):
        recording = read_recording(str(run))
        metrics = buggy_metrics(recording)
        measured.append(metrics)
        out = {}
        for event in recording.trace():
            if event["kind"] == "output" and event["action"] in ("mood", "landmark", "pose"):
                out.setdefault(event["action"], []).append((float(event["t"]), event["value"]))
        moods = [value for _, value in out["mood"]]
        eaten = [value for _, value in out["landmark"] if value["kind"] == "EATEN"]
        assert metrics["food_eaten"] == len(eaten) > 0
        assert metrics["wall_bumps"] == out["pose"][-1][1]["bumps"]
        spent = sum(metrics[f"{doing}_s"] for doing in ("wander", "follow", "eat", "avoid"))
        assert abs(spent - (out["mood"][-1][0] - out["mood"][0][0])) < 1e-4
        assert metrics["eat_s"] > 0 and metrics["wander_s"] > 0
        assert min(m["hunger"] for m in moods) <= metrics["mean_hunger"] <= max(m["hunger"] for m in moods)
        assert min(m["fear"] for m in moods) <= metrics["mean_fear"] <= max(m["fear"] for m in moods)
    timid, bold = measured
    assert bold["mean_hunger"] > timid["mean_hunger"]
