"""Parses ESPRIT text into the syntax tree of `syntax.py` (lark, LALR). Syntax errors become
EspritErrors that point at the offending token."""
from __future__ import annotations

import math
from functools import lru_cache
from pathlib import Path
from typing import Any

from lark import Lark, Token, Transformer, v_args
from lark.lexer import PatternStr
from lark.exceptions import LarkError, UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken, VisitError

from iotad.kernel.types import HUGE_INT

from . import syntax as S
from .errors import EspritError, Source

_OPS = {"→": "->", "∨": "||", "∧": "&&", "¬": "!", "≠": "!=", "≤": "<=", "≥": ">="}

# What a user calls the tokens lark names, for "expected ..." messages.
_TOKEN_NAMES = {
    "NAME": "a name", "INT": "a whole number", "NUMBER": "a number", "STRING": "a string",
    "SEMICOLON": "';'", "COMMA": "','", "LPAR": "'('", "RPAR": "')'", "LBRACE": "'{'", "RBRACE": "'}'",
    "LSQB": "'['", "RSQB": "']'", "COLON": "':'", "EQUAL": "'='", "DOT": "'.'", "ARROW": "'->'",
    "SLASH": "'/'", "LT": "'<'", "$END": "end of file", "ARROW": "'->'", "OR": "'||'", "AND": "'&&'",
    "NOT": "'!'", "NE": "'!='", "LE": "'<='", "GE": "'>='", "INF_SYM": "'∞'",
}


@lru_cache(maxsize=1)
def _lark() -> Lark:
    return lalr_parser("start")


def lalr_parser(start: str) -> Lark:
    """The LALR parser of grammar.lark from the rule `start`. Building its tables costs about
    0.25 s of CPU in every process that reads a spec (each node host, the launcher, the recorder,
    the tools), so they are kept in a cache file of this user's and loaded in a fiftieth of that;
    lark checks the grammar's hash in the file and builds them again when the grammar changed."""
    grammar = (Path(__file__).with_name("grammar.lark")).read_text(encoding="utf-8")
    return Lark(grammar, parser="lalr", propagate_positions=True, maybe_placeholders=True, start=start,
                cache=_cache_file(start))


def _cache_file(start: str) -> str | bool:
    """Where the tables of `start` are kept: `$XDG_CACHE_HOME/iotad` (default ~/.cache/iotad),
    made 0700. Lark unpickles the file, so a folder another user could write is not used (False:
    no cache, the tables are built each time), nor one that cannot be made."""
    import os
    import sys

    import lark

    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    folder = os.path.join(base, "iotad")
    try:
        os.makedirs(folder, mode=0o700, exist_ok=True)
        status = os.stat(folder)
    except OSError:
        return False
    if status.st_uid != os.getuid() or status.st_mode & 0o022:
        return False
    return os.path.join(folder, f"esprit-{start}-lark{lark.__version__}-py{sys.version_info[0]}.{sys.version_info[1]}.tables")


def _pos(item, children=()) -> S.Pos:
    """Where `item` (a token, a lark meta or a built node) starts; a meta with no tokens of
    its own (a block of statements) starts where its first child does."""
    if isinstance(item, Token):
        return (item.line, item.column)
    if isinstance(item, S.Node):
        return item.pos
    if item is not None and not getattr(item, "empty", True):
        return (item.line, item.column)
    for child in children:
        if child is not None and isinstance(child, (Token, S.Node)):
            return _pos(child)
    return (1, 1)


def start_of(expr: S.Node) -> S.Pos:
    """The leftmost position of an expression (a binary node's own pos is its operator)."""
    while True:
        if isinstance(expr, S.Binary):
            expr = expr.left
        elif isinstance(expr, (S.FieldOf, S.IndexOf)):
            expr = expr.obj
        else:
            return expr.pos


def _finite_literal(token: Token, value: float) -> float:
    """`value`, unless the literal is beyond the largest float (1e999 reads as inf): `inf` says so
    where it is meant, and a slip of the exponent should not silently mean 'never'."""
    if value in (math.inf, -math.inf):
        raise _Early(_pos(token), f"{token} is beyond the largest float (about 1.8e308); write inf if that is "
                                  "what you mean")
    return value


