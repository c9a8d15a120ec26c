"""The engine of a git revision against the working tree's, and both against SimPy, in one process.

    .venv/bin/python bench/engine_versus.py [--base main] [--rounds 12]

Loads `iotad/kernel/engine.py` as it is at `--base` beside the tree's own and runs, round after
round, the same systems under both: the ping-pong of bench/kernel.py (and SimPy's, before and
after), the Figure 2 scheduler with N=64 and N=2 requesters. Timed in the process's CPU time and
given as the median of the rounds' ratios, so that a machine other work keeps busy moves the
figures less (bench/kernel.py says why). Both engines run the tree's IOTAs, types and policies:
this compares the engine alone. Figures only.
"""
from __future__ import annotations

import argparse
import gc
import importlib.util
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# bench/ last, not first as for any script: its can.py would hide python-can (bench/worlds.py)
sys.path[:] = [str(ROOT)] + [p for p in sys.path if Path(p or ".").resolve() != ROOT / "bench"] + [str(ROOT / "bench")]

from iotad import Random  # noqa: E402
from iotad.kernel import engine as tree_engine  # noqa: E402

from kernel import figure2, ping_pong, simpy_ping_pong  # noqa: E402

HITS = 10_000


def engine_at(revision: str):
    """The engine module as it is at `revision`, loaded under another name."""
    source = subprocess.run(["git", "-C", str(ROOT), "show", f"{revision}:iotad/kernel/engine.py"],
                            capture_output=True, text=True)
    if source.returncode != 0:
        sys.exit(f"engine_versus: cannot read the engine at {revision!r}: {source.stderr.strip()}")
    folder = Path(tempfile.mkdtemp(prefix="engine-versus-"))
    path = folder / "engine_at_base.py"
    path.write_text(source.stdout)
    spec = importlib.util.spec_from_file_location("engine_at_base", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def hits_per_second(engine_class) -> float:
    engine = engine_class(ping_pong(), record=False)
    gc.collect()
    started = time.process_time()
    engine.run(HITS * 0.001 + 0.0005)
    return engine.firings / (time.process_time() - started)


def figure2_rate(engine_class, n: int, until: float) -> float:
    engine = engine_class(figure2(n), policy=Random(1), record=False)
    gc.collect()
    started = time.process_time()
    engine.run(until)
    return engine.firings / (time.process_time() - started)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--base", default="main", help="the git revision to compare with (default main)")
    parser.add_argument("--rounds", type=int, default=12, help="rounds, each running every system once (default 12)")
    args = parser.parse_args()
    base = engine_at(args.base).Engine
    ours = tree_engine.Engine
    ratios: dict[str, list[float]] = {name: [] for name in (
        "ping-pong, tree / base", "ping-pong, base / SimPy", "ping-pong, tree / SimPy",
        "Figure 2 N=64, tree / base", "N=64 cost / N=2 cost, base", "N=64 cost / N=2 cost, tree")}
    for _ in range(args.rounds):
        simpy_before = simpy_ping_pong(HITS)
        base_pp, tree_pp = hits_per_second(base), hits_per_second(ours)
        simpy = HITS / ((simpy_before + simpy_ping_pong(HITS)) / 2)
        base64, tree64 = figure2_rate(base, 64, 60.0), figure2_rate(ours, 64, 60.0)
        base2, tree2 = figure2_rate(base, 2, 600.0), figure2_rate(ours, 2, 600.0)
        for name, value in zip(ratios, (tree_pp / base_pp, base_pp / simpy, tree_pp / simpy, tree64 / base64,
                                        base2 / base64, tree2 / tree64)):
            ratios[name].append(value)
    print(f"engine at {args.base} (base) vs the working tree's (tree), CPU time, {args.rounds} rounds:")
    for name, values in ratios.items():
        print(f"  {name:28s} median {statistics.median(values):5.2f}x   (rounds: {min(values):.2f}-{max(values):.2f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
