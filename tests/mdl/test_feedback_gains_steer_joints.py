"""Feedback terms k (gains on sensor expressions, added to joint velocities) close the loop through
a sensor: a camera's visual error steers the arm onto the target it sees, and an interrupt on
the same error ends the atom once the target is centred."""
import pytest

from channels.joints import JOINT_STATES
from channels.mdl import SENSOR_READING, SENSOR_WIDTH, gain, hold, program
from iotad import Composite, Input, Iota, Output, Param
from mdl_harness import PerfectMotor, Run
from nodes.mdl_interp import MdlInterpreter

PIXELS_PER_RADIAN = 500.0


class Camera(Iota):
    """An end-effector camera at 50 Hz: the target's horizontal offset in pixels, which is the
    angle joint 1 still has to turn, seen through a lens."""

    target = Param(0.4)
    joint_states = Input(JOINT_STATES)
    reading = Output(SENSOR_READING)

    def init(self):
        self.position = None

    @joint_states.input
    def seen(self, x):
        self.position = x.position[0]

    @reading.action(value=lambda self: SENSOR_READING(valid=True, value=[
                        (self.target - self.position) * PIXELS_PER_RADIAN] + [0.0] * (SENSOR_WIDTH - 1)),
                    when=lambda self: self.position is not None, after=0.02)
    def sent(self):
        pass


def servo_system(target=0.4, **params):
    return Composite("arm", MdlInterpreter("mdl", rate=100.0, **params), PerfectMotor("motor"), Camera("camera", target=target),
                     bind=[("mdl.setpoints", "motor.setpoints"), ("motor.joint_states", "mdl.joint_states"),
                           ("motor.joint_states", "camera.joint_states"), ("camera.reading", "mdl.sensor[0]")])


def test_a_visual_error_gain_steers_the_joint_onto_the_target():
    run = Run(servo_system(target=0.4))
    # 0.004 rad/s per pixel: joint 1 turns at 2 rad/s per radian of error (time constant 0.5 s)
    run.command(program("servo", hold(k=[gain("joint1", "visual_error.x", 0.004)])), t=0.0)
    run.run(until=4.0)
    points = dict(run.setpoints(0))
    assert points[0.5] == pytest.approx(0.4 * (1 - 2.718281828 ** -1), abs=0.02)
    assert points[4.0] == pytest.approx(0.4, abs=0.002)
    assert all(b >= a - 1e-12 for a, b in zip(list(points.values()), list(points.values())[1:]))  # no overshoot
    assert not run.violations()
    # the camera's first frame comes at 0.02: the first tick held the joints and said why
    [fault] = run.values("fault")
    assert fault["tick"] == 1 and "visual_error: no value from sensor[0] (visual_error) yet" in fault["message"]


def test_a_negative_target_is_reached_from_the_other_side():
    run = Run(servo_system(target=-0.3))
    run.command(program("servo", hold(k=[gain("0", "visual_error.x", 0.004)])), t=0.0)
    run.run(until=4.0)
    assert dict(run.setpoints(0))[4.0] == pytest.approx(-0.3, abs=0.002)


def test_the_servo_atom_ends_when_the_target_is_centred():
    run = Run(servo_system(target=0.4))
    run.command(program("centre", hold(k=[gain("joint1", "visual_error.x", 0.004)],
                                       xi="visual_error.x < 2.0 && visual_error.x > -2.0")), t=0.0)
    run.run(until=4.0)
    [end] = run.values("atom_end")
    assert end["end"] == "INTERRUPTED"
    # 2 px is 0.004 rad: e^(-2t) = 0.01 at t ~ 2.3 s (plus the camera's 20 ms sampling)
    assert 2.2 < end["t"] < 2.5
    final = dict(run.setpoints(0))[4.0]
    assert abs(0.4 - final) * PIXELS_PER_RADIAN < 2.0 + 0.5


def test_feedback_stops_at_the_joint_limit_and_does_not_wind_up(make_run):
    upper = [0.2, 2.0944, 0.19198, 6.28318530718, 3.14159265359, 6.28318530718]
    run = make_run(upper=upper)
    run.command(program("push", hold(k=[gain("joint1", "visual_error.x", 0.004)])), t=0.0)
    for k in range(40):  # +100 px for a second (0.4 rad/s up), then -100 px
        run.sensor(0, [100.0 if k < 20 else -100.0], t=k * 0.05)
    run.run(until=1.5)
    points = dict(run.setpoints(0))
    assert points[0.5] == pytest.approx(0.2) and points[0.99] == pytest.approx(0.2)
    # -100 px from t=1.0: had the integral gone on past the limit, the joint would sit at 0.2
    # until t=1.5; it comes down at once, 0.004 rad per tick
    assert points[1.1] == pytest.approx(0.2 - 0.4 * 0.11, abs=1e-9)