class _Build(Transformer):
    """lark tree -> syntax tree. Every method gets the children (tokens, built nodes) and meta."""

    # ---------------- expressions
    @v_args(meta=True)
    def number(self, meta, children):
        token = children[0]
        try:
            value = int(token) if token.type == "INT" else float(token)
        except ValueError:  # Python reads no int of more than 4300 digits
            raise _Early(_pos(token), f"an integer literal of {len(token)} digits: {HUGE_INT}") from None
        if value.__class__ is float:
            _finite_literal(token, value)
        return S.Number(_pos(token), value)

    def true(self, c):
        return S.BoolLit(_pos(c[0]), True)

    def false(self, c):
        return S.BoolLit(_pos(c[0]), False)

    def null(self, c):
        return S.Null(_pos(c[0]))

    def inf(self, c):
        return S.Number(_pos(c[0]), float("inf"))

    def name(self, c):
        return S.Name(_pos(c[0]), str(c[0]))

    @v_args(meta=True)
    def field(self, meta, c):
        return S.FieldOf(_pos(c[1]), c[0], str(c[1]))

    @v_args(meta=True)
    def index(self, meta, c):
        return S.IndexOf(c[0].pos, c[0], c[1])

    def call(self, c):
        return S.Call(_pos(c[0]), str(c[0]), [a for a in c[1:] if a is not None])

    def unop(self, c):
        op = _OPS.get(str(c[0]), str(c[0]))
        return S.Unary(_pos(c[0]), op, c[1])

    def binop(self, c):
        op = _OPS.get(str(c[1]), str(c[1]))
        return S.Binary(_pos(c[1]), op, c[0], c[2])

    @v_args(meta=True)
    def aggregate(self, meta, c):
        return S.Aggregate(_pos(meta, [i[1] for i in c if i is not None]), [item for item in c if item is not None])

    def init_item(self, c):
        return (None if c[0] is None else str(c[0]), c[1])

    @v_args(meta=True)
    def quant_range(self, meta, c):
        var, start, var2, _lt, stop, var3 = c
        for other in (var2, var3):
            if str(other) != str(var):
                raise _Early(_pos(other), f"a quantifier counts one variable: expected {var}, found {other}")
        return (str(var), start, stop, _pos(meta, c))

    def _quantifier(self, kind, meta, c):
        (var, start, stop, pos), body = c
        return S.Quantifier(_pos(meta) if not getattr(meta, "empty", True) else pos, kind, var, start, stop, body)

    @v_args(meta=True)
    def forall(self, meta, c):
        return self._quantifier("forall", meta, c)

    @v_args(meta=True)
    def exists(self, meta, c):
        return self._quantifier("exists", meta, c)

    # ---------------- statements
    @v_args(meta=True)
    def assign(self, meta, c):
        return S.Assign(start_of(c[0]), c[0], c[1])

    def expr_stmt(self, c):
        return S.CallStmt(start_of(c[0]), c[0])

    @v_args(meta=True)
    def if_stmt(self, meta, c):
        return S.If(_pos(meta, c), c[0], c[1], c[2])

    @v_args(meta=True)
    def for_stmt(self, meta, c):
        var, start, var2, _lt, stop, var3, body = c
        for other in (var2, var3):
            if str(other) != str(var):
                raise _Early(_pos(other), f"a for loop counts one variable: expected {var}, found {other}")
        return S.For(_pos(meta, c), str(var), start, stop, body)

    @v_args(meta=True)
    def block(self, meta, c):
        return S.Block(_pos(meta, c), [s for s in c if s is not None])

    # ---------------- declarations
    def int_t(self, c):
        return S.TypeRef(_pos(c[0]), "int")

    def float_t(self, c):
        return S.TypeRef(_pos(c[0]), "float")

    def bool_t(self, c):
        return S.TypeRef(_pos(c[0]), "bool")

    def struct_t(self, c):
        return S.TypeRef(_pos(c[0]), "struct", str(c[0]))

    def enum_t(self, c):
        return S.TypeRef(_pos(c[0]), "enum", str(c[0]))

    def named_t(self, c):
        return S.TypeRef(_pos(c[0]), "named", str(c[0]))

    def rtype(self, c):
        if isinstance(c[0], Token):
            return S.TypeRef(_pos(c[0]), "void")
        return c[0]

    def range(self, c):
        return (c[0], c[1])

    def declarator(self, c):
        return S.Declarator(_pos(c[0]), str(c[0]), c[1], c[2], c[3])

    @v_args(meta=True)
    def var_decl(self, meta, c):
        return S.VarDecl(_pos(meta, c), c[0], list(c[1:]))

    field_decl = var_decl

    def struct_decl(self, c):
        return S.StructDecl(_pos(c[0]), str(c[0]), list(c[1:]))

    def enum_decl(self, c):
        return S.EnumDecl(_pos(c[0]), str(c[0]), [(str(m), _pos(m)) for m in c[1:]])

    def const_decl(self, c):
        return S.ConstDecl(_pos(c[1]), c[0], str(c[1]), c[2])

    def xparam(self, c):
        return c[0]

    def extern_decl(self, c):
        returns, name, *rest = c
        target = rest[-1]
        params = [p for p in rest[:-1] if p is not None]
        return S.ExternDecl(_pos(name), returns, str(name), params,
                            None if target is None else str(target)[1:-1])

    def extern_type_decl(self, c):
        return S.ExternTypeDecl(_pos(c[0]), str(c[0]), str(c[1])[1:-1])

    def size(self, c):
        token = c[0]
        return (int(token) if token.type == "INT" else str(token), _pos(token))

    def switching(self, c):
        token = c[0]
        return _finite_literal(token, float(token)) if token.type in ("INT", "NUMBER") else str(token)

    def chan(self, c):
        name, size, ctype, crange, switching = [x for x in c if not (isinstance(x, Token) and x.type == "SLASH")]
        return S.ChanDecl(_pos(name), str(name), None if size is None else size[0],
                          None if size is None else size[1], ctype, crange,
                          0.0 if switching is None else switching)

    def chan_list(self, c):
        return [x for x in c if x is not None]

    def param(self, c):
        return S.ParamDecl(_pos(c[1]), c[0], str(c[1]), c[2])

    def iota_params(self, c):
        return list(c)

    @v_args(meta=True)
    def states(self, meta, c):
        return ("states", list(c))

    @v_args(meta=True)
    def channels(self, meta, c):
        return ("channels", [x for x in c if x is not None])

    @v_args(meta=True)
    def include(self, meta, c):
        return ("include", list(c))

    def arg(self, c):
        return (str(c[0]), c[1], _pos(c[0]))

    def instance(self, c):
        return S.InstanceDecl(_pos(c[0]), str(c[0]), str(c[1]), [a for a in c[2:] if a is not None])

    def endpoint(self, c):
        first, second, index = c
        index_value = None if index is None else int(index)
        if second is None:
            return S.EndpointRef(_pos(first), None, str(first), index_value)
        return S.EndpointRef(_pos(first), str(first), str(second), index_value)

    def binding(self, c):
        return S.BindDecl(c[0].pos, c[0], c[2])

    def family(self, c):
        var, start, var2, _lt, stop, var3 = c
        for other in (var2, var3):
            if str(other) != str(var):
                raise _Early(_pos(other), f"an actions family counts one variable: expected {var}, found {other}")
        if not (isinstance(start, S.Number) and start.value == 0 and isinstance(start.value, int)):
            raise _Early(start.pos, f"an actions family counts from 0: write ({var}=0; {var}<N; {var}++)")
        return (str(var), _pos(var))

    def when(self, c):
        return ("when", c[0])

    def after(self, c):
        return ("after", c[0])

    def within(self, c):
        return ("within", (c[0], c[1]))

    def do(self, c):
        return ("do", c[0])

    def action(self, c):
        name, index_var, arg, *clauses = c
        action = S.ActionDecl(_pos(name), str(name), None if index_var is None else str(index_var),
                              None if index_var is None else _pos(index_var), None, arg)
        for kind, body in clauses:
            pos = body.pos if not isinstance(body, tuple) else body[0].pos
            if kind in action.clause_pos or (kind in ("after", "within") and action.time_kind):
                raise _Early(pos, f"{name}: a second {kind} clause")
            action.clause_pos[kind] = pos
            if kind == "when":
                action.when = body
            elif kind == "after":
                action.lower = action.upper = body
                action.time_kind, action.time_pos = "after", pos
            elif kind == "within":
                action.lower, action.upper = body
                action.time_kind, action.time_pos = "within", pos
            else:
                action.do = body
        return action

    def actions(self, c):
        family = c[0]
        found = []
        for action in c[1:]:
            action.family_var = None if family is None else family[0]
            found.append(action)
        return ("actions", found)

    def iota_decl(self, c):
        name, params, arrow_in, _arrow, arrow_out, *sections = c
        iota = S.IotaDecl(_pos(name), str(name), params or [], arrow_in, arrow_out)
        for chan in iota.inputs:
            chan.direction = "input"
        for chan in iota.outputs:
            chan.direction = "output"
        for kind, items in sections:
            if kind == "states":
                iota.states += items
            elif kind == "channels":
                for chan in items:
                    chan.direction = "internal"
                iota.channels += items
            elif kind == "include":
                iota.has_include = True
                for item in items:
                    (iota.instances if isinstance(item, S.InstanceDecl) else iota.bindings).append(item)
            else:
                iota.actions += items
        return iota

    def start(self, c):
        return S.Program([d for d in c if d is not None])


