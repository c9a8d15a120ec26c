"""Static checks of an ESPRIT program: names, types, clauses, windows, bindings, dead actions.

The checker also builds what the compiler needs: the kernel value types of structs and enums,
constant values, extern signatures, and for each IOTA its parameters, state and channels. It
annotates every expression with its type (`expr.type`) and every name with what it denotes
(`name.kind`). Errors are collected, not raised one by one, so `iotad spec check` can list them
all; warnings (actions that can never be enabled, outputs bound to nothing) never stop a load.
"""
from __future__ import annotations

import keyword
import math
from dataclasses import dataclass, field
from typing import Any, Callable

from iotad.kernel.types import INT_MAX, INT_MIN, ArrayType, Bool, EnumType, Float, Int, StructType, Type

from . import syntax as S
from .errors import Diagnostic, Source
from .typesys import (MAX_ELEMENTS, NULL_T, VOID, ArrayOf, assignable, comparable, describe, element_count,
                      element_of, has_null_member, is_bool, is_int, is_number, same)

# Instance attributes the kernel uses: a state variable or parameter may not take these names.
_RESERVED = {"iota_spec", "instance_name"}
_ARITH = {"+", "-", "*", "/", "%"}
_ORDER = {"<", "<=", ">", ">="}
_LOGIC = {"&&", "||", "->"}
# Built-in functions: name -> parameter list. now() is the time of the firing; reset() and
# inhibit(d) are the statements of Brooks' module inputs (docs/esprit.md).
BUILTINS = {"now": (), "reset": (), "inhibit": ("d",)}
# The internal channels the compiler adds for them, so no spec may declare these names.
HIDDEN_CHANNELS = {"reset": "restarted", "inhibit": "uninhibit"}


class NotConstant(Exception):
    """An expression that cannot be evaluated before the IOTA runs."""


@dataclass
class Extern:
    name: str
    returns: Any
    params: list
    function: Callable | None
    decl: S.ExternDecl


@dataclass
class ChanInfo:
    decl: S.ChanDecl
    direction: str
    type: Type | None
    size: int | str | None       # a number or a parameter name
    switching: float | str


@dataclass
class IotaInfo:
    decl: S.IotaDecl
    params: dict[str, tuple[Any, Any]] = field(default_factory=dict)   # name -> (type, default)
    states: dict[str, tuple[Any, S.Declarator, Any]] = field(default_factory=dict)  # (type, decl, element)
    channels: dict[str, ChanInfo] = field(default_factory=dict)
    components: dict[str, S.InstanceDecl] = field(default_factory=dict)
    uses_reset: bool = False     # a do-block calls the built-in reset()
    uses_inhibit: bool = False   # a do-block calls the built-in inhibit(d)
    # the time bounds that depend on parameters and constants only, [(lower, upper or None)]:
    # checked here with the defaults, and again by the factory with the values an instance gets
    constant_windows: list = field(default_factory=list)
    fold: Any = None             # fold(expr, params): the value of such a bound


@dataclass
class Checked:
    structs: dict[str, StructType] = field(default_factory=dict)
    enums: dict[str, EnumType] = field(default_factory=dict)
    members: dict[str, EnumType] = field(default_factory=dict)
    consts: dict[str, tuple[Any, Any]] = field(default_factory=dict)  # name -> (type, value)
    externs: dict[str, Extern] = field(default_factory=dict)
    iotas: dict[str, IotaInfo] = field(default_factory=dict)
    errors: list[Diagnostic] = field(default_factory=list)
    warnings: list[Diagnostic] = field(default_factory=list)


class _Scope:
    """Names visible in one clause: (kind, type) per name, innermost first."""

    def __init__(self, names: dict[str, tuple[str, Any]]):
        self.names = names

    def child(self, **more: tuple[str, Any]) -> "_Scope":
        return _Scope({**self.names, **more})

    def get(self, name: str):
        return self.names.get(name)


