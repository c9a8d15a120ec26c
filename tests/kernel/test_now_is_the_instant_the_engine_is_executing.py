"""`now()` (ESPRIT) and `esprit_now()` (Python IOTAs) answer the instant the engine is executing,
which the engine running in this thread says (`iotad.kernel.instant`): in a do-block, an input
action and a time bound; in the first evaluation at the start time; through `fire_due`, `deliver`
and `fire_instance`. An engine run inside another's action gives the outer one back its place;
outside every run, and in a thread where no engine runs, there is none."""
import threading

import pytest

from iotad import Engine, Float, Input, Int, Iota, Output
from iotad.esprit.runtime import esprit_now
from iotad.kernel.clock import VirtualClock
from iotad.kernel.instant import running


class Stamper(Iota):
    """Every 0.25 s outputs the instant its do-block read at the firing before; an input records
    the instant it arrived; its window's length is read from now() too (0.25 until t = 0.5,
    then 0.5)."""
    out = Output(Float)
    poke = Input(Int)

    def init(self):
        self.seen = []
        self.last = 0.0

    @out.action(value=lambda self: self.last, after=lambda self: 0.25 if esprit_now() < 0.5 else 0.5)
    def stamped(self):
        self.last = esprit_now()
        self.seen.append(("fired", self.last))

    @poke.input
    def poked(self, value):
        self.seen.append(("poked", esprit_now()))


def test_do_blocks_inputs_and_time_bounds_read_the_firings_instant():
    engine = Engine(Stamper("s"))
    engine.post(None, "poke", 1, t=0.6)
    engine.run(1.5)
    assert engine.iota("s").seen == [("fired", 0.25), ("fired", 0.5), ("poked", 0.6), ("fired", 1.0), ("fired", 1.5)]
    assert [(e["t"], e["value"]) for e in engine.trace if e["kind"] == "output"] == [
        (0.25, 0.0), (0.5, 0.25), (1.0, 0.5), (1.5, 1.0)]
    assert running.engine is None  # the run is over: no instant is left behind


def test_the_steps_replay_uses_set_the_instant_and_leave_none_behind():
    clock = VirtualClock()
    engine = Engine(Stamper("s"), clock)
    engine.start()
    assert clock.wait(0.25) is None  # nothing posted: the clock moves to 0.25, as replay moves it
    assert engine.fire_due(1) == 1
    engine.deliver("s", "poke", 3)
    assert engine.iota("s").seen == [("fired", 0.25), ("poked", 0.25)]
    assert running.engine is None


class Outer(Iota):
    """At t = 1 runs a whole other engine (an inner Stamper to 2.0) inside its do-block, then
    reads now() again."""
    out = Output(Int)

    def init(self):
        self.before = self.after = self.inner_seen = None

    @out.action(value=1, after=1.0)
    def ran_inner(self):
        self.before = esprit_now()
        inner = Engine(Stamper("inner"))
        inner.run(2.0)
        self.inner_seen = inner.iota("inner").seen[-1]
        self.after = esprit_now()


def test_an_engine_run_inside_an_action_gives_the_outer_its_instant_back():
    engine = Engine(Outer("o"))
    engine.run(1.0)
    outer = engine.iota("o")
    assert outer.inner_seen == ("fired", 2.0)
    assert (outer.before, outer.after) == (1.0, 1.0)


class Threaded(Iota):
    """Asks for now() from a thread of its own, where no engine runs."""
    out = Output(Int)

    def init(self):
        self.answer = None

    @out.action(value=1, after=0.5)
    def asked(self):
        def ask():
            try:
                self.answer = esprit_now()
            except RuntimeError as exc:
                self.answer = str(exc)
        thread = threading.Thread(target=ask)
        thread.start()
        thread.join()


def test_a_thread_where_no_engine_runs_has_no_instant():
    engine = Engine(Threaded("t"))
    engine.run(0.5)
    assert engine.iota("t").answer == "now() is defined only while an engine runs the IOTA"


def test_now_outside_every_run_is_a_clear_error():
    with pytest.raises(RuntimeError, match="only while an engine runs"):
        esprit_now()
