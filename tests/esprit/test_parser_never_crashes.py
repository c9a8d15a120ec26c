"""Fuzzing the ESPRIT front end: mutated specs load or fail with an EspritError that names a
position, never with any other exception (and never with an internal compiler error)."""
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from iotad.esprit import EspritError, load_text

ROOT = Path(__file__).resolve().parents[2]
SEEDS = [
    (ROOT / "nodes" / "scheduler" / "scheduler.iota").read_text(encoding="utf-8"),
    """
    struct p { float x, y; int a[2]; };
    const struct p ZERO = { 0, 0, {1, 2} };
    iota inner(float D = 0.5): inp(int)/0 -> out(int)/0 {
      states int v = 0; bool full = false;
      actions inp(x) do { v = x * 2 % 7; full = true; }
      out(v / 2) when full ∧ (v ≥ 0 → true) within [0, D] do { full = false; }
    }
    iota outer(int N = 2): go()/0 -> tick(int)/0, total(int)/0 {
      states int k[N] = 0; struct p q = ZERO;
      include inner c(D = 1); tick -> c.inp; c.out -> total;
      actions go() do { for (j = 0; j < N; j++) { if (k[j] != 0 ∧ ¬false) k[j] = -k[j]; else q.a[0] = j; } }
      tick(k[0] + 3) when k[0] == 0 || q.x < 1.0 after 1 do { k[0] = 1; q.x = q.x + 1; }
    }
    """,
]
# Pieces a mutation may insert: tokens of the language, near-misses and junk.
PIECES = ["{", "}", "(", ")", "[", "]", ";", ",", ".", "->", "→", "∧", "¬", "==", "=", "/", "*", "-", "0",
          "1.5", "1e400", "inf", "NULL", "N", "x", "i", "int", "float", "struct", "enum", "iota", "states",
          "channels", "include", "actions", "when", "after", "within", "do", "if", "else", "for", "extern",
          "const", "void", "true", "\"", "//", "/*", "\n", " ", "9" * 30, "request", "status", "€", "\t",
          "(i=0; i<N; i++)", "within [2, 1]", "after -1", "{ .x = 1 }", "a.b[0]"]


@st.composite
def mutated(draw):
    text = draw(st.sampled_from(SEEDS))
    for _ in range(draw(st.integers(1, 4))):
        start = draw(st.integers(0, len(text)))
        end = min(len(text), start + draw(st.integers(0, 12)))
        choice = draw(st.integers(0, 3))
        if choice == 0:  # delete a slice
            text = text[:start] + text[end:]
        elif choice == 1:  # insert a piece
            text = text[:start] + draw(st.sampled_from(PIECES)) + text[start:]
        elif choice == 2:  # replace a slice with random characters
            text = text[:start] + draw(st.text(max_size=6)) + text[end:]
        else:  # duplicate a slice
            text = text[:end] + text[start:end] + text[end:]
    return text


@settings(max_examples=400, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated())
def test_mutated_specs_raise_only_esprit_errors(text):
    try:
        module = load_text(text, "fuzz.iota")
    except EspritError as exc:
        message = str(exc)
        assert message.startswith("fuzz.iota:"), message
        assert "internal compiler error" not in message, message
        assert "^" in message
        return
    for factory in module.iotas.values():  # instantiating with defaults fails only as EspritError
        try:
            factory()
        except EspritError as exc:
            assert "internal compiler error" not in str(exc)


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=80))
def test_arbitrary_text_raises_only_esprit_errors(text):
    try:
        load_text(text, "any.iota")
    except EspritError as exc:
        assert str(exc).startswith("any.iota:")
