"""Which state cells a Python precondition reads and a do-block touches, found from its source.

The engine re-evaluates after a firing only the preconditions that read a cell the firing's
do-block may have changed; that is what keeps a 64-requester scheduler as cheap per firing as a
two-node ping-pong. The analysis is conservative: `self.request[i]` (with `i` the action's
index) is the cell at that index, any other use of `self.request` is the whole variable, and
anything it cannot follow (no source, `self` passed along, a method call, `self.__dict__`,
`super()`) is "everything". A name that a nested function, lambda, comprehension or handler
binds again is not the action's index there, so no subscript counts as "own element" then.
"""
from __future__ import annotations

import ast
import inspect
import linecache
from functools import lru_cache
from typing import Callable

from iotad.kernel.model import ALL_STATE, ANY, INDEX, by_state


@lru_cache(maxsize=None)
def _module_tree(filename: str) -> ast.Module | None:
    source = "".join(linecache.getlines(filename))
    if not source:
        return None
    try:
        return ast.parse(source)
    except SyntaxError:
        return None


@lru_cache(maxsize=None)
def _functions_by_line(filename: str) -> dict[int, list[ast.AST]] | None:
    """A module's lambdas and defs by the line a code object of theirs starts on (a def's own
    line and its decorators' lines): the module is walked once, not once per function."""
    tree = _module_tree(filename)
    if tree is None:
        return None
    by_line: dict[int, list[ast.AST]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Lambda):
            by_line.setdefault(node.lineno, []).append(node)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for line in {node.lineno} | {d.lineno for d in node.decorator_list}:
                by_line.setdefault(line, []).append(node)
    return by_line


def _function_nodes(fn: Callable) -> list[ast.AST]:
    """The AST nodes (lambdas or defs) that may be `fn`; several if a line holds look-alikes."""
    code = getattr(fn, "__code__", None)
    if code is None:
        return []
    try:
        filename = inspect.getsourcefile(fn)
    except TypeError:
        return []
    by_line = _functions_by_line(filename) if filename else None
    if by_line is None:
        return []
    argnames = code.co_varnames[:code.co_argcount]
    return [n for n in by_line.get(code.co_firstlineno, ())
            if (isinstance(n, ast.Lambda) or n.name == code.co_name)
            and tuple(a.arg for a in n.args.args) == argnames]


def cells_of(fn: Callable | None, state_names: frozenset[str] | set[str] | None,
             opaque: frozenset[str] | set[str] = frozenset(),
             constants: frozenset[str] | set[str] = frozenset(), *, writes: bool = False) -> frozenset:
    """Cells `fn(self, index, ...)` may access; ALL_STATE when it cannot tell.

    `state_names` None: every attribute of `self` but `constants` is a cell (state set outside
    `init`, a class attribute used as a default); `opaque` names attributes that run code when
    read (properties, methods): touching one is "everything". With `writes`, `self.x[self.k]`
    is the cell `(x, by_state(k))` when `k` is assigned at most once and not in a loop."""
    if fn is None:
        return frozenset()
    nodes = _function_nodes(fn)
    if not nodes:
        return ALL_STATE
    cells: set = set()
    for node in nodes:
        found = _cells_in(node, state_names, opaque, constants, writes)
        if found is ALL_STATE:
            return ALL_STATE
        cells |= found
    return frozenset(cells)


def _binds(node: ast.AST, name: str) -> bool:
    """Whether `node` (re)binds `name`: an assignment, a loop or comprehension target, a nested
    function's or lambda's parameter, an `except ... as`, an import, a match capture."""
    if isinstance(node, ast.Name):
        return node.id == name and not isinstance(node.ctx, ast.Load)
    if isinstance(node, ast.arg):
        return node.arg == name
    if isinstance(node, (ast.ExceptHandler, ast.MatchAs, ast.MatchStar)):
        return node.name == name
    if isinstance(node, ast.alias):
        return (node.asname or node.name.split(".")[0]) == name
    if isinstance(node, (ast.Global, ast.Nonlocal)):
        return name in node.names
    return False


def _stable_attributes(module: ast.Module, self_name: str, parents: dict[int, ast.AST]) -> set[str]:
    """Attributes of `self` assigned at most once, and not inside a loop, comprehension or
    nested function: an index read from one takes at most two values during the call."""
    stores: dict[str, int] = {}
    unstable: set[str] = set()
    loops = (ast.For, ast.AsyncFor, ast.While, ast.comprehension, ast.Lambda, ast.FunctionDef,
             ast.AsyncFunctionDef, ast.ListComp, ast.SetComp, ast.DictComp, ast.GeneratorExp)
    for n in ast.walk(module):
        if (isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name) and n.value.id == self_name
                and not isinstance(n.ctx, ast.Load)):
            stores[n.attr] = stores.get(n.attr, 0) + 1
            above = parents.get(id(n))
            while above is not None:
                if isinstance(above, loops):
                    unstable.add(n.attr)
                above = parents.get(id(above))
    every = {n.attr for n in ast.walk(module) if isinstance(n, ast.Attribute)
             and isinstance(n.value, ast.Name) and n.value.id == self_name}
    return {name for name in every if stores.get(name, 0) <= 1 and name not in unstable}


