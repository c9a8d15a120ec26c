"""Shared helpers for the scheduler tests: run a spec in virtual time, summarise its trace, record
a run to MCAP and check it with `iotad check`."""
from pathlib import Path

import pytest

from iotad import Eager, Random, run_script
from iotad.cli import main
from iotad.esprit import load_iota
from iotad.recording.conformance import check_trace
from iotad.recording.engine_sink import record_run

ROOT = Path(__file__).resolve().parents[2]
SCHEDULERS = ROOT / "nodes" / "scheduler"
RESUME = SCHEDULERS / "resume.iota"
FUSION = SCHEDULERS / "fusion.iota"
SUBSUMPTION = SCHEDULERS / "subsumption.iota"
FIGURE2 = SCHEDULERS / "scheduler.iota"
EXAMPLES = ROOT / "examples"


def mode(w):
    return {"w": w, "k": 1.0}


def req(t, index, priority, epoch=2.0, timeout=10.0, w=0.5):
    """An input-script entry for req[index] of the Figure 2 / resume schedulers."""
    return {"t": t, "action": "req", "index": index,
            "value": {"control": mode(w), "epoch": epoch, "timeout": timeout, "priority": priority}}


def priority(t, index, value):
    return {"t": t, "action": "priority", "index": index, "value": value}


def run(root, inputs, until=30.0, seed=None):
    """The engine after running `root` on `inputs` (eager, or random(seed))."""
    policy = Eager() if seed is None else Random(seed)
    return run_script(root, inputs, until, policy)


def story(engine, kinds=("output", "internal")):
    """(t, action, index, value) of the events of the given kinds: what a scheduler did."""
    return [(e["t"], e["action"], e["index"], e["value"]) for e in engine.trace if e["kind"] in kinds]


def acks(engine):
    return [(e["t"], e["index"], e["value"]) for e in engine.trace if e["action"] == "ack" and e["kind"] == "output"]


def violations(engine):
    return [e for e in engine.trace if e["kind"] == "violation"]


def assert_conforms(spec_factory, inputs, until, seed, tmp_path):
    """A random-policy run recorded to MCAP is accepted by `iotad check`, and by check_trace
    in-process; returns the engine of the run."""
    recording = tmp_path / f"run-{seed}.mcap"
    engine = record_run(spec_factory(), recording, until=until, inputs=inputs, policy=Random(seed))
    assert not violations(engine)
    assert main(["check", str(recording)]) == 0
    report = check_trace(spec_factory(), engine.trace, until=until)
    assert report.ok, report.lines()
    assert report.firings == sum(1 for e in engine.trace if e["kind"] in ("output", "internal"))
    return engine


@pytest.fixture
def resume():
    return lambda **params: load_iota(str(RESUME), **params)
