"""Writing IOTAs in Python, in the shape of the paper's specifications.

    class Echo(Iota):
        inp = Input(Int, switching=1)
        out = Output(Int, switching=1)

        def init(self):
            self.pending = None

        @inp.input
        def got(self, x):
            self.pending = x

        @out.action(value=lambda self: self.pending, when=lambda self: self.pending is not None,
                    within=(0, 0.5))
        def sent(self):
            self.pending = None

Channels are class attributes; `size="N"` makes a family `name[N]` whose action functions take
the index after `self`. `after=d` is `within=(d, d)`; bounds and values may be numbers, parameter
names (`within=(0, "T")`) or functions of `(self[, i])`, evaluated when the action is enabled.
State is whatever `init` sets on `self`.
"""
from __future__ import annotations

import itertools
from typing import Any, Callable

from iotad.kernel.dependencies import cells_of, stored_attributes
from iotad.kernel.model import ALL_STATE, Action, Channel, IotaSpec, SpecError, apply_params
from iotad.kernel.types import Type

_order = itertools.count()  # declaration order of actions across all channels of a class


class Param:
    """A parameter such as N or T, with its default."""

    def __init__(self, default: Any):
        self.default = default


class _ChannelDecl:
    direction = ""

    def __init__(self, type: Type | None = None, *, switching: float | str = 0.0, size: int | str | None = None):
        self.type, self.switching, self.size = type, switching, size
        self.name = ""
        self.decls: list[tuple[int, dict]] = []

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def channel(self) -> Channel:
        switching = self.switching if isinstance(self.switching, str) else float(self.switching)
        return Channel(self.name, self.direction, self.type, switching, self.size)


class Input(_ChannelDecl):
    direction = "input"

    def input(self, fn: Callable) -> Callable:
        """The input action: `fn(self[, i], value)`, run atomically when an event arrives."""
        self.decls.append((next(_order), {"do": fn}))
        return fn


class _LocalDecl(_ChannelDecl):
    def action(self, fn: Callable | None = None, *, when: Callable | None = None, value: Any = None,
               after: Any = None, within: tuple[Any, Any] | None = None, label: str = "") -> Callable:
        """A locally controlled action on this channel; the decorated function is its do-block."""
        if after is not None and within is not None:
            raise SpecError(f"{self.name}: give `after` or `within`, not both")
        lower, upper = (after, after) if after is not None else (within or (None, None))
        clause = {"when": when, "value": value, "lower": lower, "upper": upper, "label": label}

        def register(do: Callable | None) -> Callable | None:
            self.decls.append((next(_order), dict(clause, do=do)))
            return do

        if fn is not None:
            return register(fn)
        return register

    def fires(self, **clauses: Any) -> None:
        """An action with no do-block: `ack.fires(value=..., when=...)`."""
        self.action(**clauses)(None)


class Output(_LocalDecl):
    direction = "output"


class Internal(_LocalDecl):
    direction = "internal"


def _as_fn(value: Any, family: bool, param_names: bool = True) -> Callable | None:
    """Normalise a clause to `f(iota, index)`: constants, parameter names (for time bounds; a
    string value is a constant, such as an enum member) and 1- or 2-arg functions."""
    if value is None:
        return None
    if isinstance(value, str) and param_names:
        name = value
        return lambda iota, index: getattr(iota, name)
    if not callable(value):
        constant = value
        fn = lambda iota, index: constant  # noqa: E731
        fn.iotad_constant = constant  # a time bound the engine then reads without calling it
        return fn
    if family:
        return value
    fn = value
    return _self_only(lambda iota, index: fn(iota), fn)


def _as_input_do(fn: Callable, family: bool) -> Callable:
    if family:
        return fn
    return _self_only(lambda iota, index, value: fn(iota, value), fn)


def _as_do(fn: Callable | None, family: bool) -> Callable | None:
    if fn is None or family:
        return fn
    return _self_only(lambda iota, index: fn(iota), fn)


def _self_only(wrapper: Callable, fn: Callable) -> Callable:
    """Mark `wrapper` as dropping the index: the engine then calls `fn` bound to the IOTA
    (`iotad.kernel.engine.bind`), one Python call instead of two."""
    wrapper.iotad_self_only = fn
    return wrapper


