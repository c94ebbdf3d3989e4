"""A newcomer finds the missions, worlds and parameters, reads plain help, and gets tables that fit 80 columns."""

from __future__ import annotations

import argparse
import io
import re

import pytest
from homing.benchmarks.common import column_parts, print_table
from homing.missions.cli import build_parser
from rich.console import Console

from tests.conftest import REPO
from tests.conftest import homing_cli as homing

RST = re.compile(r"``|:(class|func|mod|meth|attr|data):|`[^`']+`|^\.\. |::$", re.M)


def test_missions_lists_the_bundled_missions_and_worlds_with_their_docs() -> None:
    code, out, _ = homing("missions")
    assert code == 0
    lines = out.splitlines()
    for path in [*(REPO / "missions").glob("*.yaml"), *(REPO / "missions" / "examples").glob("*.yaml")]:
        doc = re.search(r"^doc: (.+)$", path.read_text(), re.M)
        assert doc is not None, f"{path.name} has a one-line doc"
        row = next(line for line in lines if line.split()[:1] == [path.stem])
        assert doc.group(1)[:30] in row
    assert any(line.split()[:1] == ["lab"] and "thesis's lab" in line for line in lines)
    assert all(len(line) <= 80 for line in lines)


def test_one_missions_parameters_and_an_unknown_set_lists_them() -> None:
    code, out, _ = homing("missions", "explore")
    assert code == 0 and "strategy = frontier_travel" in out and "time_limit = 30 min" in out
    code, _, err = homing("check", "explore", "--set", "strategi=nearest")
    assert code == 2 and err.count("\n") == 1
    assert "did you mean 'strategy'?" in err and "(its parameters: strategy=frontier_travel, planner=astar," in err


def _parsers(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()) -> list[tuple[str, ...]]:
    out = [prefix]
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                out += _parsers(sub, (*prefix, name))
    return out


def test_every_help_text_is_plain_text() -> None:
    commands = _parsers(build_parser())
    assert ("bench", "explore") in commands and ("replay",) in commands and ("missions",) in commands
    for argv in commands:
        code, out, _ = homing(*argv, "--help")
        assert code == 0, argv
        assert RST.search(out) is None, f"homing {' '.join(argv)} --help: {RST.search(out)}"
    for argv in (("nodes",), ("nodes", "Explore"), ("nodes", "recovery"), ("nodes", "grid_slam")):
        code, out, _ = homing(*argv)
        assert code == 0 and RST.search(out) is None, (argv, RST.search(out))


def test_a_wide_bench_table_wraps_into_parts_of_whole_columns_within_80() -> None:
    columns = ["scenario", "GTSAM total (dock) m", "grid total m", "odom total m", "GTSAM mean m",
               "GTSAM total (fit) m", "grid total (fit) m", "ATE m", "iSAM2 ms median", "tags"]
    rows = [["loop+tags/explore", 12.345, 23.456, 120.5, 0.523, 1.111, 2.222, 0.05, 0.123, "10/12"],
            ["lab/cycles", 1.5, 2.25, 3.0, 0.1, 1e-5, 123456.0, float("nan"), 0.5, "3/12"]]
    out = io.StringIO()
    print_table("Landmark error vs truth", columns, rows, console=Console(file=out, width=80))
    text = out.getvalue()
    assert max(map(len, text.splitlines())) <= 80
    for value in ("loop+tags/explore", "12.345", "23.456", "120.5", "1e-05", "1.23e+05", "10/12", "3/12", "–"):
        assert value in text, value  # no value is cut short
    assert "…" not in text and text.count("loop+tags/explore") == 2, "two parts, each naming the rows"


@pytest.mark.parametrize(("need", "width", "parts"), [
    ([10, 5, 5, 5], 80, [[0, 1, 2, 3]]),
    ([10, 20, 20, 20], 60, [[0, 1, 2], [0, 3]]),
    ([10, 60, 60], 50, [[0, 1], [0, 2]]),  # a column wider than the screen still gets a part of its own
])
def test_column_parts(need: list[int], width: int, parts: list[list[int]]) -> None:
    assert column_parts(need, width) == parts
