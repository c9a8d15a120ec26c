"""The scheduler that carries MDL programs (nodes/scheduler/program_scheduler.iota) is Figure 2's
transcription (nodes/scheduler/scheduler.iota) with other types: the rules are the same text,
each of Figure 2's scenarios gives the same schedule, acks and commands, and mdl_command
forwards the winner's program, which drives the interpreter bound to it."""
import json
from pathlib import Path

import pytest

from channels.mdl import MDL_PROGRAM, mode_program, program, program_to_plain, ramp
from iotad.esprit import load_file, load_iota
from iotad.kernel.compose import Composite
from iotad.kernel.input_script import parse_script, run_script
from iotad.kernel.policy import make_policy
from mdl_harness import PerfectMotor
from nodes.mdl_interp import MdlInterpreter

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "nodes" / "scheduler" / "scheduler.iota"
PROGRAMS = ROOT / "nodes" / "scheduler" / "program_scheduler.iota"


def req(t, index, priority, epoch=2.0, timeout=5.0, w=0.5):
    return {"t": t, "action": "req", "index": index,
            "value": {"control": {"w": w, "k": 1.0}, "epoch": epoch, "timeout": timeout, "priority": priority}}


# Figure 2's scenarios, as tests/esprit/test_figure2_scheduler_in_esprit.py states them; the
# paper's mode {w, k} is a valid program, so the same requests go to both schedulers.
SCENARIOS = {
    "commit_after_epoch": [req(0.0, 0, 1, epoch=2.0)],
    "preempt_abort": [req(0.0, 0, 1, epoch=5.0), req(1.0, 1, 5, epoch=1.0, w=1.5)],
    "timeout_reject": [req(0.0, 0, 5, epoch=5.0), req(0.5, 1, 1, timeout=1.0)],
    "lower_waits_then_runs": [req(0.0, 0, 5, epoch=2.0), req(0.5, 1, 1, epoch=1.0, timeout=10.0, w=-0.5)],
    "input_sooner_than_switching": [req(0.0, 0, 1), req(0.5, 0, 1)],
    # req[1] takes the motors at 0.4 but its mode waits for mdl_command's switching time (until
    # 1.0), and it times out at 0.7: the motors are free again for the priority-4 request at 8
    "rejected_master_frees_the_motors": [req(0.0, 0, 1, epoch=4.0), req(0.4, 1, 5, timeout=0.3),
                                         req(8.0, 0, 4, epoch=1.0, timeout=1.0)],
}


def run(spec, inputs, until=20.0, policy="eager", seed=0, **params):
    entries = parse_script([json.dumps(e) for e in inputs])
    return run_script(load_iota(str(spec), **params), entries, until, make_policy(policy, seed)).trace


def rules(path):
    """The text from the opening brace of `iota scheduler` to the end: the transition rules,
    less the lines of the program scheduler's one addition (restart notices), marked `// +restart`."""
    text = path.read_text(encoding="utf-8")
    start = text.index("iota scheduler")
    return "".join(line for line in text[text.index("{", start):].splitlines(keepends=True)
                   if not line.rstrip().endswith("// +restart"))


def test_the_rules_are_figure_2s_text():
    assert rules(PROGRAMS) == rules(FIGURE2)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_each_figure_2_scenario_gives_the_same_trace_with_the_mode_as_its_program(name):
    figure2, programs = run(FIGURE2, SCENARIOS[name]), run(PROGRAMS, SCENARIOS[name])
    assert len(figure2) == len(programs)
    for mode_event, program_event in zip(figure2, programs):
        if mode_event["action"] in ("mdl_command", "req") and mode_event["kind"] in ("output", "input"):
            mode = mode_event["value"]["control"] if mode_event["action"] == "req" else mode_event["value"]
            expected = program_to_plain(mode_program(mode["w"], mode["k"]))
            got = program_event["value"]["control"] if program_event["action"] == "req" else program_event["value"]
            assert program_to_plain(MDL_PROGRAM.from_plain(got)) == expected
            mode_event, program_event = dict(mode_event, value=None), dict(program_event, value=None)
        assert program_event == mode_event


def test_the_random_policy_gives_the_same_schedule_too():
    inputs = SCENARIOS["preempt_abort"] + [req(6.0, 0, 3, timeout=0.5), req(6.2, 1, 1, timeout=4.0)]
    def shape(spec):
        return [(e["t"], e["action"], e["index"], e["kind"]) for e in run(spec, inputs, 30.0, "random", 7, T=0.5)]
    assert shape(PROGRAMS) == shape(FIGURE2)


