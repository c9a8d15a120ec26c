"""The paper's two-float mode {w, k} stays valid: as plain data or a `mode` record wherever a
program is, and on the interpreter's own `mode_command` input; it is the one-atom program that
drives the first joint toward w with gain k on its measured position, until the next command."""
import math

import pytest

from channels.mdl import MDL_PROGRAM, MDL_PROGRAM_REQ, mode_program, program_to_plain
from channels.messages import MODE


def test_a_mode_is_accepted_where_a_program_is():
    from_plain = MDL_PROGRAM.from_plain({"w": 0.3, "k": 2.0})
    from_record = MDL_PROGRAM.from_plain(MODE(w=0.3, k=2.0))
    assert from_plain == from_record == mode_program(0.3, 2.0)
    [behaviour] = from_plain.behaviours
    [atom] = behaviour.atoms
    assert (atom.u.kind, atom.T, atom.xi) == ("hold", None, "")
    assert [(g.joint, g.sensor, g.gain) for g in atom.k] == [("0", "0.3 - position[0]", 2.0)]
    req = MDL_PROGRAM_REQ(control=from_plain, epoch=1.0, timeout=1.0, priority=1)
    assert program_to_plain(req.control) == program_to_plain(from_plain)


def test_a_mode_with_a_bad_number_is_rejected():
    from iotad.kernel.types import BadValue
    with pytest.raises(BadValue, match=r"mdlProgram.w: expected a number, got str"):
        MDL_PROGRAM.from_plain({"w": "up", "k": 1.0})


@pytest.mark.parametrize("channel", ["mdl_command", "mode_command"])
def test_a_mode_drives_the_first_joint_to_w_at_rate_k(make_run, channel):
    run = make_run()
    run.engine.post("arm/mdl", channel, {"w": 0.4, "k": 2.0}, t=0.0)
    run.run(until=3.0)
    points = {round(t * 100): p for t, p in run.setpoints(0)}
    # the motor reports each command at once and the interpreter reads it at the next tick:
    # a first-order approach with time constant 1/k, sampled at 100 Hz
    assert points[50] == pytest.approx(0.4 * (1 - math.exp(-1.0)), abs=0.01)
    assert points[300] == pytest.approx(0.4, abs=0.002)
    assert not run.values("atom_end")                         # no T, no interrupt: it runs on
    assert not run.violations()


def test_a_new_mode_preempts_the_old_one(make_run):
    run = make_run()
    run.engine.post("arm/mdl", "mode_command", {"w": 0.4, "k": 5.0}, t=0.0)
    run.engine.post("arm/mdl", "mode_command", {"w": -0.2, "k": 5.0}, t=1.5)
    run.run(until=3.0)
    assert [(v["program"], v["end"]) for v in run.values("program_end")] == [("mode w=0.4 k=5.0", "PREEMPTED")]
    points = {round(t * 100): p for t, p in run.setpoints(0)}
    assert points[149] == pytest.approx(0.4, abs=0.002) and points[300] == pytest.approx(-0.2, abs=0.002)


def test_a_mode_beyond_the_joints_limits_is_refused_as_a_ramp_goal_is(make_run):
    # it was driven into the limit with no fault: the requester asked for 100 rad and got 6.28
    run = make_run()
    run.engine.post("arm/mdl", "mode_command", {"w": 100.0, "k": 1.0}, t=0.0)
    run.engine.post("arm/mdl", "mode_command", {"w": 0.4, "k": 2.0}, t=1.0)
    run.run(until=4.0)
    [fault] = run.values("fault")
    assert ("program 'mode w=100.0 k=1.0' cannot run here: behaviours[0].atoms[0]: the mode's setpoint w = 100 of "
            "joint joint1 is outside its limits [-6.28319, 6.28319]; motors held") == fault["message"], fault["message"]
    assert [(v["program"], v["end"]) for v in run.values("program_end")] == [("mode w=100.0 k=1.0", "FAULT")]
    points = {round(t * 100): p for t, p in run.setpoints(0)}
    assert abs(points[99]) < 1e-9                                  # held where it was
    assert points[400] == pytest.approx(0.4, abs=0.002)            # the next mode runs
