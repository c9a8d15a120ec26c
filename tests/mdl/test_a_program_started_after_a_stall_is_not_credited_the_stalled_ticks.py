"""A tick that comes late steps the running motion by the ticks that passed (no drift), but a
program that this very tick starts or resumes begins there: it is stepped once, not credited
with ticks that passed before its command was applied. Made deterministic in virtual time by
letting the interpreter fire every tick at the end of a window 3.5 periods wide (the `latest`
policy), so that every tick is 4 grid points after the one before, as after a stall in real time."""
import pytest

from channels.mdl import hold, program, ramp
from iotad import Engine
from iotad.kernel.policy import Eager, Latest, PerNode
from mdl_harness import PERIOD, Run, arm

SLACK = 3.5 * PERIOD


def stalled_run():
    run = Run(arm(tick_slack=SLACK))
    run.engine = Engine(run.engine.root, policy=PerNode(Eager(), {"mdl": Latest()}, root="arm"))
    return run


def grid(t):
    return int(t / PERIOD + 1e-6)


def ticks(run):
    return [grid(e["t"]) for e in run.of("tick", "internal")]


def joint1_by_tick(run):
    """The setpoint of joint 1 each tick made (it goes out up to a period after its tick)."""
    points, tick = {}, None
    for e in sorted(run.of("tick", "internal") + run.of("setpoints", "output"), key=lambda e: e["t"]):
        if e["action"] == "tick":
            tick = grid(e["t"])
        else:
            points[tick] = e["value"]["position"][0]
    return points


def test_every_tick_of_the_stalled_run_skips_three_grid_points():
    run = stalled_run()
    run.run(until=0.5)
    made = ticks(run)
    assert len(made) > 10 and {b - a for a, b in zip(made, made[1:])} == {4}


def test_a_program_started_at_a_late_tick_moves_one_periods_worth_at_it():
    run = stalled_run()
    run.command(program("reach", ramp({"joint1": 0.5}, T=1.0)), t=0.05)
    run.run(until=1.6)
    first = min(t for t in ticks(run) if t * PERIOD > 0.05)
    points = joint1_by_tick(run)
    # the ramp goes 0.005 a period: at the tick that starts it, one period of it, not four
    assert points[first] == pytest.approx(0.005, abs=1e-12)
    # then four periods a tick, as the ticks that passed, and it ends at its target
    assert points[first + 4] == pytest.approx(0.025, abs=1e-12)
    [end] = run.values("atom_end")
    assert end["end"] == "DONE"
    assert (end["tick"] - first + 1) * PERIOD >= 1.0 - 1e-9  # never before T from its start
    assert end["elapsed"] == pytest.approx(1.01)  # 1 + 4 * 25 ticks: the first after T
    assert points[end["tick"]] == pytest.approx(0.5, abs=1e-12)


def test_a_program_resumed_at_a_late_tick_goes_on_from_where_it_stood():
    run = stalled_run()
    reach = program("reach", ramp({"joint1": 0.5}, T=1.0))
    run.command(reach, t=0.05)
    run.command(program("pause", hold(T=0.2)), t=0.45)
    run.command(reach, t=0.85)
    run.run(until=2.0)
    made = ticks(run)
    paused = min(t for t in made if t * PERIOD > 0.45)
    resumed = min(t for t in made if t * PERIOD > 0.85)
    points = joint1_by_tick(run)
    stood = points[paused - 4]
    assert points[paused] == pytest.approx(stood, abs=1e-12)       # the hold holds
    assert points[resumed] == pytest.approx(stood + 0.005, abs=1e-12)  # one period on, not four
