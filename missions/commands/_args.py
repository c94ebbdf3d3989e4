"""What the subcommands share: argument types (seeds, positive numbers, output paths, checked while parsing), help text.

Each is an argparse ``type=``: a bad value stops the command before anything
runs, as one line naming the option (argparse's ``argument --seed: …``, or a
:class:`~homing.errors.UserError` for an output path that cannot be written).
"""

from __future__ import annotations

import argparse
import inspect
import math
import re
import textwrap
from collections.abc import Callable
from pathlib import Path

MAX_SEED = 2**63 - 1  # numpy's SeedSequence takes any non-negative int; keep it an int64 for logs and JSON


def whole(low: int, high: int | None = None) -> Callable[[str], int]:
    """A ``type=`` for a whole number in [low, high] (no upper bound when ``high`` is None)."""
    span = f"{low} … {high}" if high is not None else f"≥ {low}"

    def parse(text: str) -> int:
        try:
            value = int(text, 0)
        except ValueError:
            raise argparse.ArgumentTypeError(f"needs a whole number {span}, not '{text}'") from None
        if value < low or (high is not None and value > high):
            raise argparse.ArgumentTypeError(f"needs a whole number {span}, not {value}")
        return value

    return parse


seed = whole(0, MAX_SEED)  # a run's seed: numpy's generators take no negative seed
count = whole(1)  # seeds, goals, workers, pairs


def positive(text: str) -> float:
    """A finite number > 0 (a rate, a speed factor, a duration in seconds)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"needs a number, not '{text}'") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"needs a finite number above 0, not {text}")
    return value


def output_file(option: str) -> Callable[[str], Path]:
    """A ``type=`` for an output file: checked writable now (:func:`homing.outputs.check_output`)."""
    from homing.outputs import check_output

    return lambda text: check_output(text, option)


def output_map(option: str) -> Callable[[str], Path]:
    """A ``type=`` for a map_server map to save (its .yaml and .pgm are both checked)."""
    from homing.outputs import check_output, map_files

    def check(text: str) -> Path:
        check_output(text, option)  # a folder given as the map's name is a mistake, not "folder.yaml"
        for path in map_files(text):
            check_output(path, option)
        return Path(text)

    return check


def output_folder(option: str) -> Callable[[str], Path]:
    """A ``type=`` for a folder outputs go in: existing or makeable, accepting files."""
    from homing.outputs import check_folder

    return lambda text: check_folder(text, option)


_LITERAL = re.compile(r"``(.+?)``")
_ROLE = re.compile(r":[a-z]+:`~?([^`<]*?)(?:\s*<[^>]*>)?`")
_TILDE_TARGET = re.compile(r":[a-z]+:`~([\w.]*\.)?(\w+)`")
_INTERPRETED = re.compile(r"(?<![\w`])`([^`]+)`(?![\w`])")
HELP_WIDTH = 78  # [characters] help paragraphs are refilled to this


def plain_text(doc: str | None) -> str:
    """A docstring as plain text for ``--help`` and ``homing nodes``: no reStructuredText markup.

    ````code```` → code, ``:class:`~a.b.C``` → C (``:func:`a.b``` → a.b),
    ```x``` → x, a closing ``::`` → ``:``; prose paragraphs are refilled to
    :data:`HELP_WIDTH`, lists and indented blocks kept as written.
    """
    text = inspect.cleandoc(doc or "")
    text = _TILDE_TARGET.sub(r"\2", text)
    text = _ROLE.sub(r"\1", text)
    text = _LITERAL.sub(r"\1", text)
    text = _INTERPRETED.sub(r"\1", text)
    text = re.sub(r"(?<=\S)::$", ":", text, flags=re.M)
    text = re.sub(r"^::$", "", text, flags=re.M)
    out = []
    for para in text.split("\n\n"):
        lines = para.splitlines()
        if lines and not any(line.startswith((" ", "-", "*", "|")) or re.match(r"\d+\. ", line) for line in lines):
            para = textwrap.fill(" ".join(line.strip() for line in lines), HELP_WIDTH)
        out.append(para)
    return "\n\n".join(out)
