"""Simulated CiA 402 drives whose physics runs slower than the wall clock (a loaded machine) still
answer every SYNC within the motor node's TPDO timeout. A late step catches the world up with the
clock, and the frames that come while that firing runs wait for its end: with the whole catch-up
in one firing (24 steps, 80 ms on a loaded machine), SYNCs went unanswered for longer than the
motor node's TPDO timeout (3 SYNCs of 20 ms), which takes every joint out of ARMED (TPDO_TIMEOUT)
and re-arms it; often enough, and the real-time arm test finds no 2 s with every joint armed. A
firing now catches up for at most `catch_up_time` of the wall clock; the rest stays due for the
next one (with physics at half the clock's pace, a SYNC waited 235 ms before).

A clock on which each physics step costs `cost` seconds (the process's time goes by while it
computes, and frames arrive meanwhile) stands in for the loaded machine; the engine's general loop
runs it as it runs a real clock, and the same clock times the catch-up."""
import pytest

from iotad.can import canopen as co
from iotad.can.frame import Frame
from iotad.kernel.engine import Engine
from sim.cia402_sim import SimulatedCia402Drives
from sim_helpers import BusyClock

pytest.importorskip("pybullet")

SYNC_PERIOD = 0.02   # the motor node's tick in examples/arm_canopen.toml
TPDO_TIMEOUT = 3     # SYNCs without a statusword before the motor node says TPDO_TIMEOUT
STEP = 0.005         # the drives' step_period in examples/arm_canopen.toml


def answer_delays(cost: float, **params) -> tuple[list[float], SimulatedCia402Drives]:
    """NMT START at 0.05 s, then a SYNC every 20 ms to 2 s; each physics step costs `cost` s.
    The delay from each SYNC to the first TPDO1 after it."""
    iota = SimulatedCia402Drives("drives", world="arm", step_period=STEP, timing_slack=0.01, **params)
    clock = BusyClock(0.0)
    step = iota.plant.step

    def costly_step():
        step()
        clock.spend(cost)

    iota.plant.step = costly_step
    iota.wall_clock = clock.now
    engine = Engine(iota, clock=clock)
    engine.post(None, "can_rx", co.nmt("START").to_value(), t=0.05)
    syncs, t = [], 0.1
    while t < 2.0:
        engine.post(None, "can_rx", co.sync().to_value(), t=round(t, 6))
        syncs.append(round(t, 6))
        t += SYNC_PERIOD
    try:
        engine.run(until=2.2)
    finally:
        iota.close()
    tpdo1 = [float(e["t"]) for e in engine.trace if e["kind"] == "output" and e["action"] == "can_tx"
             and Frame.from_value(e["value"]).id == co.TPDO[0] + 1]
    delays = []
    for sync in syncs:
        after = [t for t in tpdo1 if t >= sync]
        delays.append(after[0] - sync if after else float("inf"))
    return delays, iota


def test_drives_twice_slower_than_the_clock_answer_every_sync_within_the_tpdo_timeout():
    delays, drives = answer_delays(cost=2 * STEP)   # 10 ms a 5 ms step: the world runs at half the clock
    assert drives.steps_given_up > 0, "the world fell behind the clock (else this test proves nothing)"
    assert max(delays) < TPDO_TIMEOUT * SYNC_PERIOD, f"a SYNC answered {max(delays) * 1000:.0f} ms late"


def test_the_steps_a_firing_leaves_are_taken_by_the_next_ones():
    # a machine only a little slow: the world still keeps the clock's pace, in shorter firings
    delays, drives = answer_delays(cost=STEP / 2)
    assert drives.steps_given_up == 0
    assert drives.sim_time == pytest.approx(2.2 - drives.step_origin, abs=2 * STEP)
    assert max(delays) < SYNC_PERIOD


@pytest.mark.parametrize("bad", [0, -0.01, "x"])
def test_catch_up_time_must_be_a_positive_number_of_seconds(bad):
    with pytest.raises(Exception, match="catch_up_time"):
        SimulatedCia402Drives("drives", world="arm", catch_up_time=bad)
