"""Turns checked ESPRIT expressions and statements into Python source, and finds the state cells
they read and write.

Compiled functions take `(iota, index)` (an input's do-block also takes `value`); the family
index variable is `index`, loop variables are `l_<name>`, constants `k_<name>`, externs
`x_<name>`, struct types `T_<name>`, and state and parameters are attributes of `iota`.
"""
from __future__ import annotations

from iotad.kernel.model import ALL_STATE, ANY, INDEX, by_state
from iotad.kernel.types import ArrayType, StructType

from . import syntax as S
from .typesys import ArrayOf, has_null_member, is_int

_PY_OP = {"==": "==", "!=": "!=", "<": "<", "<=": "<=", ">": ">", ">=": ">=", "+": "+", "-": "-", "*": "*"}


def _mutable(t) -> bool:
    return isinstance(t, (StructType, ArrayType, ArrayOf))


def expr(node: S.Expr) -> str:
    if isinstance(node, S.Number):
        value = node.value
        return "INF" if value == float("inf") else repr(value)
    if isinstance(node, S.BoolLit):
        return repr(node.value)
    if isinstance(node, S.Null):
        return "'NULL'" if has_null_member(node.type) else "None"
    if isinstance(node, S.Name):
        kind = node.kind
        if kind in ("state", "param"):
            return f"iota.{node.id}"
        if kind == "const":
            return f"k_{node.id}"
        if kind == "member":
            return repr(node.id)
        if kind == "index":
            return "index"
        if kind == "binder":
            return "value"
        if kind == "local":
            return f"l_{node.id}"
        raise AssertionError(f"unchecked name {node.id}")  # pragma: no cover
    if isinstance(node, S.FieldOf):
        return f"{expr(node.obj)}.{node.name}"
    if isinstance(node, S.IndexOf):
        if _is_family_index(node.index):
            return f"{expr(node.obj)}[index]"  # the engine's index is always in range and >= 0
        return f"ix({expr(node.obj)}, {expr(node.index)})"
    if isinstance(node, S.Call):
        if node.builtin:
            return _builtin(node)
        return f"x_{node.func}({', '.join(expr(a) for a in node.args)})"
    if isinstance(node, S.Unary):
        return f"(not {expr(node.operand)})" if node.op == "!" else f"(-{expr(node.operand)})"
    if isinstance(node, S.Binary):
        left, right, op = expr(node.left), expr(node.right), node.op
        if op == "&&":
            return f"({left} and {right})"
        if op == "||":
            return f"({left} or {right})"
        if op == "->":
            return f"((not {left}) or {right})"
        if op == "/":
            both_int = is_int(node.left.type) and is_int(node.right.type)
            return f"c_div({left}, {right})" if both_int else f"({left} / {right})"
        if op == "%":
            return f"c_mod({left}, {right})"
        return f"({left} {_PY_OP[op]} {right})"
    if isinstance(node, S.Aggregate):
        items = [(name, _fresh(item)) for name, item in node.items]
        if isinstance(node.type, StructType):
            names = node.type.field_names
            args = ", ".join(f"{name or names[k]}={code}" for k, (name, code) in enumerate(items))
            return f"T_{node.type.name}({args})"
        return f"[{', '.join(code for _, code in items)}]"
    if isinstance(node, S.Quantifier):
        # bounds evaluated once, the body for each int in [start, stop), stopping at the first
        # counter-example (forall) or witness (exists)
        helper = "all_of" if node.kind == "forall" else "any_of"
        return f"{helper}({expr(node.start)}, {expr(node.stop)}, lambda l_{node.var}: {expr(node.body)})"
    raise AssertionError(f"unknown expression {node!r}")  # pragma: no cover


def _builtin(node: S.Call) -> str:
    """now() reads the firing's time; reset() and inhibit(d) act on the whole IOTA (runtime.py)."""
    if node.func == "now":
        return "esprit_now()"
    if node.func == "reset":
        return "esprit_reset(iota)"
    return f"esprit_inhibit(iota, {expr(node.args[0])})"


def _fresh(node: S.Expr) -> str:
    """Code for a value that will be stored: struct and array values are copied."""
    code = expr(node)
    if _mutable(node.type) and not isinstance(node, (S.Aggregate, S.Call)):
        return f"cp({code})"
    return code


def _is_family_index(node: S.Expr) -> bool:
    return isinstance(node, S.Name) and node.kind == "index"