class Checker:
    def __init__(self, source: Source, resolve_extern: Callable[[S.ExternDecl], Callable | None]):
        self.source = source
        self.resolve_extern = resolve_extern
        self.out = Checked()
        # Where the expression being checked sits ("when", "value", "bound", "do"; None outside
        # an action), and whose actions: now() and the built-in statements depend on both.
        self._where: str | None = None
        self._info: IotaInfo | None = None
        self._cyclic: set[str] = set()  # IOTAs that include themselves (check() finds them first)

    # ---------------------------------------------------------------- reporting
    def error(self, pos, message: str) -> None:
        self.out.errors.append(self.source.diagnostic(pos, message))

    def warn(self, pos, message: str) -> None:
        self.out.warnings.append(self.source.diagnostic(pos, message, "warning"))

    def _fresh(self, name: str, pos, what: str, taken: dict) -> bool:
        if name in taken:
            self.error(pos, f"{name} is already declared ({taken[name]})")
            return False
        return True

    # ---------------------------------------------------------------- program
    def check(self, program: S.Program) -> Checked:
        taken: dict[str, str] = {}  # module-level names: structs, enums, members, consts, externs
        iotas = [d for d in program.decls if isinstance(d, S.IotaDecl)]
        for decl in program.decls:
            if isinstance(decl, S.StructDecl):
                self._struct(decl, taken)
            elif isinstance(decl, S.EnumDecl):
                self._enum(decl, taken)
            elif isinstance(decl, S.ConstDecl):
                self._const(decl, taken)
            elif isinstance(decl, S.ExternDecl):
                self._extern(decl, taken)
            elif isinstance(decl, S.ExternTypeDecl):
                self._extern_type(decl)
        for decl in iotas:
            if decl.name in self.out.iotas:
                self.error(decl.pos, f"iota {decl.name} is declared twice")
                continue
            self.out.iotas[decl.name] = IotaInfo(decl)
        for decl in iotas:
            info = self.out.iotas.get(decl.name)
            if info is not None and info.decl is decl:
                self._interface(info)
        # cycles first: an IOTA that includes itself cannot be built, and what its inclusion
        # part says of that component (an input never bound...) would only mislead
        self._cyclic = self._include_cycles()
        for info in self.out.iotas.values():
            self._body(info)
        return self.out

    # ---------------------------------------------------------------- types
    def type_of(self, ref: S.TypeRef | None, allow_void: bool = False):
        if ref is None:
            return None
        if ref.kind == "int":
            return Int
        if ref.kind == "float":
            return Float
        if ref.kind == "bool":
            return Bool
        if ref.kind == "void":
            if not allow_void:
                self.error(ref.pos, "void is only a return type of an extern function")
            return VOID
        struct, enum = self.out.structs.get(ref.name), self.out.enums.get(ref.name)
        if ref.kind == "struct" and struct is None or ref.kind == "enum" and enum is None \
                or ref.kind == "named" and struct is None and enum is None:
            what = {"struct": "struct ", "enum": "enum "}.get(ref.kind, "type ")
            self.error(ref.pos, f"undeclared {what}{ref.name}")
            return None
        return struct if ref.kind == "struct" or (ref.kind == "named" and struct is not None) else enum

    def _with_range(self, base, rng, pos):
        if rng is None or base is None:
            return base
        if not is_number(base):
            self.error(pos, f"only int and float values have ranges, not {describe(base)}")
            return base
        try:
            low, high = (self.fold(e, {}) for e in rng)
        except NotConstant:
            self.error(rng[0].pos, "a range needs constant bounds")
            return base
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (low, high)):
            self.error(rng[0].pos, "a range's bounds are numbers")
            return base
        if low > high:
            self.error(rng[0].pos, f"empty range [{low}, {high}]")
            return base
        low = None if low == -math.inf else low
        high = None if high == math.inf else high
        return base(low, high)

    def _struct(self, decl: S.StructDecl, taken) -> None:
        if not self._fresh(decl.name, decl.pos, "struct", {**self.out.structs, **self.out.enums}):
            return
        fields: dict[str, Type] = {}
        for var in decl.fields:
            base = self.type_of(var.type)
            for d in var.declarators:
                if d.name.startswith("_") or keyword.iskeyword(d.name):
                    self.error(d.pos, f"{d.name} cannot name a field (reserved)")
                    continue
                if d.name in fields:
                    self.error(d.pos, f"struct {decl.name} has two fields named {d.name}")
                    continue
                if d.init is not None:
                    self.error(d.init.pos, "a struct field has no initial value (give one to the state variable)")
                ftype = self._with_range(base, d.range, d.pos)
                if d.size is not None:
                    try:
                        length = self.fold(d.size, {})
                    except NotConstant:
                        self.error(d.size.pos, "an array field needs a constant length")
                        continue
                    if isinstance(length, bool) or not isinstance(length, int) or length < 0:
                        self.error(d.size.pos, f"array length must be a whole number >= 0, got {length!r}")
                        continue
                    ftype = None if ftype is None else ArrayType(ftype, length)
                if ftype is not None:
                    fields[d.name] = ftype
        struct = StructType(decl.name, **fields)
        count = element_count(struct)
        if count > MAX_ELEMENTS:
            self.error(decl.pos, f"struct {decl.name} holds {count} values in all, past the limit of "
                                 f"{MAX_ELEMENTS} (its arrays' lengths multiply)")
            return
        self.out.structs[decl.name] = struct

    def _enum(self, decl: S.EnumDecl, taken) -> None:
        if not self._fresh(decl.name, decl.pos, "enum", {**self.out.structs, **self.out.enums}):
            return
        members = []
        for name, pos in decl.members:
            if hasattr(EnumType, name) or name in ("name", "members"):
                self.error(pos, f"{name} cannot name an enum member (reserved)")
            elif name in members:
                self.error(pos, f"enum {decl.name} lists {name} twice")
            elif name != "NULL" and name in taken:
                self.error(pos, f"{name} is already declared ({taken[name]})")
            else:
                members.append(name)
        if not members:
            return
        enum = EnumType(decl.name, *members)
        self.out.enums[decl.name] = enum
        for name in members:
            if name != "NULL":  # NULL is a keyword: it becomes the member by context
                self.out.members[name] = enum
                taken[name] = f"a member of enum {decl.name}"

    def _const(self, decl: S.ConstDecl, taken) -> None:
        ctype = self.type_of(decl.type)
        if not self._fresh(decl.name, decl.pos, "const", taken):
            return
        if ctype is None:
            return
        vtype = self.expr(decl.value, self._module_scope(), ctype)
        if vtype is not None and not assignable(ctype, vtype):
            self.error(decl.value.pos, f"{decl.name} is {describe(ctype)}; the value is {describe(vtype)}")
            return
        try:
            value = self.fold(decl.value, {})
        except NotConstant:
            self.error(decl.value.pos, "a const needs a constant value (numbers, constants, members, NULL)")
            return
        taken[decl.name] = "a constant"
        self.out.consts[decl.name] = (ctype, value)

    def _extern(self, decl: S.ExternDecl, taken) -> None:
        returns = self.type_of(decl.returns, allow_void=True)
        params = [self.type_of(p) for p in decl.params]
        if decl.name in BUILTINS:
            self.error(decl.pos, f"{decl.name} is a built-in function of ESPRIT; give the extern another name")
            return
        if not self._fresh(decl.name, decl.pos, "extern", taken):
            return
        taken[decl.name] = "an extern function"
        function = self.resolve_extern(decl)  # reports its own errors
        self.out.externs[decl.name] = Extern(decl.name, returns, params, function, decl)

    def _extern_type(self, decl: S.ExternTypeDecl) -> None:
        """`extern struct NAME = "module:OBJECT";`: OBJECT must be a value type named NAME (so that
        payloads and recordings name it alike). It goes with the structs: `struct NAME` (or
        `NAME`) then denotes it; having no fields the spec can see, it is only stored, copied,
        compared and sent."""
        from pathlib import Path

        from iotad.kernel.python_loader import load_object

        if not self._fresh(decl.name, decl.pos, "struct", {**self.out.structs, **self.out.enums}):
            return
        filename = self.source.filename
        base = Path(filename).resolve().parent if not filename.startswith("<") else Path.cwd()
        try:
            found = load_object(decl.target, base)
        except Exception as exc:  # noqa: BLE001 - any failure to import is the spec's error
            self.error(decl.pos, f"extern struct {decl.name}: cannot load {decl.target}: {exc}")
            return
        if not isinstance(found, Type):
            self.error(decl.pos, f"extern struct {decl.name}: {decl.target} is a {type(found).__name__}, "
                                 "not a value type (iotad.kernel.types.Type)")
            return
        if found.name != decl.name:
            self.error(decl.pos, f"extern struct {decl.name}: {decl.target} is the type {found.name!r}; "
                                 f"name it {found.name}")
            return
        self.out.structs[decl.name] = found

    def _module_scope(self) -> _Scope:
        names = {name: ("const", t) for name, (t, _) in self.out.consts.items()}
        names.update({m: ("member", e) for m, e in self.out.members.items()})
        return _Scope(names)

    # ---------------------------------------------------------------- constants
    def fold(self, expr: S.Expr, env: dict[str, Any]) -> Any:
        """The value of a constant expression; names look in `env` (parameters), constants,
        enum members. Raises NotConstant otherwise."""
        if isinstance(expr, (S.Number, S.BoolLit)):
            return expr.value
        if isinstance(expr, S.Null):
            return "NULL" if has_null_member(expr.type) else None
        if isinstance(expr, S.Name):
            if expr.id in env:
                return env[expr.id]
            if expr.id in self.out.consts:
                ctype, value = self.out.consts[expr.id]
                return ctype.copy(value) if isinstance(ctype, (StructType, ArrayType)) else value
            if expr.id in self.out.members:
                return expr.id
            raise NotConstant()
        if isinstance(expr, S.Unary):
            value = self.fold(expr.operand, env)
            return -value if expr.op == "-" else not value
        if isinstance(expr, S.Binary):
            left, right = self.fold(expr.left, env), self.fold(expr.right, env)
            try:
                return _apply(expr.op, left, right, both_int=is_int(expr.left.type) and is_int(expr.right.type))
            except (ArithmeticError, TypeError, ValueError):
                raise NotConstant() from None
        if isinstance(expr, S.Aggregate) and isinstance(expr.type, StructType):
            values = {}
            names = expr.type.field_names
            for position, (name, item) in enumerate(expr.items):
                values[name or names[position]] = self.fold(item, env)
            return expr.type(**values)
        if isinstance(expr, S.Aggregate) and isinstance(expr.type, (ArrayType, ArrayOf)):
            return [self.fold(item, env) for _, item in expr.items]
        if isinstance(expr, S.FieldOf):
            return getattr(self.fold(expr.obj, env), expr.name)
        raise NotConstant()

    # ---------------------------------------------------------------- IOTA interface
    def _interface(self, info: IotaInfo) -> None:
        decl = info.decl
        module = self._module_scope()
        for p in decl.params:
            ptype = self.type_of(p.type)
            if self._bad_attribute_name(p.name, p.pos) or p.name in info.params:
                if p.name in info.params:
                    self.error(p.pos, f"parameter {p.name} is declared twice")
                continue
            if module.get(p.name):
                self.error(p.pos, f"{p.name} is already declared ({module.get(p.name)[0]})")
                continue
            if ptype is not None and not isinstance(ptype, (type(Int), type(Float), type(Bool), EnumType)):
                self.error(p.type.pos, "a parameter is an int, float, bool or enum")
                continue
            vtype = self.expr(p.default, module, ptype)
            if ptype is not None and vtype is not None and not assignable(ptype, vtype):
                self.error(p.default.pos, f"parameter {p.name} is {describe(ptype)}; its default is {describe(vtype)}")
            try:
                default = self.fold(p.default, {})
            except NotConstant:
                self.error(p.default.pos, "a parameter's default must be constant")
                default = None
            info.params[p.name] = (ptype, default)
        for chan in decl.inputs + decl.outputs + decl.channels:
            self._channel(info, chan)

    def _bad_attribute_name(self, name: str, pos) -> bool:
        if keyword.iskeyword(name) or name in _RESERVED or name.startswith("_"):
            self.error(pos, f"{name} is a reserved name")
            return True
        return False

    def _channel(self, info: IotaInfo, chan: S.ChanDecl) -> None:
        if chan.name in info.channels:
            self.error(chan.pos, f"channel {chan.name} is declared twice")
            return
        ctype = self._with_range(self.type_of(chan.type), chan.range, chan.pos)
        if isinstance(ctype, ArrayOf):  # pragma: no cover - the grammar gives no array channels
            ctype = None
        size = chan.size
        if isinstance(size, str):
            if size in info.params:
                if not is_int(info.params[size][0]):
                    self.error(chan.size_pos, f"the size of {chan.name} must be an int parameter")
            elif size in self.out.consts and isinstance(self.out.consts[size][1], int):
                size = self.out.consts[size][1]
            else:
                self.error(chan.size_pos, f"undeclared size {size} (a parameter or an int constant)")
                size = None
        switching = chan.switching
        if isinstance(switching, str):
            if switching in info.params:
                if not is_number(info.params[switching][0]):
                    self.error(chan.pos, f"the switching time of {chan.name} must be a number parameter")
            elif switching in self.out.consts and is_number(self.out.consts[switching][0]):
                switching = float(self.out.consts[switching][1])
            else:
                self.error(chan.pos, f"undeclared switching time {switching} (a parameter or a constant)")
                switching = 0.0
        if not isinstance(switching, str) and not switching >= 0:
            self.error(chan.pos, f"the switching time of {chan.name} must be >= 0")
            switching = 0.0
        info.channels[chan.name] = ChanInfo(chan, chan.direction, ctype, size, switching)

    # ---------------------------------------------------------------- IOTA body
    def _body(self, info: IotaInfo) -> None:
        decl = info.decl
        names: dict[str, tuple[str, Any]] = dict(self._module_scope().names)
        names.update({p: ("param", t) for p, (t, _) in info.params.items()})
        defaults = {p: v for p, (_, v) in info.params.items()}
        for var in decl.states:
            base = self.type_of(var.type)
            for d in var.declarators:
                if self._bad_attribute_name(d.name, d.pos):
                    continue
                if d.name in names or d.name in info.states:
                    self.error(d.pos, f"{d.name} is already declared ({names.get(d.name, ('a state variable',))[0]})")
                    continue
                element = self._with_range(base, d.range, d.pos)
                vtype = element
                if d.size is not None:
                    stype = self.expr(d.size, _Scope(names), Int)
                    length = None
                    if stype is not None and not is_int(stype):
                        self.error(d.size.pos, f"an array length is an int, not {describe(stype)}")
                    else:
                        try:  # a constant length is judged here; one from a parameter when it is given
                            length = self.fold(d.size, {})
                        except NotConstant:
                            length = None
                        if isinstance(length, int) and length < 0:
                            self.error(d.size.pos, f"array length must be a whole number >= 0, got {length}")
                            length = None
                    vtype = None if element is None else ArrayOf(element, length if isinstance(length, int) else None)
                if d.init is not None and element is not None:
                    # `x[N] = v` sets every element to v; `x[N] = {a, b}` gives them one by one
                    target = vtype if isinstance(d.init, S.Aggregate) and d.size is not None else element
                    itype = self.expr(d.init, _Scope(names), target)
                    if itype is not None and not assignable(target, itype):
                        self.error(d.init.pos, f"{d.name} holds {describe(target)}; the initial value is {describe(itype)}")
                elif d.init is not None:
                    self.expr(d.init, _Scope(names), None)
                names[d.name] = ("state", vtype)
                info.states[d.name] = (vtype, d, element)
        self._check_windows_static = defaults
        scope = _Scope(names)
        self._info = info
        info.fold = self.fold
        self._actions(info, scope, defaults)
        self._info = None
        for builtin, hidden in HIDDEN_CHANNELS.items():
            if getattr(info, f"uses_{builtin}") and hidden in info.channels:
                self.error(info.channels[hidden].decl.pos, f"{hidden} is the internal channel {builtin}() adds; "
                                                          "name this channel otherwise")
        self._inclusion(info)
        self._never_enabled(info)

    def _actions(self, info: IotaInfo, scope: _Scope, defaults: dict) -> None:
        inputs_seen: dict[str, S.ActionDecl] = {}
        for action in info.decl.actions:
            chan = info.channels.get(action.channel)
            if chan is None:
                self.error(action.pos, f"undeclared channel {action.channel}")
                continue
            inner = scope
            if chan.size is not None:
                if action.index_var is None:
                    self.error(action.pos, f"{action.channel} is a family: write {action.channel}[i] "
                                           "inside actions (i=0; i<N; i++)")
                    continue
                if action.index_var != action.family_var:
                    self.error(action.index_pos, f"{action.index_var} is not the index of an enclosing "
                                                 f"actions ({action.index_var}=0; ...) family")
                    continue
                if scope.get(action.index_var):
                    self.error(action.index_pos, f"index {action.index_var} hides {scope.get(action.index_var)[0]} "
                                                 f"{action.index_var}")
                    continue
                inner = scope.child(**{action.index_var: ("index", Int)})
            elif action.index_var is not None:
                self.error(action.index_pos, f"{action.channel} is not a family; it takes no index")
                continue
            if chan.direction == "input":
                self._input_action(action, chan, inner, inputs_seen)
            else:
                self._local_action(action, chan, inner, defaults)

    def _input_action(self, action: S.ActionDecl, chan: ChanInfo, scope: _Scope, seen: dict) -> None:
        if action.channel in seen:
            self.error(action.pos, f"input {action.channel} already has an input action")
        seen[action.channel] = action
        for kind in ("when", "after", "within"):
            if kind in action.clause_pos:
                self.error(action.clause_pos[kind], f"input action {action.channel} cannot have a {kind} "
                                                    "clause: inputs are always enabled and cannot be blocked")
        if action.arg is not None and not isinstance(action.arg, S.Name):
            self.error(action.arg.pos, f"an input action names its value: {action.channel}(x)")
            return
        if action.arg is not None and chan.type is None:
            self.error(action.arg.pos, f"input {action.channel} carries no value")
            return
        if action.arg is not None:
            if scope.get(action.arg.id):
                self.error(action.arg.pos, f"{action.arg.id} is already declared ({scope.get(action.arg.id)[0]})")
                return
            action.arg.kind, action.arg.type = "binder", chan.type
            scope = scope.child(**{action.arg.id: ("binder", chan.type)})
        if action.do is not None:
            self._where = "do"
            self.stmt(action.do, scope)
            self._where = None

    def _local_action(self, action: S.ActionDecl, chan: ChanInfo, scope: _Scope, defaults: dict) -> None:
        if action.arg is None and chan.type is not None:
            self.error(action.pos, f"output {action.channel} carries {describe(chan.type)}: give its value, "
                                   f"{action.channel}(...)")
        elif action.arg is not None and chan.type is None:
            self.error(action.arg.pos, f"{action.channel} carries no value")
        elif action.arg is not None:
            self._where = "value"
            vtype = self.expr(action.arg, scope, chan.type)
            if vtype is not None and not assignable(chan.type, vtype):
                self.error(action.arg.pos, f"{action.channel} carries {describe(chan.type)}, not {describe(vtype)}")
        if action.when is not None:
            self._where = "when"
            wtype = self.expr(action.when, scope, Bool)
            if wtype is not None and not is_bool(wtype):
                self.error(action.when.pos, f"a when clause is a bool condition, not {describe(wtype)}")
        bounds = []
        for bound in ([action.lower] if action.time_kind == "after" else [action.lower, action.upper]):
            if bound is None:
                continue
            self._where = "bound"
            btype = self.expr(bound, scope, Float)
            if btype is not None and not is_number(btype):
                self.error(bound.pos, f"a time bound is a number, not {describe(btype)}")
                continue
            try:
                bounds.append((bound, float(self.fold(bound, defaults))))
            except (NotConstant, TypeError, ValueError):
                bounds.append((bound, None))
        for bound, value in bounds:
            if value is not None and value < 0:
                self.error(bound.pos, f"a time bound must be >= 0, got {value:g}")
        if action.time_kind == "within" and len(bounds) == 2:
            (_, low), (upper_expr, high) = bounds
            if low is not None and high is not None and high < low:
                self.error(upper_expr.pos, f"within [{low:g}, {high:g}]: the upper bound is below the lower one")
        if self._info is not None and bounds and all(value is not None for _, value in bounds):
            self._info.constant_windows.append((bounds[0][0], bounds[1][0] if len(bounds) == 2 else None))
        if action.do is not None:
            self._where = "do"
            self.stmt(action.do, scope)
        self._where = None

    # ---------------------------------------------------------------- inclusion part
    def _inclusion(self, info: IotaInfo) -> None:
        decl = info.decl
        if not decl.has_include:
            return
        for inst in decl.instances:
            target = self.out.iotas.get(inst.iota)
            if target is None:
                self.error(inst.pos, f"undeclared iota {inst.iota}")
                continue
            if inst.name in info.components:
                self.error(inst.pos, f"two components named {inst.name}")
                continue
            info.components[inst.name] = inst
            outer = _Scope({**self._module_scope().names,
                            **{p: ("param", t) for p, (t, _) in info.params.items()}})
            given = set()
            for name, value, pos in inst.args:
                if name in given:
                    self.error(pos, f"parameter {name} is given twice")
                    continue
                given.add(name)
                if name not in target.params:
                    self.error(pos, f"iota {inst.iota} has no parameter {name} (it has {sorted(target.params) or 'none'})")
                    continue
                ptype = target.params[name][0]
                vtype = self.expr(value, outer, ptype)
                if ptype is not None and vtype is not None and not assignable(ptype, vtype):
                    self.error(value.pos, f"parameter {name} of {inst.iota} is {describe(ptype)}, not {describe(vtype)}")
        own_handled = {a.channel for a in decl.actions}
        bound_inputs: dict[tuple, S.BindDecl] = {}
        used: set[tuple] = set()
        for bind in decl.bindings:
            src = self._endpoint(info, bind.source, "output")
            dst = self._endpoint(info, bind.target, "input")
            if src is None or dst is None:
                continue
            (src_key, src_chan), (dst_key, dst_chan) = src, dst
            if (src_chan.type is None) != (dst_chan.type is None) or (
                    src_chan.type is not None and src_chan.type.json_schema() != dst_chan.type.json_schema()):
                self.error(bind.pos, f"{bind.source} carries {describe(src_chan.type) if src_chan.type else 'nothing'}, "
                                     f"{bind.target} {describe(dst_chan.type) if dst_chan.type else 'nothing'}")
            if src_key[0] is not None and dst_key[0] is not None and isinstance(src_chan.switching, float) \
                    and isinstance(dst_chan.switching, float) and src_chan.switching < dst_chan.switching:
                self.warn(bind.pos, f"{bind.source} may send every {src_chan.switching:g} but {bind.target} takes an "
                                    f"input at most every {dst_chan.switching:g}: what comes sooner is refused "
                                    "(a switching_time violation)")
            outer, inner = (src, dst) if src_key[0] is None else (dst, src) if dst_key[0] is None else (None, None)
            if outer is not None and inner[0][0] is not None and isinstance(outer[1].switching, float) \
                    and isinstance(inner[1].switching, float) and outer[1].switching != inner[1].switching:
                # parameters are compared when it is built (compiler.IotaFactory); numbers here
                self.error(bind.pos, f"{outer[0][1]} has switching time {outer[1].switching:g} but it is "
                                     f"{inner[0][0]}.{inner[0][1]}, whose switching time is {inner[1].switching:g}: "
                                     "a channel bound to a component's is that channel; give both the same")
            used.add(src_key)
            used.add(dst_key)
            whole, index = dst_key[:2], dst_key[2]
            clash = [k for k in bound_inputs if k[:2] == whole and (k[2] is None or index is None or k[2] == index)]
            if clash:
                self.error(bind.target.pos, f"{bind.target} is bound twice (also at line {bound_inputs[clash[0]].pos[0]})")
            bound_inputs[dst_key] = bind
        for name, inst in info.components.items():
            target = self.out.iotas.get(inst.iota)
            for chan in target.channels.values():
                if chan.direction == "internal":
                    continue
                if not any(k[:2] == (name, chan.decl.name) for k in used):
                    if inst.iota in self._cyclic:
                        continue  # the cycle is the error (said once, above)
                    if chan.direction == "input":
                        self.error(inst.pos, f"input {name}.{chan.decl.name} is never bound: it could never fire")
                    else:
                        self.warn(inst.pos, f"output {name}.{chan.decl.name} is bound to nothing")
        for chan in info.channels.values():
            if chan.direction != "internal" and chan.decl.name not in own_handled \
                    and not any(k[:2] == (None, chan.decl.name) for k in used):
                self.error(chan.decl.pos, f"{chan.direction} {chan.decl.name} of {decl.name} is never bound to a "
                                          "component and has no action of its own")

    def _endpoint(self, info: IotaInfo, ref: S.EndpointRef, want: str):
        """Checks one side of a binding; returns ((child, channel, index), ChanInfo)."""
        if ref.child is None:
            chan = info.channels.get(ref.channel)
            if chan is None or chan.direction == "internal":
                self.error(ref.pos, f"{ref.channel} is not a channel of {info.decl.name}'s interface")
                return None
            # The IOTA's own input feeds a component's input; a component's output is its output.
            if chan.direction == want:
                handled = any(a.channel == ref.channel for a in info.decl.actions)
                if not handled:
                    self.error(ref.pos, f"{ref.channel} is an {chan.direction} of {info.decl.name}: "
                                        f"{'it receives from' if want == 'input' else 'it sends to'} a component, "
                                        "so put it on the other side of ->")
                    return None
        else:
            inst = info.components.get(ref.child)
            if inst is None:
                self.error(ref.pos, f"no component {ref.child}")
                return None
            target = self.out.iotas[inst.iota]
            chan = target.channels.get(ref.channel)
            if chan is None or chan.direction == "internal":
                self.error(ref.pos, f"iota {inst.iota} has no external channel {ref.channel}")
                return None
            if chan.direction != want:
                self.error(ref.pos, f"{ref} is an {chan.direction}; the {'left' if want == 'output' else 'right'} "
                                    f"side of a binding is an {want}")
                return None
        if ref.index is not None:
            if chan.size is None:
                self.error(ref.pos, f"{ref.channel} is not a family; it takes no index")
                return None
            if isinstance(chan.size, int) and ref.index >= chan.size:
                self.error(ref.pos, f"{ref} is out of range ({ref.channel} has {chan.size} members)")
                return None
        return (ref.child, ref.channel, ref.index), chan

    def _include_cycles(self) -> set[str]:
        """Report each IOTA that includes itself, directly or through others, naming the cycle;
        return their names. From the declarations, before any body is checked."""
        cyclic: set[str] = set()

        def visit(name: str, path: list[str]) -> None:
            info = self.out.iotas.get(name)
            if info is None:
                return
            for inst in info.decl.instances:
                if inst.iota == path[0]:
                    cyclic.add(path[0])
                    self.error(inst.pos, f"iota {path[0]} includes itself (through {' -> '.join(path + [inst.iota])}): "
                                         "an IOTA cannot be one of its own components")
                elif inst.iota not in path:  # a cycle that does not pass path[0] is reported from its own start
                    visit(inst.iota, path + [inst.iota])
        for name in self.out.iotas:
            visit(name, [name])
        return cyclic

    # ---------------------------------------------------------------- dead actions
    def _never_enabled(self, info: IotaInfo) -> None:
        """Warn about actions whose precondition can never hold: constant false, or a conjunct
        `v == M` for an enum member M that nothing ever stores (no assignment, initial value,
        constant or input can produce it)."""
        produced = self._produced_members(info)
        for action in info.decl.actions:
            chan = info.channels.get(action.channel)
            if action.when is None or chan is None or chan.direction == "input" or action.when.type is None:
                continue
            try:
                if self.fold(action.when, {}) is False:
                    self.warn(action.when.pos, f"{action.channel} can never be enabled: its precondition is always false")
                    continue
            except NotConstant:
                pass
            for conjunct in _conjuncts(action.when):
                if isinstance(conjunct, S.Binary) and conjunct.op == "==":
                    for side in (conjunct.left, conjunct.right):
                        if isinstance(side, S.Name) and side.kind == "member":
                            enum = self.out.members[side.id]
                            if enum.name in produced and side.id not in produced[enum.name]:
                                self.warn(conjunct.pos, f"{action.channel} can never be enabled: nothing ever "
                                                        f"sets a value to {side.id}")

    def _produced_members(self, info: IotaInfo) -> dict[str, set]:
        """Per enum, the members a state cell can hold; an enum absent from the map could hold any
        (it arrives on an input, or is a parameter)."""
        open_enums: set[str] = set()

        def opens(t) -> None:
            if isinstance(t, EnumType):
                open_enums.add(t.name)
            elif isinstance(t, StructType):
                for f in t.fields.values():
                    opens(f)
            elif isinstance(t, (ArrayType, ArrayOf)):
                opens(t.element)
        for chan in info.channels.values():
            if chan.direction == "input" and chan.type is not None:
                opens(chan.type)
        for ptype, _ in info.params.values():
            opens(ptype)
        for ext in self.out.externs.values():
            opens(ext.returns)
        produced: dict[str, set] = {}

        def add_value(t, value) -> None:
            if isinstance(t, EnumType) and isinstance(value, str):
                produced.setdefault(t.name, set()).add(value)
            elif isinstance(t, StructType) and value is not None:
                for name, ftype in t.fields.items():
                    add_value(ftype, getattr(value, name, None))
            elif isinstance(t, (ArrayType, ArrayOf)) and isinstance(value, list):
                for item in value:
                    add_value(t.element, item)

        def walk(node) -> None:
            if isinstance(node, (S.Name, S.Null)) and isinstance(node.type, EnumType):
                if isinstance(node, S.Null) or node.kind == "member":
                    produced.setdefault(node.type.name, set()).add("NULL" if isinstance(node, S.Null) else node.id)
            for child in S.children(node):
                walk(child)

        for _, d, element in info.states.values():
            if d.init is None:
                add_value(element, element.default() if element is not None else None)
            else:
                try:
                    add_value(element, self.fold(d.init, {p: v for p, (_, v) in info.params.items()}))
                except (NotConstant, AttributeError, TypeError):
                    opens(element)
        for action in info.decl.actions:
            if action.do is not None:
                for node in _assigned_values(action.do):
                    walk(node)
        for enum in open_enums:
            produced.pop(enum, None)
        for enum in self.out.enums.values():
            if enum.name not in open_enums:
                produced.setdefault(enum.name, set())
        return produced

    # ---------------------------------------------------------------- statements
    def stmt(self, node: S.Node, scope: _Scope) -> None:
        if isinstance(node, S.Block):
            for item in node.body:
                self.stmt(item, scope)
        elif isinstance(node, S.Assign):
            self._assign(node, scope)
        elif isinstance(node, S.CallStmt):
            if not isinstance(node.call, S.Call):
                self.error(node.pos, "a statement is an assignment, a call, if, for or a block")
                return
            self.expr(node.call, scope, None, statement=True)
        elif isinstance(node, S.If):
            ctype = self.expr(node.cond, scope, Bool)
            if ctype is not None and not is_bool(ctype):
                self.error(node.cond.pos, f"an if condition is a bool, not {describe(ctype)}")
            self.stmt(node.then, scope)
            if node.orelse is not None:
                self.stmt(node.orelse, scope)
        elif isinstance(node, S.For):
            if scope.get(node.var):
                self.error(node.pos, f"loop variable {node.var} hides {scope.get(node.var)[0]} {node.var}")
                return
            for bound in (node.start, node.stop):
                btype = self.expr(bound, scope, Int)
                if btype is not None and not is_int(btype):
                    self.error(bound.pos, f"a for loop counts with ints, not {describe(btype)}")
            self.stmt(node.body, scope.child(**{node.var: ("local", Int)}))

    def _assign(self, node: S.Assign, scope: _Scope) -> None:
        root = node.target
        while isinstance(root, (S.FieldOf, S.IndexOf)):
            root = root.obj
        if not isinstance(root, S.Name):
            self.error(node.pos, "only a state variable (or a field or element of one) can be assigned")
            return
        entry = scope.get(root.id)
        if entry is not None and entry[0] != "state":
            what = {"param": "parameter", "const": "constant", "member": "enum member", "index": "family index",
                    "binder": "input value", "local": "loop variable"}[entry[0]]
            self.error(root.pos, f"{root.id} is a {what}; only state variables can be assigned")
            return
        ttype = self.expr(node.target, scope, None)
        if ttype is None:
            self.expr(node.value, scope, None)
            return
        vtype = self.expr(node.value, scope, ttype)
        if vtype is not None and not assignable(ttype, vtype):
            self.error(node.value.pos, f"cannot assign {describe(vtype)} to {describe(ttype)}")
        elif isinstance(ttype, (ArrayOf, ArrayType)):
            # an array keeps its length: a length known only when it runs is checked then (codegen)
            node.keeps_length = True
        elif is_number(ttype):
            # a declared range holds for state too (the paper's declarations give states ranges);
            # an int's range is at most what the wire carries, so that a loop squaring an int
            # stops with a runtime_error at the first overflow instead of growing a number of
            # millions of digits (each product slower than the last: a hung node)
            low, high = ttype.low, ttype.high
            if getattr(ttype, "name", None) == "int":
                low = INT_MIN if low is None else max(low, INT_MIN)
                high = INT_MAX if high is None else min(high, INT_MAX)
            if low is not None or high is not None:
                node.within_range = (low, high)

    # ---------------------------------------------------------------- expressions
    def expr(self, node: S.Expr, scope: _Scope, expected=None, statement: bool = False):
        """Type of `node` (None after an error, which is already reported)."""
        result = self._expr(node, scope, expected, statement)
        node.type = result
        return result

    def _expr(self, node, scope, expected, statement):
        if isinstance(node, S.Number):
            return Int if isinstance(node.value, int) else Float
        if isinstance(node, S.BoolLit):
            return Bool
        if isinstance(node, S.Null):
            return expected if has_null_member(expected) else NULL_T
        if isinstance(node, S.Name):
            entry = scope.get(node.id)
            if entry is None:
                hint = " (a function is called: name(...))" if node.id in self.out.externs else ""
                self.error(node.pos, f"undeclared name {node.id}{hint}")
                return None
            node.kind = entry[0]
            return entry[1]
        if isinstance(node, S.FieldOf):
            otype = self.expr(node.obj, scope)
            if otype is None:
                return None
            if otype is NULL_T or not isinstance(otype, StructType):
                self.error(node.pos, f"{describe(otype)} has no fields (.{node.name})")
                return None
            if node.name not in otype.fields:
                self.error(node.pos, f"struct {otype.name} has no field {node.name} "
                                     f"(it has {', '.join(otype.field_names) or 'none'})")
                return None
            return otype.fields[node.name]
        if isinstance(node, S.IndexOf):
            otype = self.expr(node.obj, scope)
            itype = self.expr(node.index, scope, Int)
            if itype is not None and not is_int(itype) and itype is not NULL_T:
                self.error(node.index.pos, f"an index is an int, not {describe(itype)}")
            if otype is None:
                return None
            if element_of(otype) is None:
                self.error(node.pos, f"{describe(otype)} is not an array")
                return None
            return element_of(otype)
        if isinstance(node, S.Call):
            return self._call(node, scope, statement)
        if isinstance(node, S.Unary):
            otype = self.expr(node.operand, scope, Bool if node.op == "!" else None)
            if otype is None:
                return None
            if node.op == "!":
                if not is_bool(otype):
                    self.error(node.pos, f"! needs a bool, not {describe(otype)}")
                    return None
                return Bool
            if not is_number(otype):
                self.error(node.pos, f"- needs a number, not {describe(otype)}")
                return None
            return Int if is_int(otype) else Float
        if isinstance(node, S.Binary):
            return self._binary(node, scope)
        if isinstance(node, S.Aggregate):
            return self._aggregate(node, scope, expected)
        if isinstance(node, S.Quantifier):
            return self._quantifier(node, scope)
        raise AssertionError(f"unknown expression {node!r}")  # pragma: no cover

    def _binary(self, node: S.Binary, scope: _Scope):
        op = node.op
        if op in _LOGIC:
            types = [self.expr(side, scope, Bool) for side in (node.left, node.right)]
            for side, t in zip((node.left, node.right), types):
                if t is not None and not is_bool(t):
                    self.error(side.pos, f"{op} needs bool operands, not {describe(t)}")
                    return None
            return None if None in types else Bool
        # NULL takes its meaning from the other side: check that side first.
        if isinstance(node.left, S.Null) and not isinstance(node.right, S.Null):
            right = self.expr(node.right, scope)
            left = self.expr(node.left, scope, right)
        else:
            left = self.expr(node.left, scope)
            right = self.expr(node.right, scope, left)
        if left is None or right is None:
            return None
        if op in ("==", "!="):
            if not comparable(left, right):
                self.error(node.pos, f"cannot compare {describe(left)} with {describe(right)}")
                return None
            return Bool
        if not (is_number(left) and is_number(right)):
            self.error(node.pos, f"{op} needs numbers, not {describe(left)} and {describe(right)}")
            return None
        if op in _ORDER:
            return Bool
        if op == "%" and not (is_int(left) and is_int(right)):
            self.error(node.pos, "% needs ints")
            return None
        return Int if is_int(left) and is_int(right) else Float

    def _aggregate(self, node: S.Aggregate, scope: _Scope, expected):
        if isinstance(expected, StructType):
            names = expected.field_names
            seen = set()
            for position, (name, item) in enumerate(node.items):
                if name is None:
                    if any(n is not None for n, _ in node.items):
                        self.error(item.pos, "give every field by name (.f = v) or none")
                        return None
                    if position >= len(names):
                        self.error(item.pos, f"struct {expected.name} has only {len(names)} fields")
                        return None
                    name = names[position]
                if name not in expected.fields:
                    self.error(item.pos, f"struct {expected.name} has no field {name}")
                    return None
                if name in seen:
                    self.error(item.pos, f"field {name} is given twice")
                    return None
                seen.add(name)
                ftype = expected.fields[name]
                itype = self.expr(item, scope, ftype)
                if itype is not None and not assignable(ftype, itype):
                    self.error(item.pos, f"field {name} is {describe(ftype)}, not {describe(itype)}")
            return expected
        element = element_of(expected)
        if element is not None:
            if any(name is not None for name, _ in node.items):
                self.error(node.pos, "an array value lists its elements, without names")
                return None
            if getattr(expected, "length", None) is not None and len(node.items) != expected.length:
                self.error(node.pos, f"{describe(expected)} has {expected.length} elements, not {len(node.items)}")
                return None
            for _, item in node.items:
                itype = self.expr(item, scope, element)
                if itype is not None and not assignable(element, itype):
                    self.error(item.pos, f"an element is {describe(element)}, not {describe(itype)}")
            return expected
        self.error(node.pos, "a {...} value needs a struct or array where it is used")
        return None

    def _quantifier(self, node: S.Quantifier, scope: _Scope):
        if scope.get(node.var):
            self.error(node.pos, f"{node.kind} variable {node.var} hides {scope.get(node.var)[0]} {node.var}")
            return None
        for bound in (node.start, node.stop):
            btype = self.expr(bound, scope, Int)
            if btype is not None and not is_int(btype):
                self.error(bound.pos, f"a {node.kind} counts with ints, not {describe(btype)}")
        body = self.expr(node.body, scope.child(**{node.var: ("local", Int)}), Bool)
        if body is not None and not is_bool(body):
            self.error(node.body.pos, f"{node.kind} needs a bool condition, not {describe(body)}")
            return None
        return Bool

    def _builtin(self, node: S.Call, scope: _Scope, statement: bool):
        """now(), reset(), inhibit(d): see docs/esprit.md "Time, reset and inhibit"."""
        node.builtin = True
        want = BUILTINS[node.func]
        if len(node.args) != len(want):
            self.error(node.pos, f"{node.func} takes {len(want)} argument(s), not {len(node.args)}")
            return None
        for arg in node.args:
            atype = self.expr(arg, scope, Float)
            if atype is not None and not is_number(atype):
                self.error(arg.pos, f"the argument of {node.func} is a number (a time), not {describe(atype)}")
        if node.func == "now":
            if self._where not in ("do", "bound"):
                where = {"when": "a precondition (it is evaluated only when the state changes, not as time "
                                 "passes)", "value": "an output value (store it in a do-block first)"}
                self.error(node.pos, "now() is read only in do-blocks and time bounds, not in "
                                     + where.get(self._where, "a declaration"))
                return None
            return Float
        if not statement or self._where != "do":
            self.error(node.pos, f"{node.func}(...) is a statement of a do-block")
            return None
        if self._info is not None:
            if node.func == "reset":
                self._info.uses_reset = True
            else:
                self._info.uses_inhibit = True
        return VOID

    def _call(self, node: S.Call, scope: _Scope, statement: bool):
        ext = self.out.externs.get(node.func)
        if ext is None and node.func in BUILTINS:
            return self._builtin(node, scope, statement)
        if ext is None:
            for arg in node.args:
                self.expr(arg, scope)
            self.error(node.pos, f"undeclared function {node.func} (declare it: extern TYPE {node.func}(...) = \"module:function\";)")
            return None
        if len(node.args) != len(ext.params):
            self.error(node.pos, f"{node.func} takes {len(ext.params)} argument(s), not {len(node.args)}")
            return None
        for arg, ptype in zip(node.args, ext.params):
            atype = self.expr(arg, scope, ptype)
            if ptype is not None and atype is not None and not assignable(ptype, atype):
                self.error(arg.pos, f"argument of {node.func} is {describe(ptype)}, not {describe(atype)}")
        if ext.returns is VOID and not statement:
            self.error(node.pos, f"{node.func} returns nothing (void); call it as a statement")
            return None
        return ext.returns


