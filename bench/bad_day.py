"""A bad day: the conveyor over three hosts, secured, in real time, under a seeded schedule of
faults (prints figures and writes a PNG timeline; asserts nothing).

    .venv/bin/python bench/bad_day.py [--minutes 10] [--seed 1] [--no-baseline] [--png FILE] [--keep DIR]
    .venv/bin/python bench/bad_day.py --seed 3,7,11     several seeds against one fault-free run
    .venv/bin/python bench/bad_day.py --seed 3 --baseline DIR   against the fault-free run --keep kept
    .venv/bin/python bench/bad_day.py --schedule-only --seed 3 --minutes 10
    .venv/bin/python bench/bad_day.py --minutes 1.9 --no-baseline --schedule '25 slow arm 20 1mbit; 70 slow arm 20 256kbit'

The split (tests/bad_day_run.py `conveyor_over_three_hosts`): `brain` holds the hub, the
scheduler, the MDL interpreter, planning and manipulation; `arm` the world with its simulated
ODrives, the CAN motor node and their bus (a CAN bus is local to its machine, so the drives and
the motor node must share a host); `camera` holds vision, as a smart camera computes beside its
sensor. So a partition of arm takes the motors' setpoints away (the motor node's link watch must
make them safe), one of camera takes the arm's eyes away (the scheduler must not strand a
request), and both reach the hub through their own routers. TLS and access control on, started
as a person would: certificates, an agent on arm and on camera, one `iotad run --certs` on brain.
arm and camera keep their nodes' traces home (`[hosts.NAME] traces = "home"`), as a robot whose
arm and camera reach the brain over radio links would: each host's own file holds them, and the
merge joins the files (`--traces-at-hub` sends them to the hub as well, the way before).

Faults (tests/fault_schedule.py, drawn from `--seed`): kill -9 of a random node, of a host's agent
(which this benchmark starts again after 1 s, as systemd's Restart=on-failure would), of a host's
launcher or of a recorder; a partition of arm or camera for 1 to 20 s (a third of them past
zenoh's 10 s lease); the link of one of them slowed with `tc tbf`; SIGSTOP of a node for 0.2 to
2 s. One at a time, each given time to recover before the next.

It prints the schedule; per fault the time until every axis was safe (from the CAN frames the arm
recorded) and until the nodes it touched were heard at the hub again; commands that reached an
axis while its host was cut; the launchers' restarts; the merged recording's gaps, each with the
fault that caused it; `iotad check --all` of the merged recording, each problem judged against
the faults' windows; cubes placed against a fault-free run of the same length (`--no-baseline`
skips it; the belt brings cubes for the whole run), beside the share of the run during which no
link was cut or slowed below what the cell needs, 256 kbit/s ("links usable": the cell cannot
pick through those, so it bounds the cubes), and the cubes against the fault-free run's in that
share of its time ("per usable time"), and what became of the others (fell off the belt's end,
dropped, gone with a world started again). With several seeds, one fault-free run serves them
all, and a table of the goals per seed ends the output. Everything it starts it stops, also on
Ctrl-C: the namespaces are removed and what was left in them is killed and said ("orphans").
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import sys
import tempfile
import time
from contextlib import nullcontext
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

PORT, NET = 7671, 221
NODE_LINE = re.compile(r"^[\w/]+: \d+ events, \d+ firings checked, \d+ problem")
COLOURS = {"partition": "tab:red", "slow": "tab:orange", "stop": "tab:purple", "kill": "black"}


def interrupted(signum, frame) -> None:
    """The first Ctrl-C (or SIGTERM) stops the campaign where it is; what follows stops everything
    it started. Later ones are ignored, so that the stop itself is not cut short."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    print("\ninterrupted: stopping every process and removing the namespaces...", flush=True)
    raise KeyboardInterrupt


