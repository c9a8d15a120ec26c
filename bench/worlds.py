"""Virtual-time speed of the paper's robots, as a multiple of real time, and where the time goes.

    .venv/bin/python bench/worlds.py [--seconds 60] [--world buggy]

One function per world (`buggy` here; the conveyor arm adds its own). Each runs the example system
file in one process in virtual time, as `iotad run --virtual` does, three ways:

1. recorded to MCAP (what `iotad run --virtual -o` does): the speed users see;
2. not recorded (no sink): the baseline; recording's cost is the difference;
3. not recorded, with timers around every IOTA's own code (preconditions, values, do-blocks) and
   around the world's methods (PyBullet ray casts, the kinematic step). The split: PyBullet/world,
   CAN (the bus model, the CAN motor node, the simulated ODrives' axes and frames), behaviours (the
   ESPRIT IOTAs), the engine (scheduling, checks, delivery: the rest of run 2), and recording
   (run 1 minus run 2). Timers add their own cost to run 3, so its shares are of run 3's time.

Figures only; timings on a shared machine vary from run to run.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from iotad.kernel.clock import VirtualClock  # noqa: E402
from iotad.kernel.compose import flatten  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.kernel.policy import Eager  # noqa: E402
from iotad.launcher.in_process import compose  # noqa: E402
from iotad.launcher.system_file import load_system  # noqa: E402
from iotad.recording.mcap_io import EngineRecorder, McapSink  # noqa: E402


def _run(system, seconds: float, record: Path | None = None, timed=None) -> tuple[float, int]:
    root = compose(system)
    if timed is not None:
        timed(root)
    sinks = []
    if record is not None:
        sink = McapSink(record)
        sinks.append(EngineRecorder(sink, root, system.name, time_unit=system.time_unit))
    engine = Engine(root, VirtualClock(), Eager(), record=False, sinks=sinks)
    started = time.perf_counter()
    engine.run(seconds)
    if record is not None:
        sink.finish()
    wall = time.perf_counter() - started
    for leaf in flatten(root).leaves:
        close = getattr(leaf.iota, "close", None)
        if callable(close):
            close()
    return wall, engine.firings


def _timer(totals: dict, key: str, fn):
    def timed(*args, **kw):
        t0 = time.perf_counter()
        try:
            return fn(*args, **kw)
        finally:
            totals[key] += time.perf_counter() - t0
    return timed


def buggy(seconds: float = 60.0) -> dict:
    """examples/buggy.toml: speed recorded and not, and the cost split."""
    system = load_system(ROOT / "examples" / "buggy.toml")
    with tempfile.TemporaryDirectory() as folder:
        recorded, firings = _run(system, seconds, Path(folder) / "buggy.mcap")
    bare, _ = _run(system, seconds)
    totals: dict[str, float] = defaultdict(float)

    def group(path: str) -> str:
        name = path.split("/")[1] if "/" in path else path
        return {"can0": "CAN", "motor": "CAN", "body": "CAN"}.get(name, "behaviours")

    def instrument(root) -> None:
        seen = set()
        for leaf in flatten(root).leaves:
            spec = leaf.iota.iota_spec
            if id(spec) in seen:
                continue
            seen.add(id(spec))
            key = group(leaf.path)
            for action in spec.actions:
                for part in ("when", "value", "do"):
                    fn = getattr(action, part)
                    if fn is not None:
                        object.__setattr__(action, part, _timer(totals, key, fn))
            plant = getattr(leaf.iota, "plant", None)
            if plant is not None:  # the world's time counts as PyBullet, not as the body's CAN work
                for method in ("step", "proximity", "crack_vector", "pose", "read_joints", "apply_torques"):
                    inner = _timer(totals, "PyBullet/world", getattr(plant, method))
                    setattr(plant, method, inner)

    timed, _ = _run(system, seconds, timed=instrument)
    # body's action timers include its world calls: move those to PyBullet/world only
    totals["CAN"] -= totals["PyBullet/world"]
    engine = timed - sum(totals.values())
    split = {"engine": engine, **totals}
    return {"world": "buggy", "virtual_s": seconds, "firings": firings, "recorded_wall_s": recorded,
            "bare_wall_s": bare, "timed_wall_s": timed, "recording_s": recorded - bare, "split_s": split}


def conveyor(seconds: float = 60.0) -> dict:
    """examples/conveyor.toml: speed recorded and not, and the cost split (PyBullet: the world's
    step, joints and camera, and the interpreter's inverse kinematics; CAN: the bus model, the
    motor node and the simulated axes; vision, the other controllers, the engine, recording)."""
    system = load_system(ROOT / "examples" / "conveyor.toml")
    with tempfile.TemporaryDirectory() as folder:
        recorded, firings = _run(system, seconds, Path(folder) / "conveyor.mcap")
    bare, _ = _run(system, seconds)
    totals: dict[str, float] = defaultdict(float)
    groups = {"arm_bus": "CAN", "motor": "CAN", "sim": "CAN", "vision": "vision (segmentation)",
              "interpreter": "MDL interpreter"}

    def instrument(root) -> None:
        for leaf in flatten(root).leaves:
            key = groups.get(leaf.path.split("/")[-1], "planning, manipulation, scheduler")
            for action in leaf.iota.iota_spec.actions:
                for part in ("when", "value", "do"):
                    fn = getattr(action, part)
                    if fn is not None:
                        object.__setattr__(action, part, _timer(totals, key, fn))
            plant = getattr(leaf.iota, "plant", None)
            if plant is not None:  # the sim's world calls count as PyBullet, not as its axes' CAN work
                for method in ("step", "read_joints", "apply_torques", "camera_image", "end_effector_pose"):
                    setattr(plant, method, _timer(totals, "PyBullet/world", getattr(plant, method)))
            kinematics = getattr(leaf.iota, "_kinematics", None)
            if kinematics is not None:
                kinematics.solve = _timer(totals, "PyBullet IK", kinematics.solve)

    timed, _ = _run(system, seconds, timed=instrument)
    totals["CAN"] -= totals["PyBullet/world"]
    totals["MDL interpreter"] -= totals["PyBullet IK"]
    engine = timed - sum(totals.values())
    split = {"engine": engine, **totals}
    return {"world": "conveyor", "virtual_s": seconds, "firings": firings, "recorded_wall_s": recorded,
            "bare_wall_s": bare, "timed_wall_s": timed, "recording_s": recorded - bare, "split_s": split}


WORLDS = {"buggy": buggy, "conveyor": conveyor}


def report(result: dict) -> None:
    v = result["virtual_s"]
    print(f"{result['world']}: {v:g} s of virtual time, {result['firings']} firings")
    print(f"  recorded (iotad run --virtual -o):  {result['recorded_wall_s']:6.2f} s wall  "
          f"{v / result['recorded_wall_s']:6.1f}x real time")
    print(f"  not recorded (baseline):            {result['bare_wall_s']:6.2f} s wall  "
          f"{v / result['bare_wall_s']:6.1f}x real time  (recording costs "
          f"{result['recorded_wall_s'] / result['bare_wall_s']:.2f}x the baseline)")
    print(f"  {result['firings'] / result['bare_wall_s']:.0f} firings/s in the baseline")
    timed = result["timed_wall_s"]
    print(f"  cost split (run with timers, {timed:.2f} s; recording from the first two runs):")
    parts = dict(result["split_s"], recording=result["recording_s"])
    whole = timed + result["recording_s"]
    for name, seconds in sorted(parts.items(), key=lambda kv: -kv[1]):
        print(f"    {name:16s} {seconds:6.2f} s  {100 * seconds / whole:5.1f} %")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=60.0, help="virtual seconds per run")
    parser.add_argument("--world", choices=sorted(WORLDS), action="append", help="which world(s); default all")
    args = parser.parse_args()
    for name in args.world or sorted(WORLDS):
        report(WORLDS[name](args.seconds))
    return 0


if __name__ == "__main__":
    sys.exit(main())
