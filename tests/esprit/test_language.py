"""The ESPRIT language beyond Figure 2: statements, operators (ASCII and the paper's symbols),
struct values, externs, composites, runtime faults, parameters, and the cells actions touch."""
import json

import pytest

from iotad import cli
from iotad.kernel.compose import Composite, flatten
from iotad.esprit import EspritError, load_iota, load_text
from recorded_systems import COMPOSITE
from iotad.kernel.model import ANY, INDEX, Instance
from iotad.kernel.input_script import run_script


def run(text, until=10.0, inputs=(), **params):
    return run_script(load_iota(text, **params), list(inputs), until).trace


def outputs(trace, action=None):
    return [(e["t"], e["value"]) for e in trace if e["kind"] == "output" and action in (None, e["action"])]


def violations(trace):
    return [(e["t"], e["value"]["violation"], e["value"]["message"]) for e in trace if e["kind"] == "violation"]


COUNTER_ASCII = """
iota counter(int N = 4): -> out(bool)/0, sum(int)/0 {
  states int k = 0, total = 0;
  actions
  out(!(k >= 2) && true || false -> k != 1)
  when k < N && !(k == 99)
  after 1
  do { k = k + 1; }
  sum(total) when k == N && total == 0 do { for (j = 0; j < N; j++) total = total + j * 2; }
}
"""
COUNTER_UNICODE = (COUNTER_ASCII.replace("!(", "¬(").replace("&&", "∧").replace("||", "∨").replace("->", "→")
                   .replace(">=", "≥").replace("!=", "≠"))


def test_unicode_operators_mean_the_ascii_ones():
    assert "∧" in COUNTER_UNICODE and "→" in COUNTER_UNICODE and "¬" in COUNTER_UNICODE
    ascii_trace, unicode_trace = run(COUNTER_ASCII), run(COUNTER_UNICODE)
    assert ascii_trace == unicode_trace
    # -> binds loosest: (!(k>=2) && true || false) -> (k != 3)
    assert outputs(ascii_trace, "out") == [(1.0, True), (2.0, False), (3.0, True), (4.0, True)]
    assert outputs(ascii_trace, "sum") == [(4.0, 0)]  # the value is taken before the do-block
    engine = run_script(load_iota(COUNTER_UNICODE), [], 10)
    assert engine.iota("counter").total == 0 + 2 + 4 + 6  # the for loop ran j = 0..N-1


def test_if_else_blocks_and_arithmetic():
    spec = """
    iota a: -> out(int)/0, f(float)/0 {
      states int n = 0, r = 0; float x = 0;
      actions
      out(r) when n < 4 after 1 do {
        n = n + 1;
        if (n % 2 == 0) { r = -7 / 2; } else if (n == 3) r = 7 % -3; else { r = 10 - 2 * 3; }
      }
      f(x) when n == 4 && x == 0 do x = 7 / 2.0 + 1;
    }"""
    trace = run(spec)
    assert outputs(trace, "out") == [(1.0, 0), (2.0, 4), (3.0, -3), (4.0, 1)]  # C division truncates
    assert outputs(trace, "f") == [(4.0, 0)]
    assert load_iota(spec).x == 0


def test_struct_values_fields_arrays_and_constants():
    spec = """
    struct point { float x, y; };
    struct path { struct point p[3]; int len; };
    const struct point ORIGIN = { 0, 0 };
    const int LIMIT = 2 + 1;
    iota a: -> out(struct path)/0 {
      states struct path route = { .len = 0 }; struct point last = ORIGIN;
      actions
      out(route) when route.len < LIMIT after 1 do {
        last.x = last.x + 1.5; last.y = route.len;
        route.p[route.len] = last;
        route.len = route.len + 1;
      }
    }"""
    trace = run(spec)
    final = outputs(trace)[-1][1]
    assert final["len"] == 2  # the value is taken before the do-block
    assert final["p"][1] == {"x": 3.0, "y": 1} and final["p"][2] == {"x": 0.0, "y": 0.0}
    iota = load_iota(spec)
    run_script(iota, [], 10)
    iota.last.x = 100  # stored struct values are copies, not shared
    assert iota.route.p[2].x == 4.5


