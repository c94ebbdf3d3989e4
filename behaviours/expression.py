"""A small expression language over blackboard values, after BT.CPP v4's scripting (no ``eval``).

A script is statements separated by ``;``; its value is the last one's::

    retries := 0                      # create (or overwrite) the entry
    retries += 1; retries < 3         # update, then compare
    mode = (battery < 20) ? 'dock' : 'explore'

Values are numbers, strings (``'single'`` or ``"double"`` quotes), ``true``
and ``false``. Operators, loosest first: ``? :``; ``||`` (``or``); ``&&``
(``and``); ``==`` ``!=``; ``<`` ``<=`` ``>`` ``>=``; ``..`` (string
concatenation, as BT.CPP); ``+`` ``-``; ``*`` ``/`` ``%``; unary ``!``
(``not``) and ``-``. Assignments: ``:=`` creates or overwrites an entry,
``=`` overwrites one that must already exist (as BT.CPP), ``+=`` ``-=``
``*=`` ``/=`` update one.

Names are blackboard keys: ``retries`` is resolved like a port ``{retries}``
(``/retries`` at the top of a mission, the subtree's own entry inside one);
``@retries`` is the root's ``/retries``; ``{/nav/failure}`` any absolute
key. The parser (:func:`parse`) is a recursive descent over a tokeniser,
and evaluation walks the tree: nothing is handed to Python's ``eval``, and
no name reaches anything but the blackboard.
"""

from __future__ import annotations

import operator
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

_TOKEN = re.compile(
    r"""\s*(?:
      (?P<number>\d+\.\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?|\d+(?:[eE][-+]?\d+)?)
    | (?P<string>'[^']*'|"[^"]*")
    | (?P<key>\{[^{}]*\})
    | (?P<name>@?[A-Za-z_][A-Za-z0-9_]*)
    | (?P<op>:=|\+=|-=|\*=|/=|==|!=|<=|>=|&&|\|\||\.\.|[-+*/%<>!?:;()=])
    )""",
    re.VERBOSE,
)
ASSIGNMENTS = (":=", "=", "+=", "-=", "*=", "/=")
WORDS = {"and": "&&", "or": "||", "not": "!"}


class ScriptSyntaxError(ValueError):
    """A script that does not parse; ``col`` is the 1-based column in the script's text."""

    def __init__(self, message: str, col: int):
        super().__init__(f"{message} (column {col} of the script)")
        self.col = col


class ScriptError(Exception):
    """A script that failed while running (unset entry, wrong types, division by zero)."""


@dataclass(frozen=True)
class Const:
    value: Any


@dataclass(frozen=True)
class Name:
    text: str  # as written: retries, @retries, {/nav/failure}
    col: int


@dataclass(frozen=True)
class Unary:
    op: str
    operand: Any


@dataclass(frozen=True)
class Binary:
    op: str
    left: Any
    right: Any


@dataclass(frozen=True)
class Ternary:
    condition: Any
    then: Any
    other: Any


@dataclass(frozen=True)
class Assign:
    op: str
    target: Name
    value: Any


def _tokens(code: str) -> list[tuple[str, str, int]]:
    out: list[tuple[str, str, int]] = []
    pos = 0
    while pos < len(code):
        if code[pos:].strip() == "":
            break
        m = _TOKEN.match(code, pos)
        if m is None or m.end() == pos:
            col = len(code) - len(code[pos:].lstrip()) + 1
            raise ScriptSyntaxError(f"unexpected '{code[col - 1]}'", col)
        kind = m.lastgroup or "op"
        text = m.group(kind)
        if kind == "name" and text in WORDS:
            kind, text = "op", WORDS[text]
        out.append((kind, text, m.start(kind) + 1))
        pos = m.end()
    out.append(("end", "", len(code) + 1))
    return out


class _Parser:
    def __init__(self, code: str):
        self.tokens = _tokens(code)
        self.i = 0

    def peek(self) -> tuple[str, str, int]:
        return self.tokens[self.i]

    def take(self, *ops: str) -> tuple[str, str, int] | None:
        kind, text, col = self.peek()
        if kind == "op" and text in ops:
            self.i += 1
            return kind, text, col
        return None

    def expect(self, op: str) -> None:
        if self.take(op) is None:
            kind, text, col = self.peek()
            raise ScriptSyntaxError(f"expected '{op}', found {text or 'the end'}", col)

    def script(self) -> list[Any]:
        statements = []
        while True:
            while self.take(";"):
                pass
            if self.peek()[0] == "end":
                break
            statements.append(self.statement())
            if self.peek()[0] != "end":
                self.expect(";")
        if not statements:
            raise ScriptSyntaxError("empty script", 1)
        return statements

    def statement(self) -> Any:
        start = self.i
        kind, text, col = self.peek()
        if kind in ("name", "key"):
            self.i += 1
            op = self.take(*ASSIGNMENTS)
            if op is not None:
                return Assign(op[1], Name(text, col), self.expression())
            self.i = start
        return self.expression()

    def expression(self) -> Any:
        condition = self.binary(0)
        if self.take("?"):
            then = self.expression()
            self.expect(":")
            return Ternary(condition, then, self.expression())
        return condition

    LEVELS = (("||",), ("&&",), ("==", "!="), ("<", "<=", ">", ">="), ("..",), ("+", "-"), ("*", "/", "%"))

    def binary(self, level: int) -> Any:
        if level == len(self.LEVELS):
            return self.unary()
        left = self.binary(level + 1)
        while (op := self.take(*self.LEVELS[level])) is not None:
            left = Binary(op[1], left, self.binary(level + 1))
        return left

    def unary(self) -> Any:
        op = self.take("!", "-", "+")
        if op is not None:
            return Unary(op[1], self.unary())
        return self.primary()

    def primary(self) -> Any:
        kind, text, col = self.peek()
        self.i += 1
        if kind == "number":
            number = float(text)
            return Const(int(text) if re.fullmatch(r"\d+", text) else number)
        if kind == "string":
            return Const(text[1:-1])
        if kind == "name" and text in ("true", "false"):
            return Const(text == "true")
        if kind in ("name", "key"):
            return Name(text, col)
        if kind == "op" and text == "(":
            inner = self.expression()
            self.expect(")")
            return inner
        raise ScriptSyntaxError(f"expected a value, found {text or 'the end'}", col)


