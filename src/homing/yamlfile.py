"""YAML loading that remembers where every value came from.

Worlds, missions and maps are YAML files a user writes by hand, so every
complaint about one must name ``file:line:col``. :func:`load` returns plain
Python data, except that mappings are :class:`LocatedDict` and sequences
:class:`LocatedList`, which know the 1-based line and column of each key and
value. A syntax error becomes a :class:`~homing.errors.UserError` at the
place the parser stopped.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from homing.errors import UserError


class LocatedDict(dict):
    """A dict from YAML that knows where its keys and values are.

    ``key_loc[k]`` and ``value_loc[k]`` are (line, col), 1-based.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.key_loc: dict[Any, tuple[int, int]] = {}
        self.value_loc: dict[Any, tuple[int, int]] = {}
        self.loc: tuple[int, int] = (0, 0)


class LocatedList(list):
    """A list from YAML that knows where each item is: ``item_loc[i]`` = (line, col)."""

    def __init__(self, *args: Any) -> None:
        super().__init__(*args)
        self.item_loc: list[tuple[int, int]] = []
        self.loc: tuple[int, int] = (0, 0)


def _mark(node: yaml.Node) -> tuple[int, int]:
    return node.start_mark.line + 1, node.start_mark.column + 1


class _Loader(yaml.SafeLoader):
    """SafeLoader whose mappings and sequences carry their source positions."""


def _construct_mapping(loader: _Loader, node: yaml.MappingNode) -> LocatedDict:
    out = LocatedDict()
    out.loc = _mark(node)
    loader.flatten_mapping(node)
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                None, None, "a mapping key must be a plain value", key_node.start_mark
            ) from None
        if key in out:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key {key!r}", key_node.start_mark
            )
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_loc[key] = _mark(key_node)
        out.value_loc[key] = _mark(value_node)
    return out


def _construct_sequence(loader: _Loader, node: yaml.SequenceNode) -> LocatedList:
    out = LocatedList(loader.construct_object(child, deep=True) for child in node.value)
    out.loc = _mark(node)
    out.item_loc = [_mark(child) for child in node.value]
    return out


_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_Loader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


_CLOSERS = {"[": "]", "{": "}", "'": "'", '"': '"'}
# Problems that mean "the parser reached the end of what it could read without the closing bracket or quote".
_UNCLOSED = ("expected ',' or ']'", "expected ',' or '}'", "end of stream", "<stream end>")


def loads(text: str, file: str | Path = "<string>") -> Any:
    """Parse YAML text; a syntax error raises :class:`UserError` at its position.

    A bracket, brace or quote that is never closed is reported where it
    opens — where a person looks for the mistake — with the place the
    parser gave up (often the end of the file) in the message.
    """
    try:
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        line, col = (mark.line + 1, mark.column + 1) if mark is not None else (0, 0)
        problem = err.problem or err.context or "invalid YAML"
        opener = _unclosed(text, err) if any(u in problem for u in _UNCLOSED) else None
        if opener is not None:
            char, (oline, ocol) = opener
            raise UserError(f"invalid YAML: this {char!r} is never closed (no matching {_CLOSERS[char]!r}; the parser "
                            f"gave up at line {line}, column {col}: {problem})", file, oline, ocol) from None
        raise UserError(f"invalid YAML: {problem}", file, line, col) from None
    except yaml.YAMLError as err:
        raise UserError(f"invalid YAML: {err}", file) from None


def _unclosed(text: str, err: yaml.MarkedYAMLError) -> tuple[str, tuple[int, int]] | None:
    """The innermost bracket, brace or quote still open where parsing failed, and its (line, col); else None."""
    context = err.context or ""
    if "quoted scalar" in context and err.context_mark is not None:
        m = err.context_mark
        quote = text.splitlines()[m.line][m.column] if m.line < len(text.splitlines()) else '"'
        return (quote if quote in "'\"" else '"'), (m.line + 1, m.column + 1)
    stack: list[tuple[str, tuple[int, int]]] = []
    try:
        for token in yaml.scan(text, Loader=yaml.SafeLoader):
            if isinstance(token, (yaml.FlowSequenceStartToken, yaml.FlowMappingStartToken)):
                m = token.start_mark
                stack.append(("[" if isinstance(token, yaml.FlowSequenceStartToken) else "{", (m.line + 1, m.column + 1)))
            elif isinstance(token, (yaml.FlowSequenceEndToken, yaml.FlowMappingEndToken)) and stack:
                if stack[-1][0] != ("[" if isinstance(token, yaml.FlowSequenceEndToken) else "{"):
                    break  # a ']' where a '}' was due: the '{' is the one never closed
                stack.pop()
    except yaml.YAMLError:
        pass
    if not stack:
        return None
    problem = err.problem_mark
    if problem is not None:  # openers before the place the parser stopped
        stack = [o for o in stack if o[1] <= (problem.line + 1, problem.column + 1)]
    return stack[-1] if stack else None


def load(path: str | Path) -> Any:
    """Read and parse a YAML file; unreadable files raise :class:`UserError`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError("no such file", p) from None
    except IsADirectoryError:
        raise UserError("is a directory, not a YAML file", p) from None
    except UnicodeDecodeError as err:
        raise UserError(f"not UTF-8 text (byte {err.start})", p) from None
    except OSError as err:
        raise UserError(f"cannot read: {err.strerror}", p) from None
    return loads(text, p)


def where(container: Any, key: Any, *, value: bool = True) -> tuple[int, int]:
    """(line, col) of ``container[key]`` (its value, or its key if ``value=False``); (0, 0) if unknown."""
    if isinstance(container, LocatedDict):
        table = container.value_loc if value else container.key_loc
        return table.get(key, container.loc)
    if isinstance(container, LocatedList) and isinstance(key, int) and 0 <= key < len(container.item_loc):
        return container.item_loc[key]
    return getattr(container, "loc", (0, 0))
