"""A stress run of a system (`iotad stress`): the system run under eager, latest and N random
seeds on the sweep's executors (a local pool, or Ray), each run's goals judged, the results as a
table; for the first run that misses a goal, where its outputs part from the eager run's and the
window of that firing. Windows are contracts: every one of these runs is a correct execution,
so a goal one of them misses is a goal the system's specs do not guarantee (docs/stress.md)."""
from __future__ import annotations

import csv
import io
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from iotad.sweep import SweepError
from iotad.sweep.results import SweepFolder
from iotad.launcher.goals import Goal, Verdict, judge

FORMAT = "iotad-stress/1"
TABLE = "results.csv"
REFERENCE = "eager"


@dataclass
class StressPlan:
    system: str                       # the system file, absolute
    until: float                      # virtual seconds per run
    seeds: int                        # random:0 .. random:seeds-1
    goals: list[Goal]
    metrics: str | None               # the [sweep] metrics hook
    timeout: float | None = None      # wall seconds a run may take

    def policies(self) -> list[str]:
        """Every run's policy, the reference (eager) first."""
        return [REFERENCE, "latest", *(f"random:{seed}" for seed in range(self.seeds))]

    def describe(self) -> dict:
        return {"system": self.system, "until": self.until, "seeds": self.seeds, "timeout": self.timeout,
                "metrics": self.metrics, "goals": [str(goal) for goal in self.goals], "policies": self.policies()}


def run_name(policy: str) -> str:
    """A run's name (its files'): `eager`, `latest`, `random-07`."""
    name, _, seed = policy.partition(":")
    return f"{name}-{int(seed):02d}" if seed else name


@dataclass
class RunResult:
    policy: str
    status: str                       # ok | failed
    error: str = ""
    metrics: dict[str, Any] = field(default_factory=dict)
    verdicts: list[Verdict] = field(default_factory=list)

    @property
    def missed(self) -> list[Verdict]:
        return [verdict for verdict in self.verdicts if not verdict.met]

    @property
    def ok(self) -> bool:
        return self.status == "ok" and not self.missed


