"""With --seed-param, each run's seed goes into a node parameter (a world's seed), and the
firing policy stays eager: the recording has no policy seed, and the parameter took the seed."""
import csv

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording


def test_the_seed_sets_the_parameter_and_the_policy_is_eager(system, tmp_path):
    out = tmp_path / "sweep"
    assert main(["sweep", str(system), "--set", "ticker.period=0.5", "--seed-param", "ticker.step", "--seeds", "3",
                 "--until", "5", "-o", str(out), "--plain"]) == 0
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [row["seed"] for row in rows] == ["0", "1", "2"]
    for row in rows:
        recording = read_recording(out / "runs" / f"{row['run']}.mcap")
        assert recording.info.get("policy") == "eager" and "seed" not in recording.info
        # eager: every tick at the start of its window, [0.5, 1.0]: ticks at 0.5, 1.0, ... 5.0
        assert row["ticks"] == "10" and row["first_t"] == "0.5"
        assert int(row["last"]) == 9 * int(row["seed"])  # step = the seed
    assert main(["sweep", str(system), "--seed-param", "ticker.stride", "--until", "5", "-o", str(tmp_path / "x")]) == 2
