"""Compiles a checked ESPRIT program onto the kernel model: one IotaSpec per IOTA (actions as
Python closures over generated code), and a factory per IOTA that makes ready instances (an
`Instance`, or a `Composite` for an IOTA with an inclusion part)."""
from __future__ import annotations

import types as pytypes
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from iotad.kernel.compose import Composite
from iotad.kernel.model import Action, Channel, Instance, IotaSpec, SpecError
from iotad.kernel.types import BadValue, BoolType, EnumType, FloatType, IntType, StructType

from . import codegen
from . import syntax as S
from .static_checks import Checked, IotaInfo
from .errors import EspritError, Source
from .runtime import (all_of, any_of, c_div, c_mod, cp, esprit_inhibit, esprit_now, esprit_reset, fresh_budget,
                      in_range, inhibit_left, ix, ix_set, loop_range, restarted, same_length, uninhibit, with_budget)
from .typesys import MAX_ELEMENTS, VOID, ArrayOf, describe, element_count

MAX_ARRAY = MAX_ELEMENTS  # elements of one state array: more is a slip (a parameter off by powers of ten)


@dataclass
class Module:
    """A loaded spec file: its IOTAs (name -> factory), types, constants and warnings."""

    path: str
    text: str
    iotas: dict[str, "IotaFactory"] = field(default_factory=dict)
    structs: dict[str, StructType] = field(default_factory=dict)
    enums: dict[str, EnumType] = field(default_factory=dict)
    consts: dict[str, Any] = field(default_factory=dict)
    warnings: list = field(default_factory=list)

    def factory(self, iota: str | None = None) -> "IotaFactory":
        if not self.iotas:
            raise EspritError(Source(self.text, self.path).diagnostic(None, "the file declares no iota"))
        if iota is None:
            return list(self.iotas.values())[-1]
        if iota not in self.iotas:
            raise EspritError(Source(self.text, self.path).diagnostic(
                None, f"no iota {iota} in this file (it has {', '.join(self.iotas)})"))
        return self.iotas[iota]


class IotaFactory:
    """Makes instances of one IOTA: `factory(name=None, **params)`."""

    def __init__(self, module: Module, info: IotaInfo, spec: IotaSpec | None, source: Source,
                 arg_fns: dict[str, list[tuple[str, Callable, tuple]]], bindings: dict):
        self.module, self.info, self.spec, self.source = module, info, spec, source
        self.name = info.decl.name
        self.params = {p: default for p, (_, default) in info.params.items()}
        self.composite = info.decl.has_include
        self._arg_fns, self._bindings = arg_fns, bindings

    def __repr__(self) -> str:
        return f"<ESPRIT iota {self.name}>"

    def _check_windows(self, values: dict[str, Any]) -> None:
        """The time bounds that depend on parameters only, checked with these values as the
        static checks did with the defaults: `within [0, T]` with T = -1 is an error when the
        IOTA is built (`iotad run --check`), not a bad_window at every enabling of the run."""
        changed = ", ".join(f"{name} = {value!r}" for name, value in values.items() if value != self.params.get(name))
        for lower, upper in self.info.constant_windows:
            try:
                low = float(self.info.fold(lower, values))
                high = None if upper is None else float(self.info.fold(upper, values))
            except Exception:  # noqa: BLE001 - not foldable with these values: the run says what fails
                continue
            if not low >= 0:
                raise self.source.error(lower.pos, f"a time bound must be >= 0, got {low:g} (with {changed})")
            if high is not None and not high >= low:
                raise self.source.error(upper.pos, f"within [{low:g}, {high:g}]: the upper bound is below the "
                                                   f"lower one (with {changed})")

    def check_params(self, params: dict[str, Any]) -> dict[str, Any]:
        """Parameter values checked against their declared types (an int param takes no 2.5)."""
        decl = self.info.decl
        out = dict(self.params)
        for name, value in params.items():
            if name not in self.info.params:
                raise self.source.error(decl.pos, f"iota {self.name} has no parameter {name} "
                                                  f"(it has {', '.join(self.params) or 'none'})")
            ptype = self.info.params[name][0]
            pos = next(p.pos for p in decl.params if p.name == name)
            try:
                out[name] = coerce(ptype, value)
            except BadValue as exc:
                raise self.source.error(pos, f"parameter {name}: {exc}") from None
        for name, value in out.items():
            if value is None:  # its default did not compile; already an error
                raise self.source.error(decl.pos, f"parameter {name} has no value")
        return out

    def __call__(self, name: str | None = None, **params: Any) -> Any:
        values = self.check_params(params)
        if values != self.params:
            self._check_windows(values)
        instance_name = name or self.name
        own = None
        if self.spec is not None:
            try:
                own = Instance(self.spec, instance_name, **values)
            except SpecError as exc:
                raise self.source.error(self.info.decl.pos, str(exc)) from None
        if not self.composite:
            return own
        scope = pytypes.SimpleNamespace(**values)
        components = []
        component_values = {}
        for inst_name, args in self._arg_fns.items():
            inst = self.info.components[inst_name]
            given = {}
            for arg_name, fn, pos in args:
                try:
                    given[arg_name] = fn(scope, None)
                except Exception as exc:  # noqa: BLE001 - a bad argument is the spec's error
                    raise self.source.error(pos, f"{arg_name}: {type(exc).__name__}: {exc}") from None
            factory = self.module.iotas[inst.iota]
            components.append(factory(inst_name, **given))
            component_values[inst_name] = (factory, factory.check_params(given))
        self._check_mapped_switching(values, component_values)
        try:
            return Composite(instance_name, *components, bind=self._bindings["bind"],
                             inputs=self._bindings["inputs"], outputs=self._bindings["outputs"], own=own)
        except SpecError as exc:
            raise self.source.error(self.info.decl.pos, str(exc)) from None

    def switching_of(self, channel: str, values: dict[str, Any]) -> float:
        """The switching time of one of its channels, with parameters `values`."""
        switching = self.info.channels[channel].switching
        return float(values[switching] if isinstance(switching, str) else switching)

    def _check_mapped_switching(self, values: dict[str, Any], components: dict[str, tuple]) -> None:
        """A channel of the composite bound to a component's channel IS that channel (the
        engine runs the component's): it must declare the same switching time, or the
        interface would promise what nothing enforces (an input accepted sooner than it says)."""
        for bind in self.info.decl.bindings:
            for own, inner, want in ((bind.source, bind.target, "input"), (bind.target, bind.source, "output")):
                if own.child is not None or inner.child is None or \
                        self.info.channels[own.channel].direction != want:
                    continue
                factory, inner_values = components[inner.child]
                mine = self.switching_of(own.channel, values)
                theirs = factory.switching_of(inner.channel, inner_values)
                if mine != theirs:
                    raise self.source.error(
                        self.info.channels[own.channel].decl.pos,
                        f"{want} {own.channel} of {self.name} has switching time {mine:g} but it is "
                        f"{inner.child}.{inner.channel} ({factory.name}), whose switching time is {theirs:g}: "
                        "a channel bound to a component's is that channel; give both the same")


