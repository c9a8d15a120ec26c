"""Property tests: firings stay inside their windows and switching times, eager fires at the
earliest allowed time, stale windows never fire, runs are reproducible, and re-evaluating only
the preconditions a firing can affect gives the same trace as re-evaluating all of them."""
from hypothesis import given, settings
from hypothesis import strategies as st

from iotad import Composite, Eager, Engine, Input, Int, Internal, Iota, Output, Param, Random

from scheduler import Scheduler


class Responder(Iota):
    """Armed by `go`, disarmed by `cancel`; two actions share the `resp` channel so that the
    switching time and the windows interact."""
    L = Param(0.0)
    U = Param(1.0)
    S = Param(0.0)
    go = Input(Int)
    cancel = Input()
    resp = Output(Int, switching="S")

    def init(self):
        self.armed = False
        self.echo = 0

    @go.input
    def on_go(self, x):
        self.armed = True
        self.echo = x

    @cancel.input
    def on_cancel(self, x):
        self.armed = False

    @resp.action(value=lambda self: self.echo, when=lambda self: self.armed, within=("L", "U"))
    def answer(self):
        self.armed = False


def make(lower, upper, switching):
    return Responder("r", L=lower, U=upper, S=switching)


inputs = st.lists(st.tuples(st.floats(0, 20, allow_nan=False).map(lambda t: round(t, 3)),
                            st.sampled_from(["go", "cancel"]), st.integers(0, 9)),
                  max_size=12).map(sorted)
windows = st.tuples(st.floats(0, 3).map(lambda x: round(x, 3)), st.floats(0, 3).map(lambda x: round(x, 3))) \
    .map(lambda lu: (min(lu), max(lu)))


def drive(root, script, policy, until=40, **options):
    engine = Engine(root, policy=policy, **options)
    for t, channel, value in script:
        engine.post(None, channel, value if channel == "go" else None, t=t)
    engine.run(until)
    return engine


def reference_windows(trace, lower, upper):
    """Replays the trace against the spec's enabling rule: yields (firing, te) pairs and checks
    that no firing happened while disarmed (a stale window)."""
    armed, te, fired = False, None, []
    for event in trace:
        if event["action"] == "go" and event["kind"] == "input":
            if not armed:
                armed, te = True, event["t"]
        elif event["action"] == "cancel" and event["kind"] == "input":
            armed = False
        elif event["kind"] == "output":
            assert armed, f"fired from a stale window: {event}"
            fired.append((event, te))
            armed = False
    return fired


@settings(max_examples=150, deadline=None)
@given(script=inputs, window=windows, switching=st.sampled_from([0.0, 0.5, 2.0]), seed=st.integers(0, 2**16))
def test_random_firings_lie_inside_windows_and_respect_switching(script, window, switching, seed):
    lower, upper = window
    engine = drive(make(lower, upper, switching), script, Random(seed))
    unreachable = {v["t"] for v in engine.trace if v["kind"] == "violation"
                   and v["value"]["violation"] == "unreachable_window"}
    last = None
    for event, te in reference_windows(engine.trace, lower, upper):
        t = event["t"]
        if last is not None:
            assert t >= last + switching - 1e-9, "switching time broken"
        if te not in unreachable:
            assert te + lower - 1e-9 <= t <= te + upper + 1e-9, (te, t, window)
        last = t


@settings(max_examples=150, deadline=None)
@given(script=inputs, window=windows, switching=st.sampled_from([0.0, 0.5, 2.0]))
def test_eager_fires_at_the_earliest_allowed_time(script, window, switching):
    lower, upper = window
    engine = drive(make(lower, upper, switching), script, Eager())
    last = None
    for event, te in reference_windows(engine.trace, lower, upper):
        earliest = te + lower if last is None else max(te + lower, last + switching)
        assert abs(event["t"] - earliest) < 1e-9
        last = event["t"]


@settings(max_examples=60, deadline=None)
@given(script=inputs, window=windows, seed=st.integers(0, 2**16))
def test_same_inputs_and_seed_give_the_same_trace(script, window, seed):
    first = drive(make(*window, 0.5), script, Random(seed)).trace
    again = drive(make(*window, 0.5), script, Random(seed)).trace
    assert first == again


