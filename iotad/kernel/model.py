"""The IOTA model: channels, actions and the spec that holds them, independent of how it was written.

Both the Python API (`iotad.kernel.api`) and the ESPRIT compiler (`iotad.esprit`) build an `IotaSpec`;
the engine only ever sees specs and the instances that carry their state.

Functions in an action (`when`, bounds, `value`, `do`) all take `(iota, index)`: the instance
holding params and state as attributes, and the index of the family member (None for a plain
channel). `reads`/`writes` name the state cells an action's precondition reads and its do-block
may touch, so that a firing re-evaluates only the preconditions it can affect.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

from iotad.kernel.types import Type

DIRECTIONS = ("input", "output", "internal")

# A cell is (state variable, key): key INDEX means "the element at the action's own index",
# ANY means "the whole variable". ALL_STATE stands for "could read or write anything".
INDEX = "index"
ANY = "*"
ALL_STATE = frozenset({("*", ANY)})


MAX_FAMILY = 10_000  # members of one channel family (`size=`)

def by_state(name: str) -> tuple[str, str]:
    """A write key "the element indexed by state variable `name`" (`request[current_master]`).
    Only for writes, and only where the do-block assigns `name` at most once outside loops: the
    element written is then the one at its value before or after the firing, which the engine
    reads on both sides of the firing."""
    return ("state", name)


def is_by_state(key: object) -> bool:
    return isinstance(key, tuple)


class SpecError(Exception):
    """A specification is inconsistent (unknown channel, bad size, two input actions...)."""


@dataclass
class Channel:
    name: str
    direction: str
    type: Type | None = None
    switching_time: float | str = 0.0  # a number, or the name of a parameter
    size: int | str | None = None  # None: one channel; int or parameter name: a family name[N]

    def __post_init__(self) -> None:
        if self.direction not in DIRECTIONS:
            raise SpecError(f"channel {self.name}: direction must be one of {DIRECTIONS}")
        if not isinstance(self.switching_time, str) and not (self.switching_time >= 0):
            raise SpecError(f"channel {self.name}: switching time must be >= 0")

    @property
    def external(self) -> bool:
        return self.direction != "internal"


Fn = Callable[[Any, Any], Any]


@dataclass
class Action:
    """One action of a spec. Inputs have only `do`; locally controlled ones have the rest."""

    channel: str
    when: Fn | None = None        # precondition; None is "always"
    lower: Fn | None = None       # window lower bound, evaluated at enabling; None is 0
    upper: Fn | None = None       # window upper bound; None is infinity
    value: Fn | None = None       # output value, evaluated just before the do-block
    do: Fn | None = None
    reads: frozenset = ALL_STATE  # cells the precondition reads
    writes: frozenset = ALL_STATE  # cells the do-block may change
    label: str = ""               # how messages name it, e.g. "ack[i](ABORT)"
    line: int | None = None       # where it was declared, for messages

    def __post_init__(self) -> None:
        if not self.label:
            self.label = self.channel


@dataclass
class IotaSpec:
    name: str
    params: dict[str, Any] = field(default_factory=dict)
    channels: dict[str, Channel] = field(default_factory=dict)
    actions: list[Action] = field(default_factory=list)
    init: Callable[[Any], None] | None = None  # sets the initial state on an instance
    state_names: tuple[str, ...] = ()
    source: str | None = None                  # the spec's text, when it came from a file
    source_path: str | None = None

    def validate(self) -> None:
        inputs_with_action: set[str] = set()
        for action in self.actions:
            channel = self.channels.get(action.channel)
            if channel is None:
                raise SpecError(f"{self.name}: action {action.label} names unknown channel {action.channel}")
            if channel.direction == "input":
                if action.channel in inputs_with_action:
                    raise SpecError(f"{self.name}: input channel {action.channel} has two input actions")
                if action.when or action.lower or action.upper or action.value:
                    raise SpecError(f"{self.name}: input action {action.label} cannot have when, "
                                    "time or value clauses (inputs cannot be blocked)")
                inputs_with_action.add(action.channel)
            elif channel.type is not None and action.value is None:
                raise SpecError(f"{self.name}: action {action.label} on typed channel "
                                f"{channel.name} ({channel.type}) needs a value")
            elif channel.type is None and action.value is not None:
                raise SpecError(f"{self.name}: action {action.label} gives a value, but channel "
                                f"{channel.name} carries none")
        for channel in self.channels.values():
            if isinstance(channel.size, str) and channel.size not in self.params:
                raise SpecError(f"{self.name}: channel {channel.name}[{channel.size}] names unknown parameter")
            if isinstance(channel.switching_time, str) and channel.switching_time not in self.params:
                raise SpecError(f"{self.name}: channel {channel.name}/{channel.switching_time} names unknown parameter")

    def switching_of(self, channel: Channel, params: dict[str, Any]) -> float:
        value = channel.switching_time
        if isinstance(value, str):
            if value not in params:
                raise SpecError(f"{self.name}: switching time of {channel.name} names unknown parameter {value}")
            value = params[value]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
            raise SpecError(f"{self.name}: switching time of {channel.name} must be a number >= 0, got {value!r}")
        return float(value)

    def size_of(self, channel: Channel, params: dict[str, Any]) -> int | None:
        if channel.size is None:
            return None
        size = params[channel.size] if isinstance(channel.size, str) else channel.size
        if not isinstance(size, int) or isinstance(size, bool) or size < 0:
            raise SpecError(f"{self.name}: size of {channel.name} must be a whole number >= 0, got {size!r}")
        if size > MAX_FAMILY:
            # every member is an action instance the engine evaluates: a million of them takes
            # seconds to build and is almost surely a slip of the keyboard
            raise SpecError(f"{self.name}: size of {channel.name} is {size}; a channel family has at most "
                            f"{MAX_FAMILY} members")
        return size


class Instance:
    """A running copy of a spec: parameters and state live here as attributes."""

    def __init__(self, spec: IotaSpec, name: str | None = None, **params: Any):
        object.__setattr__(self, "iota_spec", spec)
        object.__setattr__(self, "instance_name", name or spec.name)
        apply_params(self, spec, params)
        if spec.init:
            spec.init(self)


def apply_params(obj: Any, spec: IotaSpec, overrides: dict[str, Any]) -> None:
    unknown = set(overrides) - set(spec.params)
    if unknown:
        raise SpecError(f"{spec.name} has no parameter(s) {sorted(unknown)}; "
                        f"it has {sorted(spec.params) or 'none'}")
    for name, default in spec.params.items():
        value = overrides.get(name, default)
        if name in overrides:
            problem = param_kind_problem(default, value)
            if problem:
                raise SpecError(f"{spec.name}: parameter {name}: {problem}")
        object.__setattr__(obj, name, value)


def param_kind_problem(default: Any, value: Any) -> str:
    """Why `value` cannot stand for a parameter whose default is `default` ("" when it can): no
    text, flag or NaN for a number, nothing but true or false for a flag. Other kinds are the
    IOTA's own business (a number's default may take a list of one per joint, a list's a table).
    Said before the IOTA runs, not as a fault inside it."""
    if isinstance(default, bool):
        return "" if isinstance(value, bool) else f"expected true or false (its default is {default!r}), got {value!r}"
    if isinstance(default, (int, float)):
        if isinstance(value, (str, bool)):
            return f"expected a number (its default is {default!r}), got {value!r}"
        if isinstance(value, float) and math.isnan(value):
            return f"expected a number (its default is {default!r}), got NaN"
    return ""


def param_values(obj: Any) -> dict[str, Any]:
    return {name: getattr(obj, name) for name in obj.iota_spec.params}


def window_ok(lower: float, upper: float) -> bool:
    return 0 <= lower <= upper and not math.isnan(lower) and not math.isnan(upper)
