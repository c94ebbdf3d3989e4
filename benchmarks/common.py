"""What every benchmark shares: the public floor plans, the printed table and the JSON file."""

from __future__ import annotations

import json
import math
import os
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from homing.atomic import atomic_write

WORLDS_ENV = "HOMING_WORLDS"  # a folder of map_server floor plans, searched first
PUBLIC_PLANS = ("room", "corner", "corridor", "loop", "loop_with_corridor", "room_with_corner")
EXTRA_PLANS = ("explorebench_room_1", "explorebench_room_2", "explorebench_room_3", "simple_rooms", "maze")  # in extra/


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
               folders: Sequence[Path] | None = None, quiet: bool = False) -> dict[str, Path]:
    """``{name: YAML}`` of the public floor plans in the first of ``folders`` (default :func:`plan_folders`) holding any.

    When none is found, says on stderr where it looked and what the benchmark
    does instead (``why``) unless ``quiet``, and returns an empty dict.
    """
    folders = plan_folders() if folders is None else folders
    for folder in folders:
        found = {n: folder / f"{n}.yaml" for n in names if (folder / f"{n}.yaml").is_file()}
        if found:
            return found
    if quiet:
        return {}
    looked = ", ".join(str(f) for f in folders)
    print(f"note: no public floor plans found (looked in {looked}; set {WORLDS_ENV}=DIR)"
          + (f": {why}" if why else ""), file=sys.stderr)
    return {}


def find_extra_plans() -> dict[str, Path]:
    """``{name: YAML}`` of the five more public plans (``extra/`` beside the six), where found; quiet when not."""
    return find_plans(EXTRA_PLANS, folders=[f / "extra" for f in plan_folders()], quiet=True)


def _fmt(value: Any) -> str:
    if isinstance(value, float):
        if math.isnan(value):
            return "–"
        if value != 0 and (abs(value) >= 1e4 or abs(value) < 1e-3):
            return f"{value:.3g}"
        return f"{value:.3f}" if abs(value) < 100 else f"{value:.1f}"
    return str(value)


def print_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]], console: Any = None) -> None:
    """Print a table with rich (plain text when stdout is not a terminal), never cutting a value short.

    Headers wrap at their spaces; when the values still do not fit the
    console's width (80 columns when piped), the table is split into parts
    of whole columns, each repeating the first (the row's name), as a wide
    data frame is printed.
    """
    from rich.console import Console
    from rich.table import Table

    console = console or Console()
    cells = [[_fmt(v) for v in row] for row in rows]
    need = [max([len(w) for w in str(col).split()] + [len(r[i]) for r in cells if i < len(r)], default=1)
            for i, col in enumerate(columns)]
    for k, part in enumerate(column_parts(need, console.width)):
        table = Table(title=title if k == 0 else "(continued)")
        for i in part:
            table.add_column(columns[i], justify="left" if i == 0 else "right", width=need[i])
        for row in cells:
            table.add_row(*(row[i] if i < len(row) else "" for i in part))
        console.print(table)


def column_parts(need: Sequence[int], width: int) -> list[list[int]]:
    """Column indices split into parts that each fit ``width``; every part starts with column 0.

    ``need`` is each column's width in characters; a column costs 3 more
    (padding and rule), a table 1 more (its last rule).
    """
    parts: list[list[int]] = []
    part, used = [0], 1 + need[0] + 3 if need else 1
    for i in range(1, len(need)):
        if used + need[i] + 3 > width and len(part) > 1:
            parts.append(part)
            part, used = [0], 1 + need[0] + 3
        part.append(i)
        used += need[i] + 3
    parts.append(part)
    return parts


def run_to_end(runner: Any) -> Any:
    """``runner.run()`` (a :class:`homing.missions.runner.Runner`); its RunResult.

    Ctrl-C, SIGTERM and SIGHUP reach a runner as a stop request and end its run ``interrupted``: a benchmark
    must then stop (KeyboardInterrupt, which the CLI reports), not score the run it cut short, count it as a
    failure or an intervention, and go on.
    """
    result = runner.run()
    if result.reason == "interrupted":
        raise KeyboardInterrupt
    return result


def write_json(path: str | Path | None, data: Mapping[str, Any]) -> None:
    """Write the benchmark's figures to ``path`` atomically (nothing if ``path`` is None)."""
    if path:
        atomic_write(path, json.dumps(data, indent=2, sort_keys=True, default=float) + "\n")


@contextmanager
def progress_bar(label: str, total: int) -> Iterator[Callable[[str], None]]:
    """A rich progress bar of ``total`` runs; the yielded function marks one run done with a description."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    with Progress(TextColumn(f"[bold]{label}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("{task.description}")) as progress:
        task = progress.add_task("", total=total)
        yield lambda text: progress.update(task, advance=1, description=text)
