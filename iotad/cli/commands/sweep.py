"""`iotad sweep`: many virtual runs of one system, over a grid (or random points) of node
parameters and seeds, in parallel on this machine or on a Ray cluster; the results as a table,
sweep.json and a summary plot."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from iotad.cli import CliError, positive_float, positive_int, nonnegative_int

ORDER = 22

EPILOG = """\
examples:
  iotad sweep examples/buggy-sweep.toml -o sweeps/buggy               the sweep file's grid and seeds
  iotad sweep examples/buggy.toml --set buggy.FEAR_GAIN=0.05,0.15,0.3 --set buggy.HUNGER_RATE=0.02,0.06 \\
      --seeds 3 --until 60 -o sweeps/fear-hunger
  iotad sweep examples/buggy.toml --set buggy.FEAR_GAIN=0.05..0.3 --sample 20 --until 60 -o sweeps/random
  iotad sweep examples/conveyor-sweep.toml -o sweeps/belt --ray       on a local Ray cluster
  iotad sweep examples/buggy-sweep.toml -o sweeps/buggy --ray ray://head:10001

Each run is `iotad run SYSTEM --virtual --until S --seed K` with its parameter values (with
--seed-param, K goes into that parameter and the policy is eager), recorded in
DIR/runs/run-NNNN.mcap (its printed output beside it, .log), then measured by the function the
system file's [sweep] metrics names. DIR/results.csv has a row per run (parameters, seed, status,
error, metrics), DIR/summary.png each metric against each swept parameter, DIR/sweep.json the
plan. A run that raises or outlasts --timeout is a failed row; the sweep goes on. Run the same
command again to resume: finished runs are skipped, failed ones tried again. Exit status: 0 when
every run is ok, 1 when one failed, 2 for a bad option or file, 130 on Ctrl-C. docs/sweeps.md."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("sweep", help="run a system many times in virtual time over parameters and seeds",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="SYSTEM.toml",
                        help="a system file, or a sweep file ([sweep] system = \"...\" and its grid)")
    parser.add_argument("--set", action="append", default=[], metavar="NODE.PARAM=V1,V2",
                        help="a swept parameter and its values (a grid); NODE.PARAM=LOW..HIGH with --sample; "
                             "a nested parameter as NODE.TABLE.KEY; repeat for each parameter")
    parser.add_argument("--seeds", type=positive_int, metavar="N",
                        help="runs per point, seeds 0..N-1 of the random firing policy (iotad run --seed); "
                             "default: each point once under the system's own policy (eager), as iotad run --virtual")
    parser.add_argument("--seed-param", metavar="NODE.PARAM",
                        help="put each run's seed into this node parameter (a world's seed), the policy eager, "
                             "instead of seeding the random firing policy")
    parser.add_argument("--until", type=positive_float, metavar="SECONDS", help="virtual seconds per run")
    parser.add_argument("--sample", type=positive_int, metavar="K", help="K random points instead of the grid")
    parser.add_argument("--sample-seed", type=nonnegative_int, metavar="N",
                        help="what draws the --sample points (default 0: the same points each time)")
    parser.add_argument("--timeout", type=positive_float, metavar="SECONDS",
                        help="wall seconds a run may take; longer, it is a failed row (default: no limit)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="the sweep's folder")
    parser.add_argument("-j", "--jobs", type=positive_int, metavar="N",
                        help="worker processes (default: one per core); with --ray, the CPUs of a local cluster")
    parser.add_argument("--ray", nargs="?", const="", metavar="ADDRESS",
                        help="run each run as a Ray task: on the cluster at ADDRESS, or on a local one started here")
    parser.add_argument("--plain", action="store_true", help="progress as lines, even on a terminal")
    parser.set_defaults(func=run)


def plan_from(args: argparse.Namespace):
    """The sweep's plan and its system, from the file and the options (options win)."""
    from iotad.cli import load_checked
    from iotad.sweep.plan import Plan, check_against, make_runs, parse_set, read_sweep_file

    path = Path(args.file)
    if not path.is_file():
        raise CliError(f"{args.file}: no such file")
    table = read_sweep_file(path) or {}
    system = load_checked(table.get("system", str(path)))
    swept = dict(table.get("set", {}))
    sample = args.sample if args.sample is not None else table.get("sample")
    for text in args.set:
        name, values = parse_set(text, sample is not None)
        swept[name] = values
    until = args.until if args.until is not None else table.get("until")
    if not isinstance(until, (int, float)) or isinstance(until, bool) or until <= 0:
        raise CliError("--until SECONDS is needed (virtual seconds per run), or until = S in the sweep file")
    seeds = args.seeds if args.seeds is not None else table.get("seeds", 1)
    # without seeds asked for, each point once under the system's own policy (what `iotad run
    # --virtual` gives); the random policy only when seeds say so
    randomised = args.seeds is not None or "seeds" in table
    plan = Plan(system=str(system.path), until=float(until), seeds=int(seeds), swept=swept, sample=sample,
                sample_seed=args.sample_seed if args.sample_seed is not None else table.get("sample_seed", 0),
                timeout=args.timeout if args.timeout is not None else table.get("timeout"),
                metrics=table.get("metrics") or system.sweep_metrics,
                seed_param=args.seed_param or table.get("seed_param"), random=randomised)
    check_against(plan, system)
    where = (plan.metrics or "").rpartition(":")[0]
    if where.endswith(".py") and not Path(where).is_file():
        raise CliError(f"metrics {plan.metrics}: no such file (the [sweep] metrics of {system.file})")
    plan.runs = make_runs(plan)
    return plan, system


class Progress:
    """`sweep: 12/40 runs (1 failed; 4 done before), 3.5 runs/min, about 0:01:20 left` on stderr."""

    def __init__(self, plain: bool):
        self.live = sys.stderr.isatty() and not plain

    def __call__(self, counts: dict, todo: int, elapsed: float) -> None:
        finished = counts["ok"] + counts["failed"]
        rate = finished / elapsed * 60 if elapsed > 0 else 0.0
        left = (todo - finished) * elapsed / finished if finished else 0.0
        line = (f"sweep: {finished + counts['skipped']}/{counts['runs']} runs ({counts['failed']} failed"
                + (f"; {counts['skipped']} done before" if counts["skipped"] else "")
                + f"), {rate:.1f} runs/min, about {time.strftime('%H:%M:%S', time.gmtime(left))} left")
        print("\r" + line if self.live else line, end="" if self.live else "\n", file=sys.stderr, flush=True)

    def end(self) -> None:
        if self.live:
            print(file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    from iotad.sweep import SweepError

    try:
        return _run(args)
    except SweepError as exc:
        raise CliError(str(exc)) from None


def _run(args: argparse.Namespace) -> int:
    from iotad.sweep.plot import plot_summary
    from iotad.sweep.results import SweepFolder
    from iotad.sweep.session import sweep
    from iotad.virtual.virtual_run import cores

    plan, system = plan_from(args)
    folder = SweepFolder(args.output)
    folder.open(plan)
    if not plan.metrics:
        print(f"note: {system.file} names no [sweep] metrics: the table has no metrics (docs/sweeps.md)",
              file=sys.stderr)
    jobs = args.jobs or cores()
    progress = Progress(args.plain)
    if plan.seed_param:
        how_fired = f"{plan.seeds} seeds into {plan.seed_param}, eager policy"
    elif plan.random:
        how_fired = f"{plan.seeds} seeds of the random firing policy"
    else:
        how_fired = "1 run each under the system's own policy (eager); --seeds N for the random policy"
    print(f"sweep of {system.name}: {len(plan.runs)} runs ({len(plan.runs) // plan.seeds} points x {how_fired}), "
          f"{plan.until:g} s virtual each, into {folder.folder}", file=sys.stderr)
    try:
        how = sweep(plan, folder, jobs, args.ray, progress)
    except KeyboardInterrupt:
        progress.end()
        folder.write_table(plan)
        done = sum(folder.finished(run.name) for run in plan.runs)
        print(f"interrupted: {done} of {len(plan.runs)} runs done; the same command again resumes", file=sys.stderr)
        return 130
    progress.end()
    folder.describe(plan, how)
    table = folder.write_table(plan)
    rows = folder.table(plan)
    picture = None
    try:
        picture = plot_summary(rows, list(plan.swept), folder.folder / "summary.png",
                               f"{system.name}: sweep of {', '.join(plan.swept) or 'seeds'}")
    except ImportError:
        print("note: no summary plot: it needs matplotlib (pip install 'iotad[plot]')", file=sys.stderr)
    failed = [row for row in rows if row["status"] != "ok"]
    print(f"sweep of {system.name}: {len(rows) - len(failed)} ok, {len(failed)} failed of {len(plan.runs)} runs "
          f"({how['skipped']} done before; {how['wall_s']:.1f} s wall, {how['executor']})")
    for row in failed[:5]:
        print(f"  {row['run']} failed: {row['error']}  (log: {folder.log(row['run'])})")
    print(f"  table: {table}" + (f"   summary: {picture}" if picture else ""))
    return 1 if failed else 0
