"""Interrupts (ESPRIT expressions over the interpreter's inputs) end an atom, a behaviour or the
whole plan at the first tick at which they hold, in virtual time, exactly."""
import pytest

from channels.mdl import behaviour, hold, program, velocity
from mdl_harness import PERIOD

VISUAL_ERROR, PROXIMITY = 0, 1  # sensor indices of the default `sensors` parameter


def test_an_interrupt_ends_the_atom_at_the_first_tick_after_the_sensor_says_so(make_run):
    run = make_run()
    run.command(program("approach", velocity({"joint1": 0.5}, xi="proximity.distance < 0.3"), hold(T=0.1)), t=0.0)
    for t, distance in [(0.0, 1.0), (0.1001, 0.6), (0.2001, 0.35), (0.3051, 0.25)]:
        run.sensor(PROXIMITY, [distance, 0.0], t=t)
    run.run(until=1.0)
    first, second = run.values("atom_end")
    assert (first["end"], first["level"], first["condition"]) == ("INTERRUPTED", "ATOM", "proximity.distance < 0.3")
    assert first["tick"] == 31                                   # the tick after 0.3051
    assert first["elapsed"] == pytest.approx(30 * PERIOD)        # it moved from tick 1 to 30
    assert (second["end"], second["tick"]) == ("DONE", 40)      # the hold ran ticks 31..40
    points = dict(run.setpoints(0))
    assert points[0.3] == pytest.approx(0.15) and points[0.31] == pytest.approx(0.15)  # no step at 31
    assert [(v["end"], v["tick"]) for v in run.values("program_end")] == [("DONE", 40)]


def test_an_interrupt_can_read_the_measured_joint_positions(make_run):
    run = make_run()
    run.command(program("until", velocity({"0": 1.0}, xi="position[0] > 0.2")), t=0.0)
    run.run(until=0.5)
    [end] = run.values("atom_end")
    # the motor reports 0.21 after tick 21; the interpreter sees it at tick 22
    assert (end["end"], end["tick"], end["elapsed"]) == ("INTERRUPTED", 22, pytest.approx(0.21))
    assert dict(run.setpoints(0))[0.4] == pytest.approx(0.21)


def test_a_behaviour_interrupt_skips_the_rest_of_the_behaviour(make_run):
    run = make_run()
    run.command(program("plan", behaviour(hold(T=1.0), hold(T=1.0), name="look", xi="visual_error.x > 10"),
                        behaviour(hold(T=0.1), name="next")), t=0.0)
    run.sensor(VISUAL_ERROR, [0.0, 0.0], t=0.0)
    run.sensor(VISUAL_ERROR, [20.0, 0.0], t=0.5051)
    run.run(until=1.0)
    ends = [(e["behaviour"], e["atom"], e["end"], e["level"], e["tick"]) for e in run.values("atom_end")]
    assert ends == [(0, 0, "INTERRUPTED", "BEHAVIOUR", 51), (1, 0, "DONE", "NONE", 60)]


def test_a_plan_interrupt_ends_the_program(make_run):
    run = make_run()
    run.command(program("plan", hold(T=1.0), hold(T=1.0), xi="force.z > 5.0 || force.z < -5.0"), t=0.0)
    run.sensor(2, [0.0, 0.0, 0.0], t=0.0)
    run.sensor(2, [0.0, 0.0, -6.5], t=0.2501)
    run.run(until=1.0)
    [atom] = run.values("atom_end")
    [plan] = run.values("program_end")
    assert (atom["level"], atom["tick"]) == ("PLAN", 26)
    assert (plan["end"], plan["level"], plan["condition"], plan["tick"]) == \
        ("INTERRUPTED", "PLAN", "force.z > 5.0 || force.z < -5.0", 26)


def test_an_interrupt_that_holds_when_its_atom_starts_ends_it_at_once(make_run):
    run = make_run()
    run.sensor(PROXIMITY, [0.1, 0.0], t=0.0)
    run.command(program("blocked", velocity({"0": 1.0}, xi="proximity.distance < 0.3"), hold(T=0.05)), t=0.0)
    run.run(until=0.2)
    ends = [(e["atom"], e["end"], e["tick"], e["elapsed"]) for e in run.values("atom_end")]
    assert ends == [(0, "INTERRUPTED", 1, 0.0), (1, "DONE", 5, pytest.approx(0.05))]
    assert {p for _, p in run.setpoints(0)} == {0.0}


def test_interrupts_may_use_quantifiers_over_the_joints(make_run):
    run = make_run()
    run.command(program("any", velocity({"0": 0.5, "4": 1.0},
                                        xi="exists (j=0; j<6; j++) (position[j] > 0.1)")), t=0.0)
    run.run(until=0.5)
    [end] = run.values("atom_end")
    assert end["tick"] == 12  # joint 4 passes 0.1 after tick 11
