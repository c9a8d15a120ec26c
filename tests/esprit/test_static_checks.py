"""Every static check of `iotad spec check` has a spec that trips it and one that does not;
errors name file:line:col, show the line with a caret, and exit 2 without a traceback."""
import re

import pytest

from iotad import cli
from iotad.esprit import EspritError, check_text, load_iota, load_text

PINGPONG = """
iota ping: inp()/0 -> out()/0 { states int n = 0;
  actions inp() do { n = n + 1; }  out() when n < 3 after 1 do { n = n + 1; } }
iota pong: inp()/0 -> out()/0 { states bool got = false;
  actions inp() do { got = true; }  out() when got after 0.5 do { got = false; } }
"""

# a component whose channels a composite's interface maps (`go -> a.go`)
LEAF = """
iota leaf: go(int)/0 -> out(int)/0 { states int n = 0;
  actions go(x) do n = x;  out(n) when n > 0 do n = 0; }
"""

# name -> (spec that trips the check, the same spec fixed, text the message must contain)
CHECKS = {
    "float_literal_overflows": ("iota a: go()/1e999 -> { actions go() }", "iota a: go()/1e300 -> { actions go() }",
                                "1e999 is beyond the largest float"),
    "array_length_float": ("iota t(float T = 1.0): go()/0 -> { states int a[T] = 0; actions go() }",
                           "iota t(int T = 1): go()/0 -> { states int a[T] = 0; actions go() }",
                           "an array length is an int, not float"),
    # nested arrays multiply: 1e6 structs of 1e6 floats would fill the memory before any error
    "struct_too_large": ("struct a { float q[1000000]; }; struct b { struct a x[1000000]; }; "
                         "iota t: go()/0 -> { states struct b s = {}; actions go() }",
                         "struct a { float q[1000]; }; struct b { struct a x[1000]; }; "
                         "iota t: go()/0 -> { states struct b s = {}; actions go() }",
                         "struct b holds 1000000000000 values in all, past the limit of 1000000"),
    "undeclared_name": ("iota a: -> out(int)/1 { actions out(y) }",
                        "iota a: -> out(int)/1 { actions out(1) }", "undeclared name y"),
    "undeclared_type": ("iota a: -> out(struct nope)/1 { }",
                        "struct nope { int x; }; iota a: -> out(struct nope)/1 { }", "undeclared struct nope"),
    "undeclared_channel": ("iota a: -> out()/1 { actions outt() }",
                           "iota a: -> out()/1 { actions out() }", "undeclared channel outt"),
    "undeclared_field": ("struct s { int x; }; iota a: -> out(int)/1 { states struct s v; actions out(v.y) }",
                         "struct s { int x; }; iota a: -> out(int)/1 { states struct s v; actions out(v.x) }",
                         "no field y"),
    "undeclared_function": ("iota a: -> out(int)/1 { actions out(f(1)) }",
                            "extern int f(int) = \"builtins:abs\"; iota a: -> out(int)/1 { actions out(f(1)) }",
                            "undeclared function f"),
    "negative_state_array": ("iota a: -> { states int v[-1] = 0; }", "iota a: -> { states int v[1] = 0; }",
                             "array length must be a whole number >= 0, got -1"),
    "type_mismatch_init": ("iota a: -> { states bool b = 3; }", "iota a: -> { states bool b = true; }",
                           "b holds bool; the initial value is int"),
    "type_mismatch_assign": ("iota a: -> out()/1 { states int n = 0; actions out() do n = true; }",
                             "iota a: -> out()/1 { states int n = 0; actions out() do n = 1; }",
                             "cannot assign bool to int"),
    "type_mismatch_output": ("enum e { A }; iota a: -> out(int)/1 { actions out(A) }",
                             "enum e { A }; iota a: -> out(enum e)/1 { actions out(A) }",
                             "out carries int, not enum e"),
    "type_mismatch_when": ("iota a: -> out()/1 { states int n = 0; actions out() when n }",
                           "iota a: -> out()/1 { states int n = 0; actions out() when n > 0 }",
                           "a when clause is a bool condition"),
    "type_mismatch_logic": ("iota a: -> out()/1 { actions out() when 1 && true }",
                            "iota a: -> out()/1 { actions out() when 1 > 0 && true }", "&& needs bool operands"),
    "type_mismatch_compare": ("enum e { A }; iota a: -> out()/1 { actions out() when A == 1 }",
                              "enum e { A }; iota a: -> out()/1 { actions out() when A == A }",
                              "cannot compare enum e with int"),
    "input_with_when": ("iota a: inp(int)/1 -> { actions inp(x) when true }",
                        "iota a: inp(int)/1 -> { actions inp(x) }", "cannot have a when clause"),
    "input_with_after": ("iota a: inp(int)/1 -> { actions inp(x) after 1 }",
                         "iota a: inp(int)/1 -> { actions inp(x) }", "cannot have a after clause"),
    "input_with_within": ("iota a: inp(int)/1 -> { actions inp(x) within [0, 1] }",
                          "iota a: inp(int)/1 -> { actions inp(x) }", "cannot have a within clause"),
    "within_upper_below_lower": ("iota a: -> out()/1 { actions out() within [2, 1] }",
                                 "iota a: -> out()/1 { actions out() within [1, 2] }", "upper bound is below"),
    "within_upper_below_lower_param": ("iota a(float T = 0.5): -> out()/1 { actions out() within [1, T] }",
                                       "iota a(float T = 1.5): -> out()/1 { actions out() within [1, T] }",
                                       "within [1, 0.5]"),
    "negative_within": ("iota a: -> out()/1 { actions out() within [-1, 2] }",
                        "iota a: -> out()/1 { actions out() within [0, 2] }", "must be >= 0, got -1"),
    "negative_after": ("iota a: -> out()/1 { actions out() after -0.5 }",
                       "iota a: -> out()/1 { actions out() after 0.5 }", "must be >= 0, got -0.5"),
    "bound_twice": (PINGPONG + "iota pair: -> { include ping a; pong b; a.out -> b.inp; b.out -> b.inp; b.out -> a.inp; }",
                    PINGPONG + "iota pair: -> { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; }",
                    "b.inp is bound twice"),
    "input_never_bound": (PINGPONG + "iota pair: -> { include ping a; pong b; a.out -> b.inp; }",
                          PINGPONG + "iota pair: -> { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; }",
                          "input a.inp is never bound"),
    "interface_never_bound": (PINGPONG + "iota pair: -> served()/0 { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; }",
                              PINGPONG + "iota pair: -> served()/0 { include ping a; pong b; a.out -> b.inp; "
                                         "b.out -> a.inp; b.out -> served; }",
                              "output served of pair is never bound"),
    "binding_direction": (PINGPONG + "iota pair: -> { include ping a; pong b; b.inp -> a.out; a.out -> b.inp; b.out -> a.inp; }",
                          PINGPONG + "iota pair: -> { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; }",
                          "b.inp is an input"),
    "interface_switching_in": (LEAF + "iota top: go(int)/5 -> out(int)/0 { include leaf a; go -> a.go; a.out -> out; }",
                               LEAF + "iota top: go(int)/0 -> out(int)/0 { include leaf a; go -> a.go; a.out -> out; }",
                               "go has switching time 5 but it is a.go, whose switching time is 0"),
    "interface_switching_out": (LEAF + "iota top: go(int)/0 -> out(int)/2 { include leaf a; go -> a.go; a.out -> out; }",
                                LEAF + "iota top: go(int)/0 -> out(int)/0 { include leaf a; go -> a.go; a.out -> out; }",
                                "out has switching time 2 but it is a.out, whose switching time is 0"),
    "array_length_literal": ("iota a: -> out()/1 { states float v[3] = 0.0; actions out() do v = {1.0, 2.0}; }",
                             "iota a: -> out()/1 { states float v[3] = 0.0; actions out() do v = {1.0, 2.0, 3.0}; }",
                             "float[3] has 3 elements, not 2"),
    "array_length_assign": ("iota a: -> out()/1 { states float v[3] = 0.0, w[2] = 0.0; actions out() do v = w; }",
                            "iota a: -> out()/1 { states float v[3] = 0.0, w[3] = 0.0; actions out() do v = w; }",
                            "cannot assign float[2] to float[3]"),
    "include_cycle": ("iota a: -> { include a inner; }", "iota b: -> { } iota a: -> { include b inner; }",
                      "includes itself"),
    "assign_to_parameter": ("iota a(int N = 1): -> out()/1 { actions out() do N = 2; }",
                            "iota a(int N = 1): -> out()/1 { states int n = 0; actions out() do n = 2; }",
                            "N is a parameter"),
    "family_without_index": ("iota a(int N = 2): -> out[N]()/1 { actions out() }",
                             "iota a(int N = 2): -> out[N]()/1 { actions (i=0; i<N; i++) out[i]() }",
                             "out is a family"),
    "output_without_value": ("iota a: -> out(int)/1 { actions out() }",
                             "iota a: -> out(int)/1 { actions out(0) }", "give its value"),
    "duplicate": ("iota a: -> out()/1 { states int n, n; }", "iota a: -> out()/1 { states int n, m; }",
                  "n is already declared"),
    "extern_arity": ("extern int f(int) = \"builtins:abs\"; iota a: -> out(int)/1 { actions out(f(1, 2)) }",
                     "extern int f(int) = \"builtins:abs\"; iota a: -> out(int)/1 { actions out(f(-1)) }",
                     "f takes 1 argument(s), not 2"),
    "extern_missing": ("extern int f(int) = \"no_such_module_xyz:f\"; iota a: -> { }",
                       "extern int f(int) = \"builtins:abs\"; iota a: -> { }", "cannot load no_such_module_xyz:f"),
}