def campaign(folder: Path, minutes: float, schedule: list, say, traces_home: bool = True) -> tuple:
    """One run of the conveyor over three hosts under `schedule` (empty: fault-free); (campaign, reading)."""
    from bad_day_reading import read_campaign
    from bad_day_run import Campaign, conveyor_over_three_hosts
    from namespaces import hosts

    with hosts("brain", "arm", "camera", net=NET) as net:
        text, machine = conveyor_over_three_hosts(net.addresses[("brain", "arm")], PORT, net.addresses["arm"],
                                                  net.addresses["camera"], minutes * 60, traces_home=traces_home)
        run = Campaign(net, folder, PORT, text, machine, schedule, minutes * 60)
        try:
            run.start()
            say(f"every host's start gate open; the campaign runs {minutes * 60:g} s")
            run.play(say)
        finally:
            run.stop()
    return run, read_campaign(run)


def kept_campaign(folder: Path, minutes: float):
    """The campaign that --keep kept in `folder`, its schedule as made; None if there is none."""
    from bad_day_run import Campaign, conveyor_over_three_hosts

    if not (folder / "faults.json").exists():
        return None
    text, machine = conveyor_over_three_hosts("10.0.0.1", PORT, "10.0.0.2", "10.0.0.3")
    run = Campaign(None, folder, PORT, text, machine, [], minutes * 60)
    run.load()
    return run


def again(folder: Path, minutes: float):
    """(campaign, reading) of a kept folder, read again; None if there is none."""
    from bad_day_reading import read_campaign

    run = kept_campaign(folder, minutes)
    return None if run is None else (run, read_campaign(run))


def kept_placements(folder: Path, minutes: float, parser):
    """The cubes placed in a fault-free run that --keep kept in `folder` (its merged recording
    read again, not checked): what a campaign's cubes are compared with."""
    from bad_day_reading import Reading, placements
    from iotad.recording.mcap_reader import read_recording

    merged = folder / "conveyor.merged.mcap"
    run = kept_campaign(folder, minutes) if merged.exists() else None
    if run is None:
        parser.error(f"--baseline {folder}: no kept fault-free run there (faults.json and conveyor.merged.mcap)")
    if abs(run.length - minutes * 60) > 1:
        parser.error(f"--baseline {folder}: a run of {run.length:g} s, not {minutes * 60:g}")
    out = Reading([], [], [], merged, "")
    out.placements, out.placed, out.fates = placements(read_recording(merged), run)
    return out


