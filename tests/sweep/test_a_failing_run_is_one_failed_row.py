"""A run that raises, and one that outlasts --timeout, are each one failed row with its error,
and the runs beside them still run and are measured."""
import csv

from iotad.cli import main


def test_a_run_that_raises_or_hangs_fails_alone(system, tmp_path, capsys):
    out = tmp_path / "sweep"
    code = main(["sweep", str(system), "--set", "ticker.mode=ok,explode,spin", "--until", "5", "--timeout", "4",
                 "-o", str(out), "--plain"])
    assert code == 1  # a run failed
    rows = {r["ticker.mode"]: r for r in csv.DictReader((out / "results.csv").open())}
    assert rows["ok"]["status"] == "ok" and int(rows["ok"]["ticks"]) > 10
    assert rows["explode"]["status"] == "failed"
    assert "this ticker explodes as it is built" in rows["explode"]["error"]
    assert rows["explode"]["ticks"] == ""
    assert rows["spin"]["status"] == "failed"
    assert rows["spin"]["error"] == "timed out after 4 s of wall time"
    # the failure's traceback is in the run's log, and the summary names the failed runs
    assert "ValueError" in (out / "runs" / f"{rows['explode']['run']}.log").read_text()
    said = capsys.readouterr().out
    assert "1 ok, 2 failed of 3 runs" in said and rows["explode"]["run"] in said
