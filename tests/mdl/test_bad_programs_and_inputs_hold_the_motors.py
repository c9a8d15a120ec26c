"""Malformed programs, unknown joints, missing or NaN sensor values and programs that fail while
running: each is refused with a message that names the field, the motors are held where they
were commanded, and the interpreter stays alive and runs the next good program."""
import pytest

from channels.mdl import MDL_PROGRAM, gain, hold, program, program_from_plain, ramp
from iotad.kernel.types import BadValue
from mdl_harness import arm


def atom(**fields):
    return {"id": "p", "behaviours": [{"atoms": [fields]}]}


@pytest.mark.parametrize("plain, message", [
    ({"behaviours": []}, "mdlProgram: missing field(s) ['id']"),
    ({"id": "p", "behaviours": []}, "mdlProgram.behaviours: must not be empty"),
    ({"id": "p", "behaviours": [{"atoms": [{}]}]}, "mdlProgram.behaviours[0].atoms[0]: missing field(s) ['u']"),
    (atom(u={"kind": "teleport"}), "mdlProgram.behaviours[0].atoms[0].u.kind: 'teleport' is not one of"),
    (atom(u={"kind": "ramp", "target": {"joint1": 0.5}}), "atoms[0].T: a ramp needs a duration T"),
    (atom(u={"kind": "ramp", "target": {"joint1": 0.5}}, T=-1), "atoms[0].T: expected a number > 0"),
    (atom(u={"kind": "ramp", "target": {"joint1": float("nan")}}, T=1), "u.target.joint1: expected a finite number"),
    (atom(u={"kind": "ramp", "target": {}}, T=1), "u.target: names no joint"),
    (atom(u={"kind": "ramp", "target": {"joint1": 1}, "pose": {"position": [0, 0, 0]}}, T=1),
     "give exactly one"),
    (atom(u={"kind": "ramp", "pose": {"position": [0.3, 0.0]}}, T=1), "u.pose.position: expected 3 numbers"),
    (atom(u={"kind": "sine", "amplitude": {"joint1": 0.1}, "frequency": 0}), "u.frequency: expected a number > 0"),
    (atom(u={"kind": "hold"}, xi="proximity.distance <"), "atoms[0].xi: not an ESPRIT expression"),
    (atom(u={"kind": "hold"}, k=[{"joint": "joint1", "sensor": "x", "gain": "fast"}]),
     "atoms[0].k[0].gain: expected a number, got str"),
    (atom(u={"kind": "hold"}, speed=3), "unknown field(s) ['speed']"),
    ([1, 2], "mdlProgram: expected an object, got list"),
    # JSON's "\ud800" is a lone surrogate: valid JSON, but no UTF-8 (the wire, a recording) carries it
    ({"id": "\u00e9\ud800", "behaviours": [{"atoms": [{"u": {"kind": "hold"}}]}]},
     "mdlProgram.id: not Unicode text (a lone surrogate"),
    (atom(u={"kind": "ramp", "target": {"joint\udc80": 0.5}}, T=1), "u.target key: not Unicode text"),
])
def test_a_malformed_program_is_rejected_naming_the_field(plain, message):
    with pytest.raises(BadValue) as caught:
        program_from_plain(plain)
    assert message in str(caught.value)


def test_a_syntax_error_in_an_interrupt_points_at_its_column():
    with pytest.raises(BadValue) as caught:
        program_from_plain(atom(u={"kind": "hold"}, xi="proximity.distance < < 0.3"))
    assert "1:22" in str(caught.value) and "^" in str(caught.value)


def test_a_malformed_program_on_the_channel_is_a_violation_and_the_running_one_goes_on(make_run):
    run = make_run()
    run.command(program("reach", ramp({"joint1": 0.5}, T=1.0)), t=0.0)
    run.command(atom(u={"kind": "ramp", "target": {"joint1": 0.9}}), t=0.5)
    run.run(until=1.2)
    [violation] = run.violations()
    assert violation["value"]["violation"] == "bad_value"
    assert "input mdl_command: mdlProgram.behaviours[0].atoms[0].T: a ramp needs a duration T" in \
        violation["value"]["message"]
    assert dict(run.setpoints(0))[1.0] == pytest.approx(0.5)
    assert [(v["program"], v["end"]) for v in run.values("program_end")] == [("reach", "DONE")]


def test_an_unknown_joint_is_a_fault_the_motors_hold_and_the_next_program_runs(make_run):
    run = make_run()
    run.command(program("elbow", ramp({"elbow": 0.5}, T=1.0)), t=0.0)
    run.command(program("reach", ramp({"joint1": 0.2}, T=0.2)), t=0.5)
    run.run(until=1.0)
    [fault] = run.values("fault")
    assert "program 'elbow' cannot run here: behaviours[0].atoms[0].u.target: unknown joint 'elbow'" in fault["message"]
    assert "motors held" in fault["message"]
    points = {round(t * 100): p for t, p in run.setpoints(0)}
    assert {points[m] for m in range(1, 50)} == {0.0}                      # held until the next program
    assert points[70] == pytest.approx(0.2)
    ends = [(v["program"], v["end"]) for v in run.values("program_end")]
    assert ends == [("elbow", "FAULT"), ("reach", "DONE")]