def test_loops_past_the_budget_are_runtime_errors_not_hangs():
    """A for loop or quantifier of two billion, or loops nested to 1e10 iterations, ends the
    evaluation with a recorded runtime error (runtime.LOOP_BUDGET per evaluation), and the IOTA
    goes on; a loop within the budget runs, in every evaluation anew."""
    spec = """
    iota a: go(int)/0 -> out(int)/0 {
      states int n = 0, acc = 0;
      actions
      go(v) do { n = v; for (j = 0; j < n; j++) acc = acc + 1; }
      out(acc) when exists (j = 0; j < n; j++) (j == 999999) after 1 do { n = 0; }
    }"""
    trace = run(spec, inputs=[{"t": 0.5, "action": "go", "index": None, "value": 2_000_000_000},
                              {"t": 2.5, "action": "go", "index": None, "value": 1_000_000}])
    found = violations(trace)
    assert [(t, code) for t, code, _ in found] == [(0.5, "runtime_error"), (0.5, "runtime_error")]
    assert "go(v): LoopBudgetExceeded: a loop or quantifier from 0 to 2000000000 passes the budget" in found[0][2]
    assert "out (when): LoopBudgetExceeded" in found[1][2]
    assert outputs(trace) == [(3.5, 1_000_000)]  # a million, in a do-block, then in a quantifier

    nested = """
    iota b: go(int)/0 -> out(int)/0 {
      states int acc = 0;
      actions
      go(v) do { for (j = 0; j < v; j++) for (k = 0; k < v; k++) acc = acc + 1; }
    }"""
    found = violations(run(nested, inputs=[{"t": 0.5, "action": "go", "index": None, "value": 100_000}]))
    assert [(t, code) for t, code, _ in found] == [(0.5, "runtime_error")] and "LoopBudgetExceeded" in found[0][2]


@pytest.mark.parametrize("body", ["!" * 250 + "true", "(" * 5 + "true" + ")" * 5])
def test_nesting_past_what_python_compiles_is_an_error_not_an_internal_one(body, tmp_path, capsys):
    path = tmp_path / "deep.iota"
    path.write_text(f"iota d: -> out()/1 {{\n  actions\n  out() when {body}\n}}\n")
    if body.startswith("!"):
        with pytest.raises(EspritError, match="nests too deeply"):
            load_text(path.read_text(), str(path))
        assert cli.main(["spec", "check", str(path)]) == 2
        err = capsys.readouterr().err
        assert "the spec nests too deeply" in err and "internal" not in err and "unexpected" not in err
    else:
        assert load_text(path.read_text(), str(path)).iotas  # shallow nesting compiles


def test_runtime_faults_become_violations_and_the_iota_goes_on():
    spec = """
    iota a(int N = 2): -> out(int)/0 {
      states int k = 0, a[N] = 5, m = NULL;
      actions
      out(10 / (2 - k)) when k < 4 after 1 do { k = k + 1; a[k] = k; }
    }"""
    trace = run(spec)
    assert outputs(trace) == [(1.0, 5), (2.0, 10), (4.0, -10)]
    found = violations(trace)
    # t=3: the value divides by zero (no output) and the do-block still runs (and faults)
    assert [(t, code) for t, code, _ in found] == [(2.0, "runtime_error"), (3.0, "runtime_error"),
                                                    (3.0, "runtime_error"), (4.0, "runtime_error")]
    assert "IndexError: index 2 out of range" in found[0][2]
    assert "(value): ZeroDivisionError" in found[1][2]
    assert "(do): IndexError: index 3 out of range" in found[2][2]
    null_index = "iota b: -> out(int)/0 { states int a[2] = 0, m = NULL; actions out(a[m]) after 1 }"
    assert "index is NULL" in violations(run(null_index, 1.5))[0][2]