def stmt(node: S.Node, indent: int) -> list[str]:
    pad = "    " * indent
    if isinstance(node, S.Block):
        lines = [line for item in node.body for line in stmt(item, indent)]
        return lines or [pad + "pass"]
    if isinstance(node, S.Assign):
        target, value = node.target, _fresh(node.value)
        bounds = getattr(node, "within_range", None)
        if bounds is not None:  # refused before it is stored: the state keeps its value
            value = f"in_range({value}, {bounds[0]!r}, {bounds[1]!r}, {_label(target)!r})"
        if isinstance(target, S.IndexOf) and not _is_family_index(target.index):
            return [f"{pad}ix_set({expr(target.obj)}, {expr(target.index)}, {value})"]
        if getattr(node, "keeps_length", False):  # a whole array: as long as the one it replaces
            return [f"{pad}{expr(target)} = same_length({expr(target)}, {value})"]
        return [f"{pad}{expr(target)} = {value}"]
    if isinstance(node, S.CallStmt):
        return [pad + expr(node.call)]
    if isinstance(node, S.If):
        lines = [f"{pad}if {expr(node.cond)}:"] + stmt(node.then, indent + 1)
        if node.orelse is not None:
            lines += [f"{pad}else:"] + stmt(node.orelse, indent + 1)
        return lines
    if isinstance(node, S.For):
        # the bounds are evaluated once and the loop variable cannot be assigned: it terminates
        return [f"{pad}for l_{node.var} in loop_range({expr(node.start)}, {expr(node.stop)}):"] + stmt(node.body, indent + 1)
    raise AssertionError(f"unknown statement {node!r}")  # pragma: no cover


def _label(target: S.Expr) -> str:
    """How a message names an assigned state: `x`, `a[]`, `s.f`."""
    if isinstance(target, S.Name):
        return target.id
    if isinstance(target, S.IndexOf):
        return _label(target.obj) + "[]"
    if isinstance(target, S.FieldOf):
        return f"{_label(target.obj)}.{target.name}"
    return "the value"


# ---------------------------------------------------------------- cells
def reads(node: S.Expr | None) -> frozenset:
    """State cells an expression reads: (var, INDEX) for `var[i]` with i the family index, else
    (var, ANY)."""
    found: set = set()
    if node is not None:
        _reads(node, found)
    return frozenset(found)


def _reads(node: S.Expr, found: set) -> None:
    if isinstance(node, S.IndexOf) and isinstance(node.obj, S.Name) and node.obj.kind == "state" \
            and _is_family_index(node.index):
        found.add((node.obj.id, INDEX))
        return
    if isinstance(node, S.Name):
        if node.kind == "state":
            found.add((node.id, ANY))
        return
    for child in S.children(node):
        _reads(child, found)


def writes(node: S.Node | None) -> frozenset:
    """State cells a do-block may change. Externs get copies of what they are passed, so a call
    writes nothing."""
    if node is None:
        return frozenset()
    builtins = {call.func for call in _builtin_statements(node)}
    if "reset" in builtins:
        return ALL_STATE  # every state variable goes back to its initial value
    assigns = list(_assignments(node, False))
    counts: dict[str, int] = {}
    for assign, in_loop in assigns:
        root, _ = _assigned_root(assign.target)
        if isinstance(root, S.Name) and root.kind == "state":
            counts[root.id] = counts.get(root.id, 0) + (2 if in_loop else 1)  # a loop: many times
    found: set = set()
    for assign, _ in assigns:
        chain, above = _assigned_root(assign.target)
        if not (isinstance(chain, S.Name) and chain.kind == "state"):
            continue
        if isinstance(above, S.IndexOf) and _is_family_index(above.index):
            found.add((chain.id, INDEX))
        elif (isinstance(above, S.IndexOf) and isinstance(above.index, S.Name)
              and above.index.kind == "state" and counts.get(above.index.id, 0) <= 1):
            # `x[k] = ...` with k assigned at most once here: the engine reads k before and
            # after the firing to know which element changed (model.by_state)
            found.add((chain.id, by_state(above.index.id)))
        else:
            found.add((chain.id, ANY))
    if "inhibit" in builtins:
        found |= INHIBIT_CELLS
    return frozenset(found)


# The hidden state cells inhibit(d) writes and every gated output action reads (runtime.py).
INHIBIT_CELLS = frozenset({("_inhibited", ANY), ("_inhibit_until", ANY), ("_inhibit_phase", ANY)})
RESET_CELLS = frozenset({("_resetting", ANY)})


def _builtin_statements(node: S.Node):
    """The built-in calls (reset(), inhibit(d)) a statement makes."""
    if isinstance(node, S.CallStmt):
        if isinstance(node.call, S.Call) and node.call.builtin:
            yield node.call
    elif isinstance(node, S.Block):
        for item in node.body:
            yield from _builtin_statements(item)
    elif isinstance(node, S.If):
        yield from _builtin_statements(node.then)
        if node.orelse is not None:
            yield from _builtin_statements(node.orelse)
    elif isinstance(node, S.For):
        yield from _builtin_statements(node.body)


def _assigned_root(target: S.Expr) -> tuple[S.Expr, S.Expr | None]:
    """The variable an assignment target lands in, and the access just above it."""
    chain, above = target, None
    while isinstance(chain, (S.FieldOf, S.IndexOf)):
        above, chain = chain, chain.obj
    return chain, above


def _assignments(node: S.Node, in_loop: bool):
    """Every assignment in a statement, with whether it sits in a loop."""
    if isinstance(node, S.Assign):
        yield node, in_loop
    elif isinstance(node, S.Block):
        for item in node.body:
            yield from _assignments(item, in_loop)
    elif isinstance(node, S.If):
        yield from _assignments(node.then, in_loop)
        if node.orelse is not None:
            yield from _assignments(node.orelse, in_loop)
    elif isinstance(node, S.For):
        yield from _assignments(node.body, True)
