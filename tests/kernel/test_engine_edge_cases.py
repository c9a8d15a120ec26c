"""Review of the engine against docs/design.md section 4: corner cases found by trying to break it, and
property tests (a run continued equals one long run; the engine's own traces pass the checker)."""
import math
import sys
from pathlib import Path
import threading
import time

from hypothesis import given, settings
from hypothesis import strategies as st

from iotad import Composite, Eager, Engine, Input, Int, Internal, Iota, Output, Param, Random, RealClock
from iotad.recording.conformance import check_implements, check_trace


def fired(engine, kind="output"):
    return [(e["t"], e["iota"], e["action"], e["index"], e["value"]) for e in engine.trace if e["kind"] == kind]


def violations(engine):
    return [(e["t"], e["action"], e["value"]["violation"]) for e in engine.trace if e["kind"] == "violation"]


class NeverAndOnce(Iota):
    """`never` has the window [inf, inf]; `once` must still fire at 1 under any policy."""
    D = Param(math.inf)
    never = Output()
    once = Output()

    def init(self):
        self.done = False

    never.fires(after="D")

    @once.action(after=1.0, when=lambda self: not self.done)
    def fire_once(self):
        self.done = True


def test_an_infinite_lower_bound_never_fires_and_blocks_nothing_under_random():
    for policy in (Eager(), Random(1)):
        engine = Engine(NeverAndOnce("x"), policy=policy)
        engine.run(5)
        assert [a for _, _, a, _, _ in fired(engine)] == ["once"]
    assert Random(3).choose(math.inf, math.inf) == math.inf


class Bounds(Iota):
    """The window's upper bound is 1/d: d = 0 makes the bound raise at enabling."""
    inp = Input(Int)
    out = Output()

    def init(self):
        self.d, self.on = 1, False

    @inp.input
    def got(self, x):
        self.on, self.d = True, x

    @out.action(when=lambda self: self.on, within=(0, lambda self: 1.0 / self.d))
    def sent(self):
        self.on = False


def test_a_window_whose_bound_raises_leaves_no_stale_window_behind():
    engine = Engine(Bounds("b"))
    engine.post(None, "inp", 1, t=0.0)
    engine.post(None, "inp", 0, t=2.0)
    engine.run(10)
    assert fired(engine) == [(0.0, "b", "out", None, None)]
    assert violations(engine) == [(2.0, "out", "runtime_error")]
    instance = engine.instances[0]
    assert instance.enabled and instance.te == 2.0 and instance.upper == math.inf
    report = check_trace(Bounds("b"), engine.trace, until=10)
    # the fault is found (by the checker's engine, and as recorded); no window "expired"
    assert {f.code for f in report.findings} == {"runtime_error", "recorded_violation"}, report.lines()


class Src(Iota):
    N = Param(2)
    out = Output(Int, size="N")

    def init(self):
        self.n = [0, 0]

    @out.action(value=lambda self, i: self.n[i], when=lambda self, i: self.n[i] < 2, after=1.0)
    def sent(self, i):
        self.n[i] += 1


class Sink(Iota):
    inp = Input(Int, size=2)

    def init(self):
        self.seen = []

    @inp.input
    def got(self, i, x):
        self.seen.append(i)


def test_a_root_channel_that_is_one_family_member_shows_only_that_member():
    def make():
        return Composite("top", Src("s"), outputs={"first": "s.out[0]"})
    engine = Engine(make())
    engine.run(5)
    assert [(e["t"], e["action"], e["index"], e["value"]) for e in engine.external_trace()] == \
        [(1.0, "first", None, 0), (2.0, "first", None, 1)]
    report = check_implements(make(), engine.external_trace())
    assert report.ok, report.lines()  # out[1] is hidden: the spec may fire it freely


def test_an_index_posted_to_a_single_root_channel_is_not_delivered_to_another_member():
    engine = Engine(Composite("top", Sink("s"), inputs={"first": "s.inp[0]"}))
    engine.post(None, "first", 3, index=1, t=0.0)
    engine.post(None, "first", 4, t=1.0)
    engine.run(2)
    assert engine.iota("top/s").seen == [0]
    assert violations(engine) == [(0.0, "first", "unknown_input")]