def coerce(ptype, value: Any) -> Any:
    if isinstance(ptype, BoolType):
        if not isinstance(value, bool):
            raise BadValue(f"expected bool, got {value!r}")
        return value
    if isinstance(ptype, IntType):
        if isinstance(value, bool) or not isinstance(value, int):
            raise BadValue(f"expected int, got {value!r}")
    elif isinstance(ptype, FloatType):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise BadValue(f"expected float, got {value!r}")
        value = float(value)
    ptype.check(value)
    return value


class Compiler:
    def __init__(self, checked: Checked, source: Source):
        self.checked, self.source = checked, source
        self.globals: dict[str, Any] = {"ix": ix, "ix_set": ix_set, "same_length": same_length, "in_range": in_range,
                                        "cp": cp, "c_div": c_div, "c_mod": c_mod,
                                        "all_of": all_of, "any_of": any_of, "loop_range": loop_range,
                                        "fresh_budget": fresh_budget, "esprit_now": esprit_now,
                                        "esprit_reset": esprit_reset, "esprit_inhibit": esprit_inhibit,
                                        "INF": float("inf"), "__builtins__": {"range": range}}
        for name, struct in checked.structs.items():
            self.globals[f"T_{name}"] = struct
        for name, (_, value) in checked.consts.items():
            self.globals[f"k_{name}"] = value
        for name, ext in checked.externs.items():
            self.globals[f"x_{name}"] = _extern_wrapper(ext)

    def module(self) -> Module:
        module = Module(self.source.filename, self.source.text, structs=dict(self.checked.structs),
                        enums=dict(self.checked.enums),
                        consts={n: v for n, (_, v) in self.checked.consts.items()},
                        warnings=list(self.checked.warnings))
        for name, info in self.checked.iotas.items():
            module.iotas[name] = self._factory(module, info)
        return module

    # ---------------------------------------------------------------- code
    def _function(self, name: str, args: str, body: list[str]) -> Callable:
        if with_budget("\n".join(body)):
            body = ["fresh_budget()", *body]  # its loops' budget (runtime.LOOP_BUDGET)
        code = f"def {name}({args}):\n" + "\n".join("    " + line for line in body) + "\n"
        namespace: dict[str, Any] = {}
        exec(compile(code, f"<esprit {self.source.filename}>", "exec"), self.globals, namespace)  # noqa: S102
        fn = namespace[name]
        fn.esprit_source = code  # for debugging a spec: what it compiled to
        return fn

    def _expr_fn(self, name: str, node: S.Expr | None) -> Callable | None:
        if node is None:
            return None
        return self._function(name, "iota, index", [f"return {codegen.expr(node)}"])

    # ---------------------------------------------------------------- IOTAs
    def _factory(self, module: Module, info: IotaInfo) -> IotaFactory:
        decl = info.decl
        mapped = self._mapped_channels(info)
        spec = self._spec(info, exclude=mapped)
        has_own = bool(spec.actions or spec.state_names or spec.channels)
        bindings = {"bind": [], "inputs": {}, "outputs": {}}
        arg_fns: dict[str, list] = {}
        if decl.has_include:
            for inst in decl.instances:
                arg_fns[inst.name] = [(n, self._expr_fn("arg", e), pos) for n, e, pos in inst.args]
            for bind in decl.bindings:
                src, dst = bind.source, bind.target
                if src.child is None and info.channels[src.channel].direction == "input":
                    bindings["inputs"][src.channel] = str(dst)
                elif dst.child is None and info.channels[dst.channel].direction == "output":
                    bindings["outputs"][dst.channel] = str(src)
                else:
                    bindings["bind"].append((str(src), str(dst)))
        return IotaFactory(module, info, spec if (has_own or not decl.has_include) else None, self.source,
                           arg_fns, bindings)

    def _mapped_channels(self, info: IotaInfo) -> set[str]:
        """Interface channels that are a component's channel (no action of the IOTA's own)."""
        out = set()
        for bind in info.decl.bindings:
            for side, want in ((bind.source, "input"), (bind.target, "output")):
                if side.child is None and info.channels[side.channel].direction == want:
                    out.add(side.channel)
        return out

    def _spec(self, info: IotaInfo, exclude: set[str]) -> IotaSpec:
        decl = info.decl
        channels = {}
        for name, chan in info.channels.items():
            if name in exclude:
                continue
            channels[name] = Channel(name, chan.direction, chan.type, chan.switching, chan.size)
        actions = [self._action(info, k, a) for k, a in enumerate(decl.actions)]
        hidden = _hidden_actions(info)
        for action in hidden:
            channels[action.channel] = Channel(action.channel, "internal")
        actions += hidden
        spec = IotaSpec(decl.name, {p: d for p, (_, d) in info.params.items()}, channels, actions,
                        init=self._init(info), state_names=tuple(info.states) + _hidden_state(info),
                        source=self.source.text, source_path=self.source.filename)
        try:
            spec.validate()
        except SpecError as exc:
            raise self.source.error(decl.pos, str(exc)) from None
        return spec

    def _action(self, info: IotaInfo, number: int, action: S.ActionDecl) -> Action:
        chan = info.channels[action.channel]
        label = action.channel + (f"[{action.index_var}]" if action.index_var else "")
        prefix = f"{action.channel}_{number}"
        if chan.direction == "input":
            binder = action.arg.id if isinstance(action.arg, S.Name) else ""
            do = None
            if action.do is not None:
                do = self._function(f"{prefix}_do", "iota, index, value", codegen.stmt(action.do, 0))
            return Action(action.channel, do=do, reads=frozenset(), writes=codegen.writes(action.do),
                          label=f"{action.channel}({binder})", line=action.pos[0])
        if isinstance(action.arg, (S.Name, S.Number, S.BoolLit)) and getattr(action.arg, "kind", "member") == "member":
            label += f"({action.arg.id if isinstance(action.arg, S.Name) else action.arg.value})"
        lower = self._expr_fn(f"{prefix}_lower", action.lower)
        upper = lower if action.time_kind == "after" else self._expr_fn(f"{prefix}_upper", action.upper)
        do = None
        if action.do is not None:
            do = self._function(f"{prefix}_do", "iota, index", codegen.stmt(action.do, 0))
        # reset() and inhibit(d) hold actions back through hidden state (docs/esprit.md)
        gates, gated_reads = [], frozenset()
        if info.uses_reset:
            gates.append("not iota._resetting")
            gated_reads |= codegen.RESET_CELLS
        if info.uses_inhibit and chan.direction == "output":
            gates.append("not iota._inhibited")
            gated_reads |= codegen.INHIBIT_CELLS
        if gates:
            condition = " and ".join(gates + ([f"({codegen.expr(action.when)})"] if action.when is not None else []))
            when = self._function(f"{prefix}_when", "iota, index", [f"return {condition}"])
        else:
            when = self._expr_fn(f"{prefix}_when", action.when)
        return Action(action.channel, when=when, lower=lower, upper=upper,
                      value=self._expr_fn(f"{prefix}_value", action.arg), do=do,
                      reads=codegen.reads(action.when) | gated_reads, writes=codegen.writes(action.do),
                      label=label, line=action.pos[0])

    def _init(self, info: IotaInfo) -> Callable | None:
        steps = []
        for name, (vtype, d, element) in info.states.items():
            value_fn = self._expr_fn(f"init_{name}", d.init)
            size_fn = self._expr_fn(f"size_{name}", d.size)
            steps.append((name, vtype, element, value_fn, size_fn, d))
        hidden = _hidden_initial_state(info)
        if not steps and not hidden:
            return None
        source = self.source

        def init(iota: Any) -> None:
            for name, value in hidden.items():
                object.__setattr__(iota, name, value)
            for name, vtype, element, value_fn, size_fn, d in steps:
                try:
                    value = element.default() if value_fn is None else value_fn(iota, None)
                    if size_fn is not None:
                        length = size_fn(iota, None)
                        if isinstance(length, bool) or not isinstance(length, int) or length < 0:
                            raise ValueError(f"array length must be a whole number >= 0, got {length!r}")
                        if length > MAX_ARRAY:
                            raise ValueError(f"array length {length} is past the limit of {MAX_ARRAY} elements")
                        if length * element_count(element) > MAX_ELEMENTS:
                            raise ValueError(f"{length} elements of {element_count(element)} values each are past "
                                             f"the limit of {MAX_ELEMENTS} values")
                        if isinstance(d.init, S.Aggregate):
                            if len(value) != length:
                                raise ValueError(f"{len(value)} initial values for {length} elements")
                        else:
                            value = [cp(value) for _ in range(length)]
                    low, high = getattr(element, "low", None), getattr(element, "high", None)
                    if low is not None or high is not None:  # a declared range holds from the start
                        for item in (value if size_fn is not None else [value]):
                            in_range(item, low, high, name, then="")
                except Exception as exc:  # noqa: BLE001 - reported at the declaration
                    raise source.error(d.pos, f"initial value of {name}: {type(exc).__name__}: {exc}") from None
                object.__setattr__(iota, name, value)
        return init


