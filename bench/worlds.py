"""Virtual-time speed of the paper's robots, as a multiple of real time, and where the time goes.

    .venv/bin/python bench/worlds.py [--seconds 60] [--world buggy] [--repeat 3] [--cpu]

Goals (issue 12): Buggy >= 100x real time, the conveyor arm >= 20x, recorded (what
`iotad run --virtual -o` does); issue 35: Buggy >= 250x, and the conveyor's recorded run at most
2x its physics-only time (the PyBullet/world part of the split: what the world alone costs). One function per world; each runs the example system file in one
process in virtual time, as `iotad run --virtual` does, three ways:

1. recorded to MCAP: the speed users see; as `iotad run` does it, by a second process
   (`iotad.recording.writer_process`) where the machine has two cores or more, and also once in
   the engine's own process (what a one-core machine gets);
2. not recorded (no sink): the baseline; recording's cost is run 1 minus run 2;
3. not recorded, with timers around every IOTA's own code (preconditions, time bounds, values,
   do-blocks) and around the world's methods (PyBullet ray casts and steps, the camera, inverse
   kinematics). The timers cost time themselves, so run 3's parts are scaled to run 2's time:
   the split's parts add up to the recorded run. "engine" is what is left: scheduling, windows,
   value checks and deliveries, the events' dicts.

Runs 1 and 2 are repeated (--repeat) and the best taken: the machine is shared, and the best run
is the one least disturbed. A second baseline is measured in the same process: the engine alone
on a trivial system (two IOTAs ping-ponging a counter), its cost per firing; each world's cost
per firing is given as a multiple of it. Figures only; timings on a shared machine vary: --cpu
times every run in this process's CPU time instead, which other work on the machine moves far
less (a writer process's CPU is then not counted; the run recorded in the engine process is the
whole cost, and its ratio to the physics is printed too).
"""
from __future__ import annotations

import argparse
import gc
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# bench/ last, not first as for any script: its can.py would hide python-can from the libraries
# that import it as `can` (the systems' CAN nodes do); `kernel` below is still found there
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"] + [str(ROOT / "bench")]

from iotad.kernel.clock import VirtualClock  # noqa: E402
from iotad.kernel.compose import flatten  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.kernel.policy import Eager  # noqa: E402
from iotad.launcher.system.in_process import compose  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402
from iotad.virtual.virtual_run import close_nodes, cores  # noqa: E402
from iotad.recording.engine_sink import EngineRecorder, recording_header  # noqa: E402
from iotad.recording.mcap_sink import McapSink  # noqa: E402
from iotad.recording.writer_process import RecordingProcess  # noqa: E402

from kernel import ping_pong  # noqa: E402  (bench/kernel.py: the same trivial system)

# What the runs are timed by: the wall clock, or with --cpu this process's CPU time, which on a
# machine other work keeps busy does not count the others' turns (a writer process's own CPU
# time is then not counted: the run "recorded in the engine process" holds the whole cost)
CLOCK = time.perf_counter

RECORDING_FORMAT = 2  # --format: how the buses are modelled and recorded (1: a firing and an event per frame)
GOALS = {"buggy": 250.0, "conveyor": 20.0}  # x real time, recorded
PHYSICS_GOALS = {"conveyor": 2.0}  # the recorded run over its physics-only time, at most


def _run(system, seconds: float, record: Path | None = None, timed=None,
         separate: bool = False, clock=None) -> tuple[float, int, int]:
    """(wall seconds, firings, events) of one run of `system` for `seconds` of virtual time;
    `separate`: recorded by a writer process (its start-up not counted, as `iotad run` overlaps
    it with building the system; waiting for it to write the last events is)."""
    writer = RecordingProcess() if record is not None and separate else None
    root = compose(system, RECORDING_FORMAT)
    if timed is not None:
        timed(root)
    events = [0]

    def count(event: dict) -> None:
        events[0] += 1

    sinks = [count]
    if writer is not None:
        sink = writer
        writer.open(record)
        writer.begin(recording_header(root, system.name, time_unit=system.time_unit))
        sinks.insert(0, writer)
    elif record is not None:
        sink = McapSink(record)
        sinks.insert(0, EngineRecorder(sink, root, system.name, time_unit=system.time_unit))
    engine = Engine(root, VirtualClock(), Eager(), record=False, sinks=sinks)
    gc.freeze()  # as `iotad run --virtual` does: full collections skip the system's own objects
    clock = clock or CLOCK
    started = clock()
    engine.run(seconds)
    if record is not None:
        sink.finish()
    wall = clock() - started
    gc.unfreeze()  # the next run's system is another
    close_nodes(flatten(root).leaves)
    return wall, engine.firings, events[0]


def _timer(totals: dict, key: str, fn):
    def timed(*args, **kw):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kw)
        finally:
            totals[key] += time.perf_counter() - t0
    return timed


