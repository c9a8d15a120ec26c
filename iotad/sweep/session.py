"""One session of a sweep: the runs of its plan still to do, run locally or on Ray into its
folder, each row kept as it comes (`sweep`)."""
from __future__ import annotations

import time

TABLE_EVERY = 10.0  # wall seconds between rewrites of results.csv while a sweep runs (it reads every row)


def tasks_for(plan, folder) -> list[dict]:
    """The runs still to do, each as the plain task a worker runs (iotad/sweep/run.py: run_one)."""
    return [{"run": run.name, "system": plan.system, "values": run.values, "seed": run.seed, "until": plan.until,
             "timeout": plan.timeout, "metrics": plan.metrics, "seed_param": plan.seed_param,
             "recording": str(folder.recording(run.name)),
             "log": str(folder.log(run.name))}
            for run in plan.runs if not folder.finished(run.name)]


def sweep(plan, folder, jobs: int, ray: str | None = None, progress=None) -> dict:
    """Run the plan's unfinished runs into `folder`, keeping each row as it comes; returns how
    it went (`sweep.json`'s last_session). KeyboardInterrupt leaves the finished rows kept."""
    from iotad.sweep.executors import run_local, run_ray

    todo = tasks_for(plan, folder)
    counts = {"runs": len(plan.runs), "skipped": len(plan.runs) - len(todo), "ok": 0, "failed": 0}
    started = time.perf_counter()

    written = [started]

    def done(task: dict, row: dict) -> None:
        folder.keep(row)
        counts["ok" if row["status"] == "ok" else "failed"] += 1
        if time.perf_counter() - written[0] > TABLE_EVERY:  # the table so far, to look at; each row
            folder.write_table(plan)                         # is kept at once in its own file
            written[0] = time.perf_counter()
        if progress is not None:
            progress(counts, len(todo), time.perf_counter() - started)

    if ray is not None:
        run_ray(todo, ray or None, jobs, done)
    else:
        run_local(todo, jobs, done)
    folder.write_table(plan)
    counts["wall_s"] = round(time.perf_counter() - started, 3)
    counts["executor"] = "ray" if ray is not None else f"local pool of {min(jobs, max(len(todo), 1))}"
    return counts