def parse(code: str) -> list[Any]:
    """The statements of ``code``; raises :class:`ScriptSyntaxError` with the column of the mistake."""
    if not isinstance(code, str):
        raise ScriptSyntaxError(f"a script is text, not {type(code).__name__}", 1)
    return _Parser(code).script()


def names(statements: list[Any]) -> tuple[list[Name], list[Name]]:
    """(names read, names written) by ``statements``; ``=`` and ``+=`` … need their target to exist: read too."""
    reads: list[Name] = []
    writes: list[Name] = []

    def walk(node: Any) -> None:
        if isinstance(node, Name):
            reads.append(node)
        elif isinstance(node, Unary):
            walk(node.operand)
        elif isinstance(node, Binary):
            walk(node.left)
            walk(node.right)
        elif isinstance(node, Ternary):
            walk(node.condition)
            walk(node.then)
            walk(node.other)
        elif isinstance(node, Assign):
            walk(node.value)
            if node.op != ":=":
                reads.append(node.target)
            writes.append(node.target)

    for statement in statements:
        walk(statement)
    return reads, writes


def _number(value: Any, op: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ScriptError(f"'{op}' needs numbers, not {value!r}")
    return value


def _arith(op: str, a: Any, b: Any) -> Any:
    x, y = _number(a, op), _number(b, op)
    if op in ("/", "%") and y == 0:
        raise ScriptError("division by zero")
    result = {"+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv, "%": operator.mod}[op](x, y)
    return result


def _compare(op: str, a: Any, b: Any) -> bool:
    if op == "==":
        return bool(a == b)
    if op == "!=":
        return bool(a != b)
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (a, b))
    if not numbers and not (isinstance(a, str) and isinstance(b, str)):
        raise ScriptError(f"cannot compare {a!r} {op} {b!r}")
    return bool({"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}[op](a, b))


class Evaluator:
    """Runs parsed statements against a blackboard through three callables.

    ``key_of(name)`` gives the absolute key a :class:`Name` stands for (or a
    :class:`Const` for a subtree parameter fixed to a value); ``get(key)``
    raises KeyError when the entry is unset; ``set(key, value)`` writes it.
    """

    def __init__(self, key_of: Callable[[Name], Any], get: Callable[[str], Any], set: Callable[[str, Any], None]):
        self.key_of, self.get, self.set = key_of, get, set

    def run(self, statements: list[Any]) -> Any:
        value = None
        for statement in statements:
            value = self.eval(statement)
        return value

    def read(self, name: Name) -> Any:
        where = self.key_of(name)
        if isinstance(where, Const):
            return where.value
        try:
            return self.get(where)
        except KeyError:
            raise ScriptError(f"'{name.text}' ({where}) is not set") from None

    def eval(self, node: Any) -> Any:
        if isinstance(node, Const):
            return node.value
        if isinstance(node, Name):
            return self.read(node)
        if isinstance(node, Unary):
            value = self.eval(node.operand)
            return (not value) if node.op == "!" else (-_number(value, "-") if node.op == "-" else _number(value, "+"))
        if isinstance(node, Ternary):
            return self.eval(node.then) if self.eval(node.condition) else self.eval(node.other)
        if isinstance(node, Binary):
            if node.op in ("&&", "||"):
                left = bool(self.eval(node.left))
                if (node.op == "&&") != left:
                    return left
                return bool(self.eval(node.right))
            a, b = self.eval(node.left), self.eval(node.right)
            if node.op == "..":
                return f"{_text(a)}{_text(b)}"
            if node.op in ("==", "!=", "<", "<=", ">", ">="):
                return _compare(node.op, a, b)
            return _arith(node.op, a, b)
        if isinstance(node, Assign):
            where = self.key_of(node.target)
            if isinstance(where, Const):
                raise ScriptError(f"cannot assign to '{node.target.text}': it is a parameter fixed to {where.value!r}")
            value = self.eval(node.value)
            if node.op != ":=":
                current = self.read(node.target)
                if node.op != "=":
                    value = _arith(node.op[0], current, value)
            self.set(where, value)
            return value
        raise ScriptError(f"cannot evaluate {node!r}")


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value.is_integer():
        return str(int(value))
    return str(value)