class _Early(Exception):
    """A mistake noticed while building the tree (e.g. `for (i=0; j<N; i++)`)."""

    def __init__(self, pos, message):
        super().__init__(message)
        self.pos, self.message = pos, message


def _token_name(name: str) -> str:
    if name in _TOKEN_NAMES:
        return _TOKEN_NAMES[name]
    try:
        pattern = _lark().get_terminal(name).pattern
    except KeyError:
        return name.lower()
    if isinstance(pattern, PatternStr):
        return repr(pattern.value)
    return name.lower()


def _expected(names) -> str:
    shown = sorted({_token_name(n) for n in names})
    if len(shown) > 8:
        shown = shown[:8] + ["..."]
    return ", ".join(shown)


def parse(source: Source) -> S.Program:
    return parse_with(_lark(), source, "file")


def _unclosed_comment(text: str) -> int | None:
    """Where a /* comment opens that no */ closes (outside // comments and strings), or None."""
    k, n = 0, len(text)
    while k < n:
        if text.startswith("//", k):
            k = text.find("\n", k)
            if k < 0:
                return None
        elif text.startswith("/*", k):
            end = text.find("*/", k + 2)
            if end < 0:
                return k
            k = end + 2
            continue
        elif text[k] == '"':
            end = text.find('"', k + 1)
            if end < 0:
                return None
            k = end
        k += 1
    return None


