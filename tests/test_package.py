"""The package installs as `homing.<part>` and the CLI treats mistakes as one-line errors."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from tests.conftest import REPO

PARTS = ["robot", "sim", "perception", "mapping", "navigation", "lifecycle", "behaviours", "missions", "benchmarks",
         "btxml", "logs", "emulators", "live"]


def test_every_folder_with_init_is_a_listed_package() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    dirs = config["package-dir"]
    found = set()
    for pkg, folder in dirs.items():
        root = REPO / folder
        for init in root.rglob("__init__.py"):
            rel = init.parent.relative_to(root)
            found.add(".".join([pkg, *rel.parts]) if rel.parts else pkg)
    assert found <= listed, f"packages not listed in pyproject.toml: {sorted(found - listed)}"
    assert listed <= found, f"listed packages without a folder: {sorted(listed - found)}"


@pytest.mark.parametrize("part", PARTS)
def test_parts_import_as_homing_subpackages(part: str) -> None:
    module = importlib.import_module(f"homing.{part}")
    assert module.__file__ is not None
    assert module.__name__ == f"homing.{part}"


def _homing(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "homing.missions.cli", *args], capture_output=True, text=True, timeout=120
    )


def test_help_lists_subcommands() -> None:
    out = _homing("--help")
    assert out.returncode == 0
    assert "bench" in out.stdout


def test_bad_argument_is_one_line_exit_2() -> None:
    out = _homing("no-such-command")
    assert out.returncode == 2
    assert out.stderr.count("\n") == 1, out.stderr
    assert "Traceback" not in out.stderr


def test_ci_runs_the_readme_test_command() -> None:
    readme = (REPO / "README.md").read_text()
    ci = (REPO / ".ci" / "run").read_text()
    command = next(line for line in ci.splitlines() if line.startswith("python3 -m venv"))
    assert command in readme


def test_readme_mission_example_compiles(tmp_path) -> None:
    import re

    from homing.missions.compiler import compile_mission

    block = re.search(r"```yaml\n(.*?)```", (REPO / "README.md").read_text(), re.S)
    assert block is not None, "the README shows a mission"
    path = tmp_path / "readme.yaml"
    path.write_text(block.group(1))
    mission = compile_mission(path)
    assert {spec.name for spec, _ in mission.services} == {"grid_slam", "navigation"}


def test_log_formats_import_no_mission_language_simulator_or_benchmark() -> None:
    """``homing.logs`` is a layer below the missions that record and replay logs (DESIGN.md, Layout)."""
    import ast

    above = ("homing.missions", "homing.behaviours", "homing.lifecycle", "homing.sim", "homing.benchmarks")
    offenders = []
    for path in sorted((REPO / "logs").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else (
                [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            offenders += [f"{path.name}:{node.lineno}: {n}" for n in names if n.startswith(above)]
    assert not offenders, offenders


def test_every_behaviour_module_imports_so_no_node_silently_goes_missing() -> None:
    from homing.behaviours import load_nodes
    from homing.behaviours.registry import NODES

    assert load_nodes(entry_points=False) == []
    for name in ("Undock", "GoHome", "ServoToStaging", "AutoDock", "Charge", "IsDocked", "EnoughEnergy", "Charged"):
        assert name in NODES