def test_an_array_keeps_its_declared_length():
    # lengths from parameters are known only when it runs: a whole array of another length is
    # refused there (a runtime_error; the array stays as it was), never stored
    spec = """
    iota a(int N = 3, int M = 2): -> out(float)/0 {
      states int k = 0; float arr[N] = 1.0, other[M] = 9.0, same[N] = 2.0;
      actions
      out(arr[N - 1]) when k < 3 after 1 do { k = k + 1; if (k == 1) arr = other; else arr = same; }
    }"""
    trace = run(spec)
    assert outputs(trace) == [(1.0, 1.0), (2.0, 1.0), (3.0, 2.0)]
    assert violations(trace) == [(1.0, "runtime_error", "out (do): ValueError: an array of 3 elements cannot be given 2")]
    assert violations(run(spec, M=3)) == []


def test_an_int_that_overflows_64_bits_is_a_runtime_error_not_a_hung_node():
    # squaring 26 times would build a number of 2**26 digits, each product slower than the last
    spec = """
    iota x: a()/0 -> b(int)/0 {
      states int v = 3; bool d = false;
      actions
      a() do { for (j = 0; j < 26; j++) v = v * v; d = true; }
      b(v % 7) when d after 1 do d = false;
    }"""
    trace = run(spec, inputs=[{"t": 0.5, "action": "a"}], until=5.0)
    assert violations(trace) == [
        (0.5, "runtime_error", "a(): ValueError: v = an int of 102 bits overflows an int (the wire and recordings "
                               "carry -9223372036854775808..18446744073709551615); it keeps its value")]
    assert outputs(trace) == []  # the do-block stopped there: d was never set


def test_a_state_keeps_to_its_declared_range():
    spec = """
    struct pt { float x in [0.0, 1.0]; };
    iota r: -> out(int)/0 {
      states int x in [0, 10] = 0; int a[2] in [0, 3] = 0; struct pt p = {0.5};
      actions
      out(x) after 1 do { x = x + 5; a[1] = x; }
    }"""
    trace = run(spec, until=4.0)
    # x: 0, 5, 10, then 15 is refused and x stays 10; a[1] never takes 5 or 10
    assert outputs(trace) == [(1.0, 0), (2.0, 5), (3.0, 10), (4.0, 10)]
    assert [(t, message.split(": ", 1)[1]) for t, _, message in violations(trace)] == [
        (1.0, "ValueError: a[] = 5 is outside its declared range [0, 3]; it keeps its value"),
        (2.0, "ValueError: a[] = 10 is outside its declared range [0, 3]; it keeps its value"),
        (3.0, "ValueError: x = 15 is outside its declared range [0, 10]; it keeps its value"),
        (4.0, "ValueError: x = 15 is outside its declared range [0, 10]; it keeps its value")]
    with pytest.raises(EspritError, match=r"initial value of x: ValueError: x = 55 is outside its declared range "
                                          r"\[0, 10\]\n"):
        run(spec.replace("int x in [0, 10] = 0", "int x in [0, 10] = 55"))
    field = spec.replace("do { x = x + 5; a[1] = x; }", "do p.x = 2.0;").replace("out(x) after 1", "out(0) after 1")
    assert violations(run(field, until=1.0)) == [
        (1.0, "runtime_error", "out(0) (do): ValueError: p.x = 2.0 is outside its declared range [0.0, 1.0]; "
                               "it keeps its value")]


def test_family_with_index_and_parameters():
    spec = """
    iota fan(int N = 3, float T = 0.5): -> tick[N](int)/T {
      states int count[N] = 0;
      actions (i=0; i<N; i++)
      tick[i](count[i] * 10 + i) when count[i] < 2 within [T, 1] do count[i] = count[i] + 1;
    }"""
    trace = run(spec)
    ticks = [(e["t"], e["index"], e["value"]) for e in trace]
    assert ticks == [(0.5, 0, 0), (0.5, 1, 1), (0.5, 2, 2), (1.0, 0, 10), (1.0, 1, 11), (1.0, 2, 12)]
    assert [e["t"] for e in run(spec, N=1, T=0.8)] == [0.8, 1.6]
    with pytest.raises(EspritError, match="parameter N: expected int"):
        load_iota(spec, N=1.5)
    with pytest.raises(EspritError, match="has no parameter M"):
        load_iota(spec, M=1)