def _apply(op: str, left, right, both_int: bool):
    from .runtime import c_div, c_mod
    if op == "+":
        return left + right
    if op == "-":
        return left - right
    if op == "*":
        return left * right
    if op == "/":
        return c_div(left, right) if both_int else left / right
    if op == "%":
        return c_mod(left, right)
    if op == "==":
        return left == right
    if op == "!=":
        return left != right
    if op in ("<", "<=", ">", ">="):
        return {"<": left < right, "<=": left <= right, ">": left > right, ">=": left >= right}[op]
    if op == "&&":
        return left and right
    if op == "||":
        return left or right
    if op == "->":
        return (not left) or right
    raise NotConstant()


def _conjuncts(expr):
    if isinstance(expr, S.Binary) and expr.op == "&&":
        return _conjuncts(expr.left) + _conjuncts(expr.right)
    return [expr]


def _assigned_values(stmt):
    """The value expressions of every assignment in a statement."""
    if isinstance(stmt, S.Assign):
        return [stmt.value]
    if isinstance(stmt, S.Block):
        return [v for s in stmt.body for v in _assigned_values(s)]
    if isinstance(stmt, S.If):
        return _assigned_values(stmt.then) + (_assigned_values(stmt.orelse) if stmt.orelse else [])
    if isinstance(stmt, S.For):
        return _assigned_values(stmt.body)
    return []