requests = st.lists(st.tuples(
    st.floats(0, 30, allow_nan=False).map(lambda t: round(t, 2)), st.integers(0, 5),
    st.integers(1, 5), st.floats(0.5, 4).map(lambda x: round(x, 2)), st.floats(0.5, 6).map(lambda x: round(x, 2))),
    max_size=20).map(sorted)


def scheduler_run(reqs, seed, track):
    engine = Engine(Scheduler("scheduler", N=6, T=0.5), policy=Random(seed), track_dependencies=track)
    for t, i, priority, epoch, timeout in reqs:
        engine.post(None, "req", {"control": {"w": float(i), "k": 1.0}, "epoch": epoch,
                                  "timeout": timeout, "priority": priority}, index=i, t=t)
    engine.run(60)
    return engine.trace


@settings(max_examples=80, deadline=None)
@given(reqs=requests, seed=st.integers(0, 2**16))
def test_dependency_tracking_gives_the_same_trace_as_re_evaluating_everything(reqs, seed):
    assert scheduler_run(reqs, seed, True) == scheduler_run(reqs, seed, False)


def test_dependency_tracking_matches_on_a_composite_with_bindings():
    from requesters import Requester
    def build():
        return Composite("fig2", Scheduler("scheduler", N=3, T=0.5),
                         *[Requester(f"r{i}", priority=i + 1, epoch=1.0 + i, timeout=2.0 + i, start=0.3 * i,
                                     pause=0.7, count=5) for i in range(3)],
                         bind=[(f"r{i}.req", f"scheduler.req[{i}]") for i in range(3)]
                         + [(f"scheduler.ack[{i}]", f"r{i}.ack") for i in range(3)])
    for seed in range(5):
        tracked = Engine(build(), policy=Random(seed))
        tracked.run(60)
        full = Engine(build(), policy=Random(seed), track_dependencies=False)
        full.run(60)
        assert tracked.trace == full.trace
        assert {e["value"] for e in tracked.trace if e["action"] == "ack" and e["kind"] == "output"} \
            >= {"COMMIT"}


class Ring(Iota):
    """Writes the element a state pointer selects (`slots[self.k]`) and moves the pointer once,
    before or after the write: the element-by-state write tracking must find both elements."""
    N = Param(3)
    poke = Input(Int, size="N")
    take = Internal(size="N")
    write_then_move = Internal()
    move_then_write = Internal()

    def init(self):
        self.slots = [0] * self.N
        self.k = 0
        self.moves = 0

    @poke.input
    def on_poke(self, i, x):
        self.slots[i] = x

    @take.action(when=lambda self, i: self.slots[i] > 0, within=(0.1, 0.4))
    def on_take(self, i):
        self.slots[i] -= 1

    @write_then_move.action(when=lambda self: self.moves % 2 == 0 and self.moves < 40, within=(0.2, 0.6))
    def on_write_then_move(self):
        self.slots[self.k] += 2          # the element at the pointer's old value
        self.k = (self.k + 1) % self.N
        self.moves += 1

    @move_then_write.action(when=lambda self: self.moves % 2 == 1 and self.moves < 40, within=(0.2, 0.6))
    def on_move_then_write(self):
        self.k = (self.k + 2) % self.N
        self.slots[self.k] += 1          # the element at its new value
        self.moves += 1


@settings(max_examples=60, deadline=None)
@given(pokes=st.lists(st.tuples(st.floats(0, 10).map(lambda t: round(t, 2)), st.integers(0, 2),
                                st.integers(0, 3)), max_size=8).map(sorted),
       seed=st.integers(0, 2**16))
def test_writes_to_an_element_chosen_by_state_are_tracked(pokes, seed):
    from iotad.kernel.model import by_state
    for action in Ring("r").iota_spec.actions[2:]:
        assert ("slots", by_state("k")) in action.writes and ("slots", "*") not in action.writes

    def run(track):
        engine = Engine(Ring("r"), policy=Random(seed), track_dependencies=track)
        for t, i, x in pokes:
            engine.post(None, "poke", x, index=i, t=t)
        engine.run(30)
        return engine.trace

    assert run(True) == run(False)