def parse_with(parser: Lark, source: Source, unit: str = "file") -> Any:
    """`source` parsed by `parser` (a whole spec, or one expression) into syntax; every syntax
    error an EspritError at its line and column ("unexpected end of <unit>" at the end)."""
    text = source.text
    try:
        try:
            tree = parser.parse(text)
        except UnexpectedInput:
            # a comment whose */ never comes reads as code from its /* on: say that, where it opens
            opened = _unclosed_comment(text)
            if opened is None:
                raise
            line = text.count("\n", 0, opened) + 1
            raise source.error((line, opened - (text.rfind("\n", 0, opened) + 1) + 1),
                               "comment /* ... is never closed by */") from None
    except UnexpectedToken as exc:
        if exc.token.type == "$END":
            raise source.error(None, f"unexpected end of {unit}; expected {_expected(exc.expected)}") from None
        raise source.error((exc.line, exc.column),
                           f"unexpected {str(exc.token)[:40]!r}; expected {_expected(exc.expected)}") from None
    except UnexpectedCharacters as exc:
        char = text[exc.pos_in_stream] if 0 <= exc.pos_in_stream < len(text) else "?"
        raise source.error((exc.line, exc.column), f"unexpected character {char!r}") from None
    except UnexpectedEOF as exc:
        raise source.error(None, f"unexpected end of {unit}; expected {_expected(exc.expected)}") from None
    except UnexpectedInput as exc:  # pragma: no cover - the three above are all lark raises
        raise source.error((exc.line, exc.column), "syntax error") from None
    try:
        return _Build().transform(tree)
    except VisitError as exc:
        if isinstance(exc.orig_exc, _Early):
            raise source.error(exc.orig_exc.pos, exc.orig_exc.message) from None
        raise
    except RecursionError:
        raise source.error(None, f"the {unit} nests too deeply") from None
    except LarkError as exc:  # pragma: no cover
        raise source.error(None, str(exc)) from None
