"""nodes/scheduler/subsumption.iota and the r-level tree of them (nodes/scheduler/subsumption_tree.py):
the output follows the dominant input, and the inferior one only while the dominant one has been
absent for more than `hold`. Exact traces, a 4-level tree, trees of any size against the
functional definition, and random-policy conformance."""
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from iotad.cli import main
from iotad.esprit import load_iota

from scheduling_helpers import EXAMPLES, SUBSUMPTION, assert_conforms, run
from nodes.scheduler.subsumption_tree import load_tree, main as generate, tree_spec


def subsumption(hold=1.0):
    return load_iota(str(SUBSUMPTION), hold=hold)


def event(t, channel, value):
    return {"t": t, "action": channel, "value": value}


def outs(engine):
    return [(e["t"], e["value"]) for e in engine.external_trace() if e["action"] == "out"]


def test_without_the_dominant_input_the_output_is_the_inferior_input():
    engine = run(subsumption(), [event(0.0, "inferior", 1.0), event(0.4, "inferior", 2.0), event(3.0, "inferior", 3.0)])
    assert outs(engine) == [(0.0, 1.0), (0.4, 2.0), (3.0, 3.0)]


def test_with_the_dominant_input_the_inferior_one_waits_until_it_is_absent_for_more_than_hold():
    engine = run(subsumption(hold=1.0), [
        event(0.0, "inferior", 1.0),
        event(1.0, "dominant", 9.0),
        event(1.5, "inferior", 1.5),     # dominant 0.5 ago: suppressed
        event(2.0, "inferior", 2.0),     # exactly hold ago: not "more than", suppressed
        event(2.25, "inferior", 2.25),   # 1.25 ago: the inferior input goes out again
        event(3.0, "inferior", 3.0), event(3.0, "dominant", 8.0),  # one instant: one output, the dominant's
        event(5.0, "dominant", 7.0), event(5.0, "inferior", 5.0),
    ])
    assert outs(engine) == [(0.0, 1.0), (1.0, 9.0), (2.25, 2.25), (3.0, 8.0), (5.0, 7.0)]
    assert [(e["t"], e["action"]) for e in engine.trace if e["kind"] == "violation"] == []


def test_hold_zero_suppresses_only_at_the_same_instant():
    engine = run(subsumption(hold=0.0), [event(1.0, "dominant", 9.0), event(1.0, "inferior", 1.0),
                                         event(1.001, "inferior", 2.0)])
    assert outs(engine) == [(1.0, 9.0), (1.001, 2.0)]



def test_the_pair_example_script_with_iotad_spec_run(capsys):
    script = EXAMPLES / "subsumption-pair-inputs.jsonl"
    assert main(["spec", "run", str(SUBSUMPTION), "--inputs", str(script), "--until", "6"]) == 0
    trace = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(e["t"], e["value"]) for e in trace if e["kind"] == "output"] == [
        (0.0, 1.0), (0.5, 1.5),   # no dominant input yet: the inferior one goes out
        (1.0, 9.0),               # the dominant one
        (2.25, 3.0),              # inferior at 1.5 and 2.0 suppressed (dominant not absent > hold)
        (3.0, 8.0),               # both at one instant: the dominant one
        (5.0, 4.0)]               # dominant absent for 2 > hold
    assert not [e for e in trace if e["kind"] == "violation"]

def test_a_four_level_tree_with_the_example_script(capsys):
    script = EXAMPLES / "subsumption-inputs.jsonl"
    assert main(["spec", "run", str(EXAMPLES / "priority-tree4.iota"), "--inputs", str(script), "--until", "12"]) == 0
    trace = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    root = [(e["t"], e["value"]) for e in trace if e["iota"] == "priority_tree4/s0_3" and e["kind"] == "output"]
    assert root == [
        (0.0, 3.0),   # level3 alone
        (0.5, 2.0),   # level2 dominates level3
        (2.0, 3.2),   # level3 at 1.0 was suppressed (level2 0.5 ago); at 2.0 level2 is 1.5 ago
        (2.5, 0.0),   # level0 dominates everything
        (4.0, 1.1),   # level1 at 3.0 and level2 at 3.0 were suppressed by level0 (2.5)
        (6.0, 3.3)]   # level2 at 4.5 was suppressed by level1 (4.0); level3 at 6.0 is free
    inner = {(e["iota"].split("/")[1], e["t"]) for e in trace if e["kind"] == "output"}
    assert ("s2_3", 4.5) in inner and ("s0_3", 4.5) not in inner


def test_the_committed_four_level_tree_is_the_generator_output():
    assert (EXAMPLES / "priority-tree4.iota").read_text() == tree_spec(4)


def test_the_generator_command_line(tmp_path, capsys):
    out = tmp_path / "tree5.iota"
    assert generate(["5", "-o", str(out)]) == 0
    assert main(["spec", "check", str(out)]) == 0
    text = out.read_text()
    assert text.count("subsumption s") == 4 and "iota priority_tree5(" in text
    with pytest.raises(SystemExit) as exit_info:
        generate(["1"])
    assert exit_info.value.code == 2 and "at least 2 levels" in capsys.readouterr().err


def subsume(dominant, inferior, hold):
    """The subsumption-IOTA as a function of two event lists [(t, value)] at distinct times."""
    kept = [(t, v) for t, v in inferior if not any(0 <= t - d <= hold for d, _ in dominant)]
    return sorted(dominant + kept)


def tree(levels, low, high, hold):
    """The same split as the generator: the upper half dominates the lower half."""
    if high - low == 1:
        return levels[low]
    middle = (low + high + 1) // 2
    return subsume(tree(levels, low, middle, hold), tree(levels, middle, high, hold), hold)


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 6).flatmap(lambda r: st.tuples(
    st.just(r), st.lists(st.tuples(st.integers(0, 80), st.integers(0, r - 1)), max_size=25,
                         unique_by=lambda item: item[0]))))
def test_a_tree_of_any_size_is_the_composition_of_subsumptions(case):
    r, ticks = case
    hold = 1.0
    levels = [[] for _ in range(r)]
    inputs = []
    for tick, level in sorted(ticks):
        t = tick * 0.25  # exact in binary: `t - d <= hold` is decided exactly on both sides
        levels[level].append((t, float(level * 100 + tick)))
        inputs.append(event(t, f"level{level}", float(level * 100 + tick)))
    engine = run(load_tree(r, hold=hold), inputs, until=25.0)
    assert outs(engine) == tree(levels, 0, r, hold)


def test_a_tree_forgets_suppressed_events_as_brooks_wires_do():
    # level1 at 0.9 is suppressed by level0 (0.0), so it does not keep level3 at 1.5 out: the
    # tree is not "the highest level with any event in the last hold" (docs/schedulers.md)
    engine = run(load_tree(4, hold=1.0), [event(0.0, "level0", 0.0), event(0.9, "level1", 1.0),
                                          event(1.5, "level3", 3.0)])
    assert outs(engine) == [(0.0, 0.0), (1.5, 3.0)]


@pytest.mark.parametrize("seed", [1, 2])
def test_random_policy_runs_of_the_tree_conform(seed, tmp_path):
    from iotad.kernel.input_script import parse_script
    lines = (EXAMPLES / "subsumption-inputs.jsonl").read_text().splitlines()
    engine = assert_conforms(lambda: load_tree(4, hold=1.0, name="priority_tree4"), parse_script(lines), 12.0,
                             seed, tmp_path)
    assert len(outs(engine)) == 6
