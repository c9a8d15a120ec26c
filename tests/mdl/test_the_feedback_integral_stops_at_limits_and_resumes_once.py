"""The feedback integral of an atom's gains k and the limits the interpreter keeps (joint
limits, max_velocity): while a limit cuts the reference, the integral does not grow toward it
(conditional integration), and it never takes up what the open-loop motion lost at a limit.
On resume, a joint the target leaves out is re-anchored without its integral counted twice."""
import pytest

from channels.mdl import gain, hold, mode_program, program, ramp, sine

from mdl_harness import Run, arm


def positions(run, joint=0):
    return {round(t * 100): p for t, p in run.setpoints(joint)}


def test_a_mode_limited_by_max_velocity_does_not_overshoot():
    # a first-order law k (w - x), 500 Hz, k dt = 0.1: stable and monotone, however fast it is
    # asked to go; the integral wound up against max_velocity and overshot 2.0 to 2.675
    for max_velocity in (3.14, 1000.0):
        run = Run(arm(rate=500.0, max_velocity=max_velocity))
        run.command(mode_program(2.0, 50.0), t=0.0)
        run.run(until=2.0)
        path = [p for _, p in run.setpoints(0)]
        assert max(path) <= 2.0 + 1e-9, (max_velocity, max(path))
        assert path[-1] == pytest.approx(2.0, abs=1e-6)
        assert all(b >= a - 1e-12 for a, b in zip(path, path[1:]))


def test_a_zero_gain_leaves_a_sine_clipped_at_a_joint_limit_as_it_is_without_one():
    # joint3's upper limit is 0.19198: the sine of amplitude 0.3 is clipped there; with a gain
    # that adds nothing, the clipped part went into the integral and stayed as an offset of -0.108
    runs = []
    for k in ([], [gain("joint3", "position[0]", 0.0)]):
        run = Run(arm())
        run.command(program("s", sine({"joint3": 0.3}, frequency=1.0, T=2.0, k=k)), t=0.0)
        run.run(until=2.2)
        runs.append(positions(run, 2))
    plain, with_gain = runs
    assert max(plain.values()) == pytest.approx(0.19198) and plain[75] == pytest.approx(-0.3)
    assert with_gain == plain


def test_a_resumed_ramp_counts_the_integral_of_a_joint_it_leaves_out_once():
    # joint2 is driven by a gain only (joint1 by the ramp): held from 0.3 to 0.7, the rest of the
    # run must be the uninterrupted one shifted by 0.4 s; joint2 ended 0.06 (its integral at the
    # preemption) too far
    reach = program("A", ramp({"joint1": 0.6}, T=1.0, k=[gain("joint2", "1.0", 0.2)]), hold(T=0.2))
    alone = Run(arm())
    alone.command(reach, t=0.0)
    alone.run(until=2.0)
    resumed = Run(arm())
    resumed.command(reach, t=0.0)
    resumed.command(program("B", hold()), t=0.3005)
    resumed.command(reach, t=0.7005)
    resumed.run(until=2.0)
    for joint in (0, 1):
        base, got = positions(alone, joint), positions(resumed, joint)
        assert max(abs(got[m] - base[m - 40]) for m in range(71, 160)) < 1e-9, joint