def report(run, reading, baseline) -> None:
    say = print
    say("\nper fault (safe: every axis IDLE or not closed loop, from the fault, on the arm's recorded frames; "
        "recovered: from its end until every node it touched was heard at the hub again)")
    for item in reading.faults:
        fault = item.done.fault
        safe = "-" if item.safe is None else f"{item.safe * 1e3:.0f} ms"
        if item.unsafe:
            safe += f" (axes {item.unsafe} never safe)"
        if item.silence is not None:
            safe += f", {item.silence * 1e3:.0f} ms after its last setpoint (motor node's clock)"
        recovered = f"{item.recovered:.2f} s" if item.recovered is not None else "NEVER" if item.touched or (
            fault.target == "recorder") else "-"
        cut = "" if item.commands_while_cut is None else f"; commands while cut: {item.commands_while_cut}"
        missed = f" NOT MADE: {item.done.missed}" if item.done.missed else ""
        missed += f" ({item.note})" if item.note else ""
        say(f"  {fault.at:6.1f} s  {fault.describe():55s} safe {safe}; recovered {recovered}{cut}{missed}")
    cut = [f for f in reading.faults if f.commands_while_cut is not None]
    say(f"commands that reached an axis while arm was cut: {sum(f.commands_while_cut for f in cut)} "
        f"(over {len(cut)} partition(s) of arm)")
    counts: dict[str, int] = {}
    for event in reading.events:
        counts[event["event"]] = counts.get(event["event"], 0) + 1
    # a node started again: every `live` of a node after its first (by its launcher's policy, or
    # with its host's part); an `exit` event's message is often empty, so it cannot tell
    seen: set = set()
    restarts = 0
    for event in reading.events:
        if event["event"] == "live":
            who = (event.get("host"), event.get("node"))
            restarts += who in seen
            seen.add(who)
    say(f"launcher events: {dict(sorted(counts.items()))}; node restarts: {restarts}; "
        f"agents started again by their supervisor: {len(run.agent_restarts)}")
    for event in reading.events:  # those of the campaign, not of the stop at its end
        if event["event"] in ("exit", "stale", "lost", "down", "host_back", "giveup") \
                and run.seconds(event["log_time"]) < run.length:
            say(f"    {run.seconds(event['log_time']):7.1f} s  {event['event']:9s} [{event.get('host') or 'brain'}] "
                f"{event.get('node') or ''}: {str(event.get('message', ''))[:110]}")
    if reading.merge_error:
        say(f"merge of {', '.join(p.name for p in run.files())}: FAILED: {reading.merge_error}")
    if reading.merged:
        say(f"merged {len(run.files())} recordings ({', '.join(p.name for p in run.files())}): "
            f"{len(reading.gaps)} gap(s)")
    for gap in reading.gaps:
        say(f"    [{gap.get('host')}] {run.seconds(gap['from_ns']):.1f}-{run.seconds(gap['to_ns']):.1f} s, "
            f"{gap.get('events')} event(s): {gap['reason'][:90]}\n        cause: {gap['cause'] or 'NO FAULT EXPLAINS IT'}")
    say(f"iotad check of the {'merged' if reading.merged else 'hub'} recording (exit {reading.check_code}):")
    for line in reading.check.splitlines():  # its verdicts: per node, the delivery, the whole
        if NODE_LINE.match(line) or line.startswith(("delivery:", "check:")):
            say(f"    {line[:150]}")
    explained = [p for p in reading.problems if p["cause"]]
    unexplained = [p for p in reading.problems if not p["cause"]]
    say(f"  of its {len(reading.problems)} problems (check.txt beside the recordings has them all), "
        f"{len(explained)} fall within a fault's window (from 1 s before it to its end and settling)"
        + (f"; the {len(unexplained)} others, by node and kind: {unexplained_kinds(reading)}; first ones:"
           if unexplained else ""))
    for problem in unexplained[:6]:
        say(f"      {problem['where']}: {problem['line'][:140]}")
    inside = sum(1 for _, cause in reading.trips if cause)
    say(f"the motor node's link watch tripped {len(reading.trips)} time(s) (every axis safe for want of "
        f"setpoints), {inside} inside a fault's window" + (
            ": " + ", ".join(f"{run.seconds(t):.1f} s" for t, cause in reading.trips if not cause)[:200]
            + " outside" if inside < len(reading.trips) else ""))
    if reading.placed is not None:
        against = "" if baseline is None else f" against {baseline.placed} in the fault-free run " \
                                              f"({100 * reading.placed / max(1, baseline.placed):.0f} %)"
        fates = reading.fates
        said = f"; of the {fates['brought']} the belts brought, {fates['missed']} fell off the belt's end, " \
               f"{fates['dropped']} dropped, {fates['gone with a world']} went with the " \
               f"{fates['worlds restarted']} world(s) started again (the world's node killed, or its host's part)" \
            if fates else ""
        say(f"cubes placed: {reading.placed}{against}{said}")
    say(f"orphans after the stop: {sum(len(p) for p in run.orphans.values())} "
        f"{ {h: [' '.join(a)[:80] for a in p.values()] for h, p in run.orphans.items()} if run.orphans else ''}")


def unexplained_kinds(reading) -> str:
    """The problems no fault's window holds, counted by node and kind: 'motor late 3, ...'."""
    counts: dict[str, int] = {}
    for problem in reading.problems:
        if not problem["cause"]:
            key = f"{problem['where']} {problem['kind']}"
            counts[key] = counts.get(key, 0) + 1
    return ", ".join(f"{key} {n}" for key, n in sorted(counts.items(), key=lambda kv: -kv[1]))