def test_a_missing_sensor_holds_the_atom_still_until_it_comes(make_run):
    run = make_run()
    run.command(program("servo", hold(k=[gain("joint1", "visual_error.x", 0.01)], T=0.2)), t=0.0)
    for k in range(10):                                                   # 0.1 rad/s from tick 51
        run.sensor(0, [10.0, 0.0], t=0.5001 + 0.05 * k)
    run.run(until=1.0)
    [fault] = run.values("fault")
    assert "reads visual_error: no value from sensor[0] (visual_error) yet; motors held" in fault["message"]
    [end] = run.values("atom_end")
    assert (end["end"], end["tick"]) == ("DONE", 70)                      # its 0.2 s ran from tick 51
    points = {round(t * 100): p for t, p in run.setpoints(0)}
    assert points[50] == 0.0 and points[70] == pytest.approx(0.02)


def test_a_stale_or_invalid_sensor_holds_the_motors_and_says_why(make_run):
    run = make_run(sensor_timeout=0.05)
    run.command(program("servo", hold(k=[gain("joint1", "visual_error.x", 0.01)])), t=0.0)
    run.sensor(0, [10.0, 0.0], t=0.0)
    run.sensor(0, [10.0, 0.0], t=0.3, valid=False)
    run.run(until=0.5)
    messages = [v["message"] for v in run.values("fault")]
    assert len(messages) == 2                                            # once per cause, not per tick
    assert any("the last value from sensor[0] (visual_error) is 0.06 s old (sensor_timeout 0.05 s)" in m
               for m in messages)
    assert any("sensor[0] (visual_error) says its value is not valid" in m for m in messages)
    points = {round(t * 100): p for t, p in run.setpoints(0)}
    assert points[5] == pytest.approx(0.005) and points[20] == points[5]


def test_a_nan_sensor_value_is_rejected_and_the_motors_hold(make_run):
    run = make_run()
    run.command(program("servo", hold(k=[gain("joint1", "visual_error.x", 0.01)])), t=0.0)
    run.sensor(0, [float("nan"), 0.0], t=0.0)
    run.run(until=0.2)
    [violation] = run.violations()
    assert "input sensor: sensorReading.value: [0]: NaN is not a valid float value; rejected" in \
        violation["value"]["message"]
    assert {p for _, p in run.setpoints(0)} == {0.0}


def test_a_feedback_term_that_fails_stops_the_program_and_holds(make_run):
    run = make_run()
    run.command(program("divide", hold(k=[gain("joint1", "1.0 / visual_error.y", 0.01)])), t=0.0)
    run.sensor(0, [1.0, 0.0], t=0.0)
    run.command(program("after", ramp({"joint1": 0.1}, T=0.1)), t=0.1)
    run.run(until=0.3)
    fault = run.values("fault")[0]
    assert "program 'divide' stopped: behaviours[0].atoms[0].k[0].sensor: '1.0 / visual_error.y' failed: " \
           "ZeroDivisionError" in fault["message"]
    assert [(v["program"], v["end"]) for v in run.values("program_end")] == [("divide", "FAULT"), ("after", "DONE")]
    assert dict(run.setpoints(0))[0.25] == pytest.approx(0.1)


def test_an_expression_over_a_sensor_the_interpreter_lacks_is_refused_when_it_starts(make_run):
    run = make_run()
    run.command(program("lidar", hold(xi="lidar.range < 1.0")), t=0.0)
    run.run(until=0.1)
    [fault] = run.values("fault")
    assert "program 'lidar' cannot run here" in fault["message"] and "lidar" in fault["message"]
    assert not run.violations()


def test_a_program_value_built_by_hand_is_checked_like_plain_data():
    from channels.mdl import Atom, Behaviour, Motion, Program
    with pytest.raises(BadValue, match="a ramp needs a duration T"):
        MDL_PROGRAM.check(Program("p", (Behaviour((Atom(Motion("ramp", target=(("0", 1.0),))),)),)))


