"""In real time every step of SimulatedOdrives fires a little late, and each step's window starts
at the late firing before it. Without catching up, a busy machine ran the conveyor's world 14 %
slower than the wall clock and every pick, timed from what vision saw, missed. A late step now
takes the physics steps due by its instant (up to `max_catch_up`), and the world's stamps are on
the engine's clock (`clock_time`).

A clock that wakes every wait 1.5 ms late (a loaded machine, deterministically) stands in for
the real one; the engine's general loop runs it as it runs a real clock."""
import pytest

from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import Engine
from iotad.kernel.model import SpecError
from sim.odrive_sim import SimulatedOdrives

pytest.importorskip("pybullet")

DT = 1.0 / 240.0


class LateClock(VirtualClock):
    """Every wait that reaches its deadline wakes `late` seconds after it."""

    def __init__(self, late: float, start: float = 0.0):
        super().__init__(start)
        self.late = late

    def wait(self, deadline):
        item = super().wait(deadline)
        if item is None:
            self._now += self.late
        return item


def run_late(seconds: float, late: float, start: float = 0.0, **params):
    iota = SimulatedOdrives("sim", world="arm", **params)
    try:
        engine = Engine(iota, clock=LateClock(late, start))
        engine.run(until=start + seconds)
        steps = [e for e in engine.trace if e["action"] == "step" and e["kind"] == "internal"]
        return iota.steps, len(steps), iota.clock_time, engine.now(), iota.steps_given_up
    finally:
        iota.close()


def test_late_steps_take_the_physics_steps_due_so_the_world_keeps_the_clocks_pace():
    steps, firings, clock_time, now, given_up = run_late(2.0, late=0.0015)
    assert firings < 0.8 * 2.0 / DT               # each firing was late: fewer firings than steps due
    assert abs(steps - 2.0 / DT) <= 2              # but the world took every step of 2 s
    assert abs(clock_time - now) <= 2 * DT         # and its time is the engine's, within a step
    assert given_up == 0


def test_without_catching_up_the_world_falls_behind_and_says_by_how_much():
    steps, firings, _, now, given_up = run_late(2.0, late=0.0015, max_catch_up=1)
    assert steps == firings                        # one physics step a firing, as before
    assert steps < 0.8 * now / DT                  # a world about a quarter slower than the clock
    assert given_up == pytest.approx(now / DT - steps, abs=2)


def test_the_stamps_are_on_the_engines_clock_when_it_does_not_start_at_zero():
    # a real-time node's engine starts seconds after its launcher's origin
    steps, _, clock_time, now, _ = run_late(1.0, late=0.0, start=4.25)
    assert steps == pytest.approx(1.0 / DT, abs=1)
    assert clock_time == pytest.approx(now, abs=DT)


@pytest.mark.parametrize("bad, error", [(0, "max_catch_up must be a whole number of steps >= 1, got 0"),
                                        (-3, "max_catch_up must be a whole number of steps >= 1, got -3"),
                                        (2.5, "max_catch_up must be a whole number of steps >= 1, got 2.5"),
                                        ("12", "parameter max_catch_up: expected a number")])
def test_max_catch_up_must_be_a_whole_number_of_steps(bad, error):
    with pytest.raises((ValueError, SpecError), match=error):
        SimulatedOdrives("sim", world="arm", max_catch_up=bad)
