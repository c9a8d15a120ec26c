"""Each kind of atom commands its profile, tick by tick, in virtual time: ramps and minimum-jerk
moves reach their target exactly at T, velocities and sines follow their formulas, and every
setpoint stays within the joints' velocity and position limits."""
import math

import pytest

from channels.mdl import hold, minimum_jerk, program, ramp, sine, velocity
from mdl_harness import PERIOD, tick_of


def test_a_ramp_reaches_its_target_at_T(make_run):
    run = make_run()
    run.command(program("reach", ramp({"joint1": 0.5}, T=1.0)), t=0.005)
    run.run(until=1.5)
    points = dict(run.setpoints(0))
    # the program starts at the first tick (0.01) from where the joints were at the tick before
    assert points[0.01] == pytest.approx(0.005, abs=1e-12)
    assert points[0.5] == pytest.approx(0.25, abs=1e-12)
    assert points[1.0] == pytest.approx(0.5, abs=1e-12)
    assert points[1.2] == pytest.approx(0.5, abs=1e-12)  # then held
    [end] = run.values("atom_end")
    assert (end["end"], end["tick"], end["elapsed"]) == ("DONE", tick_of(1.0), pytest.approx(1.0))
    [done] = run.values("program_end")
    assert (done["program"], done["end"], done["tick"]) == ("reach", "DONE", tick_of(1.0))
    speeds = [e["value"]["velocity_ff"][0] for e in run.of("setpoints", "output") if 0.01 <= e["t"] <= 1.0]
    assert speeds == pytest.approx([0.5] * len(speeds))
    other_joints = {tuple(e["value"]["position"][1:]) for e in run.of("setpoints", "output")}
    assert other_joints == {(0.0,) * 5}


def test_a_minimum_jerk_move_starts_and_ends_at_rest(make_run):
    run = make_run()
    run.command(program("mj", minimum_jerk({"1": -0.4}, T=0.8)), t=0.0)
    run.run(until=1.0)
    points = dict(run.setpoints(1))
    assert points[0.4] == pytest.approx(-0.2, abs=1e-9)        # halfway at half time
    assert points[0.8] == pytest.approx(-0.4, abs=1e-12)       # at the target at T
    speeds = {e["t"]: e["value"]["velocity_ff"][1] for e in run.of("setpoints", "output")}
    assert abs(speeds[0.01]) < 0.01 and abs(speeds[0.8]) < 0.01
    assert max(abs(v) for v in speeds.values()) == pytest.approx(1.875 * 0.4 / 0.8, rel=0.01)  # peak 15/8 * D/T


def test_velocity_and_sine_atoms_follow_their_formulas(make_run):
    run = make_run()
    run.command(program("moves", velocity({"joint2": 0.2}, T=0.5),
                        sine({"joint4": 0.1}, frequency=1.0, T=1.0)), t=0.0)
    run.run(until=2.0)
    joint2, joint4 = dict(run.setpoints(1)), dict(run.setpoints(3))
    assert joint2[0.25] == pytest.approx(0.05, abs=1e-12)
    assert joint2[0.5] == pytest.approx(0.1, abs=1e-12)
    assert joint2[1.0] == pytest.approx(0.1, abs=1e-12)          # held during the sine
    assert joint4[0.75] == pytest.approx(0.1, abs=1e-9)          # a quarter period into the sine
    assert joint4[1.25] == pytest.approx(-0.1, abs=1e-9)
    assert joint4[1.5] == pytest.approx(0.0, abs=1e-9)
    ends = [(e["atom"], e["end"], e["tick"]) for e in run.values("atom_end")]
    assert ends == [(0, "DONE", tick_of(0.5)), (1, "DONE", tick_of(1.5))]


def test_a_duration_that_is_not_a_whole_number_of_ticks_ends_at_the_next_tick(make_run):
    run = make_run()
    run.command(program("odd", hold(T=0.0349)), t=0.0)
    run.run(until=0.2)
    [end] = run.values("atom_end")
    assert end["tick"] == 4 and end["elapsed"] == pytest.approx(0.04)


def test_setpoints_never_exceed_the_velocity_limit(make_run):
    run = make_run(max_velocity=1.0)
    run.command(program("fast", ramp({"joint1": 2.0}, T=0.1), hold(T=3.0)), t=0.0)
    run.run(until=3.5)
    positions = [p for _, p in run.setpoints(0)]
    steps = [b - a for a, b in zip(positions, positions[1:])]
    assert max(steps) <= 1.0 * PERIOD + 1e-12
    speeds = [e["value"]["velocity_ff"][0] for e in run.of("setpoints", "output")]
    assert max(speeds) <= 1.0 + 1e-9
    # the ramp asked for 20 rad/s: its atom ended at T short of the goal, and the hold that
    # follows holds where the command was
    assert positions[tick_of(0.1) - 1] == pytest.approx(0.1)
    assert positions[-1] == pytest.approx(0.1)
    assert [(e["atom"], e["end"]) for e in run.values("atom_end")] == [(0, "DONE"), (1, "DONE")]
    # ... and the requester is told, once, that the arm is not where the profile said
    [fault] = run.values("fault")
    assert fault["program"] == "fast" and fault["tick"] == tick_of(0.1)
    assert fault["message"] == ("behaviours[0].atoms[0] ended at T = 0.1 s with joint joint1 1.9 short of its "
                                "reference: its max_velocity (1/s) kept it behind")


def test_a_profile_within_the_velocity_limit_says_nothing(make_run):
    run = make_run(max_velocity=1.0)
    run.command(program("slow", ramp({"joint1": 0.5}, T=1.0), hold(T=0.1)), t=0.0)  # 0.5 rad/s
    run.run(until=1.5)
    assert run.setpoints(0)[-1][1] == pytest.approx(0.5)
    assert not run.values("fault")


def test_setpoints_stay_within_the_joint_limits(make_run):
    run = make_run()
    run.command(program("up", velocity({"joint3": 1.0}, T=1.0)), t=0.0)
    run.run(until=1.1)
    joint3 = [p for _, p in run.setpoints(2)]
    assert max(joint3) == pytest.approx(0.19198)
    assert joint3[-1] == pytest.approx(0.19198)


def test_a_goal_outside_the_joint_limits_stops_the_program_and_holds(make_run):
    run = make_run()
    run.command(program("too-far", ramp({"joint3": 1.0}, T=1.0)), t=0.0)
    run.run(until=0.1)
    [fault] = run.values("fault")
    assert "joint3" in fault["message"] and "outside its limits" in fault["message"]
    assert [v["end"] for v in run.values("program_end")] == ["FAULT"]
    assert {p for _, p in run.setpoints(2)} == {0.0}
    assert not run.violations()


def test_behaviours_run_one_after_the_other(make_run):
    from channels.mdl import behaviour
    run = make_run()
    run.command(program("plan", behaviour(ramp({"0": 0.1}, T=0.2), hold(T=0.1), name="first"),
                        behaviour(ramp({"0": 0.0}, T=0.2), name="second")), t=0.0)
    run.run(until=1.0)
    ends = [(e["behaviour"], e["atom"], e["tick"]) for e in run.values("atom_end")]
    assert ends == [(0, 0, 20), (0, 1, 30), (1, 0, 50)]
    assert [(v["end"], v["tick"]) for v in run.values("program_end")] == [("DONE", 50)]
    assert dict(run.setpoints(0))[0.5] == pytest.approx(0.0, abs=1e-12)
    assert math.isclose(dict(run.setpoints(0))[0.3], 0.1)