def goals(seed: int, run, reading, baseline) -> dict:
    """The issue's goals for one campaign, as figures: the worst time from an axis's last setpoint
    to safe, commands while cut, faults never recovered, gaps and problems no fault explains,
    cubes against the fault-free run, the share of the run no cut or too slow a link took and the
    cubes against the fault-free run's in that share of its time, orphans."""
    from bad_day_reading import impaired_share

    usable = 1 - impaired_share(run)
    silences = [item.silence for item in reading.faults if item.silence is not None]
    unsafe = sum(bool(item.unsafe) for item in reading.faults)
    never = sum(item.recovered is None and bool(item.touched or item.done.fault.target == "recorder")
                for item in reading.faults)
    cut = [item.commands_while_cut for item in reading.faults if item.commands_while_cut is not None]
    return {"seed": seed, "faults": len(reading.faults),
            "safe after setpoint (worst)": f"{max(silences) * 1e3:.0f} ms" if silences else "-",
            "never safe": unsafe, "commands while cut": sum(cut), "never recovered": never,
            "gaps unnamed": sum(not gap["cause"] for gap in reading.gaps) if reading.merged else "no merge",
            "problems unexplained": f"{sum(not p['cause'] for p in reading.problems)} of {len(reading.problems)}",
            "cubes": f"{reading.placed}" + ("" if baseline is None or reading.placed is None else
                                           f" ({100 * reading.placed / max(1, baseline.placed):.0f} %)"),
            # the share of the run no cut or too slow a link took: what bounds the cubes (impaired_share)
            "links usable": f"{100 * usable:.0f} %",
            # the cubes against what the fault-free run placed in as much time
            "per usable time": "-" if baseline is None or reading.placed is None or not usable else
                               f"{100 * reading.placed / max(1, baseline.placed) / usable:.0f} %",
            "orphans": sum(len(p) for p in run.orphans.values())}


def table(rows: list[dict]) -> None:
    keys = list(rows[0])
    widths = {key: max(len(key), *(len(str(row[key])) for row in rows)) for key in keys}
    print("  ".join(key.ljust(widths[key]) for key in keys))
    for row in rows:
        print("  ".join(str(row[key]).ljust(widths[key]) for key in keys))