def test_reads_and_writes_match_the_python_scheduler():
    from scheduler import Scheduler
    from pathlib import Path
    spec = load_iota(str(Path(__file__).resolve().parents[2] / "nodes/scheduler/scheduler.iota")).iota_spec
    python = Scheduler("scheduler").iota_spec
    assert [a.label for a in spec.actions] == [a.label for a in python.actions]
    for mine, theirs in zip(spec.actions, python.actions):
        assert mine.reads == theirs.reads, mine.label
        # the Python analysis counts current_master in request[current_master].status = ... as
        # touched; the ESPRIT one knows it is only read there: a subset, never a miss
        assert mine.writes <= theirs.writes, mine.label
    schedule = spec.actions[1]
    assert schedule.reads == {("request", INDEX), ("current_priority", ANY)}
    assert spec.source.startswith("// The motion scheduler") and spec.source_path.endswith("scheduler.iota")


def test_cells_of_loops_and_other_indices_are_whole_variables():
    spec = """
    iota a(int N = 2): -> out[N]()/0 {
      states int v[N] = 0, w[N] = 0;
      actions (i=0; i<N; i++)
      out[i]() when v[i] == 0 && w[0] == 0 do { for (j = 0; j < N; j++) w[j] = 1; v[i] = 1; }
    }"""
    action = load_iota(spec).iota_spec.actions[0]
    assert action.reads == {("v", INDEX), ("w", ANY)}
    assert action.writes == {("v", INDEX), ("w", ANY)}


def test_extern_functions(tmp_path):
    (tmp_path / "helpers.py").write_text(
        "def clamp(x, lo, hi):\n    return max(lo, min(hi, x))\n"
        "def grow(p):\n    p.x = p.x * 10\n    return {'x': p.x + 1, 'y': 0.0}\n"
        "def boom(x):\n    raise ValueError('no')\n")
    spec = tmp_path / "ext.iota"
    spec.write_text("""
    struct point { float x, y; };
    extern float clamp(float, float, float) = "helpers.py:clamp";
    extern struct point grow(struct point p) = "helpers.py:grow";
    extern void note(int);
    extern int boom(int) = "helpers.py:boom";
    iota a: -> out(float)/0, moved(struct point)/0, bad(int)/0 {
      states int k = 0; struct point p = { 1, 2 };
      actions
      out(clamp(k * 2.5, 0, 4)) when k < 3 after 1 do { k = k + 1; note(k); }
      moved(grow(p)) when k == 3 do { p = grow(p); k = 4; }
      bad(boom(k)) when k == 4 after 1 do k = 5;
    }""")
    seen = []
    iota = load_iota(spec, externs={"note": seen.append})
    trace = run_script(iota, [], 10).trace
    assert outputs(trace, "out") == [(1.0, 0.0), (2.0, 2.5), (3.0, 4)]
    # grow gets a copy of p each time: the call in the value does not change p for the do-block
    assert outputs(trace, "moved") == [(3.0, {"x": 11.0, "y": 0.0})]
    assert iota.p.x == 11.0 and iota.p.y == 0.0
    assert seen == [1, 2, 3]
    assert [(t, code) for t, code, _ in violations(trace)] == [(4.0, "runtime_error")]
    with pytest.raises(EspritError, match="extern note names no Python function"):
        load_iota(spec)


def test_composite_spec_with_inclusion_part_and_own_actions():
    root = load_iota(COMPOSITE, P=2.0)
    assert isinstance(root, Composite) and isinstance(root.own, Instance)
    assert set(root.components) == {"c", "d"}
    engine = run_script(root, [{"t": 1.0, "action": "go", "index": None, "value": None, "iota": None}], 20)
    assert [(e["t"], e["iota"], e["action"], e["kind"]) for e in engine.trace][:6] == [
        (1.0, "clocked", "go", "input"), (3.0, "clocked", "tick", "output"), (3.0, "clocked/c", "tick", "input"),
        (3.0, "clocked/c", "count", "output"), (3.0, "clocked/d", "inp", "input"), (3.5, "clocked/d", "out", "output")]
    assert [(e["t"], e["value"]) for e in engine.external_trace() if e["action"] == "total"] == [
        (3.5, 2), (5.5, 4), (7.5, 6)]
    assert engine.iota("clocked").sent == 3


