"""`iotad stress`: run a system under every kind of firing its windows allow (eager, latest, N
random seeds) in virtual time, judge its [goals] in each run, and name where the first run that
misses one parts from the eager run."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from iotad.cli import CliError, nonnegative_int, positive_float

ORDER = 23

EPILOG = """\
examples:
  iotad stress examples/conveyor.toml -o stress/conveyor           eager, latest and 20 random seeds
  iotad stress examples/figure2.toml --seeds 50 --until 20 -o stress/fig2
  iotad stress examples/buggy.toml -o stress/buggy --ray            as Ray tasks

Windows are contracts: any firing inside an action's window is a correct execution, so a goal
that one of these runs misses is a goal the specs do not guarantee. Each run is
`iotad run SYSTEM --virtual --until S --policy P` (P: eager, latest, random:0 .. random:N-1),
recorded in DIR/runs/NAME.mcap, measured by the system file's [sweep] metrics hook plus
`violations`, and judged against its [goals]. For the first run that misses a goal, the report
names the earliest output whose value differs from the eager run's (node, action, time) and the
window that firing was in. DIR/results.csv has a row per run, DIR/stress.png each goal's metric
by run. Run the same command again to resume. Exit status: 0 when every goal held in every run,
1 when one was missed or a run failed, 2 for a bad option or file, 130 on Ctrl-C. docs/stress.md."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("stress", help="run a system under eager, latest and random firings; judge its goals",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="SYSTEM.toml", help="a system file with a [goals] table")
    parser.add_argument("--seeds", type=nonnegative_int, default=20, metavar="N",
                        help="random seeds 0..N-1 (default 20), beside eager and latest")
    parser.add_argument("--until", type=positive_float, metavar="SECONDS",
                        help="virtual seconds per run (default: the [goals] table's until)")
    parser.add_argument("--timeout", type=positive_float, metavar="SECONDS",
                        help="wall seconds a run may take; longer, it is a failed row (default: no limit)")
    parser.add_argument("-o", "--output", required=True, metavar="DIR", help="the stress run's folder")
    parser.add_argument("-j", "--jobs", type=int, metavar="N",
                        help="worker processes (default: one per core); with --ray, the CPUs of a local cluster")
    parser.add_argument("--ray", nargs="?", const="", metavar="ADDRESS",
                        help="run each run as a Ray task: on the cluster at ADDRESS, or on a local one started here")
    parser.add_argument("--plain", action="store_true", help="progress as lines, even on a terminal")
    parser.set_defaults(func=run)


def plan_from(args: argparse.Namespace):
    from iotad.cli import load_checked
    from iotad.sweep.stress_runs import StressPlan

    if not Path(args.file).is_file():
        raise CliError(f"{args.file}: no such file")
    system = load_checked(args.file)
    if not system.goals:
        raise CliError(f"{system.file} has no [goals] table: stress judges a system by its goals (docs/stress.md)")
    until = args.until if args.until is not None else system.goals_until
    if until is None:
        raise CliError("--until SECONDS is needed (virtual seconds per run), or until = S in the [goals] table")
    if args.jobs is not None and args.jobs < 1:
        raise CliError(f"-j {args.jobs}: at least 1")
    plan = StressPlan(system=str(system.path), until=float(until), seeds=args.seeds, goals=list(system.goals),
                      metrics=system.sweep_metrics, timeout=args.timeout)
    return plan, system


def run(args: argparse.Namespace) -> int:
    """`iotad stress`: the library's stress run; its refusals (a folder of another run...) in one line."""
    from iotad.sweep import SweepError

    try:
        return _stress(args)
    except SweepError as exc:
        raise CliError(str(exc)) from None


