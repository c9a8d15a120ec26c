"""The ESPRIT extensions the schedulers need (docs/esprit.md "Quantifiers, time,
reset and inhibit"): forall/exists, now(), reset(), inhibit(d). Parsing, static checks, generated code,
the cells actions read and write, and their runtime behaviour."""
import pytest

from iotad import run_script
from iotad.esprit import EspritError, check_text, load_iota, load_text
from iotad.kernel.model import ALL_STATE, ANY, INDEX

from scheduling_helpers import RESUME, priority, req, run


def errors(text):
    found, _ = check_text(text)
    return [d.message for d in found]


def one_error(text):
    found = errors(text)
    assert len(found) == 1, found
    return found[0]


def action(spec_text, label, iota=None):
    module = load_text(spec_text)
    spec = module.factory(iota).spec
    return next(a for a in spec.actions if a.label == label)


# ---------------------------------------------------------------- quantifiers
QUANT = """
iota q(int N = 3): set[N](int)/0 -> all_pos()/0, some_big()/0 {
  states int x[N] = 0; bool done = false, told = false;
  actions (i=0; i<N; i++)
  set[i](v) do x[i] = v;
  actions
  all_pos() when ¬done ∧ ∀ (j=0; j<N; j++) (x[j] > 0) do done = true;
  some_big() when ¬told ∧ exists (k=0; k<N; k++) (x[k] > 10 ∧ forall (m=0; m<k; m++) (x[m] < x[k])) do told = true;
}
"""


def test_quantifiers_in_preconditions():
    engine = run(load_iota(QUANT), [{"t": 1.0, "action": "set", "index": 0, "value": 1},
                                   {"t": 2.0, "action": "set", "index": 2, "value": 20},
                                   {"t": 3.0, "action": "set", "index": 1, "value": 30}], until=5)
    assert [(e["t"], e["action"]) for e in engine.trace if e["kind"] == "output"] == [(2.0, "some_big"),
                                                                                       (3.0, "all_pos")]


def test_empty_ranges_and_statements():
    spec = """
    iota e(int N = 0): -> out(int)/0 {
      states int n = 0;
      actions
      out(n) when n == 0 ∧ forall (j=0; j<N; j++) (false) ∧ ¬exists (j=0; j<N; j++) (true)
      do { if (forall (j=2; j<1; j++) (false)) n = 1; else n = 2; }
    }"""
    engine = run(load_iota(spec), [], until=1)
    assert [e["value"] for e in engine.trace] == [0] and engine.iota("e").n == 1


def test_quantifiers_read_whole_variables():
    when = action(QUANT, "all_pos")
    assert when.reads == frozenset({("done", ANY), ("x", ANY)})


@pytest.mark.parametrize("text, message", [
    ("forall (j=0; k<3; j++) (true)", "a quantifier counts one variable: expected j, found k"),
    ("forall (n=0; n<3; n++) (true)", "forall variable n hides state n"),
    ("exists (j=0; j<1.5; j++) (true)", "a exists counts with ints, not float"),
    ("forall (j=0; j<3; j++) (j + 1)", "forall needs a bool condition, not int"),
    ("forall (j=0; j<3; j++) true", "unexpected 'true'"),
])
def test_quantifier_errors(text, message):
    assert message in one_error(f"iota a: -> out()/0 {{ states int n = 0; actions out() when {text} do n = 1; }}")


# ---------------------------------------------------------------- now()
TIMED = """
iota timed(float D = 2.0): go(float)/0 -> done(float)/0 {
  states float due = 0; float started = -1; bool armed = false;
  actions
  go(x) do { started = now(); due = now() + x; armed = true; }
  done(started) when armed within [due - now(), due - now() + D] do armed = false;
}
"""


def test_now_in_do_blocks_and_time_bounds():
    engine = run(load_iota(TIMED), [{"t": 1.5, "action": "go", "value": 2.0}], until=10)
    assert [(e["t"], e["value"]) for e in engine.trace if e["kind"] == "output"] == [(3.5, 1.5)]


def test_now_is_the_instant_of_the_firing_under_any_policy():
    from iotad import Random
    engine = run_script(load_iota(TIMED), [{"t": 1.5, "action": "go", "value": 2.0}], 10, Random(4))
    [done] = [e for e in engine.trace if e["kind"] == "output"]
    assert 3.5 <= done["t"] <= 5.5 and done["value"] == 1.5


@pytest.mark.parametrize("clause, message", [
    ("out() when now() > 1.0 do n = 1;", "now() is read only in do-blocks and time bounds, not in a precondition"),
    ("val(now()) do n = 1;", "not in an output value"),
    ("out() do n = now(1);", "now takes 0 argument(s), not 1"),
])
def test_now_where_it_cannot_be_read(clause, message):
    text = f"iota a: -> out()/0, val(float)/0 {{ states float n = 0; actions out() do n = 2; val(n) do n = 3; {clause} }}"
    assert message in one_error(text)


