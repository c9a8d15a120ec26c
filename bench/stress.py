"""Stress throughput and the shipped systems' goals: runs per minute of `iotad stress` on the
local pool against `iotad sweep`'s on the same runs, and a system's goal metric under eager,
latest and N random seeds (min and median).

    .venv/bin/python bench/stress.py [--system examples/buggy.toml] [--seeds 6] [--until 20] [--jobs N]
    .venv/bin/python bench/stress.py --system examples/conveyor.toml --seeds 20 --until 150 --metric placed

1. `iotad sweep` of the system, `--seeds` + 2 runs of the random policy (as many runs as the
   stress run makes), `--until` virtual seconds each, recorded and measured: runs per minute;
2. `iotad stress` of the same system: eager, latest and `--seeds` random seeds, each judged
   against its goals: runs per minute, and its cost beyond the sweep's (the goals' `violations`,
   counted from each recording);
3. the table of the stress run: `--metric` (default: the first goal's) under eager, latest, and
   the random seeds' min and median, and which goals held.

A fresh pool's workers import iotad once each; that start is part of both figures. Figures
only; on a shared machine they vary, so the load is printed with them.
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from argparse import Namespace
from pathlib import Path
from statistics import median

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from iotad.cli.commands.stress import plan_from as stress_plan_from  # noqa: E402
from iotad.cli.commands.sweep import plan_from as sweep_plan_from  # noqa: E402
from iotad.sweep.session import sweep  # noqa: E402
from iotad.sweep.stress_runs import StressFolder, results, stress  # noqa: E402
from iotad.sweep.results import SweepFolder  # noqa: E402
from iotad.virtual.virtual_run import cores  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--system", default=str(ROOT / "examples" / "buggy.toml"), help="a system file with [goals]")
    parser.add_argument("--seeds", type=int, default=6, help="random seeds of the stress run (default 6)")
    parser.add_argument("--until", type=float, default=20.0, help="virtual seconds per run (default 20)")
    parser.add_argument("--jobs", type=int, default=cores(), help="worker processes (default: one per core)")
    parser.add_argument("--metric", help="the metric to show by policy (default: the first goal's)")
    parser.add_argument("--no-sweep", action="store_true", help="skip the sweep (only the stress run's figures)")
    args = parser.parse_args()

    print(f"load average at start: {' '.join(f'{x:.2f}' for x in os.getloadavg())}   cores: {cores()}   "
          f"workers: {args.jobs}")
    runs = args.seeds + 2
    with tempfile.TemporaryDirectory(prefix="iotad-bench-stress-") as folder:
        if not args.no_sweep:
            plan, _ = sweep_plan_from(Namespace(file=args.system, set=[], seeds=runs, seed_param=None, until=args.until,
                                                sample=None, sample_seed=None, timeout=None))
            into = SweepFolder(Path(folder) / "sweep")
            into.open(plan)
            started = time.perf_counter()
            how = sweep(plan, into, args.jobs)
            wall = time.perf_counter() - started
            print(f"iotad sweep:  {runs} runs of {args.until:g} s in {wall:.1f} s wall: {runs / wall * 60:.1f} runs/min"
                  f" ({how['failed']} failed)")
        splan, system = stress_plan_from(Namespace(file=args.system, seeds=args.seeds, until=args.until, jobs=None,
                                                   timeout=None))
        out = StressFolder(Path(folder) / "stress")
        out.open_for(splan)
        started = time.perf_counter()
        how = stress(splan, out, args.jobs)
        swall = time.perf_counter() - started
        print(f"iotad stress: {runs} runs of {args.until:g} s in {swall:.1f} s wall: {runs / swall * 60:.1f} runs/min"
              f" ({how['failed']} failed)" + ("" if args.no_sweep else f"; {swall / wall:.2f}x the sweep's wall time"))
        rows = results(splan, out)
    metric = args.metric or splan.goals[0].metric
    by = {row.policy: row for row in rows}

    def value(policy):
        row = by.get(policy)
        return row.metrics.get(metric) if row is not None and row.status == "ok" else None

    seeds = [v for v in (value(f"random:{k}") for k in range(args.seeds)) if isinstance(v, (int, float))]
    print(f"{system.name}, {metric} in {args.until:g} s: eager {value('eager')}, latest {value('latest')}, "
          + (f"random:0..{args.seeds - 1} min {min(seeds)}, median {median(seeds):g} "
             f"(each: {', '.join(str(v) for v in seeds)})" if seeds else "no random run finished"))
    held = sum(1 for row in rows if row.ok)
    print(f"goals ({', '.join(str(goal) for goal in splan.goals)}) held in {held} of {len(rows)} runs"
          + "".join(f"\n  {row.policy}: missed {'; '.join(v.line() for v in row.missed) or row.error}"
                    for row in rows if not row.ok))
    print(f"load average at end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