def test_a_program_of_more_atoms_than_one_instant_can_end_is_refused_and_the_largest_runs(make_run):
    """64 behaviours of 256 atoms whose interrupts all hold at once would end 16,384 atoms in one
    instant, past the engine's 10,000 firings per instant (it halts, and every node with it):
    such a program is refused at the channel; 4,096 atoms, all interrupted at once, run."""
    def many(behaviours, atoms):
        return {"id": "many", "behaviours": [{"atoms": [{"u": {"kind": "hold"}, "xi": "true"}] * atoms}
                                             for _ in range(behaviours)]}
    with pytest.raises(BadValue, match=r"mdlProgram.behaviours: 16384 atoms in all; a program has at most 4096"):
        program_from_plain(many(64, 256))
    run = make_run()
    run.command(many(16, 256), t=0.0)
    run.command(program("reach", ramp({"joint1": 0.2}, T=0.2)), t=0.5)
    run.run(until=1.0)
    assert not run.violations()
    assert len(run.values("atom_end")) >= 4096
    assert [(v["program"], v["end"]) for v in run.values("program_end")] == [("many", "DONE"), ("reach", "DONE")]


@pytest.mark.parametrize("bad, said", [
    (atom(u={"kind": "ramp", "target": {"joint1": 0.3}}, T=1e307),
     "program 'p' cannot run here: behaviours[0].atoms[0].T: 1e+307 s is more ticks of 0.01 s than can be counted"),
    (atom(u={"kind": "sine", "amplitude": {"joint1": 0.1}, "frequency": 1e308}, T=0.5),
     "program 'p' stopped: behaviours[0].atoms[0]: ValueError: math domain error"),
    (atom(u={"kind": "ramp", "target": {"joint1": 0.3}}, T=0.5, xi="exists (j=0; j<2000000000; j++) (position[0] > 1.0)"),
     "LoopBudgetExceeded: a loop or quantifier from 0 to 2000000000 passes the budget of 1,000,000 iterations"),
    (atom(u={"kind": "ramp", "target": {"joint1": 0.3}}, T=0.5,
          xi="exists (j=0; j<100000; j++) (exists (k=0; k<100000; k++) (position[0] > 1.0))"),
     "LoopBudgetExceeded"),
    (atom(u={"kind": "ramp", "target": {"²": 0.3}}, T=0.5), "unknown joint '²'"),
    (atom(u={"kind": "ramp", "target": {"٣": 0.3}}, T=0.5), "unknown joint '٣'"),  # not index 3
    (atom(u={"kind": "ramp", "target": {"joint1": 0.5, "0": 0.1}}, T=0.5),  # one joint by name and by index
     "behaviours[0].atoms[0].u.target: joint 'joint1' is given twice ('0' is it too)"),
    (atom(u={"kind": "hold"}, xi="!" * 395 + "true"), "the expression nests too deeply"),
])
def test_a_program_whose_numbers_break_something_is_a_fault_and_the_next_one_runs(make_run, bad, said):
    """What no check foresaw (a duration of 1e307, a quantifier over two billion, an interrupt
    nested past Python's limits) ends that program with a fault and program_end FAULT, quickly:
    never a bare runtime error that leaves its requester waiting, never a hung interpreter."""
    run = make_run()
    run.command(bad, t=0.0)
    run.command(program("reach", ramp({"joint1": 0.2}, T=0.2)), t=0.5)
    run.run(until=1.0)
    [fault] = run.values("fault")
    assert said in fault["message"] and "motors held" in fault["message"], fault["message"]
    assert [(v["program"], v["end"]) for v in run.values("program_end")] == [("p", "FAULT"), ("reach", "DONE")]
    assert not [v for v in run.violations() if v["value"]["violation"] == "runtime_error"]


def test_joints_measured_outside_their_limits_are_held_at_the_limit_and_said_once(make_run):
    """The first setpoints hold the joints where they are measured, but never outside the
    limits: a joint reported beyond one (a bad offset, a sensor glitch of 1e308) is held at it."""
    run = make_run(arm(start=[0.0, 5.0, -1e308, 0.0, 0.0, 0.0]))
    run.run(until=0.1)
    lower, upper = run.interpreter.lower, run.interpreter.upper
    positions = [e["value"]["position"] for e in run.of("setpoints", "output")]
    assert len(positions) >= 5
    assert all(p[1] == upper[1] and p[2] == lower[2] and p[0] == 0.0 for p in positions)
    [fault] = run.values("fault")
    assert f"joint2 at 5 (limits [{lower[1]:g}, {upper[1]:g}])" in fault["message"]
    assert "joint3 at -1e+308" in fault["message"] and "held at the limit" in fault["message"]


def test_a_text_field_refuses_a_lone_surrogate_and_takes_any_other_unicode():
    from channels.mdl import Text

    Text(10).check("été ✓ 機械")
    with pytest.raises(BadValue, match="not Unicode text"):
        Text(10).check("a\ud800")


@pytest.mark.parametrize("rate, message", [(0, "expected a control rate in Hz > 0"),
                                           (1e12, r"rate: 1e\+12 Hz is past 100000 Hz")])
def test_a_rate_no_controller_could_follow_is_refused_when_the_interpreter_is_built(rate, message):
    from nodes.mdl_interp import MdlInterpreter

    with pytest.raises(ValueError, match=message):
        MdlInterpreter("mdl", rate=rate)
