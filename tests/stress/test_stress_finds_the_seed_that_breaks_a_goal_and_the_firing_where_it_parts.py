"""`iotad stress` on a system with a known timing bug (tests/stress/late_watchdog.py): the
eager run keeps its goals, `latest` and the random seeds do not; the report names the failing
runs and the earliest output whose value differs from the eager run's, with its node, action,
time and the window it fired in; the table and picture are written. With the sender's window
narrowed to what the watchdog tolerates, every run keeps its goals."""
import csv

from iotad.cli import main
from late_watchdog import write_system


def test_stress_names_the_failing_seeds_and_the_diverging_firing(tmp_path, capsys):
    system = write_system(tmp_path)
    out = tmp_path / "stress"
    assert main(["stress", str(system), "--seeds", "2", "-o", str(out), "-j", "2", "--plain"]) == 1
    report = capsys.readouterr().out
    assert "late == 0: MISSED in 3: latest (16), random:0 (" in report and "random:1 (" in report
    assert "pings >= 10: held in every run" in report and "violations == 0: held in every run" in report
    # latest is the first failing run: its watchdog says 1 where eager's said 0, at 0.6 + 0.05 s
    assert "first failing run: latest, missed late == 0 (16)" in report
    assert "earliest output that differs from the eager run's: watchdog.late at t=0.6500 s" in report
    assert "t=0.6500 s watchdog.late: 1 (output #1; the reference's was 0 at t=0.1000 s)" in report
    assert "window [0.6000, 0.6500] s (enabled at 0.6000 s), fired at its window's end" in report
    with open(out / "results.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert [(row["run"], row["policy"], row["seed"], row["goals_met"]) for row in rows] == [
        ("eager", "eager", "", "yes"), ("latest", "latest", "", "no"),
        ("random-00", "random", "0", "no"), ("random-01", "random", "1", "no")]
    assert [row["late"] for row in rows][:2] == ["0", "16"] and all(int(row["late"]) > 0 for row in rows[1:])
    assert (out / "stress.png").stat().st_size > 1000 and (out / "runs" / "latest.mcap").is_file()


def test_narrowed_to_what_the_watchdog_tolerates_every_run_keeps_its_goals(tmp_path, capsys):
    system = write_system(tmp_path, window_end=0.5)
    assert main(["stress", str(system), "--seeds", "2", "-o", str(tmp_path / "stress"), "-j", "2", "--plain"]) == 0
    report = capsys.readouterr().out
    assert "late == 0: held in every run" in report and "first failing run" not in report


def test_stress_needs_goals(tmp_path, capsys):
    system = write_system(tmp_path)
    system.write_text(system.read_text().split("[goals]")[0])
    assert main(["stress", str(system), "-o", str(tmp_path / "s")]) == 2
    assert "has no [goals] table" in capsys.readouterr().err