def test_real_clock_waits_for_a_far_deadline_without_overflow():
    clock = RealClock()
    threading.Timer(0.05, clock.post, args=("x",)).start()
    assert clock.wait(1e12) == "x"
    started = time.monotonic()
    assert clock.wait(clock.now() - 5) is None and time.monotonic() - started < 0.05  # a past deadline


class Ping(Iota):
    out = Output(Int)

    def init(self):
        self.k = 0

    @out.action(value=lambda self: self.k, when=lambda self: self.k < 3, within=(0.5, 0.5))
    def sent(self):
        self.k += 1


class Count(Iota):
    inp = Input(Int, switching=0.2)

    def init(self):
        self.total = 0

    @inp.input
    def got(self, x):
        self.total += 1


def test_the_checker_does_not_apply_a_bound_input_twice():
    def make():
        return Composite("c", Ping("p"), Count("s"), bind=[("p.out", "s.inp")])
    engine = Engine(make())
    engine.run(5)
    assert len(fired(engine, "input")) == 3
    checker_root = make()
    report = check_trace(checker_root, engine.trace)
    assert report.ok, report.lines()
    # a bound input with no output behind it is a finding
    forged = engine.trace + [{"t": 4.0, "iota": "c/s", "action": "inp", "index": None, "kind": "input", "value": 9}]
    assert [f.code for f in check_trace(make(), forged).findings] == ["not_enabled"]


# ------------------------------------------------------------------ properties
class Relay(Iota):
    """Two actions share `out` (switching S); `tick` is internal; inputs arm and disarm."""
    L = Param(0.0)
    U = Param(1.0)
    S = Param(0.0)
    go = Input(Int)
    stop = Input()
    out = Output(Int, switching="S")
    tick = Internal()

    def init(self):
        self.armed, self.value, self.ticks = False, 0, 0

    @go.input
    def on_go(self, x):
        self.armed, self.value = True, x

    @stop.input
    def on_stop(self, x):
        self.armed = False

    @out.action(value=lambda self: self.value, when=lambda self: self.armed, within=("L", "U"))
    def answer(self):
        self.armed = self.value % 2 == 1  # odd values re-arm: a new window at the firing time

    @out.action(value=lambda self: -1, when=lambda self: self.ticks == 2, within=(0, "U"))
    def report(self):
        self.ticks = 0

    @tick.action(when=lambda self: self.ticks < 2, within=(0.5, 1.5))
    def count(self):
        self.ticks += 1


class Listener(Iota):
    inp = Input(Int, switching=0.0)

    def init(self):
        self.last = 0

    @inp.input
    def got(self, x):
        self.last = x


def system(lower, upper, switching):
    return Composite("sys", Relay("relay", L=lower, U=upper, S=switching), Listener("listener"),
                     bind=[("relay.out", "listener.inp")], inputs={"go": "relay.go", "stop": "relay.stop"},
                     outputs={"out": "relay.out"})


script = st.lists(st.tuples(st.floats(0, 10).map(lambda t: round(t, 2)), st.sampled_from(["go", "stop"]),
                            st.integers(0, 5)), max_size=8).map(sorted)
window = st.tuples(st.sampled_from([0.0, 0.3, 1.0]), st.sampled_from([0.0, 0.5, 2.0])).map(lambda w: (min(w), max(w)))


def feed(engine, inputs):
    for t, channel, value in inputs:
        engine.post(None, channel, value if channel == "go" else None, t=t)


@settings(max_examples=60, deadline=None)
@given(inputs=script, window=window, switching=st.sampled_from([0.0, 0.4]), seed=st.integers(0, 999),
       cut=st.floats(0, 12).map(lambda t: round(t, 2)))
def test_a_run_continued_equals_one_long_run(inputs, window, switching, seed, cut):
    whole = Engine(system(*window, switching), policy=Random(seed))
    feed(whole, inputs)
    whole.run(12)
    split = Engine(system(*window, switching), policy=Random(seed))
    feed(split, inputs)
    split.run(cut)
    split.run(cut)  # running to the same time again changes nothing
    split.run(12)
    assert split.trace == whole.trace


