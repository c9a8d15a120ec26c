"""What a sweep runs: the swept node parameters and their values (a grid, or random points in
ranges), the seeds, the virtual time of each run, and each run's name and overrides.

A plan is plain data (lists, dicts, numbers, strings): it is written whole into `sweep.json`,
compared with the one there to resume, and sent to the processes or Ray tasks that run it."""
from __future__ import annotations

import itertools
import json
import math
import random
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from iotad.sweep import SweepError

SWEEP_FILE_KEYS = {"system", "set", "seeds", "until", "sample", "sample_seed", "timeout", "metrics", "seed_param"}
_FILE_NUMBERS = {"seeds": (int, "a whole number > 0"), "sample": (int, "a whole number > 0"),
                 "sample_seed": (int, "a whole number >= 0"), "until": ((int, float), "a number of seconds > 0"),
                 "timeout": ((int, float), "a number of seconds > 0")}


@dataclass(frozen=True)
class Range:
    """A range to draw random points from (`--sample`): floats, or whole numbers when both ends are."""

    low: float
    high: float

    def draw(self, rng: random.Random) -> Any:
        if isinstance(self.low, int) and isinstance(self.high, int):
            return rng.randint(self.low, self.high)
        return rng.uniform(self.low, self.high)

    def __str__(self) -> str:
        return f"{self.low!r}..{self.high!r}"


@dataclass(frozen=True)
class Run:
    """One run: its name (`run-0007`: its place in the plan), the parameter values and the seed
    (None: the run fires under the system's own policy, eager unless stated, as `iotad run
    --virtual` does without --seed)."""

    name: str
    values: dict[str, Any]
    seed: int | None

    def policy(self, plan: "Plan") -> str:
        """The firing policy of this run, as the table names it: `eager`, or `random(K)`."""
        return "eager" if self.seed is None or plan.seed_param else f"random({self.seed})"


@dataclass
class Plan:
    system: str                                  # the system file, absolute
    until: float                                 # virtual seconds per run
    seeds: int                                   # seeds 0 .. seeds-1: the random policy's (iotad run --seed),
    #                                              or with seed_param that node parameter's (policy eager)
    swept: dict[str, list | Range]               # "node.param[.key...]" -> grid values, or a range
    sample: int | None = None                    # None: the grid; K: K random points
    sample_seed: int = 0                         # what draws the K points: the same plan, the same points
    timeout: float | None = None                 # wall seconds a run may take before it is a failed row
    metrics: str | None = None                   # the hook, "file.py:function" or "module:function"
    seed_param: str | None = None                # "node.param[.key...]" the seed goes into, if not the policy
    # False (no --seeds, no seeds in the sweep file): each point runs once under the system's own
    # policy, exactly as `iotad run --virtual` runs it; True: seeds 0..seeds-1 of `random`
    random: bool = True
    runs: list[Run] = field(default_factory=list)

    def describe(self) -> dict:
        """The plan as `sweep.json` holds it."""
        return {"system": self.system, "until": self.until, "seeds": self.seeds,
                "set": {name: (str(v) if isinstance(v, Range) else v) for name, v in self.swept.items()},
                "sample": self.sample, "sample_seed": self.sample_seed, "timeout": self.timeout,
                "metrics": self.metrics, "seed_param": self.seed_param,
                "policy": "random" if self.random and not self.seed_param else "eager",
                "runs": [asdict(run) for run in self.runs]}


def parse_value(text: str) -> Any:
    """A value as written after `=`: a whole number, a number, true/false, else the text itself."""
    text = text.strip()
    for kind in (int, float):
        try:
            value = kind(text)
        except ValueError:
            continue
        if isinstance(value, float) and not math.isfinite(value):
            break
        return value
    if text in ("true", "false"):
        return text == "true"
    return text


def parse_set(text: str, sample: bool) -> tuple[str, list | Range]:
    """`node.param=v1,v2,...` (a grid) or, with --sample, `node.param=LOW..HIGH` (a range)."""
    name, eq, values = text.partition("=")
    name = name.strip()
    if not eq or "." not in name or not values.strip():
        raise SweepError(f"--set {text!r}: expected NODE.PARAM=V1,V2,... (or NODE.PARAM=LOW..HIGH with --sample)")
    if ".." in values:
        low, _, high = values.partition("..")
        low, high = parse_value(low), parse_value(high)
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (low, high)) or low > high:
            raise SweepError(f"--set {text!r}: a range is LOW..HIGH, two numbers with LOW <= HIGH")
        if not sample:
            raise SweepError(f"--set {text!r}: a range is for --sample K (random points); a grid lists its values")
        return name, Range(low, high)
    return name, [parse_value(v) for v in values.split(",")]