WARNINGS = {
    "never_enabled_member": ("enum e { A, B }; iota a: -> out()/1 { states enum e s = A; actions out() when s == B }",
                             "enum e { A, B }; iota a: -> out()/1 { states enum e s = A; actions out() when s == B "
                             "do s = A; in2() do s = B; } ",
                             "can never be enabled: nothing ever sets a value to B"),
    "faster_than_its_reader": (PINGPONG.replace("inp()/0 -> out()/0 { states bool", "inp()/2 -> out()/0 { states bool")
                               + "iota pair: -> { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; }",
                               PINGPONG + "iota pair: -> { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; }",
                               "a.out may send every 0 but b.inp takes an input at most every 2"),
    "never_enabled_false": ("iota a: -> out()/1 { actions out() when 1 > 2 }",
                            "iota a: -> out()/1 { actions out() when 2 > 1 }", "precondition is always false"),
}


@pytest.mark.parametrize("name", sorted(CHECKS))
def test_check_trips_and_passes(name):
    bad, good, message = CHECKS[name]
    errors, _ = check_text(bad, f"{name}.iota")
    assert errors, f"{name}: the bad spec passed"
    assert message in errors[0].message, str(errors[0])
    errors, warnings = check_text(good, f"{name}.iota")
    assert errors == [], "\n".join(map(str, errors))


