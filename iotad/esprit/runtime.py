"""Helpers that compiled ESPRIT code calls at run time. Each raises an ordinary exception on a
fault (index out of range, NULL index, division by zero), which the engine turns into a
`runtime_error` violation while the IOTA goes on."""
from __future__ import annotations

from typing import Any

from iotad.kernel.instant import running
from iotad.kernel.types import INT_MAX, INT_MIN, Record


def ix(sequence: Any, index: Any) -> Any:
    """`a[k]` with C bounds: no negative indices from the end, no NULL index."""
    return sequence[_checked(sequence, index)]


def ix_set(sequence: Any, index: Any, value: Any) -> None:
    sequence[_checked(sequence, index)] = value


def in_range(value: Any, low: Any, high: Any, name: str, then: str = "; it keeps its value") -> Any:
    """`value`, to store in state `name` declared `in [low, high]` (None: unbounded that side)."""
    if value is not None and not ((low is None or low <= value) and (high is None or value <= high)):
        shown = f"an int of {value.bit_length()} bits" if isinstance(value, int) and value.bit_length() > 64 \
            else repr(value)
        if (low, high) == (INT_MIN, INT_MAX):
            raise ValueError(f"{name} = {shown} overflows an int (the wire and recordings carry "
                             f"{INT_MIN}..{INT_MAX}){then}")
        raise ValueError(f"{name} = {shown} is outside its declared range [{'-inf' if low is None else low}, "
                         f"{'inf' if high is None else high}]{then}")
    return value


def same_length(old: Any, new: Any) -> Any:
    """`new`, to replace the array `old`: an array's length is its declaration's, for good."""
    if old is not None and new is not None and len(new) != len(old):
        raise ValueError(f"an array of {len(old)} elements cannot be given {len(new)}")
    return new


def _checked(sequence: Any, index: Any) -> int:
    if index is None:
        raise IndexError("index is NULL")
    if sequence is None:
        raise TypeError("indexing NULL")
    if not 0 <= index < len(sequence):
        raise IndexError(f"index {index} out of range [0, {len(sequence) - 1}]")
    return index


def c_div(left: int, right: int) -> int:
    """Integer division as in C: truncates toward zero."""
    if right == 0:
        raise ZeroDivisionError("integer division by zero")
    quotient = abs(left) // abs(right)
    return quotient if (left < 0) == (right < 0) else -quotient


def c_mod(left: int, right: int) -> int:
    if right == 0:
        raise ZeroDivisionError("integer modulo by zero")
    return left - right * c_div(left, right)


def cp(value: Any) -> Any:
    """A copy of a struct or array value, so that two cells never share one mutable value."""
    if isinstance(value, Record):
        return value._type.copy(value)
    if isinstance(value, list):
        return [cp(item) for item in value]
    return value


def field_of(value: Any, name: str) -> Any:  # pragma: no cover - kept for readable messages
    if value is None:
        raise AttributeError(f"field {name} of NULL")
    return getattr(value, name)


# ---------------------------------------------------------------- loops and quantifiers
# A spec's loops end (their bounds are evaluated once), but a bound of two billion, or loops
# nested deep, would hold the engine for hours: every evaluation of a compiled function (a
# precondition, a do-block, a value, an MDL interrupt) may enter at most this many iterations,
# the ranges of its for loops and quantifiers counted as each is entered. Past it: a runtime
# error (a recorded violation), not a hung node.
LOOP_BUDGET = 1_000_000
_left = [LOOP_BUDGET]


class LoopBudgetExceeded(RuntimeError):
    pass


def fresh_budget() -> None:
    """Called first by every compiled function that loops: its evaluation starts with the whole
    budget (one that does not loop takes none, and is not slowed by this call)."""
    _left[0] = LOOP_BUDGET


def with_budget(body: str) -> bool:
    """Whether generated code enters loops (for, forall, exists), so needs `fresh_budget()` first."""
    return "loop_range(" in body or "all_of(" in body or "any_of(" in body


def loop_range(start: int, stop: int) -> range:
    """`range(start, stop)`, its length taken from this evaluation's budget."""
    if stop > start:
        _left[0] -= stop - start
        if _left[0] < 0:
            raise LoopBudgetExceeded(f"a loop or quantifier from {start} to {stop} passes the budget of "
                                     f"{LOOP_BUDGET:,} iterations per evaluation")
    return range(start, stop)


def all_of(start: int, stop: int, body: Any) -> bool:
    """`forall (j=start; j<stop; j++) (body)`."""
    return all(body(j) for j in loop_range(start, stop))


def any_of(start: int, stop: int, body: Any) -> bool:
    """`exists (j=start; j<stop; j++) (body)`."""
    return any(body(j) for j in loop_range(start, stop))


# ---------------------------------------------------------------- time, reset, inhibit
def later_of(a: float, b: float) -> float:
    """`a - b` when positive, else 0: how long until time `a` from time `b` (an extern for specs
    whose window waits out a switching time: nodes/scheduler/resume.iota's mdl_command)."""
    return a - b if a > b else 0.0


def esprit_now() -> float:
    """`now()`: the time of the firing (or enabling) in progress, in spec time units.

    The kernel calls an action's functions as `f(iota, index)` and passes no time: time is the
    engine's: the engine running the IOTA's code in this thread (`iotad.kernel.instant`) says
    which instant it is executing. The static checks keep now() out of preconditions and output
    values, which the trace checker also evaluates outside any engine firing.
    """
    engine = running.engine
    if engine is None:
        raise RuntimeError("now() is defined only while an engine runs the IOTA")
    return float(engine.executing)


def esprit_reset(iota: Any) -> None:
    """`reset()`: every state variable back to its initial value, and every locally controlled
    action disabled until the hidden `restarted` action fires at this same instant, so that each
    window starts again as if the IOTA had just started (Brooks' reset input)."""
    init = iota.iota_spec.init
    if init is not None:
        init(iota)
    object.__setattr__(iota, "_resetting", True)


def esprit_inhibit(iota: Any, duration: float) -> None:
    """`inhibit(d)`: every output action of the IOTA disabled from now for `d` time units; an
    inhibition already running ends at the later of the two ends (the union of both).

    The hidden `uninhibit` action must then start a new window to the new end. A window starts
    again only when its precondition turns false and true, which one firing cannot do to one
    action: so `uninhibit` is two actions, enabled by the parity of `_inhibit_phase`, and each
    inhibit(d) flips it, dropping the old window and opening the new one."""
    if not duration >= 0:
        raise ValueError(f"inhibit({duration!r}): the time must be >= 0")
    until = esprit_now() + duration
    if iota._inhibited:
        until = max(until, iota._inhibit_until)
    object.__setattr__(iota, "_inhibit_until", until)
    object.__setattr__(iota, "_inhibited", True)
    object.__setattr__(iota, "_inhibit_phase", 1 - iota._inhibit_phase)


def inhibit_left(iota: Any, index: Any = None) -> float:
    """The hidden `uninhibit` action's window: it fires when the inhibition ends."""
    return max(0.0, iota._inhibit_until - esprit_now())


def uninhibit(iota: Any, index: Any = None) -> None:
    """The hidden `uninhibit` action: the inhibition is over."""
    object.__setattr__(iota, "_inhibited", False)


def restarted(iota: Any, index: Any = None) -> None:
    """The hidden `restarted` action, right after a reset(): the IOTA's actions may start again."""
    object.__setattr__(iota, "_resetting", False)
