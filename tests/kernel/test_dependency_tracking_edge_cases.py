"""Review: the dependency analysis must never be less conservative than re-evaluating every
precondition. Each case is a Python IOTA whose trace with tracking must equal the trace
without it (the reference), plus a random-program property test."""
from hypothesis import given, settings
from hypothesis import strategies as st

from iotad import Engine, Input, Int, Iota, Output, Param, Random
from iotad.kernel.dependencies import cells_of
from iotad.kernel.model import ALL_STATE, ANY

STATE = frozenset({"request", "flag"})


def both(make, script, until=6.0, policy=None):
    traces = []
    for track in (True, False):
        engine = Engine(make(), policy=policy() if policy else None, track_dependencies=track)
        for t, channel, value, index in script:
            engine.post(None, channel, value, index=index, t=t)
        engine.run(until)
        traces.append(engine.trace)
    assert traces[0] == traces[1]
    return traces[0]


class NestedShadow(Iota):
    """The do-block marks element 1 through a nested function whose parameter is also named i."""
    N = Param(2)
    go = Input(Int, size="N")
    out = Output(Int, size="N")

    def init(self):
        self.flag = [False, False]

    @go.input
    def on_go(self, i, x):
        def mark(i):
            self.flag[i] = True
        mark(1)

    @out.action(value=lambda self, i: i, when=lambda self, i: self.flag[i])
    def sent(self, i):
        self.flag[i] = False


def test_a_nested_parameter_named_like_the_index_is_not_the_own_element():
    trace = both(lambda: NestedShadow("n"), [(1.0, "go", 5, 0)])
    assert [(e["t"], e["index"]) for e in trace if e["kind"] == "output"] == [(1.0, 1)]


def test_rebinding_the_index_anywhere_makes_subscripts_whole_variables():
    assert cells_of(lambda self, i: [self.request[i] for i in range(2)], STATE) == {("request", ANY)}
    assert cells_of(lambda self, i: (lambda i: self.request[i])(0), STATE) == {("request", ANY)}

    def handler(self, i):
        try:
            pass
        except ValueError as i:  # noqa: F841
            pass
        self.request[i] = 1
    assert cells_of(handler, STATE) == {("request", ANY)}


def test_dict_access_and_super_are_everything():
    assert cells_of(lambda self: self.__dict__["flag"], STATE) is ALL_STATE

    class Base:
        def touch(self):
            pass

    class Child(Base):
        def act(self):
            super().touch()
    assert cells_of(Child.act, STATE) is ALL_STATE


def pop_first(self):
    return self.queue.pop(0)


class ValueMutates(Iota):
    """The output's value function consumes the queue; `done` waits for it to be empty."""
    inp = Input(Int)
    out = Output(Int)
    done = Output()

    def init(self):
        self.queue = []

    @inp.input
    def got(self, x):
        self.queue.append(x)

    out.fires(value=pop_first, when=lambda self: len(self.queue) > 0, within=(1, 1))
    done.fires(when=lambda self: len(self.queue) == 0, within=(0.5, 0.5))


def test_what_a_value_function_changes_counts_as_written():
    trace = both(lambda: ValueMutates("v"), [(0.0, "inp", 1, None), (0.0, "inp", 2, None)], until=3)
    assert [(e["t"], e["action"]) for e in trace if e["kind"] == "output"][:3] == \
        [(1.0, "out"), (2.0, "out"), (2.5, "done")]


class ClassDefault(Iota):
    """State as a class attribute default, shadowed by the do-block: not set in `init`."""
    inp = Input(Int)
    out = Output()
    armed = False

    @inp.input
    def got(self, x):
        self.armed = True

    @out.action(when=lambda self: self.armed)
    def sent(self):
        self.armed = False


def test_a_class_attribute_used_as_state_is_tracked():
    trace = both(lambda: ClassDefault("c"), [(1.0, "inp", 1, None)])
    assert [e["t"] for e in trace if e["kind"] == "output"] == [1.0]


class ParamAssigned(Iota):
    """A do-block changes a parameter another precondition reads."""
    LIMIT = Param(0)
    inp = Input(Int)
    out = Output()

    def init(self):
        self.sent_count = 0

    @inp.input
    def got(self, x):
        self.LIMIT = x

    @out.action(when=lambda self: self.sent_count < self.LIMIT, after=0.5)
    def sent(self):
        self.sent_count += 1


def test_a_parameter_a_do_block_assigns_is_state():
    trace = both(lambda: ParamAssigned("p"), [(1.0, "inp", 2, None)])
    assert [e["t"] for e in trace if e["kind"] == "output"] == [1.5, 2.0]


class ViaProperty(Iota):
    inp = Input(Int)
    out = Output()

    def init(self):
        self.items = []

    @property
    def busy(self):
        return bool(self.items)

    @inp.input
    def got(self, x):
        self.items.append(x)

    @out.action(when=lambda self: self.busy)
    def sent(self):
        self.items.clear()


def test_a_property_read_in_a_precondition_is_everything():
    trace = both(lambda: ViaProperty("p"), [(1.0, "inp", 1, None), (2.0, "inp", 2, None)])
    assert [e["t"] for e in trace if e["kind"] == "output"] == [1.0, 2.0]


# ------------------------------------------------------------------ random ESPRIT programs
def esprit_program(assignments, guards):
    """An IOTA over int arrays a[2], b[2] with a family of two actions per guard."""
    body = []
    for k, (guard, writes) in enumerate(zip(guards, assignments)):
        stmts = " ".join(writes)
        body.append(f"out{k}[i]() when {guard} after 1 do {{ {stmts} }}")
    channels = ", ".join(f"out{k}[2]()/0" for k in range(len(guards)))
    return f"""
    iota r: go[2](int)/0 -> {channels} {{
      states int a[2] = 0, b[2] = 0, c = 0;
      actions (i=0; i<2; i++)
      go[i](x) do {{ a[i] = x; }}
      {' '.join(body)}
    }}"""


# `a[c]` is an element chosen by state: the engine finds it from c before and after a firing
cells = st.sampled_from(["a[i]", "a[0]", "a[1]", "b[i]", "b[0]", "b[1]", "c", "a[c]", "b[c]"])
guards = st.builds(lambda x, op, n: f"{x} {op} {n}", cells, st.sampled_from(["<", "==", ">", "!="]),
                   st.integers(0, 3))
writes = st.lists(st.one_of(
    st.builds(lambda x, n: f"{x} = {n};", cells, st.integers(0, 3)),
    st.builds(lambda x, y: f"{x} = {y} + 1;", cells, cells),
    st.builds(lambda x, n: f"for (j = 0; j < 2; j++) {x}[j] = {n};", st.sampled_from(["a", "b"]), st.integers(0, 3)),
    st.builds(lambda x: f"if (c < 5) {{ c = c + 1; }} else {{ {x} = 0; }}", cells)), max_size=3)


@settings(max_examples=40, deadline=None)
@given(spec=st.lists(st.tuples(guards, writes), min_size=1, max_size=3),
       inputs=st.lists(st.tuples(st.integers(0, 8), st.integers(0, 1), st.integers(0, 3)), max_size=5),
       seed=st.integers(0, 1000))
def test_random_esprit_programs_track_like_re_evaluating_everything(spec, inputs, seed):
    from iotad.esprit import load_iota
    text = esprit_program([w for _, w in spec], [g for g, _ in spec])
    script = sorted((t * 0.5, "go", x, i) for t, i, x in inputs)
    both(lambda: load_iota(text), script, until=8, policy=lambda: Random(seed))