@pytest.mark.parametrize("name", sorted(WARNINGS))
def test_warning_trips_and_passes(name):
    bad, good, message = WARNINGS[name]
    if name == "never_enabled_member":  # the good one needs an input that sets B
        good = "enum e { A, B }; iota a: go()/0 -> out()/1 { states enum e s = A; " \
               "actions go() do s = B; out() when s == B do s = A; }"
    errors, warnings = check_text(bad)
    assert errors == [] and any(message in w.message for w in warnings), warnings
    load_text(bad)  # a warning never stops a load
    errors, warnings = check_text(good)
    assert errors == [] and warnings == []


def test_enum_arriving_on_an_input_may_hold_anything():
    spec = ("enum e { A, B }; struct m { enum e v; }; iota a: inp(struct m)/0 -> out()/1 "
            "{ states struct m s = { .v = A }; actions inp(x) do s = x; out() when s.v == B }")
    assert check_text(spec) == ([], [])


def test_unbound_component_output_is_a_warning():
    spec = PINGPONG + "iota solo: -> { include ping a; pong b; a.out -> b.inp; b.out -> a.inp; ping c; b.out -> c.inp; }"
    errors, warnings = check_text(spec)
    assert errors == []
    assert any("output c.out is bound to nothing" in w.message for w in warnings)