def test_now_in_a_constant_or_a_default_is_an_error():
    assert "now() is read only in do-blocks and time bounds, not in a declaration" in errors(
        "const float X = now(); iota a: -> { }")
    assert "not in a declaration" in one_error("iota a: -> { states float t0 = now(); }")


def test_now_outside_an_engine_is_a_clear_runtime_error():
    module = load_text(TIMED)
    spec = module.factory().spec
    go = next(a for a in spec.actions if a.channel == "go")
    instance = module.factory()()
    with pytest.raises(RuntimeError, match="only while an engine runs"):
        go.do(instance, None, 1.0)


# ---------------------------------------------------------------- reset() and inhibit(d)
def test_reset_writes_everything_and_inhibit_its_own_cells():
    text = """
    iota m: reset()/0, inhibit(float)/0, poke(int)/0 -> out(int)/0, aux()/0 {
      states int n = 0;
      channels tick()/0;
      actions
      reset() do reset();
      inhibit(d) do { if (d > 1) inhibit(d); }
      poke(x) do n = x;
      out(n) when n > 0 do n = 0;
      aux() when n > 5 do n = 0;
      tick() when n < 0 do n = 0;
    }"""
    module = load_text(text)
    spec = module.factory().spec
    by_label = {a.label: a for a in spec.actions}
    assert by_label["reset()"].writes == ALL_STATE
    assert {("_inhibited", ANY), ("_inhibit_until", ANY), ("_inhibit_phase", ANY)} <= by_label["inhibit(d)"].writes
    assert ("_inhibited", ANY) in by_label["out"].reads and ("_inhibited", ANY) in by_label["aux"].reads
    assert ("_inhibited", ANY) not in by_label["tick"].reads          # internal actions are not inhibited
    assert all(("_resetting", ANY) in a.reads for a in spec.actions if spec.channels[a.channel].direction != "input"
               and a.channel in ("out", "aux", "tick"))
    assert [a.channel for a in spec.actions[-3:]] == ["uninhibit", "uninhibit", "restarted"]
    assert spec.channels["uninhibit"].direction == "internal"


@pytest.mark.parametrize("body, message", [
    ("n = reset();", "reset(...) is a statement of a do-block"),
    ("inhibit();", "inhibit takes 1 argument(s), not 0"),
    ("inhibit(true);", "the argument of inhibit is a number (a time), not bool"),
])
def test_reset_and_inhibit_misuse(body, message):
    assert message in one_error(f"iota a: go()/0 -> {{ states int n = 0; actions go() do {{ {body} }} }}")


def test_reset_is_not_a_value_anywhere():
    assert "statement" in one_error("iota a: -> out(int)/0 { states int n = 0; actions out(reset()) do n = 1; }")


def test_the_hidden_channels_cannot_be_declared_by_a_spec_that_needs_them():
    text = "iota a: stop(float)/0 -> {{ channels {name}()/0; actions stop(d) do inhibit(d); {name}() do {{}} }}"
    assert "uninhibit is the internal channel inhibit() adds" in one_error(text.format(name="uninhibit"))
    assert errors(text.format(name="restarted")) == []  # free while nobody calls reset()


def test_builtin_names_cannot_be_externs():
    assert "now is a built-in function of ESPRIT" in one_error('extern float now() = "time:time"; iota a: -> { }')


def test_a_composite_own_part_can_be_a_module():
    text = """
    iota leaf: inp(int)/0 -> out(int)/0 { states int v = 0; bool f = false;
      actions inp(x) do { v = x; f = true; } out(v) when f do f = false; }
    iota box: inhibit(float)/0, inp(int)/0 -> out(int)/0, echo(int)/0 {
      states int last = 0; bool f = false;
      include leaf l; inp -> l.inp; l.out -> out;
      actions inhibit(d) do inhibit(d); echo(last) when f do f = false;
    }"""
    assert errors(text) == []
    load_iota(text)


# ---------------------------------------------------------------- dependency tracking
def test_dependency_tracking_gives_the_same_trace_as_re_evaluating_everything():
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    from iotad import Random
    inputs = [req(0.0, 0, 1, epoch=5.0), req(0.5, 1, 2, epoch=2.0), req(1.0, 2, 3, epoch=1.0),
              priority(1.5, 0, 9), req(4.0, 1, 4, epoch=3.0, timeout=1.0), priority(5.0, 2, 1)]
    traces = []
    for tracked in (True, False):
        engine = Engine(load_iota(str(RESUME), N=3), VirtualClock(), Random(5), track_dependencies=tracked)
        for entry in inputs:
            engine.post(None, entry["action"], entry["value"], entry["index"], t=entry["t"])
        engine.run(30)
        traces.append(engine.trace)
    assert len(traces[0]) > 12
    assert traces[0] == traces[1]