def _cells_in(node: ast.AST, state_names, opaque, constants, writes: bool = False) -> frozenset:
    args = [a.arg for a in node.args.args]
    if not args:
        return frozenset()
    self_name = args[0]
    index_name = args[1] if len(args) > 1 else None
    body = node.body if isinstance(node.body, list) else [node.body]
    module = ast.Module(body=body, type_ignores=[])
    if index_name and any(_binds(n, index_name) for n in ast.walk(module)):
        index_name = None  # the index is rebound somewhere: `x[i]` may not be the own element
    if any(isinstance(n, ast.Name) and n.id == "super" for n in ast.walk(module)):
        return ALL_STATE  # `super()` reaches `self` without naming it
    parents: dict[int, ast.AST] = {}
    for parent in ast.walk(module):
        for child in ast.iter_child_nodes(parent):
            parents[id(child)] = parent
    stable = _stable_attributes(module, self_name, parents) if writes else set()
    cells: set = set()
    for n in ast.walk(module):
        if not (isinstance(n, ast.Name) and n.id == self_name):
            continue
        attribute = parents.get(id(n))
        if not isinstance(attribute, ast.Attribute):
            return ALL_STATE  # `self` escapes (passed to a function, aliased): cannot follow it
        if attribute.attr.startswith("__") or attribute.attr in opaque:
            return ALL_STATE  # `self.__dict__[...]`, a property: state reached by another name
        if attribute.attr in constants if state_names is None else attribute.attr not in state_names:
            user = parents.get(id(attribute))
            if isinstance(user, ast.Call) and user.func is attribute:
                return ALL_STATE  # a method may touch anything
            continue  # a parameter or a constant: never changes
        subscript = parents.get(id(attribute))
        if (index_name and isinstance(subscript, ast.Subscript) and subscript.value is attribute
                and isinstance(subscript.slice, ast.Name) and subscript.slice.id == index_name):
            cells.add((attribute.attr, INDEX))
        elif (isinstance(subscript, ast.Subscript) and subscript.value is attribute
              and isinstance(subscript.slice, ast.Attribute) and isinstance(subscript.slice.value, ast.Name)
              and subscript.slice.value.id == self_name and subscript.slice.attr in stable
              and subscript.slice.attr not in opaque and not subscript.slice.attr.startswith("__")):
            cells.add((attribute.attr, by_state(subscript.slice.attr)))
        else:
            cells.add((attribute.attr, ANY))
    return frozenset(cells)


def stored_attributes(fn: Callable | None) -> frozenset | None:
    """Attributes of `self` that `fn` may change (assigned, deleted, a method called on them or
    passed to a function); None when it cannot tell."""
    if fn is None:
        return frozenset()
    nodes = _function_nodes(fn)
    if not nodes:
        return None
    stored: set = set()
    for node in nodes:
        args = [a.arg for a in node.args.args]
        if not args:
            continue
        body = node.body if isinstance(node.body, list) else [node.body]
        module = ast.Module(body=body, type_ignores=[])
        parents = {id(c): p for p in ast.walk(module) for c in ast.iter_child_nodes(p)}
        for n in ast.walk(module):
            if not (isinstance(n, ast.Name) and n.id == args[0]):
                continue
            attribute = parents.get(id(n))
            if not isinstance(attribute, ast.Attribute):
                return None
            top = attribute
            while isinstance(parents.get(id(top)), (ast.Attribute, ast.Subscript)) and parents[id(top)].value is top:
                top = parents[id(top)]
            user = parents.get(id(top))
            if not isinstance(getattr(top, "ctx", None), ast.Load) or isinstance(user, ast.Call):
                stored.add(attribute.attr)
    return frozenset(stored)


def describe(cells: frozenset) -> str:
    if cells is ALL_STATE or cells == ALL_STATE:
        return "everything"
    def one(var: str, key: object) -> str:
        if key == INDEX:
            return f"{var}[i]"
        return f"{var}[{key[1]}]" if isinstance(key, tuple) else var
    return ", ".join(sorted(one(v, k) for v, k in cells)) or "nothing"

