"""The engine reads a constant time bound (`after=0.25`, `within=(0, 1)`) as a float without
calling the clause; a bound that is a function or a parameter's name is called as before. The
traces must be the same either way, under both policies, and for bounds that are not a window
(NaN, negative, lower above upper, not a number)."""
import math

import pytest

from iotad import Engine, Int, Iota, Output, Random


def ticker(lower, upper):
    """An IOTA whose one output counts its firings in the window [lower, upper], each bound as
    given (constant or function); each firing opens the next window."""

    class Ticker(Iota):
        out = Output(Int)

        def init(self):
            self.count = 0

        @out.action(value=lambda self: self.count, within=(lower, upper))
        def tick(self):
            self.count += 1

    return Ticker("ticker")


def trace(lower, upper, policy=None):
    engine = Engine(ticker(lower, upper), policy=policy)
    engine.run(3.0)
    return [(e["t"], e["iota"], e["action"], e["kind"], repr(e["value"])) for e in engine.trace]


def as_function(bound):
    return lambda self: bound


@pytest.mark.parametrize("lower, upper", [(0.25, 0.25), (0, 0.5), (0.1, math.inf), (1, 2)])
@pytest.mark.parametrize("seed", [None, 7])
def test_a_constant_window_fires_as_the_same_window_given_as_functions(lower, upper, seed):
    policy = None if seed is None else Random(seed)
    constant = trace(lower, upper, policy)
    policy = None if seed is None else Random(seed)
    assert constant == trace(as_function(lower), as_function(upper), policy)
    assert [e for e in constant if e[3] == "output"], "it never fired"


@pytest.mark.parametrize("lower, upper", [(math.nan, 1.0), (-0.5, 1.0), (0.5, 0.25), (0.1, math.nan)])
def test_a_constant_bound_that_is_no_window_is_reported_as_the_same_function_is(lower, upper):
    constant = trace(lower, upper)
    assert constant == trace(as_function(lower), as_function(upper))
    assert [e for e in constant if "bad_window" in e[4]], "no bad_window reported"


def test_a_constant_bound_that_is_not_a_number_is_a_runtime_error_as_the_same_function_is():
    constant = trace([0.5], 1.0)
    assert constant == trace(as_function([0.5]), as_function(1.0))
    assert [e for e in constant if "runtime_error" in e[4] and "time bound" in e[4]]