class Iota:
    """Base of IOTAs written in Python. Subclass it; instantiate with `Name(name, **params)`."""

    iota_spec: IotaSpec
    _spec_cache: IotaSpec | None = None

    def __init__(self, name: str | None = None, **params: Any):
        cls = type(self)
        spec = cls.__dict__.get("_spec_cache")
        object.__setattr__(self, "instance_name", name or cls.__name__.lower())
        declared = _params_of(cls)
        apply_params(self, IotaSpec(cls.__name__, declared), params)
        before = set(self.__dict__)
        self.init()
        state_names = tuple(k for k in self.__dict__ if k not in before)
        if spec is None:
            spec = _build_spec(cls, declared, state_names)
            cls._spec_cache = spec
        object.__setattr__(self, "iota_spec", spec)

    def init(self) -> None:
        """Set the initial state. Override it."""

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.instance_name}>"


def close_iotas(iotas) -> None:
    """Let go of what each IOTA holds (a PyBullet world), by its `close()` if it has one, as its
    process would at its end: a second build or run in this process (a test, a notebook, the
    system file's check) must not find the first one's worlds open under their keys. A close
    that fails is passed over: what it was closing for is over, and one node's fault must not
    hide the others' close nor the caller's result."""
    for iota in iotas:
        close = getattr(iota, "close", None)
        if callable(close):
            try:
                close()
            except Exception:  # noqa: BLE001 - see above
                pass


def _params_of(cls: type) -> dict[str, Any]:
    params: dict[str, Any] = {}
    for klass in reversed(cls.__mro__):
        for name, value in vars(klass).items():
            if isinstance(value, Param):
                params[name] = value.default
    return params


def _union(a: frozenset, b: frozenset) -> frozenset:
    return ALL_STATE if ALL_STATE in (a, b) else a | b


def _build_spec(cls: type, params: dict[str, Any], state_names: tuple[str, ...]) -> IotaSpec:
    decls: list[_ChannelDecl] = []
    for klass in reversed(cls.__mro__):
        decls += [v for v in vars(klass).values() if isinstance(v, _ChannelDecl)]
    channels = {d.name: d.channel() for d in decls}
    ordered = sorted((order, d, clause) for d in decls for order, clause in d.decls)
    # Every attribute is a cell, not only what `init` set: a class attribute may serve as a
    # default that a do-block later shadows. Parameters no function assigns stay constants;
    # attributes that run code when read (properties, methods) are opaque.
    opaque = frozenset(name for klass in cls.__mro__[:-1] for name, v in vars(klass).items()
                       if not isinstance(v, (Param, _ChannelDecl)) and (callable(v) or hasattr(type(v), "__get__")))
    assigned: set = set()
    for _, _, clause in ordered:
        for fn in (clause["do"], clause.get("value")):
            if callable(fn):
                assigned |= stored_attributes(fn) or frozenset()  # None: that fn writes everything
    constants = frozenset(params) - assigned

    def cells(fn: Any, writes: bool = False) -> frozenset:
        return cells_of(fn, None, opaque, constants, writes=writes) if callable(fn) else frozenset()

    actions = []
    for _, decl, clause in ordered:
        family = decl.size is not None
        if decl.direction == "input":
            do = clause["do"]
            actions.append(Action(decl.name, do=_as_input_do(do, family), reads=frozenset(),
                                  writes=cells(do, True), label=f"{decl.name}(x)",
                                  line=do.__code__.co_firstlineno))
            continue
        do = clause["do"]
        label = clause["label"] or (f"{decl.name}[i]" if family else decl.name)
        if not clause["label"] and clause["value"] is not None and not callable(clause["value"]):
            label += f"({clause['value']})"
        actions.append(Action(
            decl.name, when=_as_fn(clause["when"], family), lower=_as_fn(clause["lower"], family),
            upper=_as_fn(clause["upper"], family), value=_as_fn(clause["value"], family, param_names=False),
            do=_as_do(do, family), reads=cells(clause["when"]),
            # a value function runs once per firing, just before the do-block: what it
            # touches (`self.queue.pop(0)`) counts as written too
            writes=_union(cells(do, True), cells(clause["value"], True)), label=label,
            line=do.__code__.co_firstlineno if do else None))
    spec = IotaSpec(cls.__name__, params, channels, actions, init=None, state_names=state_names)
    spec.validate()
    return spec
