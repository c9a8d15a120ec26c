"""Brooks' module inputs in ESPRIT: `reset() do reset();` takes a module back to its initial state
(state and timers), `inhibit(d) do inhibit(d);` disables its outputs for d time units. Traces of
examples/behaviours.iota and of small modules, and conformance of recorded runs."""
import json

import pytest

from iotad.cli import main
from iotad.esprit import load_iota
from iotad.kernel.input_script import parse_script

from scheduling_helpers import EXAMPLES, assert_conforms, run, story, violations

BEHAVIOURS = EXAMPLES / "behaviours.iota"


def behaviour(**params):
    return load_iota(str(BEHAVIOURS), **params)


def test_the_example_module_with_iotad_spec_run(capsys):
    assert main(["spec", "run", str(BEHAVIOURS), "--param", "step=0.5", "--inputs",
                 str(EXAMPLES / "behaviour-inputs.jsonl"), "--until", "10"]) == 0
    trace = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(e["t"], e["action"], e["value"]) for e in trace if e["kind"] in ("output", "internal")] == [
        (0.0, "out", 0.0), (1.0, "out", 0.5), (2.0, "out", 1.0),
        # inhibit(2) at 2.5, inhibit(2) at 3.0: no output until 5.0, then a new period
        (5.0, "uninhibit", None), (6.0, "out", 1.5), (7.0, "out", 2.0),
        # reset at 7.5: the count and its timer start again
        (7.5, "restarted", None), (7.5, "out", 0.0), (8.5, "out", 0.5), (9.5, "out", 1.0)]


def test_inhibit_disables_outputs_only_and_a_shorter_inhibit_does_not_cut_a_longer_one():
    engine = run(behaviour(period=1.0, step=1.0), [{"t": 0.5, "action": "inhibit", "value": 3.0},
                                                  {"t": 1.0, "action": "inhibit", "value": 0.5}], until=6.0)
    assert story(engine) == [(0.0, "out", None, 0.0), (3.5, "uninhibit", None, None), (4.5, "out", None, 1.0),
                             (5.5, "out", None, 2.0)]


def test_inhibit_zero_and_negative_times():
    engine = run(behaviour(period=1.0), [{"t": 0.5, "action": "inhibit", "value": 0.0},
                                        {"t": 0.6, "action": "inhibit", "value": -1.0}], until=2.0)
    assert [e["t"] for e in engine.trace if e["action"] == "out"] == [0.0, 1.5]  # window restarted at 0.5
    assert [(v["t"], v["value"]["violation"]) for v in violations(engine)] == [(0.6, "bad_value")]


def test_reset_ends_an_inhibition_and_restarts_every_window():
    engine = run(behaviour(start=0.5, period=2.0), [{"t": 1.0, "action": "inhibit", "value": 10.0},
                                                   {"t": 3.0, "action": "reset"}], until=6.0)
    assert story(engine) == [(0.5, "out", None, 0.0), (3.0, "restarted", None, None), (3.5, "out", None, 0.0),
                             (5.5, "out", None, 0.0)]
    state = engine.iota("behaviour")
    assert state.sent == 2 and not state._inhibited


MODULE = """
iota counter(float P = 1.0): reset()/0, inhibit(float)/0, bump()/0 -> total(int)/0 {
  states int n = 0; int bumps = 0; bool dirty = false;
  channels tick()/0;
  actions
  reset() do reset();
  inhibit(d) do inhibit(d);
  bump() do { bumps = bumps + 1; dirty = true; }
  tick() when n < 100 after P do n = n + 1;      // internal: inhibit leaves it running
  total(n + bumps) when dirty do dirty = false;
}
"""


def test_internal_actions_run_while_inhibited_and_outputs_resume_with_the_current_state():
    engine = run(load_iota(MODULE), [{"t": 0.5, "action": "inhibit", "value": 2.0},
                                     {"t": 1.0, "action": "bump"}, {"t": 4.0, "action": "reset"},
                                     {"t": 4.2, "action": "bump"}], until=5.5)
    assert story(engine) == [
        (1.0, "tick", None, None), (2.0, "tick", None, None),
        (2.5, "uninhibit", None, None), (2.5, "total", None, 3),           # bumped at 1.0, sent when allowed
        # at 4.0 the reset input comes before the tick due then (inputs first at an instant): the
        # tick's window starts again at 4.0
        (3.0, "tick", None, None), (4.0, "restarted", None, None), (4.2, "total", None, 1),
        (5.0, "tick", None, None)]


@pytest.mark.parametrize("seed", [1, 2])
def test_random_policy_runs_conform(seed, tmp_path):
    inputs = parse_script([json.dumps({"t": 0.5, "action": "inhibit", "value": 2.0}),
                           json.dumps({"t": 1.0, "action": "bump"}), json.dumps({"t": 1.2, "action": "inhibit",
                                                                                  "value": 3.0}),
                           json.dumps({"t": 4.0, "action": "reset"}), json.dumps({"t": 4.2, "action": "bump"})])
    assert_conforms(lambda: load_iota(MODULE), inputs, 8.0, seed, tmp_path)