def _stress(args: argparse.Namespace) -> int:
    from iotad.sweep.stress_plot import plot_stress
    from iotad.sweep.stress_runs import REFERENCE, StressFolder, results, stress, write_table
    from iotad.virtual.virtual_run import cores

    plan, system = plan_from(args)
    folder = StressFolder(args.output)
    folder.open_for(plan)
    live = sys.stderr.isatty() and not args.plain

    def progress(finished: int, todo: int, failed: int, elapsed: float) -> None:
        rate = finished / elapsed * 60 if elapsed > 0 else 0.0
        line = f"stress: {finished}/{todo} runs ({failed} failed), {rate:.1f} runs/min"
        print("\r" + line if live else line, end="" if live else "\n", file=sys.stderr, flush=True)

    seeds = f", random:0..{plan.seeds - 1}" if plan.seeds else ""
    print(f"stress of {system.name}: {len(plan.policies())} runs (eager, latest{seeds}), "
          f"{plan.until:g} s virtual each, into {folder.folder}", file=sys.stderr)
    try:
        how = stress(plan, folder, args.jobs or cores(), args.ray, progress)
    except KeyboardInterrupt:
        if live:
            print(file=sys.stderr)
        print("interrupted: the same command again resumes", file=sys.stderr)
        return 130
    if live:
        print(file=sys.stderr)
    rows = results(plan, folder)
    table = write_table(plan, folder, rows)
    picture = None
    try:
        picture = plot_stress(rows, plan.goals, folder.folder / "stress.png", f"{system.name}: goals by policy and seed")
    except ImportError:
        print("note: no picture: it needs matplotlib (pip install 'iotad[plot]')", file=sys.stderr)
    failed = [row for row in rows if row.status != "ok"]
    missing = [row for row in rows if row.status == "ok" and row.missed]
    print(f"stress of {system.name}: {len(rows)} runs of {plan.until:g} s ({how['wall_s']:.1f} s wall, "
          f"{how['executor']}); goals held in {len(rows) - len(failed) - len(missing)}, missed in {len(missing)}, "
          f"{len(failed)} runs failed")
    for goal in plan.goals:
        misses = [row for row in missing if any(v.goal == goal for v in row.missed)]
        values = [row.metrics.get(goal.metric) for row in rows if row.status == "ok"]
        numbers = sorted(v for v in values if isinstance(v, (int, float)) and not isinstance(v, bool))
        spread = f"min {numbers[0]:g}, median {numbers[len(numbers) // 2]:g}, max {numbers[-1]:g}" if numbers else "not measured"
        print(f"  {goal}: " + (f"MISSED in {len(misses)}: " + ", ".join(
            f"{row.policy} ({_value(row.metrics.get(goal.metric))})" for row in misses) if misses else "held in every run")
              + f"   [{spread}]")
    for row in failed[:5]:
        print(f"  {row.policy} failed: {row.error}  (log: {folder.log(_name(row.policy))})")
    first = next((row for row in missing if row.policy != REFERENCE), None)
    if any(row.policy == REFERENCE for row in missing):
        print("  the eager run itself misses a goal: the system fails it without any lateness")
    if first is not None and any(row.policy == REFERENCE and row.status == "ok" for row in rows):
        _report_divergence(plan, folder, system, first)
    print(f"  table: {table}" + (f"   picture: {picture}" if picture else ""))
    return 1 if failed or missing else 0


def _report_divergence(plan, folder, system, first) -> None:
    from iotad.sweep.stress_runs import diverging_firing, run_name

    started = time.perf_counter()
    found = diverging_firing(plan, folder, system, first.policy)
    missed = ", ".join(f"{v.goal} ({_value(v.value)})" for v in first.missed)
    print(f"first failing run: {first.policy}, missed {missed}  (recording: {folder.recording(run_name(first.policy))})")
    if found.first is None:
        print("  no output of it differs from the eager run's: the goal depends on timing alone")
        return
    difference = found.first
    print(f"  earliest output that differs from the eager run's: {difference.iota}.{difference.channel} "
          f"at t={difference.t * system.time_unit:.4f} s")
    print(f"    {difference.line(system.time_unit)}")
    if found.window is not None:
        print(f"    {found.window.line(system.time_unit)}")
    decision = found.decision
    if decision is not None:
        print(f"  earliest decision that differs (a channel of at most one output a second): "
              f"{decision.iota}.{decision.channel} at t={decision.t * system.time_unit:.4f} s")
        print(f"    {decision.line(system.time_unit)}")
        if found.decision_window is not None:
            print(f"    {found.decision_window.line(system.time_unit)}")
    others = [d for d in found.per_node if d is not difference and d is not decision][:8]
    if others:
        print("  the first difference of each other node:")
        for other in others:
            print(f"    {other.line(system.time_unit)}")
    print(f"  ({time.perf_counter() - started:.1f} s to compare with the eager run)")


def _name(policy: str) -> str:
    from iotad.sweep.stress_runs import run_name
    return run_name(policy)


def _value(value) -> str:
    return f"{value:g}" if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value)
