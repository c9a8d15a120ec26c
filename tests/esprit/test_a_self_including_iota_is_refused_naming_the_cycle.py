"""An IOTA that includes itself, directly or through another, is refused with one error that
names the cycle, before anything its inclusion part says of that component: its inputs left
unbound there were reported first ("input c.inp is never bound"), and `iotad run --check` and
load_iota show only the first error. A component that is no part of a cycle is still checked."""
import pytest

from iotad.esprit import EspritError, check_text, load_text

LEAF = "iota leaf: inp(int)/0 -> out(int)/0 { states int v = 0; actions inp(x) do v = x; out(v) when v > 0 do v = 0; }\n"

DIRECT = """iota top: inp(int)/0 -> out(int)/0 {
  include
    top c;
    c.out -> out;
  actions
    inp(x) do { }
}
"""

THROUGH = LEAF + """iota outer: inp(int)/0 -> out(int)/0 {
  include
    inner i;
    leaf a;
    inp -> a.inp;
    i.out -> out;
}
iota inner: inp(int)/0 -> out(int)/0 {
  include
    outer o;
    inp -> o.inp;
    o.out -> out;
}
"""


def test_an_iota_that_includes_itself_gets_one_error_naming_it():
    errors, _ = check_text(DIRECT, "top.iota")
    assert [e.message for e in errors] == [
        "iota top includes itself (through top -> top): an IOTA cannot be one of its own components"]
    assert "top.iota:3:5" in str(errors[0])


def test_a_cycle_through_another_is_named_with_every_iota_on_it():
    errors, _ = check_text(THROUGH, "loop.iota")
    messages = [e.message for e in errors]
    assert messages == [
        "iota outer includes itself (through outer -> inner -> outer): an IOTA cannot be one of its own components",
        "iota inner includes itself (through inner -> outer -> inner): an IOTA cannot be one of its own components"]
    assert not any("never bound" in m for m in messages)


def test_loading_it_raises_the_cycle_first():
    with pytest.raises(EspritError) as raised:
        load_text(DIRECT, "top.iota")
    assert "includes itself (through top -> top)" in str(raised.value).splitlines()[0]


def test_an_unbound_input_of_a_component_outside_any_cycle_is_still_an_error():
    errors, _ = check_text(LEAF + "iota top: inp(int)/0 -> out(int)/0 { include leaf a; a.out -> out; "
                                  "actions inp(x) do { } }\n")
    assert [e.message for e in errors] == ["input a.inp is never bound: it could never fire"]