def _time_actions(leaf, totals: dict, key: str) -> None:
    for action in leaf.iota.iota_spec.actions:
        for part in ("when", "lower", "upper", "value", "do"):
            fn = getattr(action, part)
            if fn is not None:
                object.__setattr__(action, part, _timer(totals, key, fn))


def _measure(system, seconds: float, repeat: int, group, world_methods: dict[str, tuple[str, ...]],
             subtract: dict[str, str]) -> dict:
    """The three runs. `group(path)`: the part a leaf's own code counts to; `world_methods`: the
    part -> the methods of a leaf's `plant` (or other attribute) timed as that part; `subtract`:
    a world part -> the leaf part whose timers include it (moved, not counted twice)."""
    recorded, inline, bare = [], [], []
    separate = cores() > 1  # as `iotad run --virtual` chooses
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as folder:
            wall, firings, events = _run(system, seconds, Path(folder) / "run.mcap", separate=separate)
            recorded.append(wall)
            inline.append(_run(system, seconds, Path(folder) / "inline.mcap")[0] if separate else wall)
        bare.append(_run(system, seconds)[0])
    totals: dict[str, float] = defaultdict(float)

    def instrument(root) -> None:
        seen = set()
        for leaf in flatten(root).leaves:
            if id(leaf.iota.iota_spec) not in seen:  # actions belong to the spec, shared by its instances
                seen.add(id(leaf.iota.iota_spec))
                _time_actions(leaf, totals, group(leaf.path))
            for part, (attribute, *methods) in world_methods.items():
                holder = getattr(leaf.iota, attribute, None)
                for method in methods if holder is not None else ():
                    if callable(getattr(holder, method, None)):
                        setattr(holder, method, _timer(totals, part, getattr(holder, method)))

    # the parts by the wall clock (a cheap timer; a CPU-time timer's own cost would blur the
    # split), as shares of this run's time, then scaled to the baseline, which --cpu times in CPU
    timed = _run(system, seconds, timed=instrument, clock=time.perf_counter)[0]
    for part, whole in subtract.items():
        totals[whole] -= totals[part]
    split = {"engine": timed - sum(totals.values()), **totals}
    scale = min(bare) / timed  # the timers' own cost out: the parts add up to the baseline
    split = {name: seconds * scale for name, seconds in split.items()}
    split["recording"] = max(0.0, min(recorded) - min(bare))
    return {"virtual_s": seconds, "firings": firings, "events": events, "recorded_wall_s": min(recorded),
            "inline_wall_s": min(inline), "separate": separate, "bare_wall_s": min(bare), "timed_wall_s": timed,
            "split_s": split, "runs": {"recorded": recorded, "inline": inline, "bare": bare}}


def buggy(seconds: float = 60.0, repeat: int = 3) -> dict:
    """examples/buggy.toml: the CAN bus, the motor node and the body's simulated ODrives are
    CAN; the body's world calls (ray casts, the kinematic step) are PyBullet/world."""
    system = load_system(ROOT / "examples" / "buggy.toml")

    def group(path: str) -> str:
        name = path.split("/")[1] if "/" in path else path
        return {"can0": "CAN", "motor": "CAN", "body": "CAN"}.get(name, "behaviours (ESPRIT)")

    world = {"PyBullet/world": ("plant", "step", "proximity", "crack_vector", "pose", "read_joints", "apply_torques")}
    return {"world": "buggy", **_measure(system, seconds, repeat, group, world, {"PyBullet/world": "CAN"})}


def conveyor(seconds: float = 60.0, repeat: int = 3) -> dict:
    """examples/conveyor.toml: CAN (the bus model, the motor node, the simulated axes), PyBullet
    (the world's step, joints and camera), PyBullet IK (the interpreter's inverse kinematics),
    vision, the MDL interpreter, the other controllers, the engine, recording."""
    system = load_system(ROOT / "examples" / "conveyor.toml")
    groups = {"arm_bus": "CAN", "motor": "CAN", "sim": "CAN", "vision": "vision (segmentation)",
              "interpreter": "MDL interpreter"}

    def group(path: str) -> str:
        return groups.get(path.split("/")[-1], "planning, manipulation, scheduler")

    world = {"PyBullet/world": ("plant", "step", "read_joints", "apply_torques", "camera_image", "end_effector_pose"),
             "PyBullet IK": ("_kinematics", "solve")}
    return {"world": "conveyor", **_measure(system, seconds, repeat, group, world,
                                            {"PyBullet/world": "CAN", "PyBullet IK": "MDL interpreter"})}


WORLDS = {"buggy": buggy, "conveyor": conveyor}


