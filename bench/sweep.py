"""Sweep throughput: runs per minute on one worker against all workers, with the speed-up, and
Ray's per-run overhead against the local pool.

    .venv/bin/python bench/sweep.py [--system examples/buggy.toml] [--runs 8] [--until 20] [--jobs N] [--no-ray]

Goal (issue 34): a speed-up of at least 1.8x on 2 cores. The same sweep (one system, `--runs`
seeds of one point, `--until` virtual seconds each, recorded and measured as `iotad sweep` does)
runs four times, each into a fresh folder:

1. the local pool with 1 worker: the baseline;
2. the local pool with all workers (`--jobs`, default one per core): runs per minute and the
   speed-up over 1;
3. Ray tasks on a local Ray cluster of the same CPUs (skipped without Ray, or with --no-ray):
   Ray's start is timed apart, and its per-run overhead is its wall time per run beyond the local
   pool's with the same workers (run 2), in seconds and as a share of a run.

A fresh pool's workers import iotad once each (about a second); that start is part of every
figure, as it is of every sweep. The tables of runs 1-3 are compared: the same sweep gives the
same table on every executor. Figures only; on a shared machine they vary, so say so with them.
"""
from __future__ import annotations

import argparse
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from iotad.cli.commands.sweep import plan_from  # noqa: E402
from iotad.sweep.session import sweep  # noqa: E402
from iotad.sweep.results import SweepFolder  # noqa: E402
from iotad.virtual.virtual_run import cores  # noqa: E402


def one(plan, jobs: int, ray: str | None = None) -> tuple[float, float, str]:
    """Wall seconds of the whole sweep into a fresh folder, the CPU seconds of the local pool's
    workers (its children, reaped when the pool closes; none for Ray's), and its table."""
    with tempfile.TemporaryDirectory(prefix="iotad-bench-sweep-") as folder:
        into = SweepFolder(Path(folder) / "sweep")
        into.open(plan)
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        how = sweep(plan, into, jobs, ray)
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if how["failed"]:
            raise SystemExit(f"{how['failed']} runs failed: see a run's row in {into.runs}")
        cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
        return wall, cpu, into.write_table(plan).read_text()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--system", default=str(ROOT / "examples" / "buggy.toml"), help="the system file to sweep")
    parser.add_argument("--runs", type=int, default=8, help="runs (seeds of one point; default 8)")
    parser.add_argument("--until", type=float, default=20.0, help="virtual seconds per run (default 20)")
    parser.add_argument("--jobs", type=int, default=cores(), help="workers of the parallel runs (default: cores)")
    parser.add_argument("--no-ray", action="store_true", help="skip the Ray measurement")
    args = parser.parse_args()
    plan, system = plan_from(argparse.Namespace(file=args.system, set=[], seeds=args.runs, until=args.until,
                                                sample=None, sample_seed=None, timeout=None,
                                                seed_param=None))
    print(f"sweep of {system.name}: {args.runs} runs of {args.until:g} s virtual, recorded and measured; "
          f"{cores()} cores here, shared with whatever else runs")
    load = os.getloadavg()[0]
    serial, serial_cpu, table = one(plan, 1)
    print(f"  local pool, 1 worker:   {serial:7.2f} s wall, {args.runs / serial * 60:6.1f} runs/min, "
          f"{serial_cpu / args.runs:.2f} CPU s per run (worker start included)")
    parallel, parallel_cpu, again = one(plan, args.jobs)
    print(f"  local pool, {args.jobs} workers:  {parallel:7.2f} s wall, {args.runs / parallel * 60:6.1f} runs/min, "
          f"{parallel_cpu / args.runs:.2f} CPU s per run; speed-up {serial / parallel:.2f}x (goal >= 1.8x on 2 cores)")
    print(f"  load average at the start: {load:.1f} on {cores()} cores (above the cores: other work shares them, "
          f"and the wall-clock figures say more about it than about the sweep)")
    # the work itself, whatever else runs: one worker's CPU seconds against the busiest of N
    # workers' share, the speed-up N idle cores would give (no wait between runs, none for I/O)
    print(f"  speed-up on idle cores, from CPU seconds: {serial_cpu / (parallel_cpu / args.jobs):.2f}x "
          f"(the pool's extra CPU: {parallel_cpu / serial_cpu - 1:+.0%}, its workers' start)")
    assert again == table, "the table differs with the number of workers"
    if args.no_ray:
        return 0
    try:
        import ray
    except ImportError:
        print("  Ray: not installed (pip install 'iotad[ray]'): skipped")
        return 0
    started = time.perf_counter()
    ray.init(num_cpus=args.jobs, include_dashboard=False, log_to_driver=False)
    start = time.perf_counter() - started
    try:
        on_ray, _, table_ray = one(plan, args.jobs, "")
    finally:
        ray.shutdown()
    assert table_ray == table, "the table differs on Ray"
    per_run = (on_ray - parallel) * args.jobs / args.runs  # a worker's extra seconds for each of its runs
    print(f"  Ray, {args.jobs} CPUs:          {on_ray:7.2f} s wall, {args.runs / on_ray * 60:6.1f} runs/min "
          f"(+ {start:.1f} s to start Ray)")
    print(f"  Ray's overhead against the local pool: {per_run:+.2f} s per run "
          f"({per_run / (parallel * args.jobs / args.runs):+.0%} of a run's time on the pool); same table: yes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
