"""ruff and mypy pass over the whole code base (STYLE.md: both run in CI).

mypy names modules by folder, so the repository's layout (``robot/`` is
``homing.robot``) is presented to it as a symlink farm shaped like the
installed package, built from pyproject's ``package-dir``.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from tests.conftest import REPO


def _tool(name: str) -> str:
    path = shutil.which(name, path=str(Path(sys.executable).parent)) or shutil.which(name)
    if path is None:
        pytest.fail(f"{name} is not installed: it is part of the [test] extra")
    return path


def test_ruff_is_clean() -> None:
    out = subprocess.run([_tool("ruff"), "check", "--no-cache", "."], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr


@pytest.mark.slow
def test_mypy_is_clean(tmp_path: Path) -> None:
    dirs = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    root = tmp_path / "homing"
    root.mkdir()
    for item in (REPO / dirs["homing"]).iterdir():
        (root / item.name).symlink_to(item)
    for pkg, folder in dirs.items():
        if pkg != "homing":
            (root / pkg.split(".", 1)[1]).symlink_to(REPO / folder)
    out = subprocess.run(
        [_tool("mypy"), "--config-file", str(REPO / "pyproject.toml"), "--cache-dir", str(tmp_path / ".mypy_cache"),
         "-p", "homing"],
        cwd=tmp_path, capture_output=True, text=True, timeout=900,
        env={"MYPYPATH": str(tmp_path), "PATH": str(Path(sys.executable).parent)},
    )  # fmt: skip
    assert out.returncode == 0, out.stdout[-5000:] + out.stderr[-2000:]
