"""Typed field access for hand-written YAML files (worlds, robot files), every complaint at ``file:line:col``.

The world loader, its battery and fault sections, and the robot file read YAML mappings through a
:class:`Section`: it knows the file and the mapping's positions
(:mod:`homing.yamlfile`), checks each value's type and range, and rejects
keys it was not asked about so a misspelt key fails loudly instead of being
ignored. Not a general schema language: just the few checks world files need.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from homing.errors import UserError
from homing.yamlfile import LocatedDict, LocatedList, where


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


class Section:
    """One YAML mapping of a world file, read key by key with type checks."""

    def __init__(self, doc: Any, file: Path, what: str, loc: tuple[int, int] = (0, 0)):
        if not isinstance(doc, dict):
            line, col = getattr(doc, "loc", loc)
            raise UserError(f"{what} must be a mapping, not {type(doc).__name__}", file, line, col)
        self.doc: dict = doc
        self.file = file
        self.what = what

    def error(self, key: str, message: str, *, at_key: bool = False) -> UserError:
        line, col = where(self.doc, key, value=not at_key) if key in self.doc else self.loc
        return UserError(message, self.file, line, col)

    @property
    def loc(self) -> tuple[int, int]:
        return getattr(self.doc, "loc", (0, 0))

    def has(self, key: str) -> bool:
        return key in self.doc

    def raw(self, key: str, default: Any = None) -> Any:
        return self.doc.get(key, default)

    def number(self, key: str, default: float | None = None, *, lo: float | None = None,
               hi: float | None = None, positive: bool = False) -> float:
        """A finite number (int or float) in [lo, hi]; ``default`` when absent (None: required)."""
        if key not in self.doc:
            if default is None:
                raise UserError(f"{self.what}: missing required key '{key}'", self.file, *self.loc)
            return float(default)
        value = self.doc[key]
        if not _is_number(value):
            raise self.error(key, f"'{key}' must be a number, not {value!r}")
        v = float(value)
        if positive and v <= 0:
            raise self.error(key, f"'{key}' must be positive, not {v}")
        if lo is not None and v < lo:
            raise self.error(key, f"'{key}' must be at least {lo}, not {v}")
        if hi is not None and v > hi:
            raise self.error(key, f"'{key}' must be at most {hi}, not {v}")
        return v

    def optional_number(self, key: str, **kw: Any) -> float | None:
        return self.number(key, **kw) if key in self.doc and self.doc[key] is not None else None

    def integer(self, key: str, default: int | None = None, *, lo: int | None = None,
                hi: int | None = None) -> int:
        if key not in self.doc:
            if default is None:
                raise UserError(f"{self.what}: missing required key '{key}'", self.file, *self.loc)
            return int(default)
        value = self.doc[key]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"'{key}' must be an integer, not {value!r}")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise self.error(key, f"'{key}' must be in [{lo}, {hi}], not {value}")
        return value

    def string(self, key: str, default: str | None = None, *, choices: Iterable[str] | None = None) -> str:
        if key not in self.doc:
            if default is None:
                raise UserError(f"{self.what}: missing required key '{key}'", self.file, *self.loc)
            return default
        value = self.doc[key]
        if not isinstance(value, str) or not value:
            raise self.error(key, f"'{key}' must be a non-empty string, not {value!r}")
        if choices is not None and value not in set(choices):
            raise self.error(key, f"'{key}' must be one of {', '.join(sorted(choices))}, not {value!r}")
        return value

    def vector(self, key: str, n: int) -> tuple[float, ...]:
        value = self.doc.get(key)
        if not isinstance(value, list) or len(value) != n or not all(_is_number(v) for v in value):
            raise self.error(key, f"'{key}' must be a list of {n} numbers, not {value!r}")
        return tuple(float(v) for v in value)

    def section(self, key: str) -> Section:
        return Section(self.doc[key], self.file, f"'{key}'", where(self.doc, key))

    def items(self, key: str) -> list[tuple[Any, tuple[int, int]]]:
        """A list value's items with their (line, col)."""
        value = self.doc[key]
        if not isinstance(value, list):
            raise self.error(key, f"'{key}' must be a list, not {type(value).__name__}")
        locs = value.item_loc if isinstance(value, LocatedList) else [where(self.doc, key)] * len(value)
        return list(zip(value, locs, strict=True))

    def only(self, allowed: Iterable[str]) -> None:
        """Reject keys not in ``allowed``, suggesting the closest known key."""
        known = list(allowed)
        for key in self.doc:
            if key not in known:
                close = difflib.get_close_matches(str(key), known, n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else f" (known: {', '.join(known)})"
                raise self.error(key, f"unknown key '{key}' in {self.what}{hint}", at_key=True)


def section_at(value: Any, loc: tuple[int, int], file: Path, what: str) -> Section:
    """A :class:`Section` for a list item, reporting at the item's position if it is not a mapping."""
    if not isinstance(value, LocatedDict) and isinstance(value, dict):
        return Section(value, file, what, loc)
    if not isinstance(value, dict):
        raise UserError(f"{what} must be a mapping, not {value!r}", file, *loc)
    return Section(value, file, what, loc)