class StressFolder(SweepFolder):
    """`-o DIR`: `stress.json` (the plan), `runs/NAME.mcap|.log|.json`, `results.csv`, `stress.png`."""

    def open_for(self, plan: StressPlan) -> None:
        described = self.folder / "stress.json"
        if self.folder.exists() and not self.folder.is_dir():
            raise SweepError(f"-o {self.folder}: is a file; name a folder for the stress run")
        if described.exists():
            try:
                old = json.loads(described.read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                raise SweepError(f"-o {self.folder}: its stress.json cannot be read ({exc}); choose another folder") from None
            if old.get("plan") != plan.describe():
                raise SweepError(f"-o {self.folder} holds another stress run (its stress.json differs); choose another folder")
        elif self.folder.is_dir() and any(self.folder.iterdir()):
            raise SweepError(f"-o {self.folder}: not empty and no stress run's folder (no stress.json); choose another")
        try:
            self.runs.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise SweepError(f"-o {self.folder}: cannot create it: {exc.strerror or exc}") from None
        self.describe_stress(plan, {})

    def describe_stress(self, plan: StressPlan, how: dict) -> None:
        _write_atomic(self.folder / "stress.json",
                      json.dumps({"format": FORMAT, "plan": plan.describe(), "last_session": how}, indent=1) + "\n")


def tasks_for(plan: StressPlan, folder: StressFolder) -> list[dict]:
    """The runs still to do, as the sweep's worker runs them (iotad.sweep.run.run_one), measured for goals."""
    tasks = []
    for policy in plan.policies():
        name = run_name(policy)
        if folder.finished(name):
            continue
        tasks.append({"run": name, "system": plan.system, "values": {}, "seed": None, "policy": policy,
                      "until": plan.until, "timeout": plan.timeout, "metrics": plan.metrics, "goals": True,
                      "recording": str(folder.recording(name)), "log": str(folder.log(name))})
    return tasks


def stress(plan: StressPlan, folder: StressFolder, jobs: int, ray: str | None = None,
           progress: Callable[[int, int, int, float], None] | None = None) -> dict:
    """Run the plan's unfinished runs into `folder` (each row kept as it comes); how it went."""
    from iotad.sweep.executors import run_local, run_ray

    todo = tasks_for(plan, folder)
    counts = {"runs": len(plan.policies()), "skipped": len(plan.policies()) - len(todo), "ok": 0, "failed": 0}
    started = time.perf_counter()

    def done(task: dict, row: dict) -> None:
        folder.keep(row)
        counts["ok" if row["status"] == "ok" else "failed"] += 1
        if progress is not None:
            progress(counts["ok"] + counts["failed"], len(todo), counts["failed"], time.perf_counter() - started)

    if ray is not None:
        run_ray(todo, ray or None, jobs, done)
    else:
        run_local(todo, jobs, done)
    counts["wall_s"] = round(time.perf_counter() - started, 3)
    counts["executor"] = "ray" if ray is not None else f"local pool of {min(jobs, max(len(todo), 1))}"
    folder.describe_stress(plan, counts)
    return counts


def results(plan: StressPlan, folder: StressFolder) -> list[RunResult]:
    """Every run that has a row, in plan order, its goals judged."""
    out = []
    for policy in plan.policies():
        row = folder.row(run_name(policy))
        if row is None:
            continue
        metrics = row.get("metrics", {})
        result = RunResult(policy, row.get("status", "failed"), row.get("error", ""), metrics)
        if result.status == "ok":
            result.verdicts = judge(plan.goals, metrics)
        out.append(result)
    return out


def write_table(plan: StressPlan, folder: StressFolder, rows: list[RunResult]) -> Path:
    """`results.csv`: run, policy, seed, status, error, goals_met, missed, then the metrics."""
    columns = ["run", "policy", "seed", "status", "error", "goals_met", "missed"]
    for row in rows:
        columns += [name for name in row.metrics if name not in columns]
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        name, _, seed = row.policy.partition(":")
        writer.writerow({"run": run_name(row.policy), "policy": name, "seed": seed, "status": row.status,
                         "error": row.error, "goals_met": "" if row.status != "ok" else ("yes" if row.ok else "no"),
                         "missed": "; ".join(str(v.goal) for v in row.missed),
                         **{k: repr(v) if isinstance(v, float) else v for k, v in row.metrics.items()}})
    path = folder.folder / TABLE
    _write_atomic(path, text.getvalue())
    return path


@dataclass
class Divergence:
    """Where the first failing run's outputs part from the eager run's."""

    run: str                            # its policy
    first: Any                          # divergence.Difference: the earliest output that differs; None: none
    window: Any                         # firing_window.Window of `first`, or None
    decision: Any = None                # the earliest difference on a channel of decisions, if not `first`
    decision_window: Any = None
    per_node: list = field(default_factory=list)


def diverging_firing(plan: StressPlan, folder: StressFolder, system: Any, policy: str) -> Divergence:
    """The earliest output of the `policy` run whose value differs from the eager run's, the
    earliest such on a channel of decisions, the windows they fired in (the run made again up to
    each), and the first difference of each node."""
    from iotad.launcher.run_policy import run_policy
    from iotad.recording.divergence import differences, first_decision, first_per_node
    from iotad.recording.firing_window import firing_window

    found = differences(folder.recording(run_name(policy)), folder.recording(run_name(REFERENCE)))
    first = next((d for d in found if d.t is not None), None)
    if first is None:
        return Divergence(policy, None, None, per_node=first_per_node(found, system.name))

    def window(difference):
        return firing_window(system, run_policy(system, policy), difference.iota, difference.action,
                             difference.index, difference.t)

    decision = first_decision(found, plan.until / system.time_unit)
    if decision is first:
        decision = None
    return Divergence(policy, first, window(first), decision, window(decision) if decision else None,
                      first_per_node(found, system.name))


def _write_atomic(path: Path, text: str) -> None:
    partial = path.with_name(path.name + ".partial")
    partial.write_text(text, encoding="utf-8")
    os.replace(partial, path)
