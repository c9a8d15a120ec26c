"""A sweep without --seeds runs each point once under the system's own policy (eager), so each
row's metrics are exactly those of `iotad run --virtual` of the system with that row's values;
with --seeds it says it uses the random firing policy, and the table names each row's policy."""
import csv

from iotad.cli import main
from iotad.recording.mcap_reader import read_recording

from sweep_iotas import tick_metrics

PERIODS = ("0.1", "0.25")


def test_each_row_has_the_metrics_of_the_same_virtual_run(system, tmp_path, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", str(system), "--set", f"ticker.period={','.join(PERIODS)}", "--until", "5",
                 "-o", str(out), "--plain"]) == 0
    assert "1 run each under the system's own policy (eager)" in capsys.readouterr().err
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [(r["ticker.period"], r["seed"], r["policy"]) for r in rows] == [(p, "", "eager") for p in PERIODS]
    for row in rows:
        single = tmp_path / f"ticker-{row['ticker.period']}.toml"
        single.write_text(system.read_text().replace("period = 0.1,", f"period = {row['ticker.period']},"))
        recording = tmp_path / f"run-{row['ticker.period']}.mcap"
        assert main(["run", str(single), "--virtual", "--until", "5", "-o", str(recording), "--plain"]) == 0
        alone = tick_metrics(read_recording(recording))
        assert {name: str(value) for name, value in alone.items()} == {name: row[name] for name in alone}
    # eager: the first tick at the window's start, one period in
    assert [float(r["first_t"]) for r in rows] == [float(p) for p in PERIODS]


def test_seeds_say_they_use_the_random_policy_in_the_output_and_the_table(system, tmp_path, capsys):
    out = tmp_path / "seeded"
    assert main(["sweep", str(system), "--set", "ticker.period=0.1", "--seeds", "2", "--until", "5",
                 "-o", str(out), "--plain"]) == 0
    assert "2 seeds of the random firing policy" in capsys.readouterr().err
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [(r["seed"], r["policy"]) for r in rows] == [("0", "random(0)"), ("1", "random(1)")]
    assert float(rows[0]["first_t"]) != 0.1  # a random time inside [0.1, 0.2], not the eager one