def timeline(run, reading, baseline, path: Path) -> None:
    """The campaign on one picture: each fault a span on its host's row (a kill a mark), when the
    axes were safe and when the touched nodes were heard again, each gap of the merge, and the
    cubes placed over time (the fault-free run's too)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = {"brain": 3, "arm": 2, "camera": 1}
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(15, 6.5), sharex=True, height_ratios=[3, 2])
    for item in reading.faults:
        fault, made = item.done.fault, item.done
        y, start, end = rows[fault.host], run.seconds(made.start_ns), run.seconds(made.end_ns)
        colour = COLOURS[fault.kind]
        if fault.kind == "kill":
            top.plot([start], [y], marker="X", markersize=11, color=colour)
        else:
            top.barh(y, max(end - start, 0.15), left=start, height=0.5, color=colour, alpha=0.6)
        top.annotate(fault.describe().replace(f" on {fault.host}", ""), (start, y + 0.3), fontsize=6.5, rotation=20)
        if item.safe is not None:
            top.plot([start + item.safe], [y - 0.32], marker="v", color="tab:green", markersize=7)
        if item.recovered is not None:
            top.plot([end + item.recovered], [y - 0.32], marker="^", color="tab:blue", markersize=7)
        elif item.touched or fault.target == "recorder":
            top.annotate("never heard again", (end, y - 0.4), fontsize=7, color="magenta")
    for gap in reading.gaps:
        y = rows.get(gap.get("host") or "brain", 3) - 0.45
        top.plot([run.seconds(gap["from_ns"]), run.seconds(gap["to_ns"])], [y, y], linewidth=3,
                 color="tab:brown" if gap["cause"] else "magenta")
    top.set_yticks(list(rows.values()), list(rows))
    top.set_ylim(0.3, 3.9)
    handles = [plt.Line2D([], [], color=c, lw=6, alpha=0.6, label=k) for k, c in COLOURS.items() if k != "kill"] + [
        plt.Line2D([], [], color="black", marker="X", lw=0, label="kill -9"),
        plt.Line2D([], [], color="tab:green", marker="v", lw=0, label="axes safe"),
        plt.Line2D([], [], color="tab:blue", marker="^", lw=0, label="heard again"),
        plt.Line2D([], [], color="tab:brown", lw=3, label="gap (cause named)"),
        plt.Line2D([], [], color="magenta", lw=3, label="gap (no cause)")]
    top.legend(handles=handles, fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0))
    top.set_title(f"a bad day: the conveyor over brain, arm, camera; seed {run_seed}, {run.length:g} s", fontsize=10)
    for what, data, style in (("this run", reading, "-"), ("fault-free", baseline, "--")):
        if data is not None and data.placements is not None:
            times = sorted(data.placements)
            bottom.step([0, *times, run.length], [0, *range(1, len(times) + 1), len(times)], style, where="post",
                        label=f"{what}: {len(times)} placed")
    bottom.set_ylabel("cubes placed")
    bottom.set_xlabel("s into the campaign (from every host's start gate)")
    bottom.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.005, 1.0))
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


run_seed = 0


def main() -> int:
    global run_seed
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=10.0, help="length of the campaign (default: 10)")
    parser.add_argument("--seed", default="1", help="the schedule's seed, or several: 3,7,11 (default: 1)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the fault-free run of the same length")
    parser.add_argument("--baseline", metavar="DIR", help="no fault-free run: read the one an earlier --keep kept "
                        "(DIR, or DIR/fault-free) of the same length")
    parser.add_argument("--png", default="bad-day.png", help="the timeline picture (default: bad-day.png; with "
                        "several seeds, bad-day-seed3.png and so on)")
    parser.add_argument("--keep", metavar="DIR", help="keep the recordings, system files and outputs in DIR "
                        "(DIR/fault-free, DIR/bad-day or DIR/bad-day-seedN)")
    parser.add_argument("--schedule-only", action="store_true", help="print the schedule and stop")
    parser.add_argument("--schedule", metavar="FAULTS", help="no drawn schedule: these faults, one campaign "
                        "(e.g. '25 slow arm 20 1mbit; 70 slow arm 20 256kbit'; tests/fault_schedule.py "
                        "parse_schedule says how each kind is written)")
    parser.add_argument("--traces-at-hub", action="store_true", help="arm and camera send their nodes' traces "
                        "to the hub as well (by default they keep them home: [hosts.NAME] traces = \"home\")")
    parser.add_argument("--report", metavar="DIR", help="no run: the figures and picture again from a folder that "
                        "--keep kept (DIR/bad-day-seedN or DIR/bad-day, merged and checked again; the cubes "
                        "against DIR/fault-free or --baseline)")
    args = parser.parse_args()
    try:
        seeds = [int(part) for part in args.seed.split(",")]
    except ValueError:
        parser.error(f"--seed takes whole numbers separated by commas, got {args.seed!r}")
    if args.minutes <= 0:
        parser.error("--minutes must be > 0")
    from bad_day_run import HOSTS
    from fault_schedule import draw_schedule, parse_schedule

    nodes = {"sim": "arm", "motor": "arm", "vision": "camera", "interpreter": "brain", "scheduler": "brain",
             "planning": "brain", "manipulation": "brain"}
    if args.schedule is not None:
        if len(seeds) > 1 or args.report:
            parser.error("--schedule runs one campaign: give no list of seeds and no --report")
        try:
            given = parse_schedule(args.schedule)
        except ValueError as exc:
            parser.error(f"--schedule: {exc}")
        late = [f for f in given if f.end > args.minutes * 60]
        if late:
            parser.error(f"--schedule: {late[0].describe()} at {late[0].at:g} s ends after the campaign's "
                         f"{args.minutes * 60:g} s (--minutes)")
        schedules = {seeds[0]: given}
    else:
        schedules = {seed: draw_schedule(seed, args.minutes * 60, nodes, cut_hosts=HOSTS[1:], recorder_hosts=HOSTS)
                     for seed in seeds}
    traces_home = not args.traces_at_hub
    which = "a given schedule" if args.schedule is not None else f"seed{'s' if len(seeds) > 1 else ''} {args.seed}"
    print(f"a bad day, {which}, {args.minutes:g} min; {os.cpu_count()} cores, "
          f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}; arm's and camera's traces "
          f"{'stay home' if traces_home else 'go to the hub as well'}")
    for seed, schedule in schedules.items():
        print(f"schedule{'' if args.schedule is not None else f' of seed {seed}'} ({len(schedule)} faults, "
              "from every host's start gate):")
        for fault in schedule:
            print(f"  {fault.at:6.1f} s  {fault.describe()}")
    if args.schedule_only:
        return 0
    if args.report:
        # read again: each seed's campaign (DIR/bad-day-seedN, or DIR/bad-day), merged and checked
        # anew by this code; the fault-free run's cubes from its kept merge (--baseline DIR by default)
        folder = Path(args.report)
        free = Path(args.baseline) if args.baseline else folder
        baseline = kept_placements(free / "fault-free" if (free / "fault-free").is_dir() else free, args.minutes,
                                   parser) if (free / "fault-free").is_dir() or args.baseline else None
        rows = []
        for seed in seeds:
            run_seed = seed
            part = folder / f"bad-day-seed{seed}"
            kept = again(part if part.is_dir() else folder / "bad-day", args.minutes)
            if kept is None:
                parser.error(f"{args.report} holds no campaign of seed {seed} (bad-day-seed{seed} or bad-day)")
            run, reading = kept
            png = Path(args.png) if len(seeds) == 1 else Path(args.png).with_name(
                f"{Path(args.png).stem}-seed{seed}{Path(args.png).suffix}")
            print(f"\nseed {seed}, read again from {run.folder}:")
            report(run, reading, baseline)
            timeline(run, reading, baseline, png)
            print(f"timeline: {png}")
            rows.append(goals(seed, run, reading, baseline))
        if len(rows) > 1:
            table(rows)
        return 0
    signal.signal(signal.SIGINT, interrupted)
    signal.signal(signal.SIGTERM, interrupted)
    started = time.monotonic()
    say = lambda line: print(line, flush=True)  # noqa: E731
    keep = Path(args.keep) if args.keep else None
    rows = []
    try:
        baseline = None
        if args.baseline:
            kept = Path(args.baseline)
            kept = kept / "fault-free" if (kept / "fault-free" / "faults.json").exists() else kept
            baseline = kept_placements(kept, args.minutes, parser)
            print(f"\nthe fault-free run kept in {kept}: placed {baseline.placed}", flush=True)
        elif not args.no_baseline:
            with (nullcontext(str(keep / "fault-free")) if keep else tempfile.TemporaryDirectory(prefix="iotad-badday-")) as folder:
                Path(folder).mkdir(parents=True, exist_ok=True)
                print("\nthe fault-free run first:", flush=True)
                base_run, baseline = campaign(Path(folder), args.minutes, [], say, traces_home)
                print(f"  placed {baseline.placed}; orphans {sum(len(p) for p in base_run.orphans.values())}")
        for seed in seeds:
            run_seed = seed
            name = "bad-day" if len(seeds) == 1 else f"bad-day-seed{seed}"
            png = Path(args.png) if len(seeds) == 1 else Path(args.png).with_name(
                f"{Path(args.png).stem}-seed{seed}{Path(args.png).suffix}")
            with (nullcontext(str(keep / name)) if keep else tempfile.TemporaryDirectory(prefix="iotad-badday-")) as folder:
                Path(folder).mkdir(parents=True, exist_ok=True)
                print(f"\nthe bad day, seed {seed} ({time.monotonic() - started:.0f} s in):", flush=True)
                run, reading = campaign(Path(folder), args.minutes, schedules[seed], say, traces_home)
                report(run, reading, baseline)
                timeline(run, reading, baseline, png)
                print(f"timeline: {png}")
                rows.append(goals(seed, run, reading, baseline))
    except KeyboardInterrupt:
        print(f"stopped after {time.monotonic() - started:.0f} s: every process stopped, the namespaces removed")
        return 130
    if len(rows) > 1:
        print("\nthe goals, per seed (safe: from an axis's last setpoint, 100 ms allowed; the others: 0 allowed, "
              "cubes 70 % or more):")
        table(rows)
    print(f"{time.monotonic() - started:.0f} s in all; load average now {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
