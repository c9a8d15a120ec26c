"""One test (at least) per rule of docs/design.md section 4, each failing if its rule broke."""
import math

import pytest

from iotad import Composite, Engine, Float, Input, Int, Internal, Iota, Output, Param, Random, VirtualClock
from iotad.kernel.model import SpecError
from iotad.kernel.types import Struct


def events(engine, kind=None, action=None):
    return [e for e in engine.trace if (kind is None or e["kind"] == kind)
            and (action is None or e["action"] == action)]


def times(engine, action, kind=None):
    return [e["t"] for e in events(engine, kind, action)]


def violations(engine, code=None):
    return [e for e in engine.trace if e["kind"] == "violation"
            and (code is None or e["value"]["violation"] == code)]


class Latch(Iota):
    """`go` arms it, `cancel` disarms it; `fire` answers within [L, U] while armed."""
    L = Param(1.0)
    U = Param(2.0)
    go = Input(Int, switching=0.5)
    cancel = Input()
    fire = Output(Int, switching=0.0)

    def init(self):
        self.armed = False
        self.value = 0

    @go.input
    def on_go(self, x):
        self.armed = True
        self.value = x

    @cancel.input
    def on_cancel(self, x):
        self.armed = False

    @fire.action(value=lambda self: self.value, when=lambda self: self.armed, within=("L", "U"))
    def on_fire(self):
        self.armed = False


def run(root, inputs, until, **options):
    engine = Engine(root, **options)
    for t, channel, value, *index in inputs:
        engine.post(None, channel, value, index[0] if index else None, t=t)
    engine.run(until)
    return engine


# ---------------------------------------------------------------- channels and inputs
def test_input_action_fires_on_arrival_with_value_bound():
    engine = run(Latch("latch"), [(0.5, "go", 7)], 10)
    assert events(engine, "input") == [{"t": 0.5, "iota": "latch", "action": "go", "index": None,
                                        "kind": "input", "value": 7}]
    assert engine.iota("latch").value == 7


def test_input_sooner_than_switching_time_is_rejected_and_reported():
    engine = run(Latch("latch", L=5, U=5), [(0.0, "go", 1), (0.3, "go", 2), (0.5, "go", 3)], 1)
    assert [e["value"] for e in events(engine, "input")] == [1, 3]
    [violation] = violations(engine, "switching_time")
    assert violation["t"] == 0.3 and violation["action"] == "go"
    assert engine.iota("latch").value == 3


def test_input_out_of_range_or_wrong_type_is_rejected_and_state_kept():
    class Bounded(Iota):
        speed = Input(Float(0, 1))

        def init(self):
            self.speed_now = 0.5

        @speed.input
        def on_speed(self, x):
            self.speed_now = x

    engine = run(Bounded("b"), [(0, "speed", 1.5), (1, "speed", "fast"), (2, "speed", 0.25)], 5)
    assert [v["value"]["violation"] for v in violations(engine)] == ["bad_value", "bad_value"]
    assert "outside range" in violations(engine)[0]["value"]["message"]
    assert engine.iota("b").speed_now == 0.25


def test_switching_time_applies_per_index_of_a_family():
    class Fam(Iota):
        req = Input(Int, size=2, switching=1.0)

    engine = run(Fam("f"), [(0, "req", 1, 0), (0.5, "req", 2, 1), (0.6, "req", 3, 0), (1.0, "req", 4, 0)], 5)
    accepted = [(e["t"], e["index"]) for e in events(engine, "input")]
    assert accepted == [(0, 0), (0.5, 1), (1.0, 0)]
    assert [(v["t"], v["index"]) for v in violations(engine, "switching_time")] == [(0.6, 0)]


def test_unknown_input_channel_is_a_violation_not_a_crash():
    engine = run(Latch("latch"), [(0, "nope", 1)], 1)
    assert violations(engine, "unknown_input")[0]["action"] == "nope"


# ---------------------------------------------------------------- windows
def test_eager_fires_at_lower_bound_of_within():
    engine = run(Latch("latch", L=1.5, U=3), [(2.0, "go", 9)], 10)
    assert times(engine, "fire") == [3.5]
    assert events(engine, "output")[0]["value"] == 9