def test_error_format_names_position_and_shows_caret():
    text = "iota a: -> out(int)/1 {\n  actions\n  out(nope)\n}\n"
    with pytest.raises(EspritError) as info:
        load_text(text, "spec.iota")
    lines = str(info.value).split("\n")
    assert lines[0] == "spec.iota:3:7: undeclared name nope"
    assert lines[1].strip() == "out(nope)"
    assert lines[2].index("^") == lines[1].index("nope")
    assert (info.value.line, info.value.col) == (3, 7)


def test_all_errors_are_listed():
    errors, _ = check_text("iota a: -> out(int)/1 { states bool b = 1; actions out(y) }")
    assert [e.message for e in errors] == ["b holds bool; the initial value is int", "undeclared name y"]


@pytest.mark.parametrize("text,where,message", [
    ("iota a: -> out()/1 { actions out() when x == }", (1, 46), "unexpected '}'"),
    ("iota a: -> out()/1 {", (1, 21), "unexpected end of file"),
    ("iota a: -> out()/1 { $ }", (1, 22), "unexpected character '$'"),
    ("iota a: -> out()/1 { /* never closed\n actions out() }", (1, 22), "comment /* ... is never closed by */"),
    ("iota a: -> out()/1 { actions out() when 4 /* never closed }", (1, 43), "comment /* ... is never closed by */"),
    ("iota a: -> out()/1 { actions out() do { for (i = 0; j < 3; i++) {} } }", (1, 53), "a for loop counts one variable"),
])
def test_syntax_errors(text, where, message):
    with pytest.raises(EspritError) as info:
        load_text(text, "s.iota")
    assert (info.value.line, info.value.col) == where
    assert message in str(info.value)