def read_sweep_file(path: Path) -> dict | None:
    """A sweep file's `[sweep]` table, with `system` made absolute; None for a system file (one
    with nodes): a sweep file names its system, a system file is one."""
    from iotad.launcher.system.declaration import read_toml

    try:
        data = read_toml(path)
    except OSError as exc:
        raise SweepError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except ValueError as exc:  # TOML, UTF-8, or an integer of thousands of digits
        raise SweepError(f"{path}: not valid TOML: {exc}") from None
    table = data.get("sweep")
    if "node" in data or not isinstance(table, dict) or "system" not in table:
        return None
    other = sorted(set(data) - {"sweep"})
    if other:
        raise SweepError(f"{path.name}: unknown top-level key {other[0]!r} in a sweep file (it holds one [sweep] table)")
    unknown = sorted(set(table) - SWEEP_FILE_KEYS)
    if unknown:
        raise SweepError(f"{path.name}: [sweep]: unknown key {unknown[0]!r} (expected one of {sorted(SWEEP_FILE_KEYS)})")
    for key, (kind, what) in _FILE_NUMBERS.items():
        value = table.get(key)
        if key not in table:
            continue
        number = isinstance(value, kind) and not isinstance(value, bool) and math.isfinite(value)
        if not number or not (value >= 0 if key == "sample_seed" else value > 0):
            raise SweepError(f"{path.name}: [sweep] {key} must be {what}, got {value!r}")
    if "seed_param" in table and not isinstance(table["seed_param"], str):
        raise SweepError(f"{path.name}: [sweep] seed_param must be \"node.param\", got {table['seed_param']!r}")
    if not isinstance(table["system"], str):
        raise SweepError(f"{path.name}: [sweep] system must be the system file's name, got {table['system']!r}")
    table = dict(table, system=str((path.parent / table["system"]).resolve()))
    if "metrics" in table:  # a file named as relative is relative to the sweep file, as in a system file
        where, _, function = str(table["metrics"]).rpartition(":")
        if where.endswith(".py"):
            table["metrics"] = f"{(path.parent / where).resolve()}:{function}"
    swept = table.get("set", {})
    if not isinstance(swept, dict):
        raise SweepError(f"{path.name}: [sweep.set] must be a table: \"node.param\" = [values] or {{ from, to }}")
    table["set"] = {name: _file_values(path.name, name, v) for name, v in swept.items()}
    return table


def _file_values(file: str, name: str, raw: Any) -> list | Range:
    if isinstance(raw, list) and raw:
        return raw
    if isinstance(raw, dict) and set(raw) == {"from", "to"} and all(
            isinstance(raw[k], (int, float)) and not isinstance(raw[k], bool) for k in raw) and raw["from"] <= raw["to"]:
        return Range(raw["from"], raw["to"])
    raise SweepError(f"{file}: [sweep.set] {name!r}: expected a list of values, or {{ from = LOW, to = HIGH }}")


def make_runs(plan: Plan) -> list[Run]:
    """Every run of the plan, in order: each point (grid or sample) with each seed."""
    names = list(plan.swept)
    if plan.sample is None:
        ranges = [n for n, v in plan.swept.items() if isinstance(v, Range)]
        if ranges:
            raise SweepError(f"{ranges[0]} is a range: ranges go with --sample K (random points)")
        points = [dict(zip(names, combo)) for combo in itertools.product(*plan.swept.values())]
    else:
        rng = random.Random(plan.sample_seed)
        points = [{n: (v.draw(rng) if isinstance(v, Range) else rng.choice(v)) for n, v in plan.swept.items()}
                  for _ in range(plan.sample)]
    width = max(4, len(str(len(points) * plan.seeds - 1)))
    runs = []
    for point in points:
        for seed in range(plan.seeds):
            chosen = seed if plan.random or plan.seed_param else None
            runs.append(Run(f"run-{len(runs):0{width}d}", point, chosen))
    return runs


def check_against(plan: Plan, system) -> None:
    """Each swept parameter names a node of the system and a parameter its [[node]] gives (a typo
    would sweep nothing): refused before anything runs."""
    for name in [*plan.swept, *([plan.seed_param] if plan.seed_param else [])]:
        node, _, path = name.partition(".")
        if node not in system.nodes:
            raise SweepError(f"{name}: no node {node!r} in {system.file} (nodes: {', '.join(system.nodes)})")
        params: Any = system.nodes[node].params
        for key in path.split("."):
            if not isinstance(params, dict) or key not in params:
                known = ", ".join(params) if isinstance(params, dict) else "none: it is a value"
                raise SweepError(f"{name}: {system.file} gives node {node!r} no parameter {path!r} "
                               f"({key!r} is not among {known})")
            params = params[key]


def apply(system, values: dict[str, Any]):
    """The system with each "node.param[.key...]" of `values` set in its nodes' parameters: a new
    system whose changed nodes have new declarations, built whole; the checked system it came
    from, and its declarations, unchanged (a worker keeps it for its next run)."""
    import copy
    import dataclasses

    params: dict[str, dict] = {}  # node -> its parameters with the values set, a copy of the declared
    for name, value in values.items():
        node, _, path = name.partition(".")
        table = params.setdefault(node, copy.deepcopy(dict(system.nodes[node].params)))
        *parents, leaf = path.split(".")
        for key in parents:
            table = table[key]
        table[leaf] = value
    nodes = dict(system.nodes)
    for node, changed in params.items():
        spec = nodes[node]
        nodes[node] = dataclasses.replace(spec, declared=dataclasses.replace(spec.declared, params=changed))
    return dataclasses.replace(system, nodes=nodes)


def load_checked(path: str):
    """The system file at `path`, checked as `iotad run` checks it; `SweepError` listing every
    problem otherwise."""
    from iotad.launcher.system.system_file import SystemFileError, load_system

    try:
        return load_system(path)
    except SystemFileError as exc:
        raise SweepError(str(exc) if len(exc.errors) == 1 else
                         f"{len(exc.errors)} problems in the system file:\n" + str(exc)) from None


def same_plan(plan: Plan, described: dict) -> bool:
    """Whether `sweep.json`'s plan is this one (so its finished runs are this sweep's)."""
    return json.loads(json.dumps(plan.describe())) == described.get("plan")