def test_after_is_a_hard_window():
    class Ticker(Iota):
        tick = Internal()

        @tick.action(after=0.25)
        def on_tick(self):
            pass

    engine = run(Ticker("t"), [], 1.0)
    # no precondition: re-enabled at each firing, so a new window starts at the firing time
    assert times(engine, "tick") == [0.25, 0.5, 0.75, 1.0]


def test_no_time_clause_means_zero_to_infinity_and_eager_fires_at_once():
    class Once(Iota):
        done = Output()

        def init(self):
            self.left = 1

        @done.action(when=lambda self: self.left > 0)
        def on_done(self):
            self.left -= 1

    engine = run(Once("o"), [], 10)
    assert times(engine, "done") == [0.0]


def test_bounds_are_evaluated_at_enabling_not_at_firing():
    class Later(Iota):
        poke = Input(Int)
        out = Output()

        def init(self):
            self.delay = 1.0
            self.armed = True

        @poke.input
        def on_poke(self, x):
            self.delay = x  # changes the bound while the window is open: must not move it

        @out.action(when=lambda self: self.armed, after=lambda self: self.delay)
        def on_out(self):
            self.armed = False

    engine = run(Later("l"), [(0.5, "poke", 5)], 10)
    assert times(engine, "out") == [1.0]


def test_window_dropped_when_precondition_turns_false_and_restarted_when_true_again():
    engine = run(Latch("latch", L=1, U=1), [(0.0, "go", 1), (0.5, "cancel", None), (0.7, "go", 2)], 10)
    # the first window [1, 1] was dropped at 0.5; the new one starts at 0.7
    assert times(engine, "fire") == [1.7]
    assert events(engine, "output")[0]["value"] == 2


def test_window_kept_while_precondition_stays_true():
    engine = run(Latch("latch", L=1, U=1), [(0.0, "go", 1), (0.5, "go", 2)], 10)
    # the second go leaves `armed` true: the window from t=0 is kept (value read at firing)
    assert times(engine, "fire") == [1.0]
    assert events(engine, "output")[0]["value"] == 2


def two_on_one_channel(name: str, second_within: tuple[float, float]) -> Iota:
    """Two actions enabled at 0 on one output with switching time 1; the second's window is
    `second_within`."""
    class Two(Iota):
        out = Output(Int, switching=1.0)

        def init(self):
            self.a = self.b = True

        @out.action(value=1, when=lambda self: self.a)
        def first(self):
            self.a = False

        @out.action(value=2, when=lambda self: self.b, within=second_within)
        def second(self):
            self.b = False

    return Two(name)


def test_switching_time_delays_a_second_action_on_the_same_channel():
    engine = run(two_on_one_channel("two", (0, 5)), [], 10)
    assert [(e["t"], e["value"]) for e in events(engine, "output")] == [(0.0, 1), (1.0, 2)]
    assert not violations(engine)


def test_window_made_unreachable_by_switching_time_is_a_violation():
    engine = run(two_on_one_channel("tight", (0, 0.5)), [], 10)
    [violation] = violations(engine, "unreachable_window")
    assert violation["t"] == 0.0 and "past its window" in violation["value"]["message"]
    assert times(engine, "out", "output") == [0.0, 1.0]  # still fires, at the earliest legal time


def test_empty_window_is_a_violation_and_never_fires():
    class Bad(Iota):
        out = Output()

        @out.action(within=(2, 1))
        def on_out(self):
            pass

    engine = run(Bad("bad"), [], 10)
    assert violations(engine, "bad_window")
    assert not events(engine, "output")


# ---------------------------------------------------------------- values and atomicity
def test_output_value_is_evaluated_in_the_state_before_the_do_block():
    class Counter(Iota):
        out = Output(Int)

        def init(self):
            self.n = 0

        @out.action(value=lambda self: self.n, when=lambda self: self.n < 3, after=1)
        def on_out(self):
            self.n += 1

    engine = run(Counter("c"), [], 10)
    assert [(e["t"], e["value"]) for e in events(engine, "output")] == [(1, 0), (2, 1), (3, 2)]


def test_output_value_out_of_range_is_rejected_but_the_action_fires():
    class Overshoot(Iota):
        out = Output(Float(0, 1))

        def init(self):
            self.sent = False

        @out.action(value=2.0, when=lambda self: not self.sent)
        def on_out(self):
            self.sent = True

    engine = run(Overshoot("o"), [], 10)
    assert violations(engine, "bad_value") and not events(engine, "output")
    assert engine.iota("o").sent


