"""The paper's Figure 2 motion scheduler (Python API) in virtual time: commit, preemption,
time-out, waiting, and a request faster than the switching time."""
import json

import pytest

from iotad import run_script
from iotad.kernel.input_script import ScriptError, parse_script

from scheduler import Scheduler


def request(priority, epoch, timeout, w=1.0):
    return {"control": {"w": w, "k": 0.5}, "epoch": epoch, "timeout": timeout, "priority": priority}


def scenario(*inputs, until=30, N=2, T=0.5):
    script = [{"t": t, "action": "req", "index": i, "value": value} for t, i, value in inputs]
    return run_script(Scheduler("scheduler", N=N, T=T), script, until)


def summary(engine):
    """(t, action, index, value) of outputs and internal actions, the scheduler's visible story."""
    return [(e["t"], e["action"], e["index"], e["value"]) for e in engine.trace
            if e["kind"] in ("output", "internal")]


def acks(engine):
    return [(e["t"], e["index"], e["value"]) for e in engine.trace if e["action"] == "ack" and e["kind"] == "output"]


def test_a_request_commits_after_its_epoch():
    engine = scenario((0.0, 0, request(1, epoch=2.0, timeout=5.0, w=0.3)))
    assert summary(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, {"w": 0.3, "k": 0.5}),
        (2.0, "commit", 0, None), (2.0, "ack", 0, "COMMIT")]
    assert engine.iota("scheduler").current_master is None


def test_a_higher_priority_request_preempts_the_one_signalling():
    engine = scenario((0.0, 0, request(1, epoch=5.0, timeout=10.0, w=0.1)),
                      (1.0, 1, request(5, epoch=2.0, timeout=10.0, w=0.9)))
    assert acks(engine) == [(1.0, 0, "ABORT"), (3.0, 1, "COMMIT")]
    commands = [(e["t"], e["value"]["w"]) for e in engine.trace if e["action"] == "mdl_command"]
    assert commands == [(0.0, 0.1), (1.0, 0.9)]
    assert not [e for e in engine.trace if e["action"] == "commit" and e["index"] == 0]


def test_a_request_that_cannot_be_served_in_time_is_rejected():
    engine = scenario((0.0, 0, request(5, epoch=10.0, timeout=20.0)),
                      (0.5, 1, request(1, epoch=1.0, timeout=2.0)))
    assert (2.5, "reject", 1, None) in summary(engine)
    assert acks(engine) == [(2.5, 1, "REJECT"), (10.0, 0, "COMMIT")]


def test_a_lower_priority_request_waits_and_runs_after_the_current_one_commits():
    engine = scenario((0.0, 0, request(5, epoch=2.0, timeout=10.0, w=0.1)),
                      (0.5, 1, request(1, epoch=1.5, timeout=10.0, w=0.7)))
    assert summary(engine) == [
        (0.0, "schedule", 0, None), (0.0, "mdl_command", None, {"w": 0.1, "k": 0.5}),
        (2.0, "commit", 0, None), (2.0, "schedule", 1, None),
        (2.0, "mdl_command", None, {"w": 0.7, "k": 0.5}), (2.0, "ack", 0, "COMMIT"),
        (3.5, "commit", 1, None), (3.5, "ack", 1, "COMMIT")]


def test_an_input_sooner_than_its_switching_time_is_rejected_as_a_violation():
    engine = scenario((0.0, 0, request(1, 2.0, 5.0)), (0.4, 0, request(9, 2.0, 5.0)))
    [violation] = [e for e in engine.trace if e["kind"] == "violation"]
    assert violation["t"] == 0.4 and violation["value"]["violation"] == "switching_time"
    assert acks(engine) == [(2.0, 0, "COMMIT")]  # the first request went on undisturbed


def test_a_malformed_request_is_a_violation_and_the_scheduler_goes_on():
    engine = scenario((0.0, 0, {"control": {"w": 1.0}, "epoch": 1.0}), (0.1, 1, request(1, 1.0, 5.0)))
    [violation] = [e for e in engine.trace if e["kind"] == "violation"]
    assert violation["value"]["violation"] == "bad_value" and "missing" in violation["value"]["message"]
    assert acks(engine) == [(1.1, 1, "COMMIT")]


def test_input_script_lines_are_checked_with_their_line_number():
    good = parse_script([json.dumps({"t": 0, "action": "req", "index": 0, "value": request(1, 1, 1)}), ""])
    assert good[0]["t"] == 0.0
    for line, message in [("{nope", "not JSON"), ('{"t": -1, "action": "req"}', "finite time"),
                          ('{"t": 1, "action": 3}', "action"), ('{"t": 1, "action": "a", "x": 1}', "unknown field"),
                          ('{"t": 1, "action": "a", "index": -2}', "index")]:
        with pytest.raises(ScriptError, match=rf"in\.jsonl:2: .*{message}"):
            parse_script(['{"t": 0, "action": "req"}', line], "in.jsonl")
