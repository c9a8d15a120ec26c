"""Which state cells a Python precondition reads and a do-block touches, found from its source.

The engine re-evaluates after a firing only the preconditions that read a cell the firing's
do-block may have changed; that is what keeps a 64-requester scheduler as cheap per firing as a
two-node ping-pong. The analysis is conservative: `self.request[i]` (with `i` the action's
index) is the cell at that index, any other use of `self.request` is the whole variable, and
anything it cannot follow (no source, `self` passed along, a method call) is "everything".
"""
from __future__ import annotations

import ast
import inspect
import linecache
from functools import lru_cache
from typing import Callable

from .model import ALL_STATE, ANY, INDEX


@lru_cache(maxsize=None)
def _module_tree(filename: str) -> ast.Module | None:
    source = "".join(linecache.getlines(filename))
    if not source:
        return None
    try:
        return ast.parse(source)
    except SyntaxError:
        return None


def _function_nodes(fn: Callable) -> list[ast.AST]:
    """The AST nodes (lambdas or defs) that may be `fn`; several if a line holds look-alikes."""
    code = getattr(fn, "__code__", None)
    if code is None:
        return []
    try:
        filename = inspect.getsourcefile(fn)
    except TypeError:
        return []
    tree = _module_tree(filename) if filename else None
    if tree is None:
        return []
    first = code.co_firstlineno
    argnames = code.co_varnames[:code.co_argcount]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Lambda) and node.lineno == first:
            found.append(node)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.name == code.co_name:
            starts = {node.lineno} | {d.lineno for d in node.decorator_list}
            if first in starts:
                found.append(node)
    return [n for n in found if tuple(a.arg for a in n.args.args) == argnames]


def cells_of(fn: Callable | None, state_names: frozenset[str] | set[str]) -> frozenset:
    """Cells `fn(self, index, ...)` may access; ALL_STATE when it cannot tell."""
    if fn is None:
        return frozenset()
    nodes = _function_nodes(fn)
    if not nodes:
        return ALL_STATE
    cells: set = set()
    for node in nodes:
        found = _cells_in(node, state_names)
        if found is ALL_STATE:
            return ALL_STATE
        cells |= found
    return frozenset(cells)


def _cells_in(node: ast.AST, state_names) -> frozenset:
    args = [a.arg for a in node.args.args]
    if not args:
        return frozenset()
    self_name = args[0]
    index_name = args[1] if len(args) > 1 else None
    body = node.body if isinstance(node.body, list) else [node.body]
    module = ast.Module(body=body, type_ignores=[])
    if index_name and any(isinstance(n, ast.Name) and n.id == index_name and isinstance(n.ctx, ast.Store)
                          for n in ast.walk(module)):
        index_name = None  # the index is reassigned: its subscripts no longer mean "own element"
    parents: dict[int, ast.AST] = {}
    for parent in ast.walk(module):
        for child in ast.iter_child_nodes(parent):
            parents[id(child)] = parent
    cells: set = set()
    for n in ast.walk(module):
        if not (isinstance(n, ast.Name) and n.id == self_name):
            continue
        attribute = parents.get(id(n))
        if not isinstance(attribute, ast.Attribute):
            return ALL_STATE  # `self` escapes (passed to a function, aliased): cannot follow it
        if attribute.attr not in state_names:
            user = parents.get(id(attribute))
            if isinstance(user, ast.Call) and user.func is attribute:
                return ALL_STATE  # a method may touch anything
            continue  # a parameter or a constant: never changes
        subscript = parents.get(id(attribute))
        if (index_name and isinstance(subscript, ast.Subscript) and subscript.value is attribute
                and isinstance(subscript.slice, ast.Name) and subscript.slice.id == index_name):
            cells.add((attribute.attr, INDEX))
        else:
            cells.add((attribute.attr, ANY))
    return frozenset(cells)


def describe(cells: frozenset) -> str:
    if cells is ALL_STATE or cells == ALL_STATE:
        return "everything"
    return ", ".join(sorted(f"{v}[i]" if k == INDEX else v for v, k in cells)) or "nothing"