def test_runtime_error_in_do_block_is_a_violation_and_the_iota_goes_on():
    class Faulty(Iota):
        tick = Internal()

        def init(self):
            self.n = 0

        @tick.action(when=lambda self: self.n < 3, after=1)
        def on_tick(self):
            self.n += 1
            if self.n == 2:
                raise ZeroDivisionError("division by zero")

    engine = run(Faulty("f"), [], 10)
    assert times(engine, "tick", "internal") == [1, 2, 3]
    [violation] = violations(engine, "runtime_error")
    assert violation["t"] == 2 and "ZeroDivisionError" in violation["value"]["message"]


# ---------------------------------------------------------------- order at one instant
class Ordered(Iota):
    N = Param(3)
    hit = Input(Int)
    grab = Internal(size="N")

    def init(self):
        self.token = False
        self.log = []
        self.owner = None

    @hit.input
    def on_hit(self, x):
        self.token = True
        self.log.append(("hit", x))

    @grab.action(when=lambda self, i: self.token)
    def on_grab(self, i):
        self.token = False  # the first grabber disables the others due at the same instant
        self.owner = i
        self.log.append(("grab", i))


def test_inputs_first_in_arrival_order_then_local_actions_index_ascending():
    engine = run(Ordered("o"), [(1.0, "hit", 10), (1.0, "hit", 20)], 5)
    assert engine.iota("o").log == [("hit", 10), ("hit", 20), ("grab", 0)]


def test_one_firing_disables_another_due_at_the_same_instant():
    engine = run(Ordered("o"), [(1.0, "hit", 1)], 5)
    assert [e["index"] for e in events(engine, "internal")] == [0]


def test_declaration_order_between_actions():
    class Decl(Iota):
        b = Internal()
        a = Internal()

        def init(self):
            self.log = []
            self.left = 1

        @a.action(when=lambda self: self.left > 0)  # declared first although its channel is second
        def on_a(self):
            self.log.append("a")
            self.left -= 1

        @b.action(when=lambda self: self.left > 0)
        def on_b(self):
            self.log.append("b")
            self.left -= 1

    engine = run(Decl("d"), [], 1)
    assert engine.iota("d").log == ["a"]


def test_zeno_loop_is_stopped_by_the_guard():
    class Zeno(Iota):
        spin = Internal()

        @spin.action()
        def on_spin(self):
            pass

    engine = run(Zeno("z"), [], 10, max_firings_per_instant=100)
    assert engine.halted
    [violation] = violations(engine, "zeno")
    assert violation["t"] == 0 and len(events(engine, "internal")) == 100


# ---------------------------------------------------------------- deadline misses
class LateClock(VirtualClock):
    """A virtual clock whose process wakes `lag` late for every deadline, like a loaded host."""

    def __init__(self, lag):
        super().__init__()
        self.lag = lag

    def wait(self, deadline):
        item = super().wait(deadline)
        if item is None and not math.isinf(deadline):
            self._now = deadline + self.lag
        return item


def test_deadline_miss_when_the_process_is_late():
    engine = run(Latch("latch", L=0, U=0.5), [(0, "go", 1)], 10, clock=LateClock(lag=1.0))
    [miss] = violations(engine, "deadline_miss")
    assert miss["action"] == "fire" and "after its deadline 0.5" in miss["value"]["message"]
    assert times(engine, "fire", "output") == [1.0]


def test_no_deadline_miss_within_tolerance():
    engine = run(Latch("latch", L=0, U=0.5), [(0, "go", 1)], 10, clock=LateClock(lag=0.6),
                 deadline_tolerance=0.2)
    assert not violations(engine)


# ---------------------------------------------------------------- policies
def test_random_policy_fires_inside_the_window_and_is_reproducible():
    def trace(seed):
        engine = run(Latch("latch", L=1, U=3), [(0, "go", 1), (5, "go", 2), (10, "go", 3)], 20,
                     policy=Random(seed))
        return times(engine, "fire")

    first = trace(7)
    assert first == trace(7)
    assert first != trace(8)
    for start, t in zip((0, 5, 10), first):
        assert start + 1 <= t <= start + 3


# ---------------------------------------------------------------- composition
class Ping(Iota):
    inp = Input(Int)
    out = Output(Int)

    def init(self):
        self.ball = None

    @inp.input
    def got(self, x):
        self.ball = x

    @out.action(value=lambda self: self.ball + 1, when=lambda self: self.ball is not None
                and self.ball < 4, after=1)
    def hit(self):
        self.ball = None