def _hidden_initial_state(info: IotaInfo) -> dict[str, Any]:
    """The state reset() and inhibit(d) keep, with its initial values (names a spec cannot use)."""
    state: dict[str, Any] = {}
    if info.uses_reset:
        state["_resetting"] = False
    if info.uses_inhibit:
        state.update(_inhibited=False, _inhibit_until=float("-inf"), _inhibit_phase=0)
    return state


def _hidden_state(info: IotaInfo) -> tuple[str, ...]:
    return tuple(_hidden_initial_state(info))


def _hidden_actions(info: IotaInfo) -> list[Action]:
    """The internal actions reset() and inhibit(d) need: `restarted` fires at the instant of a
    reset and lets every action start a new window; `uninhibit` fires when an inhibition ends."""
    actions = []
    if info.uses_inhibit:
        for phase in (0, 1):  # two, so that a new inhibit(d) restarts the window (runtime.esprit_inhibit)
            actions.append(Action("uninhibit", when=_inhibited_in_phase(phase), lower=inhibit_left,
                                  upper=inhibit_left, do=uninhibit, reads=codegen.INHIBIT_CELLS,
                                  writes=codegen.INHIBIT_CELLS, label="uninhibit"))
    if info.uses_reset:
        actions.append(Action("restarted", when=lambda iota, index: iota._resetting, do=restarted,
                              lower=lambda iota, index: 0.0, upper=lambda iota, index: 0.0,
                              reads=codegen.RESET_CELLS, writes=codegen.RESET_CELLS, label="restarted"))
    return actions


def _inhibited_in_phase(phase: int) -> Callable:
    return lambda iota, index: iota._inhibited and iota._inhibit_phase == phase


def _extern_wrapper(ext) -> Callable:
    """Calls a Python function from ESPRIT: struct and array arguments are copies (the function
    cannot change the IOTA's state behind the compiler's back), and the result is checked against
    the declared return type (a dict becomes the declared struct)."""
    function, returns = ext.function, ext.returns
    copy_args = [k for k, p in enumerate(ext.params) if isinstance(p, (StructType, ArrayOf)) or hasattr(p, "element")]
    convert = returns is not None and returns is not VOID and hasattr(returns, "from_plain")

    def call(*args: Any) -> Any:
        if function is None:
            raise RuntimeError(f"extern {ext.name} has no implementation")
        if copy_args:
            args = tuple(cp(a) if k in copy_args else a for k, a in enumerate(args))
        result = function(*args)
        if not convert:
            return None if returns is VOID else result
        try:
            return returns.from_plain(result)
        except BadValue as exc:
            raise BadValue(f"extern {ext.name} returned {result!r}, not {describe(returns)}: {exc}") from None
    call.__name__ = f"x_{ext.name}"
    return call