# ------------------------------------------------------------------ the trivial baseline
def trivial_engine(firings: int = 100_000, repeat: int = 3) -> float:
    """Seconds per firing of the engine alone: two IOTAs ping-ponging a counter (an output, a
    bound input, one precondition each), not recorded. The best of `repeat` runs."""
    best = float("inf")
    for _ in range(repeat):
        engine = Engine(ping_pong(), VirtualClock(), Eager(), record=False)
        started = CLOCK()
        engine.run(firings * 0.001)
        best = min(best, (CLOCK() - started) / max(engine.firings, 1))
    return best


def report(result: dict, per_firing_trivial: float) -> None:
    v, firings = result["virtual_s"], result["firings"]
    recorded, bare = result["recorded_wall_s"], result["bare_wall_s"]
    goal = GOALS.get(result["world"])
    print(f"{result['world']}: {v:g} s of virtual time, {firings} firings, {result['events']} events "
          f"(best of {len(result['runs']['bare'])} runs each)")
    unit = "wall s" if CLOCK is time.perf_counter else "CPU s"
    print(f"  {'':34s} {unit:>7s} {'x real time':>12s}  {'vs baseline':>11s}")
    how = "written by a second process" if result["separate"] else "one core: written in the engine's process"
    print(f"  {'recorded (iotad run --virtual -o)':34s} {recorded:7.3f} {v / recorded:11.1f}x  {recorded / bare:10.2f}x"
          + (f"   goal >= {goal:g}x: {'met' if v / recorded >= goal else 'NOT met'}" if goal else "") + f" ({how})")
    if result["separate"]:
        inline = result["inline_wall_s"]
        print(f"  {'recorded in the engine process':34s} {inline:7.3f} {v / inline:11.1f}x  {inline / bare:10.2f}x"
              "   (what a one-core machine gets)")
    print(f"  {'not recorded (the baseline)':34s} {bare:7.3f} {v / bare:11.1f}x  {1:10.2f}x")
    per_firing = bare / max(firings, 1)
    print(f"  per firing: {per_firing * 1e6:.1f} us not recorded, {recorded / max(firings, 1) * 1e6:.1f} us recorded; "
          f"the engine alone on a trivial system (ping-pong): {per_firing_trivial * 1e6:.2f} us "
          f"-> this world costs {per_firing / per_firing_trivial:.1f}x the trivial firing")
    print(f"  cost split of the recorded run ({recorded:.3f} s; component timers scaled to the baseline, "
          f"recording = recorded - baseline):")
    print(f"    {'part':26s} {'s':>7s} {'%':>6s} {'us/firing':>10s} {'x trivial':>10s}")
    for name, seconds in sorted(result["split_s"].items(), key=lambda kv: -kv[1]):
        print(f"    {name:26s} {seconds:7.3f} {100 * seconds / recorded:5.1f}% {seconds / max(firings, 1) * 1e6:10.2f} "
              f"{seconds / max(firings, 1) / per_firing_trivial:10.2f}")
    physics = result["split_s"].get("PyBullet/world", 0.0)
    if physics > 0:
        goal = PHYSICS_GOALS.get(result["world"])
        print(f"  recorded over physics-only (PyBullet/world, {physics:.3f} s): {recorded / physics:.2f}x"
              + (f"   goal <= {goal:g}x: {'met' if recorded / physics <= goal else 'NOT met'}" if goal else ""))
        if result["separate"]:  # the whole cost in one process (with --cpu, the fair figure)
            inline = result["inline_wall_s"]
            print(f"  recorded in the engine process over physics-only: {inline / physics:.2f}x; "
                  f"not recorded over physics-only: {bare / physics:.2f}x")
    slowest = max(result["split_s"].items(), key=lambda kv: kv[1])[0]
    print(f"  slowest part: {slowest}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="virtual seconds per run (default 60)")
    parser.add_argument("--world", choices=sorted(WORLDS), action="append", help="which world(s); default all")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each kind, the best taken (default 3)")
    parser.add_argument("--cpu", action="store_true",
                        help="time the runs in this process's CPU time, not the wall clock's (a shared machine)")
    parser.add_argument("--format", type=int, choices=(1, 2), default=2,
                        help="recording format: 2 (default) CAN frames in bursts, 1 a firing and an event per frame")
    args = parser.parse_args()
    global RECORDING_FORMAT
    RECORDING_FORMAT = args.format
    if args.seconds <= 0 or args.repeat < 1:
        parser.error("--seconds must be positive and --repeat at least 1")
    if args.cpu:
        global CLOCK
        CLOCK = time.process_time
        print("timed in this process's CPU time (--cpu); a writer process's is not counted")
    trivial = trivial_engine(repeat=args.repeat)
    for name in args.world or sorted(WORLDS):
        if not (ROOT / "examples" / f"{name}.toml").exists():
            print(f"{name}: examples/{name}.toml is not there; skipped")
            continue
        report(WORLDS[name](args.seconds, args.repeat), trivial)
    return 0


if __name__ == "__main__":
    sys.exit(main())
