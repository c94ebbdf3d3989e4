"""What every benchmark shares: the public floor plans, the printed table and the JSON file."""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from homing.atomic import atomic_write

WORLDS_ENV = "HOMING_WORLDS"  # a folder of map_server floor plans, searched first
PUBLIC_PLANS = ("room", "corner", "corridor", "loop", "loop_with_corridor", "room_with_corner")


def plan_folders() -> list[Path]:
    """Where the public floor plans may be, in search order (absolute, without repeats).

    ``$HOMING_WORLDS``; ``shared/worlds`` beside the working directory and
    beside its parent (the development layout, run from the project root or
    from above it); beside the source checkout (an editable install, from any
    working directory). An installed wheel has no checkout: the first two apply.
    """
    candidates = []
    if os.environ.get(WORLDS_ENV):
        candidates.append(Path(os.environ[WORLDS_ENV]).expanduser())
    cwd = Path.cwd()
    candidates += [cwd / "shared" / "worlds", cwd.parent / "shared" / "worlds"]
    candidates.append(Path(__file__).resolve().parents[2] / "shared" / "worlds")
    out: list[Path] = []
    for c in candidates:
        c = c.resolve()
        if c not in out:
            out.append(c)
    return out


def find_plans(names: Sequence[str] = PUBLIC_PLANS, *, why: str = "",
               folders: Sequence[Path] | None = None) -> dict[str, Path]:
    """``{name: YAML}`` of the public floor plans in the first of ``folders`` (default :func:`plan_folders`) holding any.

    When none is found, says on stderr where it looked and what the benchmark
    does instead (``why``), and returns an empty dict.
    """
    folders = plan_folders() if folders is None else folders
    for folder in folders:
        found = {n: folder / f"{n}.yaml" for n in names if (folder / f"{n}.yaml").is_file()}
        if found:
            return found
    looked = ", ".join(str(f) for f in folders)
    print(f"note: no public floor plans found (looked in {looked}; set {WORLDS_ENV}=DIR)"
          + (f": {why}" if why else ""), file=sys.stderr)
    return {}


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if value != 0 and (abs(value) >= 1e4 or abs(value) < 1e-3):
            return f"{value:.3g}"
        return f"{value:.3f}" if abs(value) < 100 else f"{value:.1f}"
    return str(value)


def print_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]]) -> None:
    """Print a table with rich (plain text when stdout is not a terminal)."""
    from rich.console import Console
    from rich.table import Table

    table = Table(title=title)
    for i, col in enumerate(columns):
        table.add_column(col, justify="left" if i == 0 else "right")
    for row in rows:
        table.add_row(*(_fmt(v) for v in row))
    Console().print(table)


def write_json(path: str | Path | None, data: Mapping[str, Any]) -> None:
    """Write the benchmark's figures to ``path`` atomically (nothing if ``path`` is None)."""
    if path:
        atomic_write(path, json.dumps(data, indent=2, sort_keys=True, default=float) + "\n")
