"""Stand-alone ESPRIT expressions: parse, type-check and compile one expression over given names.

Other parts of iotad write conditions in ESPRIT's expression language rather than inventing
their own: an MDL atom's interrupt `proximity.distance < 0.3` is such an expression, its names
being the interpreter's sensor inputs. The grammar, checker and code generator are those of
whole specs (one implementation of the operators, types and runtime faults); errors are
`EspritError`s whose diagnostic points at the line and column in the expression's text.

    cond = compile_expression("proximity.distance < 0.3", {"proximity": PROXIMITY}, Bool)
    cond.fn(view)      # view.proximity is a PROXIMITY record -> True / False
    cond.reads         # frozenset({"proximity"})
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable

from lark import Lark

from iotad.kernel.types import BoolType, FloatType, IntType, Type

from . import codegen
from . import syntax as S
from .errors import EspritError, Source
from .parser import lalr_parser, parse_with
from .runtime import all_of, any_of, c_div, c_mod, fresh_budget, ix, with_budget
from .static_checks import Checker, _Scope
from .typesys import describe, is_number


@lru_cache(maxsize=1)
def _expression_parser() -> Lark:
    return lalr_parser("expr")


def parse_expression(text: str, filename: str = "<expression>") -> S.Expr:
    """The syntax tree of one ESPRIT expression; a syntax error is an EspritError with its column."""
    source = Source(text, filename)
    if not text.strip():
        raise source.error((1, 1), "empty expression")
    return parse_with(_expression_parser(), source, "expression")


@dataclass(frozen=True)
class CompiledExpression:
    """A checked, compiled expression. `fn(view)` evaluates it with each name read as the
    attribute of that name on `view`; it raises on a runtime fault (index out of range, division
    by zero), as compiled spec code does."""

    text: str
    type: Type
    reads: frozenset          # the names it reads
    fn: Callable[[Any], Any]


# What generated expression code may call (codegen.expr); now(), reset() and inhibit() are
# refused by the checker outside an action, so they need nothing here.
_GLOBALS = {"ix": ix, "c_div": c_div, "c_mod": c_mod, "all_of": all_of, "any_of": any_of,
            "fresh_budget": fresh_budget, "INF": float("inf"),
            "__builtins__": {}}


def compile_expression(text: str, names: dict[str, Type], expect: Type | None = None,
                       filename: str = "<expression>") -> CompiledExpression:
    """Parse, check and compile `text`. `names` maps each name it may read to its value type
    (struct, array, number or bool); `expect` is Bool for a condition or Float for a number
    (an int widens). Raises EspritError (with every error found) if it does not check."""
    node = parse_expression(text, filename)
    source = Source(text, filename)

    def no_externs(decl):  # pragma: no cover - an expression declares nothing
        return None

    checker = Checker(source, no_externs)
    scope = _Scope({name: ("param", vtype) for name, vtype in names.items()})
    try:
        found = checker.expr(node, scope, expect)
    except RecursionError:
        raise source.error(None, "the expression nests too deeply") from None
    errors = checker.out.errors
    if not errors and found is not None and expect is not None and not _fits(expect, found):
        errors.append(source.diagnostic(node.pos if not isinstance(node, S.Binary) else _start(node),
                                        f"expected {describe(expect)}, but the expression is {describe(found)}"))
    if errors:
        raise EspritError(errors[0], errors)
    returned = codegen.expr(node)
    budget = "    fresh_budget()\n" if with_budget(returned) else ""  # runtime.LOOP_BUDGET
    code = f"def expression(iota, index=None):\n{budget}    return {returned}\n"
    namespace: dict[str, Any] = {}
    try:
        exec(compile(code, f"<esprit {filename}>", "exec"), dict(_GLOBALS), namespace)  # noqa: S102
    except (SyntaxError, RecursionError, MemoryError):  # Python's own limits on nesting
        raise source.error(None, "the expression nests too deeply") from None
    return CompiledExpression(text, found, frozenset(_names_read(node)), namespace["expression"])


def _fits(expect: Type, found: Any) -> bool:
    if isinstance(expect, BoolType):
        return isinstance(found, BoolType)
    if isinstance(expect, FloatType):
        return is_number(found)
    if isinstance(expect, IntType):
        return isinstance(found, IntType)
    return found is expect


def _start(node: S.Expr) -> S.Pos:
    from .parser import start_of
    return start_of(node)


def _names_read(node: S.Expr) -> set[str]:
    found: set[str] = set()

    def walk(item: S.Expr) -> None:
        if isinstance(item, S.Name) and item.kind == "param":
            found.add(item.id)
        for child in S.children(item):
            walk(child)
    walk(node)
    return found


__all__ = ["CompiledExpression", "compile_expression", "parse_expression"]
