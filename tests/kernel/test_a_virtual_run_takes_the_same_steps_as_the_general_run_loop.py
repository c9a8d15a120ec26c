"""Under a `VirtualClock` the engine runs its own loop, the clock's `wait` and `now` read
inline (`Engine._run_virtual`); any other clock, a subclass of `VirtualClock` included, takes the
general loop. Both must take the same steps: the same trace, event for event, the same clock
time after each `run(until)`, inputs posted at the instant of a firing, refused inputs, a stop
posted mid-run, the Random policy, and a run resumed in pieces."""
import pytest

from iotad import Composite, Engine, Input, Int, Iota, Output, Param, Random
from iotad.kernel.clock import VirtualClock
from iotad.kernel.engine import STOP

from scheduler import Scheduler
from requesters import Requester


class GeneralClock(VirtualClock):
    """A virtual clock of another class: the engine takes its general run loop under it."""


class Echo(Iota):
    """Answers every accepted `go` with its value plus one, within [L, U]; `go` has a switching
    time, so inputs that come too soon are refused."""
    L = Param(0.25)
    U = Param(0.5)
    go = Input(Int, switching=0.25)
    out = Output(Int)

    def init(self):
        self.pending = []

    @go.input
    def got(self, x):
        self.pending.append(x)

    @out.action(value=lambda self: self.pending[0] + 1, when=lambda self: bool(self.pending), within=("L", "U"))
    def answer(self):
        self.pending.pop(0)


def figure2(n=6):
    requesters = [Requester(f"r{i}", priority=1 + i % 3, epoch=0.5 + (i % 4) * 0.3, timeout=2.0 + i % 3,
                            start=0.01 * i, pause=1.0 + (i % 2) * 0.5, count=10**9) for i in range(n)]
    return Composite("figure2", Scheduler("scheduler", N=n, T=0.5), *requesters,
                     bind=[(f"r{i}.req", f"scheduler.req[{i}]") for i in range(n)]
                     + [(f"scheduler.ack[{i}]", f"r{i}.ack") for i in range(n)])


def run_in_pieces(clock, build, posts, pieces, seed=None):
    """The trace and the clock's time after each piece of the run."""
    engine = Engine(build(), clock, policy=None if seed is None else Random(seed))
    for t, channel, value in posts:
        engine.post(None, channel, value, t=t)
    times = []
    for until in pieces:
        engine.run(until)
        times.append(engine.clock.now())
    return engine.trace, times, engine.firings


# inputs at the instants the echo fires (0.25 after an accepted one, with L = U), two at one
# instant, one too soon after the last, one that is no int
ECHO_POSTS = [(0.0, "go", 1), (0.25, "go", 2), (0.5, "go", 3), (0.5, "go", 4), (0.6, "go", 5),
              (1.0, "go", "x"), (1.75, "go", 6), (4.0, "go", 7)]


@pytest.mark.parametrize("seed", [None, 3])
def test_an_echo_fed_at_its_own_firing_instants_runs_the_same_under_both_loops(seed):
    def build():
        return Echo("echo", L=0.25, U=0.25 if seed is None else 0.5)

    pieces = [0.5, 0.5, 1.0, 3.0, 10.0]
    fast = run_in_pieces(VirtualClock(), build, ECHO_POSTS, pieces, seed)
    general = run_in_pieces(GeneralClock(), build, ECHO_POSTS, pieces, seed)
    assert fast == general
    trace, times, _ = fast
    kinds = {e["kind"] for e in trace}
    assert {"input", "output", "violation"} <= kinds, kinds  # refusals were on the path too
    assert times == pieces  # a piece ends at its `until`, also with nothing left to happen
    outputs = [e["value"] for e in trace if e["kind"] == "output"]
    assert outputs == [2, 3, 4, 7, 8]  # 5 came too soon, "x" was no int
    if seed is None:  # Eager, L = U: each answer exactly 0.25 after its input
        assert [e["t"] for e in trace if e["kind"] == "output"] == [0.25, 0.5, 0.75, 2.0, 4.25]


def test_the_figure2_scheduler_under_the_random_policy_runs_the_same_under_both_loops():
    pieces = [3.0, 7.5, 20.0]
    fast = run_in_pieces(VirtualClock(), figure2, [], pieces, seed=11)
    general = run_in_pieces(GeneralClock(), figure2, [], pieces, seed=11)
    assert fast == general
    assert fast[2] > 100  # it did run


def test_a_stop_posted_mid_run_ends_both_loops_at_the_same_event():
    def stopped(clock):
        engine = Engine(figure2(), clock, policy=Random(5))
        engine.clock.post(STOP, 4.0)
        engine.run(50.0)
        return engine.trace, engine.clock.now(), engine.firings

    fast, general = stopped(VirtualClock()), stopped(GeneralClock())
    assert fast == general
    assert fast[1] == 4.0 and fast[0][-1]["t"] <= 4.0


class Spinner(Iota):
    """Fires at t=1, then again and again at once: a Zeno loop the engine halts."""
    out = Output(Int)

    def init(self):
        self.n = 0

    @out.action(value=lambda self: self.n, after=lambda self: 1.0 if self.n == 0 else 0.0)
    def spin(self):
        self.n += 1


def test_a_zeno_loop_halts_both_loops_at_the_same_firing():
    def halted(clock):
        engine = Engine(Spinner("spinner"), clock, max_firings_per_instant=50)
        engine.run(10.0)
        return engine.trace, engine.clock.now(), engine.firings, engine.halted

    fast, general = halted(VirtualClock()), halted(GeneralClock())
    assert fast == general
    trace, now, firings, stopped = fast
    assert stopped and now == 1.0 and firings == 50  # fifty at t=1; the fifty-first is refused
    assert trace[-1]["kind"] == "violation" and trace[-1]["value"]["violation"] == "zeno"
