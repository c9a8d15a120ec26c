"""The ESPRIT syntax tree: plain dataclasses, each node knowing where it came from (line, col)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

Pos = tuple[int, int]  # (line, column), both from 1


@dataclass
class Node:
    pos: Pos


# ---------------------------------------------------------------- expressions
@dataclass
class Expr(Node):
    # Filled in by the checker: the expression's type and, for names, what they denote.
    type: Any = field(default=None, init=False, repr=False, compare=False)


@dataclass
class Number(Expr):
    value: int | float


@dataclass
class BoolLit(Expr):
    value: bool


@dataclass
class Null(Expr):
    pass


@dataclass
class Name(Expr):
    id: str
    kind: str = field(default="", init=False)  # state, param, const, member, index, binder, local


@dataclass
class FieldOf(Expr):
    obj: Expr
    name: str


@dataclass
class IndexOf(Expr):
    obj: Expr
    index: Expr


@dataclass
class Call(Expr):
    func: str
    args: list[Expr]
    # Set by the checker: a built-in function (now, reset, inhibit; docs/esprit.md) rather
    # than an extern.
    builtin: bool = field(default=False, init=False, repr=False, compare=False)


@dataclass
class Unary(Expr):
    op: str  # "-" or "!"
    operand: Expr


@dataclass
class Binary(Expr):
    op: str  # normalised to ASCII: -> || && == != < <= > >= + - * / %
    left: Expr
    right: Expr


@dataclass
class Aggregate(Expr):
    """`{a, b}` or `{.f = a}`: a struct or array value, typed by where it goes."""
    items: list[tuple[str | None, Expr]]


@dataclass
class Quantifier(Expr):
    """`forall (j=a; j<b; j++) (P)` or `exists (...) (P)`: P over the ints a..b-1."""
    kind: str  # "forall" or "exists"
    var: str
    start: Expr
    stop: Expr
    body: Expr


# ---------------------------------------------------------------- statements
@dataclass
class Assign(Node):
    target: Expr
    value: Expr


@dataclass
class CallStmt(Node):
    call: Expr  # the checker insists that it is a Call


@dataclass
class If(Node):
    cond: Expr
    then: Node
    orelse: Node | None


@dataclass
class For(Node):
    var: str
    start: Expr
    stop: Expr
    body: Node


@dataclass
class Block(Node):
    body: list[Node]


# ---------------------------------------------------------------- declarations
@dataclass
class TypeRef(Node):
    kind: str            # int, float, bool, struct, enum, named, void
    name: str = ""


@dataclass
class Declarator(Node):
    name: str
    size: Expr | None
    range: tuple[Expr, Expr] | None
    init: Expr | None


@dataclass
class VarDecl(Node):
    type: TypeRef
    declarators: list[Declarator]


@dataclass
class StructDecl(Node):
    name: str
    fields: list[VarDecl]


@dataclass
class EnumDecl(Node):
    name: str
    members: list[tuple[str, Pos]]


@dataclass
class ConstDecl(Node):
    type: TypeRef
    name: str
    value: Expr


@dataclass
class ExternDecl(Node):
    returns: TypeRef
    name: str
    params: list[TypeRef]
    target: str | None   # "module:function" or "file.py:function"; None: given to load_text


@dataclass
class ExternTypeDecl(Node):
    """`extern struct NAME = "module:OBJECT";`: a value type defined in Python (an
    `iotad.kernel.types.Type`), opaque to the spec."""
    name: str
    target: str


@dataclass
class ChanDecl(Node):
    name: str
    size: str | int | None       # a parameter or constant name, or a number
    size_pos: Pos | None
    type: TypeRef | None
    range: tuple[Expr, Expr] | None
    switching: str | float       # a number, or a parameter or constant name
    direction: str = ""


@dataclass
class ParamDecl(Node):
    type: TypeRef
    name: str
    default: Expr


@dataclass
class InstanceDecl(Node):
    iota: str
    name: str
    args: list[tuple[str, Expr, Pos]]


@dataclass
class EndpointRef(Node):
    child: str | None    # None: a channel of the IOTA itself
    channel: str
    index: int | None

    def __str__(self) -> str:
        text = self.channel if self.child is None else f"{self.child}.{self.channel}"
        return text if self.index is None else f"{text}[{self.index}]"


@dataclass
class BindDecl(Node):
    source: EndpointRef
    target: EndpointRef


@dataclass
class ActionDecl(Node):
    channel: str
    index_var: str | None        # `ack[i]`: the family's index variable
    index_pos: Pos | None
    family_var: str | None       # the variable of the enclosing `actions (i=0; i<N; i++)`
    arg: Expr | None             # the output value, or the input's binder name
    when: Expr | None = None
    lower: Expr | None = None
    upper: Expr | None = None
    time_pos: Pos | None = None
    time_kind: str = ""          # "after" or "within"
    do: Node | None = None
    clause_pos: dict = field(default_factory=dict)


@dataclass
class IotaDecl(Node):
    name: str
    params: list[ParamDecl]
    inputs: list[ChanDecl]
    outputs: list[ChanDecl]
    states: list[VarDecl] = field(default_factory=list)
    channels: list[ChanDecl] = field(default_factory=list)
    instances: list[InstanceDecl] = field(default_factory=list)
    bindings: list[BindDecl] = field(default_factory=list)
    actions: list[ActionDecl] = field(default_factory=list)
    has_include: bool = False


@dataclass
class Program:
    decls: list[Node]


def children(node: Node) -> list:
    """The sub-expressions of an expression, for walks that look for names or calls."""
    if isinstance(node, FieldOf):
        return [node.obj]
    if isinstance(node, IndexOf):
        return [node.obj, node.index]
    if isinstance(node, Call):
        return list(node.args)
    if isinstance(node, Unary):
        return [node.operand]
    if isinstance(node, Binary):
        return [node.left, node.right]
    if isinstance(node, Aggregate):
        return [item for _, item in node.items]
    if isinstance(node, Quantifier):
        return [node.start, node.stop, node.body]
    return []
