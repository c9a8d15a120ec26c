"""The `latest` policy fires each action at the latest time its window and switching time allow
(docs/semantics.md): at the window's upper bound, or at the end of the switching time when that
is later; an unbounded window is capped as `random` caps it. Traces worked out by hand."""
import math

import pytest

from iotad import Composite, Engine, Input, Int, Internal, Iota, Output
from iotad.kernel.policy import Eager, Latest, PerNode, PolicyError, Random, parse_policy


class Ticker(Iota):
    """`tick` every [0.2, 0.5]: under latest, at 0.5, 1.0, 1.5..."""
    tick = Output(Int)

    def init(self):
        self.n = 0

    @tick.action(value=lambda self: self.n, within=(0.2, 0.5))
    def ticked(self):
        self.n += 1


class Burst(Iota):
    """Two actions on one channel of switching time 1: `a` within [0, 0.3] at once, `b` within
    [0, 0.4] after `a` fired. `b`'s window ends at 0.7 under latest (`a` fired at 0.3), but the
    channel is busy until 1.3: it fires at the switching time, the later, and the engine says
    its window was unreachable."""
    out = Output(Int, switching=1.0)

    def init(self):
        self.stage = 0

    @out.action(value=lambda self: 1, when=lambda self: self.stage == 0, within=(0, 0.3))
    def first(self):
        self.stage = 1

    @out.action(value=lambda self: 2, when=lambda self: self.stage == 1, within=(0, 0.4))
    def second(self):
        self.stage = 2


class Open(Iota):
    """`go` after an input, with no window clause: [0, inf), capped at 1 time unit."""
    start = Input()
    go = Output()

    def init(self):
        self.armed = False

    @start.input
    def started(self, _):
        self.armed = True

    @go.action(when=lambda self: self.armed)
    def went(self):
        self.armed = False


def outputs(engine):
    return [(round(e["t"], 9), e["action"], e["value"]) for e in engine.trace if e["kind"] == "output"]


def test_latest_fires_at_the_upper_bound_of_each_window():
    engine = Engine(Ticker("t"), policy=Latest())
    engine.run(2.0)
    assert outputs(engine) == [(0.5, "tick", 0), (1.0, "tick", 1), (1.5, "tick", 2), (2.0, "tick", 3)]
    eager = Engine(Ticker("t"), policy=Eager())
    eager.run(1.0)
    assert outputs(eager) == [(0.2, "tick", 0), (0.4, "tick", 1), (0.6, "tick", 2), (0.8, "tick", 3), (1.0, "tick", 4)]


def test_latest_fires_at_the_end_of_the_switching_time_when_that_is_later():
    engine = Engine(Burst("b"), policy=Latest())
    engine.run(3.0)
    assert outputs(engine) == [(0.3, "out", 1), (1.3, "out", 2)]
    unreachable = [e for e in engine.trace if e["kind"] == "violation"]
    assert [(round(e["t"], 9), e["value"]["violation"]) for e in unreachable] == [(0.3, "unreachable_window")]
    assert not [e for e in engine.trace if e["kind"] == "violation" and e["value"]["violation"] == "deadline_miss"]


def test_latest_caps_an_unbounded_window_as_random_does():
    engine = Engine(Open("o"), policy=Latest())
    engine.post(None, "start", t=2.0)
    engine.run(5.0)
    assert outputs(engine) == [(3.0, "go", None)]
    assert Latest().choose(2.0, math.inf) == 3.0 and Latest(horizon=0.25).choose(2.0, math.inf) == 2.25
    assert 2.0 <= Random(4).choose(2.0, math.inf) <= 3.0


def test_a_policy_per_node_stresses_one_node_while_the_rest_stays_eager():
    system = Composite("sys", Ticker("fast"), Ticker("slow"))
    engine = Engine(system, policy=PerNode(Eager(), {"slow": Latest()}, root="sys"))
    engine.run(1.0)
    by_node = {}
    for e in engine.trace:
        if e["kind"] == "output":
            by_node.setdefault(e["iota"], []).append(round(e["t"], 9))
    assert by_node == {"sys/fast": [0.2, 0.4, 0.6, 0.8, 1.0], "sys/slow": [0.5, 1.0]}


def test_policies_are_named_eager_latest_random_and_random_seed():
    assert isinstance(parse_policy("eager"), Eager) and isinstance(parse_policy("latest"), Latest)
    assert parse_policy("random").seed == 0 and parse_policy("random:42").seed == 42
    assert str(parse_policy("random:42")) == "random:42"
    for bad in ("lazy", "random:x", "random:-1", "latest:3"):
        with pytest.raises(PolicyError, match="policy"):
            parse_policy(bad)


def test_the_same_seed_gives_the_same_trace_and_latest_is_deterministic():
    def run(policy):
        engine = Engine(Composite("sys", Ticker("a"), Burst("b")), policy=policy)
        engine.run(4.0)
        return engine.trace

    assert run(Random(9)) == run(Random(9)) != run(Random(10))
    assert run(Latest()) == run(Latest())