def test_the_winners_program_goes_out_on_mdl_command():
    reach = program_to_plain(program("reach", ramp({"joint1": 0.5}, T=1.0)))
    dodge = program_to_plain(program("dodge", ramp({"joint2": -0.3}, T=0.5)))
    inputs = [{"t": 0.0, "action": "req", "index": 0, "value": {"control": reach, "epoch": 5.0, "timeout": 5.0,
                                                                 "priority": 1}},
              {"t": 1.0, "action": "req", "index": 1, "value": {"control": dodge, "epoch": 1.0, "timeout": 5.0,
                                                                 "priority": 5}}]
    trace = run(PROGRAMS, inputs)
    commands = [(e["t"], e["value"]["id"]) for e in trace if e["action"] == "mdl_command"]
    assert commands == [(0.0, "reach"), (1.0, "dodge")]
    assert [(e["t"], e["index"], e["value"]) for e in trace if e["action"] == "ack"] == \
        [(1.0, 0, "ABORT"), (2.0, 1, "COMMIT")]


def test_a_request_with_a_malformed_program_is_rejected_where_it_arrives():
    bad = {"id": "bad", "behaviours": [{"atoms": [{"u": {"kind": "ramp", "target": {"joint1": 0.5}}}]}]}
    trace = run(PROGRAMS, [{"t": 0.0, "action": "req", "index": 0,
                            "value": {"control": bad, "epoch": 1.0, "timeout": 1.0, "priority": 1}}])
    [violation] = [e for e in trace if e["kind"] == "violation"]
    assert violation["value"]["violation"] == "bad_value"
    assert "control: mdlProgram.behaviours[0].atoms[0].T: a ramp needs a duration T" in violation["value"]["message"]
    assert not [e for e in trace if e["action"] == "mdl_command"]


def test_the_scheduler_drives_the_interpreter_and_the_preempted_program_resumes():
    """vision's reach is preempted by a higher-priority dodge; sent again, it resumes where it was."""
    reach = program_to_plain(program("reach", ramp({"joint1": 0.5}, T=2.0)))
    dodge = program_to_plain(program("dodge", ramp({"joint2": -0.3}, T=0.5)))

    def request(t, index, control, epoch, priority):
        return {"t": t, "action": "req", "index": index,
                "value": {"control": control, "epoch": epoch, "timeout": 5.0, "priority": priority}}

    system = Composite("arm", load_iota(str(PROGRAMS), name="scheduler", T=0.5),
                       MdlInterpreter("mdl", rate=100.0), PerfectMotor("motor"),
                       bind=[("scheduler.mdl_command", "mdl.mdl_command"), ("mdl.setpoints", "motor.setpoints"),
                             ("motor.joint_states", "mdl.joint_states")])
    inputs = [request(0.0, 0, reach, 5.0, 1), request(1.0, 1, dodge, 1.0, 5), request(2.5, 0, reach, 5.0, 1)]
    entries = [dict(e, iota="arm/scheduler") for e in parse_script([json.dumps(e) for e in inputs])]
    trace = run_script(system, entries, 6.0).trace
    ends = [(e["value"]["program"], e["value"]["end"], e["t"]) for e in trace
            if e["iota"] == "arm/mdl" and e["action"] == "program_end"]
    # reach runs from tick 1 (the first joint_states come at 0) to 99: 0.99 s of its 2 s; dodge
    # runs ticks 100..149; dodge commits at 2.0 and reach, asked for again at 2.5, resumes
    # there and runs its last 1.01 s: done at tick 350
    assert ends == [("reach", "PREEMPTED", 1.0), ("dodge", "DONE", pytest.approx(1.49)),
                    ("reach", "DONE", pytest.approx(3.5))]
    setpoints = {round(e["t"] * 100): e["value"]["position"] for e in trace
                 if e["iota"] == "arm/mdl" and e["action"] == "setpoints"}
    assert setpoints[99][0] == pytest.approx(0.99 / 2.0 * 0.5)
    assert {setpoints[m][0] for m in range(99, 250)} == {setpoints[99][0]}   # held while dodging
    assert setpoints[149][1] == pytest.approx(-0.3)
    assert setpoints[300][0] == pytest.approx(0.5 * (0.99 + 0.51) / 2.0)      # on its ramp again
    assert setpoints[350][0] == pytest.approx(0.5)


def test_the_program_types_are_channel_types():
    module = load_file(PROGRAMS)
    from channels.mdl import MDL_PROGRAM_REQ
    assert module.structs["mdlProgramReq"].json_schema() == MDL_PROGRAM_REQ.json_schema()