def test_cli_check_exit_codes(tmp_path, capsys):
    bad = tmp_path / "bad.iota"
    bad.write_text("iota a: -> out()/1 {\n  actions out() within [3, 1]\n}\n")
    assert cli.main(["spec", "check", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:2:28: within [3, 1]: the upper bound is below the lower one" in err
    assert "Traceback" not in err and "^" in err
    warn = tmp_path / "warn.iota"
    warn.write_text("iota a: -> out()/1 { actions out() when false }\n")
    assert cli.main(["spec", "check", str(warn)]) == 0
    captured = capsys.readouterr()
    assert "warning: out can never be enabled" in captured.err and "ok (1 warning(s))" in captured.out
    assert cli.main(["spec", "check", str(tmp_path / "missing.iota")]) == 2
    assert "cannot read" in capsys.readouterr().err


@pytest.mark.parametrize("n, why", [("-3", "array length must be a whole number >= 0, got -3"),
                                     ("99999999999999999999999", "is past the limit of 1000000 elements")])
def test_cli_check_warns_of_default_parameters_that_build_nothing(tmp_path, capsys, n, why):
    spec = tmp_path / "family.iota"
    spec.write_text(f"iota a(int N = {n}): -> out[N]()/1 {{\n  states int count[N] = 0;\n"
                    f"  actions (i=0; i<N; i++) out[i]() after 1 do {{ count[i] = count[i] + 1; }}\n}}\n")
    assert cli.main(["spec", "check", str(spec)]) == 0
    captured = capsys.readouterr()
    assert f"warning: iota a cannot be built with its default parameters" in captured.err and why in captured.err
    assert "a system file must give it others" in captured.err and "ok (1 warning(s))" in captured.out
    assert cli.main(["spec", "run", str(spec), "--until", "1", "--param", "N=2"]) == 0  # other values build it


@pytest.mark.parametrize("text, why", [
    ("iota x: a()/0 -> b()/0 { states int v in [0, 5] = 10; actions a() do v = 1; }",
     "initial value of v: ValueError: v = 10 is outside its declared range [0, 5]"),
    ("const int N = 9223372036854775807 * 4;\niota x: a[N]()/0 -> b()/0 { actions (i=0; i<N; i++) a[i]() do {} }",
     "size of a is 36893488147419103228; a channel family has at most 10000 members"),
])
def test_cli_check_refuses_an_iota_without_parameters_that_cannot_be_built(tmp_path, capsys, text, why):
    # no parameter could change how it is built: a warning and exit 0 passed a spec nothing can run
    spec = tmp_path / "never.iota"
    spec.write_text(text + "\n")
    assert cli.main(["spec", "check", str(spec)]) == 2
    err = capsys.readouterr().err
    assert "error: iota x cannot be built" in err and why in err and "no parameters that could change that" in err
    assert "1 iota(s) that nothing can build" in err and "Traceback" not in err


@pytest.mark.parametrize("params, says", [
    ({"T": -1.0}, "within [0, -1]: the upper bound is below the lower one (with T = -1.0)"),
    ({"D": -2.0}, "a time bound must be >= 0, got -2 (with D = -2.0)"),
])
def test_parameters_that_make_a_window_empty_are_refused_when_the_iota_is_built(params, says):
    # checked with the defaults by the static checks, and again with the values an instance
    # gets: `iotad run --check` said ok, and every window of the run was a bad_window
    text = "iota a(float T = 1.0, float D = 0.5): -> out()/1, other()/1 {\n  actions\n  out() within [0, T]\n  other() after D\n}\n"
    with pytest.raises(EspritError, match=re.escape(says)):
        load_iota(text, **params)
    load_iota(text, T=2.0, D=0.0)  # values that keep the windows whole build it


def test_cli_run_errors_exit_2(tmp_path, capsys):
    spec = tmp_path / "a.iota"
    spec.write_text("iota a(int N = 1): -> out()/1 { actions out() after 1 }\n")
    assert cli.main(["spec", "run", str(spec), "--until", "1", "--param", "M=3"]) == 2
    assert "has no parameter M" in capsys.readouterr().err
    assert cli.main(["spec", "run", str(spec), "--until", "1", "--param", "oops"]) == 2
    assert "expected NAME=VALUE" in capsys.readouterr().err
    script = tmp_path / "in.jsonl"
    script.write_text("{not json\n")
    assert cli.main(["spec", "run", str(spec), "--until", "1", "--inputs", str(script)]) == 2
    assert "not JSON" in capsys.readouterr().err
    assert cli.main(["spec", "run", str(spec), "--until", "2"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines() == ['{"t": 1.0, "iota": "a", "action": "out", "index": null, "kind": "output", "value": null}',
                                '{"t": 2.0, "iota": "a", "action": "out", "index": null, "kind": "output", "value": null}']


def test_an_interface_switching_time_from_a_parameter_is_compared_when_built():
    """The composite's interface channel is its component's channel, so the engine enforces the
    component's switching time: an interface that says otherwise would promise what nothing does
    (an input at 1 s accepted by a top declared /5). Parameters are compared when it is built."""
    spec = LEAF.replace("go(int)/0", "go(int)/S").replace("iota leaf:", "iota leaf(float S = 0):") + \
        "iota top(float S = 5): go(int)/S -> out(int)/0 { include leaf a(S = S); go -> a.go; a.out -> out; }"
    module = load_text(spec)
    module.iotas["top"]()  # both 5
    wrong = spec.replace("include leaf a(S = S)", "include leaf a(S = 1)")
    with pytest.raises(EspritError, match=r"input go of top has switching time 5 but it is a\.go \(leaf\), "
                                          r"whose switching time is 1"):
        load_text(wrong).iotas["top"]()


def test_a_state_array_of_structs_counts_every_value_against_the_limit():
    spec = "struct a { float q[1000]; }; iota t(int N = 10): go()/0 -> { states struct a s[N]; actions go() }"
    make = load_text(spec).iotas["t"]
    assert len(make(N=1000).s) == 1000  # 1e6 values: at the limit
    with pytest.raises(EspritError, match="2000 elements of 1000 values each are past the limit of 1000000"):
        make(N=2000)


def test_a_spec_saved_with_a_byte_order_mark_reads_as_without_it(tmp_path, capsys):
    # editors on Windows write one; it was "1:1: unexpected character" under an invisible caret
    spec = tmp_path / "bom.iota"
    spec.write_bytes(b"\xef\xbb\xbfiota x: -> b()/0 { actions b() after 1 }\n")
    assert cli.main(["spec", "check", str(spec)]) == 0
    assert "ok (0 warning(s))" in capsys.readouterr().out
    spec.write_bytes(b"\xef\xbb\xbfiota x: -> b()/0 { actions b() aftr 1 }\n")
    assert cli.main(["spec", "check", str(spec)]) == 2
    assert f"{spec}:1:37: unexpected '1'" in capsys.readouterr().err  # columns as an editor counts them
