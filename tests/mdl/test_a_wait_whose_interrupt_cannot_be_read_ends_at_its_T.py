"""A wait (a `hold` atom with no feedback gains and an end T) moves nothing, and its T is the
longest its author lets it wait: when its interrupt reads a sensor that is missing, stale or
invalid, its clock runs on and it ends at T (DONE), said once on `fault`; a value that comes and
holds still interrupts it. An atom that moves, or steers by a sensor, still holds the motors and
stops its clock until the value comes (test_bad_programs_and_inputs_hold_the_motors.py)."""
import pytest

from channels.mdl import hold, program, ramp

PROXIMITY = 1  # the default `sensors` parameter's second sensor: proximity = [distance, _]


def test_a_wait_with_no_value_for_its_interrupt_ends_at_its_T_and_the_program_goes_on(make_run):
    run = make_run()
    run.command(program("pick", hold(T=0.3, xi="proximity.distance < 0.1"), ramp({"joint1": 0.2}, T=0.2)), t=0.0)
    run.run(until=1.0)
    wait, move = run.values("atom_end")
    assert (wait["end"], wait["tick"], wait["elapsed"]) == ("DONE", 30, pytest.approx(0.3))
    assert (move["end"], move["tick"]) == ("DONE", 50)
    assert dict(run.setpoints(0))[0.5] == pytest.approx(0.2)
    [fault] = run.values("fault")  # once, not once per tick
    assert "atoms[0] reads proximity: no value from sensor[1] (proximity) yet; a wait: it ends at its T (0.3 s)" \
        in fault["message"]


def test_a_stale_value_lets_the_wait_run_and_a_fresh_one_that_holds_still_interrupts_it(make_run):
    run = make_run(sensor_timeout=0.05)
    run.command(program("pick", hold(T=0.5, xi="proximity.distance < 0.1"), hold(T=0.1)), t=0.0)
    run.sensor(PROXIMITY, [1.0, 0.0], t=0.0)       # far, then silent: stale from 0.06
    run.sensor(PROXIMITY, [0.05, 0.0], t=0.2001)   # near: the wait ends at the next tick
    run.run(until=1.0)
    wait, after = run.values("atom_end")
    assert (wait["end"], wait["tick"], wait["condition"]) == ("INTERRUPTED", 21, "proximity.distance < 0.1")
    assert wait["elapsed"] == pytest.approx(0.2)   # its clock ran while the value was stale
    assert (after["end"], after["tick"]) == ("DONE", 30)  # it ran ticks 21..30
    [fault] = run.values("fault")
    assert "is 0.06 s old (sensor_timeout 0.05 s); a wait: it ends at its T (0.5 s)" in fault["message"]


def test_a_move_whose_interrupt_cannot_be_read_still_holds_the_motors(make_run):
    run = make_run()
    run.command(program("reach", ramp({"joint1": 0.5}, T=0.5, xi="proximity.distance < 0.1")), t=0.0)
    run.run(until=1.0)
    assert run.values("atom_end") == []
    assert {p for _, p in run.setpoints(0)} == {0.0}
    [fault] = run.values("fault")
    assert "reads proximity: no value from sensor[1] (proximity) yet; motors held" in fault["message"]


def test_an_interrupt_it_can_read_still_ends_a_wait_whose_plan_interrupt_it_cannot(make_run):
    run = make_run()
    plan = program("pick", hold(T=0.5, xi="proximity.distance < 0.1"), ramp({"joint1": 0.2}, T=0.2),
                   xi="visual_error.x > 100")  # visual_error never comes
    run.command(plan, t=0.0)
    run.sensor(PROXIMITY, [0.05, 0.0], t=0.1001)
    run.run(until=1.0)
    wait = run.values("atom_end")[0]
    assert (wait["end"], wait["level"], wait["tick"]) == ("INTERRUPTED", "ATOM", 11)
    # the ramp moves: its plan's interrupt still cannot be read, and it holds the motors
    assert {p for _, p in run.setpoints(0)} == {0.0}
    messages = [v["message"] for v in run.values("fault")]
    assert any("reads visual_error" in m and "a wait: it ends at its T (0.5 s)" in m for m in messages)
    assert any("reads visual_error" in m and m.endswith("motors held") for m in messages)
