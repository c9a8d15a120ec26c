"""A simulated ODrive judges its watchdog by when the frames reached it, not by when its process
got round to them. The conveyor split over three hosts on a loaded machine lost its arm so: the
motor node sent every axis a frame every 40-50 ms, the simulator's process stalled 85-115 ms
(its steps late), took the frames that had come meanwhile only when it woke, and stamped them
with its world's time of the last step before the stall; the catch-up then put the world 0.1 s
past them and every axis tripped (WATCHDOG_TIMER_EXPIRED, 80 ms), four times in 23 s, until the
motor node's auto_rearm gave up (REARM_LIMIT) and the arm stayed in FAULT for the rest of the run.

A clock that stalls once (nothing runs for `length`; what came meanwhile is taken when it wakes,
as a real process's queue is) stands in for the loaded machine; the engine's general loop runs it
as it runs a real clock. A host that really stops sending still trips the watchdog."""
import pytest

from iotad.can import odrive
from iotad.can.odrive import AXIS_ERROR, AXIS_STATE
from iotad.kernel.engine import Engine
from sim.odrive_sim import SimulatedOdrives
from sim_helpers import BusyClock

pytest.importorskip("pybullet")

CLOSED_LOOP = AXIS_STATE["CLOSED_LOOP_CONTROL"]
WATCHDOG = AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]
NODE = 1
FEED = 0.045         # s between the host's frames (the conveyor's motor node: 40-50 ms)


class StallingClock(BusyClock):
    """Virtual time in which the process sleeps from `at` for `length`: inputs that arrive
    meanwhile are taken when it wakes, in their order, and nothing fires before."""

    def __init__(self, at: float, length: float):
        super().__init__(0.0)
        self.at, self.length, self.stalled = at, length, False

    def wait(self, deadline):
        if not self.stalled and max(deadline, self._inbox[0][0] if self._inbox else deadline) >= self.at:
            self.stalled = True
            self.spend(max(0.0, self.at + self.length - self._now))
        return super().wait(deadline)


def run(stall_at: float, stall: float, feed_until: float = 1.2, gap: tuple = ()) -> SimulatedOdrives:
    """Arm one axis at 0.1 s, feed it Set_Input_Vel 0 every FEED (but not in `gap`), run to 1.2 s."""
    iota = SimulatedOdrives("sim", world="arm", node_ids=[1, 2, 3, 4, 5, 6, 7])
    clock = StallingClock(stall_at, stall)
    engine = Engine(iota, clock=clock)

    def send(t, name, **signals):
        engine.post(None, "can_rx", odrive.encode(NODE, name, **signals).to_value(), t=t)

    send(0.1, "Set_Controller_Mode", Control_Mode=2, Input_Mode=1)  # velocity, passthrough
    send(0.1, "Set_Axis_State", Axis_Requested_State=CLOSED_LOOP)
    t = 0.1 + FEED
    while t < feed_until:
        if not (gap and gap[0] <= t < gap[1]):
            send(round(t, 6), "Set_Input_Vel", Input_Vel=0.0, Input_Torque_FF=0.0)
        t += FEED
    engine.run(until=1.2)
    iota.engine_trace = engine.trace
    return iota


@pytest.fixture
def sims():
    made = []

    def make(*args, **kwargs):
        made.append(run(*args, **kwargs))
        return made[-1]

    try:
        yield make
    finally:
        for iota in made:
            iota.close()


def test_frames_sent_on_time_during_a_stall_keep_the_axis_armed(sims):
    sim = sims(stall_at=0.5, stall=0.1)   # the conveyor's stalls: 85-115 ms
    axis = sim.by_node[NODE]
    late = [e for e in sim.engine_trace if e["kind"] == "violation" and e["action"] == "step"]
    assert late, "the stall made the steps late (else this test proves nothing)"
    assert axis.armed and axis.active_errors == 0
    assert odrive.decode(axis.heartbeat()).signals["Axis_State"] == CLOSED_LOOP


def test_a_host_that_stops_sending_still_trips_the_watchdog(sims):
    sim = sims(stall_at=5.0, stall=0.0, gap=(0.5, 0.6))   # no stall; no frame for ~0.1 s
    axis = sim.by_node[NODE]
    assert not axis.armed and axis.active_errors & WATCHDOG


def test_a_host_that_stops_during_a_stall_trips_it_too(sims):
    sim = sims(stall_at=0.5, stall=0.1, feed_until=0.5)   # its last frame before the stall
    axis = sim.by_node[NODE]
    assert not axis.armed and axis.active_errors & WATCHDOG