def test_output_delivers_bound_inputs_in_the_same_instant():
    first = Ping("a")
    first.ball = 0
    system = Composite("pp", first, Ping("b"), bind=[("a.out", "b.inp"), ("b.out", "a.inp")])
    engine = run(system, [], 10)
    pairs = [(e["t"], e["iota"], e["action"], e["kind"], e["value"]) for e in engine.trace]
    assert pairs[:4] == [(1, "pp/a", "out", "output", 1), (1, "pp/b", "inp", "input", 1),
                         (2, "pp/b", "out", "output", 2), (2, "pp/a", "inp", "input", 2)]
    assert pairs[-1] == (4, "pp/a", "inp", "input", 4)


def test_hierarchical_paths_and_external_trace():
    inner = Composite("conscious", Ping("wander"), inputs={"sense": "wander.inp"},
                      outputs={"move": "wander.out"})
    system = Composite("buggy", inner, Ping("arbiter"), bind=[("conscious.move", "arbiter.inp")],
                       inputs={"food": "conscious.sense"}, outputs={"act": "arbiter.out"})
    engine = run(system, [(0.0, "food", 1)], 10)
    paths = {e["iota"] for e in engine.trace}
    assert paths == {"buggy/conscious/wander", "buggy/arbiter"}
    external = [(e["t"], e["action"], e["kind"], e["value"]) for e in engine.external_trace()]
    assert external == [(0.0, "food", "input", 1), (2, "act", "output", 3)]


def test_binding_errors_are_named():
    with pytest.raises(SpecError, match="no component nobody"):
        Engine(Composite("s", Ping("a"), bind=[("a.out", "nobody.inp")]))
    with pytest.raises(SpecError, match="bound twice"):
        Engine(Composite("s", Ping("a"), Ping("b"), Ping("c"), bind=[("a.out", "c.inp"), ("b.out", "c.inp")]))
    with pytest.raises(SpecError, match="is an output channel, expected an input"):
        Engine(Composite("s", Ping("a"), Ping("b"), bind=[("a.out", "b.out")]))

    class Other(Iota):
        inp = Input(Struct("point", x=Float))

    with pytest.raises(SpecError, match="types differ"):
        Engine(Composite("s", Ping("a"), Other("o"), bind=[("a.out", "o.inp")]))


def test_family_binds_element_wise_and_by_index():
    class Fan(Iota):
        N = Param(2)
        out = Output(Int, size="N")

        def init(self):
            self.left = [True] * self.N

        @out.action(value=lambda self, i: 10 + i, when=lambda self, i: self.left[i])
        def on_out(self, i):
            self.left[i] = False

    class Sink(Iota):
        N = Param(2)
        inp = Input(Int, size="N")

    engine = run(Composite("s", Fan("fan"), Sink("sink"), Ping("p"),
                           bind=[("fan.out", "sink.inp")]), [], 1)
    assert [(e["index"], e["value"]) for e in events(engine, "input")] == [(0, 10), (1, 11)]
    engine = run(Composite("s", Fan("fan"), Ping("p"), bind=[("fan.out[1]", "p.inp")]), [], 0)
    assert [(e["iota"], e["value"]) for e in events(engine, "input")] == [("s/p", 11)]


def test_input_action_with_when_clause_is_refused():
    from iotad.kernel.model import Action, Channel, IotaSpec
    spec = IotaSpec("x", channels={"i": Channel("i", "input", None)},
                    actions=[Action("i", when=lambda s, i: True)])
    with pytest.raises(SpecError, match="cannot have when"):
        spec.validate()


def test_input_tolerance_accepts_jitter_but_not_a_flood():
    inputs = [(0.0, "go", 1), (0.499, "go", 2), (0.9, "go", 3)]
    strict = run(Latch("latch", L=5, U=5), inputs, 1)
    assert [v["t"] for v in violations(strict, "switching_time")] == [0.499]
    tolerant = run(Latch("latch", L=5, U=5), inputs, 1, input_tolerance=0.002)
    assert [e["value"] for e in events(tolerant, "input")] == [1, 2]  # 0.499 is jitter, accepted
    assert [v["t"] for v in violations(tolerant, "switching_time")] == [0.9]  # 0.401 after: a flood
