"""A tiny system for the sweep tests: a ticker whose period is swept and whose random firing
times (within [period, 2 * period]) depend on the seed, with a mode that makes a run fail by
raising as it is built, or hang, and the metrics hook that counts its ticks; and the tests'
shared grid: 2 x 2 parameters, 2 seeds, 5 s of virtual time each."""
from pathlib import Path

from iotad import Input, Int, Iota, Output, Param

ROOT = Path(__file__).resolve().parents[2]
GRID = ["--set", "ticker.period=0.1,0.25", "--set", "ticker.step=1,3", "--seeds", "2", "--until", "5"]


def sweep(system, out, *more):
    """`iotad sweep` of the grid in this process (its runs in spawned workers); the exit status."""
    from iotad.cli import main

    return main(["sweep", str(system), *GRID, "-o", str(out), "--plain", *more])


class Ticker(Iota):
    period = Param(0.1)
    step = Param(1)
    mode = Param("ok")
    tick = Output(Int, switching=0)

    def init(self):
        if self.mode == "explode":
            raise ValueError("this ticker explodes as it is built")
        self.n = 0

    @tick.action(value=lambda self: self.n, within=("period", lambda self: 2 * self.period))
    def ticked(self):
        while self.mode == "spin":  # a run that never ends: the sweep's --timeout stops it
            pass
        self.n += self.step


class Counter(Iota):
    tick = Input(Int, switching=0)

    def init(self):
        self.last = 0

    @tick.input
    def got(self, n):
        self.last = n


def tick_metrics(recording) -> dict:
    ticks = [e for e in recording.trace() if e.get("kind") == "output" and e.get("action") == "tick"]
    return {"ticks": len(ticks), "last": ticks[-1]["value"] if ticks else 0,
            "first_t": round(float(ticks[0]["t"]), 9) if ticks else -1.0}


def write_system(folder: Path) -> Path:
    """The ticker's system file in `folder`, naming this file's IOTAs and hook by path."""
    here = Path(__file__).resolve()
    path = folder / "ticker.toml"
    path.write_text(f"""[system]
name = "ticker"

[[node]]
name = "ticker"
python = "{here}:Ticker"
params = {{ period = 0.1, step = 1, mode = "ok" }}

[[node]]
name = "counter"
python = "{here}:Counter"

[[bind]]
from = "ticker.tick"
to = "counter.tick"

[sweep]
metrics = "{here}:tick_metrics"
""")
    return path
