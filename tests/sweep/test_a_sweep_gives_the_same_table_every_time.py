"""A 2 x 2 grid with 2 seeds, swept twice in two folders with different numbers of workers,
gives one table byte for byte: a row per run, in plan order, the metrics of each run's
recording, and nothing that depends on the machine."""
import csv
import io
import json

from iotad.recording.mcap_reader import read_recording

from sweep_iotas import sweep
from sweep_iotas import tick_metrics


def test_the_grid_swept_again_gives_the_same_table(system, first_table, tmp_path):
    assert sweep(system, tmp_path / "again", "-j", "1") == 0
    assert (tmp_path / "again" / "results.csv").read_text() == first_table

    rows = list(csv.DictReader(io.StringIO(first_table)))
    assert [(r["ticker.period"], r["ticker.step"], r["seed"]) for r in rows] == [
        (period, step, seed) for period in ("0.1", "0.25") for step in ("1", "3") for seed in ("0", "1")]
    assert {r["status"] for r in rows} == {"ok"} and {r["error"] for r in rows} == {""}
    # each row's metrics are the hook's on that run's recording, which ran with that row's values
    for row in rows:
        recording = read_recording(tmp_path / "again" / "runs" / f"{row['run']}.mcap")
        assert {name: str(value) for name, value in tick_metrics(recording).items()} == \
            {name: row[name] for name in ("ticks", "last", "first_t")}
        assert int(row["last"]) == (int(row["ticks"]) - 1) * int(row["ticker.step"])
        assert recording.info.get("seed") == int(row["seed"])
    # a longer period, fewer ticks; another seed, other firing times
    ticks = {(r["ticker.period"], r["seed"]): int(r["ticks"]) for r in rows}
    assert ticks[("0.25", "0")] < ticks[("0.1", "0")]
    assert rows[0]["first_t"] != rows[1]["first_t"]

    described = json.loads((tmp_path / "again" / "sweep.json").read_text())
    assert described["plan"]["set"] == {"ticker.period": [0.1, 0.25], "ticker.step": [1, 3]}
    assert described["plan"]["seeds"] == 2 and described["plan"]["until"] == 5.0
    assert described["last_session"]["ok"] == 8 and described["last_session"]["failed"] == 0
    assert (tmp_path / "again" / "summary.png").stat().st_size > 0