@settings(max_examples=40, deadline=None)
@given(inputs=script, window=window, switching=st.sampled_from([0.0, 0.4]), seed=st.integers(0, 999))
def test_the_engines_own_trace_passes_the_checker_and_a_shifted_firing_fails(inputs, window, switching, seed):
    engine = Engine(system(*window, switching), policy=Random(seed))
    feed(engine, inputs)
    engine.run(12)
    trace = engine.trace
    report = check_trace(system(*window, switching), trace, until=12)
    if not violations(engine):
        assert report.ok, report.lines()
    firings = [k for k, e in enumerate(trace) if e["kind"] == "output" and e["iota"] == "sys/relay"]
    if violations(engine) or not firings:
        return
    k = firings[0]
    late = dict(trace[k], t=trace[k]["t"] + window[1] + 0.75)  # past any window it could be in
    mutated = trace[:k] + [late]
    assert not check_trace(system(*window, switching), mutated, until=late["t"]).ok
    wrong = trace[:k] + [dict(trace[k], value=99)]
    assert not check_trace(system(*window, switching), wrong, until=trace[k]["t"]).ok


@settings(max_examples=15, deadline=None)
@given(inputs=script, window=window, switching=st.sampled_from([0.0, 0.4]))
def test_an_eager_run_implements_its_own_spec(inputs, window, switching):
    # eager only: the search tries hidden firings at their earliest and latest times, not at
    # the random times in between (docs/checking.md, "Limits")
    engine = Engine(system(*window, switching))
    feed(engine, inputs)
    engine.run(12)
    if not violations(engine):
        report = check_implements(system(*window, switching), engine.external_trace(), until=12)
        assert report.ok, report.lines()


class Tight(Iota):
    """Two firings on `out`; the second's window [0, 1] ends before the switching time allows."""
    out = Output(switching=2.0)

    def init(self):
        self.n = 0

    @out.action(when=lambda self: self.n < 2, within=(0, 1))
    def sent(self):
        self.n += 1


def test_an_unreachable_window_is_one_violation_not_also_a_deadline_miss():
    engine = Engine(Tight("t"))
    engine.run(10)
    assert [e["t"] for e in engine.trace if e["kind"] == "output"] == [0.0, 2.0]
    assert violations(engine) == [(0.0, "out", "unreachable_window")]


def test_a_late_process_is_still_a_deadline_miss():
    engine = Engine(Tight("t"))
    engine.start()
    instance = engine.instances[0]
    engine.fire_instance(instance, 0.5)
    engine.fire_instance(instance, 5.0)  # enabled at 0.5, window [0.5, 1.5]: 5.0 is late
    assert violations(engine) == [(0.5, "out", "unreachable_window"), (5.0, "out", "deadline_miss")]


class Quitter(Iota):
    """Calls sys.exit() in an output's do-block and in an input's: a fault like any other."""
    inp = Input(Int)
    out = Output(Int, switching=1)

    @inp.input
    def got(self, x):
        sys.exit(x)

    @out.action(value=lambda self: 1, after=1.0)
    def sent(self):
        sys.exit(4)


def test_sys_exit_in_a_do_block_is_a_recorded_fault_not_the_end_of_the_run():
    engine = Engine(Quitter("q"))
    engine.post(None, "inp", 7, t=1.5)
    engine.run(2.5)  # returns: the process (a CLI, a node host) is not ended by a spec
    assert fired(engine) == [(1.0, "q", "out", None, 1), (2.0, "q", "out", None, 1)]
    here = Path(__file__)
    line = {n: here.read_text().splitlines().index(f"        sys.exit({n})") + 1 for n in ("x", "4")}
    assert [(e["t"], e["value"]["message"]) for e in engine.trace if e["kind"] == "violation"] == [
        (1.0, f"out (do): SystemExit: 4 (at {here}:{line['4']})"), (1.5, f"inp(x): SystemExit: 7 (at {here}:{line['x']})"),
        (2.0, f"out (do): SystemExit: 4 (at {here}:{line['4']})")]
