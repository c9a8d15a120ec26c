"""A sweep's folder: `sweep.json` (the plan and how it went), `runs/` (each run's recording, log
and row), and `results.csv`, the table of every run's parameters, seed, status, error and metrics.

A run's row is written once the run is over, so a sweep stopped half-way leaves the rows of the
runs that finished: run again, it skips them (a failed run is tried again). The table holds no
wall-clock figure, so that one sweep gives one table on any executor, any number of workers."""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

from iotad.sweep import SweepError
from iotad.sweep.plan import Plan, same_plan

FORMAT = "iotad-sweep/1"
TABLE = "results.csv"
FIXED = ["run", "seed", "policy", "status", "error"]


class SweepFolder:
    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self.runs = self.folder / "runs"

    def recording(self, run: str) -> Path:
        return self.runs / f"{run}.mcap"

    def log(self, run: str) -> Path:
        return self.runs / f"{run}.log"

    def row_file(self, run: str) -> Path:
        return self.runs / f"{run}.json"

    # ------------------------------------------------------------ the plan
    def open(self, plan: Plan) -> None:
        """Make the folder for `plan`, or take it up again where the same plan left it; a folder
        holding another sweep (or something else) is refused, so that no run is mixed up."""
        described = self.folder / "sweep.json"
        if self.folder.exists() and not self.folder.is_dir():
            raise SweepError(f"-o {self.folder}: is a file; name a folder for the sweep")
        if described.exists():
            try:
                old = json.loads(described.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise SweepError(f"-o {self.folder}: its sweep.json cannot be read ({exc}); choose another folder") from None
            if not same_plan(plan, old):
                raise SweepError(f"-o {self.folder} holds another sweep (its sweep.json differs: system, parameters, "
                               "seeds, --until, --timeout or metrics); choose another folder to start this one")
        elif self.folder.is_dir() and any(self.folder.iterdir()):
            raise SweepError(f"-o {self.folder}: not empty and no sweep's folder (no sweep.json); choose another")
        try:
            self.runs.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SweepError(f"-o {self.folder}: cannot create it: {exc.strerror or exc}") from None
        if not described.exists():
            self.describe(plan, {})

    def describe(self, plan: Plan, how: dict) -> None:
        """`sweep.json`: the plan, and how the last session of it went (`how`)."""
        _write_atomic(self.folder / "sweep.json",
                      json.dumps({"format": FORMAT, "plan": plan.describe(), "last_session": how}, indent=1) + "\n")

    # ------------------------------------------------------------ rows
    def row(self, run: str) -> dict | None:
        try:
            return json.loads(self.row_file(run).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return None

    def finished(self, run: str) -> bool:
        """A run whose row says ok, with its recording: skipped when the sweep runs again."""
        row = self.row(run)
        return row is not None and row.get("status") == "ok" and self.recording(run).is_file()

    def keep(self, row: dict) -> None:
        _write_atomic(self.row_file(row["run"]), json.dumps(row, indent=1) + "\n")

    # ------------------------------------------------------------ the table
    def table(self, plan: Plan) -> list[dict]:
        """One row per run of the plan that has one, in plan order: parameters, seed, status,
        error, then the metrics in the order they first appear."""
        rows = []
        for run in plan.runs:
            kept = self.row(run.name)
            if kept is None:
                continue
            rows.append({"run": run.name, **run.values, "seed": "" if run.seed is None else run.seed,
                         "policy": run.policy(plan), "status": kept.get("status", "failed"),
                         "error": kept.get("error", ""), **kept.get("metrics", {})})
        return rows

    def write_table(self, plan: Plan) -> Path:
        rows = self.table(plan)
        columns = ["run", *plan.swept, "seed", "policy", "status", "error"]
        for row in rows:
            columns += [name for name in row if name not in columns]
        text = io.StringIO()
        writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        for row in rows:
            writer.writerow({name: _cell(row.get(name, "")) for name in columns})
        path = self.folder / TABLE
        _write_atomic(path, text.getvalue())
        return path


def read_table(path: str | Path) -> list[dict]:
    """`results.csv` back as rows, numbers as numbers."""
    from iotad.sweep.plan import parse_value

    with open(path, newline="", encoding="utf-8") as handle:
        return [{name: (parse_value(value) if name not in ("run", "status", "error") and value != "" else value)
                 for name, value in row.items()} for row in csv.DictReader(handle)]


def _cell(value) -> str:
    return repr(value) if isinstance(value, float) else str(value)


def _write_atomic(path: Path, text: str) -> None:
    """Whole or not at all: a sweep stopped while writing leaves the old file, never half a new one."""
    partial = path.with_name(path.name + ".partial")
    partial.write_text(text, encoding="utf-8")
    os.replace(partial, path)
