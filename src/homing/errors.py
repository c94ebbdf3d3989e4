"""Errors that report a user's mistake as ``file:line:col: message``.

A user's mistake (a malformed world, mission or map; a bad command-line value)
must reach the terminal as one line naming where it is and what is wrong, with
exit status 2 and never a traceback. Code anywhere in homing raises
:class:`UserError` (or collects several into :class:`UserErrors`); the CLI
catches them, prints them and exits 2. Bugs stay ordinary exceptions.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

EXIT_USAGE = 2  # exit status for a user's mistake, as argparse uses


@dataclass(frozen=True)
class Location:
    """Where in a file a mistake is: 1-based line and column, 0 when unknown."""

    file: str
    line: int = 0
    col: int = 0

    def __str__(self) -> str:
        out = self.file
        if self.line:
            out += f":{self.line}"
            if self.col:
                out += f":{self.col}"
        return out


class UserError(Exception):
    """A mistake in something the user gave: printed as ``file:line:col: message``."""

    def __init__(self, message: str, file: str | Path | None = None, line: int = 0, col: int = 0):
        super().__init__(message)
        self.message = message
        self.location = Location(str(file), line, col) if file is not None else None

    def __str__(self) -> str:
        # One line whatever the user's text quoted in the message holds (a name with a carriage return in it
        # would otherwise split the report): control characters are shown escaped.
        message = "".join(c if c.isprintable() else c.encode("unicode_escape").decode() for c in self.message)
        if self.location is None:
            return message
        return f"{self.location}: {message}"


class UserErrors(UserError):
    """Several mistakes found in one pass, reported together (one per line)."""

    def __init__(self, errors: Iterable[UserError]):
        self.errors = list(errors)
        super().__init__("\n".join(str(e) for e in self.errors))

    def __str__(self) -> str:
        return "\n".join(str(e) for e in self.errors)
