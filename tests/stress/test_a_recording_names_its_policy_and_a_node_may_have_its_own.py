"""`iotad run --virtual --policy NAME` records under that policy and the recording names it
(`iotad info` shows it); a `[[node]]` that names its own policy fires by it while the rest of
the system keeps the run's: the sender alone stressed, the watchdog eager."""
from iotad.cli import main
from iotad.recording.mcap_reader import read_recording
from late_watchdog import write_system


def run(system, out, *more):
    return main(["run", str(system), "--virtual", "--until", "3", "-o", str(out), "--plain", *more])


def firing_times(recording, node, action):
    return [round(e["t"], 6) for e in recording.trace(node) if e["kind"] == "output" and e["action"] == action]


def test_the_recording_names_the_policy_and_info_shows_it(tmp_path, capsys):
    system = write_system(tmp_path)
    assert run(system, tmp_path / "latest.mcap", "--policy", "latest") == 0
    assert run(system, tmp_path / "seed.mcap", "--policy", "random:5") == 0
    assert run(system, tmp_path / "short.mcap", "--seed", "5") == 0
    assert read_recording(tmp_path / "latest.mcap").info["policy"] == "latest"
    seeded = read_recording(tmp_path / "seed.mcap")
    assert (seeded.info["policy"], seeded.info["seed"]) == ("random", 5)
    assert firing_times(seeded, "sender", "ping") == firing_times(read_recording(tmp_path / "short.mcap"), "sender", "ping")
    assert firing_times(read_recording(tmp_path / "latest.mcap"), "sender", "ping")[:3] == [0.6, 1.2, 1.8]
    capsys.readouterr()
    assert main(["info", str(tmp_path / "latest.mcap")]) == 0
    assert "policy: latest" in capsys.readouterr().out


def test_a_node_with_its_own_policy_fires_by_it_and_the_rest_stays_eager(tmp_path, capsys):
    system = write_system(tmp_path)
    text = system.read_text().replace('name = "sender"\n', 'name = "sender"\npolicy = "latest"\n')
    system.write_text(text)
    out = tmp_path / "one.mcap"
    assert run(system, out) == 0
    recording = read_recording(out)
    assert recording.info["policy"] == "per-node"
    assert recording.info["default"] == "eager" and recording.info["nodes"] == {"sender": "latest"}
    # the sender at its window's end (0.6 s apart), the watchdog at its window's start (at once)
    assert firing_times(recording, "sender", "ping")[:3] == [0.6, 1.2, 1.8]
    assert firing_times(recording, "watchdog", "late")[:3] == [0.6, 1.2, 1.8]
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    assert "policy: per-node (eager; sender: latest)" in capsys.readouterr().out
    # the run's policy is the rest's: under random the watchdog's answers move, the sender's do not
    assert run(system, tmp_path / "two.mcap", "--policy", "random:1") == 0
    moved = read_recording(tmp_path / "two.mcap")
    assert firing_times(moved, "sender", "ping")[:3] == [0.6, 1.2, 1.8]
    assert firing_times(moved, "watchdog", "late")[:3] != [0.6, 1.2, 1.8]