def test_composite_component_parameters():
    spec = COMPOSITE + """
    iota outer: go()/0 -> total(int)/0 {
      include clocked inner(P = 0.25, TIMES = 1); go -> inner.go; inner.total -> total;
    }"""
    root = load_iota(spec)
    assert root.own is None and root.components["inner"].own.P == 0.25
    trace = run_script(root, [{"t": 0.0, "action": "go", "index": None, "value": None, "iota": None}], 5).trace
    assert [(e["t"], e["value"]) for e in trace if e["action"] == "out"] == [(0.75, 2)]


def test_an_own_input_fed_by_a_component_is_not_external():
    """A composite's own input bound from one of its components is the composite's business: its
    parent sees only `seen`, and nobody may bind `got` a second time."""
    root = load_iota("""
    iota src: -> out(int)/0 { states int n = 0; actions out(n) when n < 3 after 1 do n = n + 1; }
    iota watch: got(int)/0 -> seen(int)/0 {
      include src s;
      s.out -> got;
      states int last = -1; bool due = false;
      actions
      got(x) do { last = x; due = true; }
      seen(last * 10) when due do due = false;
    }""")
    assert {name: direction for name, (direction, _) in flatten(root).external.items()} == {"seen": "output"}
    trace = run_script(root, [], 10).trace
    assert [(e["t"], e["value"]) for e in trace if e["action"] == "seen"] == [(1.0, 0), (2.0, 10), (3.0, 20)]


def test_load_api_and_module(tmp_path):
    from iotad.esprit import load_file
    spec = tmp_path / "two.iota"
    spec.write_text("struct s { int a; }; iota first: -> { } iota second(int K = 1): -> { states int k = K; }")
    module = load_file(spec)
    assert list(module.iotas) == ["first", "second"] and module.structs["s"].field_names == ("a",)
    assert load_iota(str(spec)).k == 1  # the last IOTA by default
    assert load_iota(str(spec), iota="second", name="x", K=5).instance_name == "x"
    assert load_iota(str(spec), "second", K=5).k == 5
    with pytest.raises(EspritError, match="no iota third"):
        load_iota(str(spec), iota="third")
    with pytest.raises(EspritError, match="cannot read"):
        load_file(tmp_path / "missing.iota")


def test_init_faults_name_the_declaration():
    with pytest.raises(EspritError) as info:
        load_iota("iota a(int N = -1): -> { states int v[N] = 0; }", name="x")
    assert "1:37: initial value of v" in str(info.value) and "whole number >= 0" in str(info.value)


def test_show_prints_the_interface(capsys):
    from pathlib import Path
    spec = Path(__file__).resolve().parents[2] / "nodes/scheduler/scheduler.iota"
    assert cli.main(["spec", "show", str(spec)]) == 0
    out = capsys.readouterr().out
    for row in (("req[N]", "input", "struct mdlReq", "1"), ("ack[N]", "output", "enum ack"),
                ("mdl_command", "output", "struct mode"), ("schedule[N]", "internal")):
        line = next(line for line in out.splitlines() if row[0] in line)
        assert all(cell in line for cell in row), line


def test_switching_time_from_a_parameter(tmp_path, capsys):
    spec = tmp_path / "s.iota"
    spec.write_text("iota a(float S = 2): -> out()/S { actions out() when true }")
    assert cli.main(["spec", "run", str(spec), "--until", "5", "--param", "S=2.5"]) == 0
    assert [json.loads(line)["t"] for line in capsys.readouterr().out.splitlines()] == [0.0, 2.5, 5.0]
