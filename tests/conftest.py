"""Shared fixtures: floor plans drawn for the tests, the public ones when present, seeded generators; Hypothesis derandomised."""

from __future__ import annotations

import contextlib
import io
import os
import selectors
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# The property tests draw the same examples every run, so a suite that passed passes again (CI lands on
# it). To search fresh examples, as a bug hunt: HYPOTHESIS_PROFILE=explore pytest tests/test_mission_check.py
settings.register_profile("seeded", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "seeded"))

REPO = Path(__file__).resolve().parent.parent
SHARED_WORLDS = REPO.parent / "shared" / "worlds"


@pytest.fixture(scope="session")
def floor_plans(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder of drawn floor plans (``loop``, ``room``, ``corridor``, ``room_with_corner``; YAML + PGM)."""
    from tests.floor_plans import write_plans

    return write_plans(tmp_path_factory.mktemp("floor_plans"))


@pytest.fixture
def shared_worlds() -> Path:
    """The six public floor plans beside the repository (development checkout only: skipped in a clone)."""
    if not SHARED_WORLDS.is_dir():
        pytest.skip(f"needs the public floor plans in ../shared/worlds (not found at {SHARED_WORLDS})")
    return SHARED_WORLDS


def homing_cli(*argv: str) -> tuple[int, str, str]:
    """(exit status, stdout, stderr) of ``homing ARGV`` run in this process (argparse's exits included)."""
    from homing.missions.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(argv))
        except SystemExit as done:
            code = int(done.code or 0)
    return code, out.getvalue(), err.getvalue()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@contextlib.contextmanager
def serving_run(option: str, banner: str, timeout: float = 60.0) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """A ``homing run explore --world lab`` subprocess at real time with ``option`` (e.g. ``--groot 0``).

    Yields the process and the stderr line that says where it serves (the first containing ``banner``);
    the process is killed on the way out if the test did not end it.
    """
    proc = subprocess.Popen(
        [sys.executable, "-m", "homing.missions.cli", "run", str(REPO / "missions" / "explore.yaml"), "--world", "lab",
         "--no-view", "--speed", "1", "--until", "10min", *option.split()],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )  # fmt: skip
    try:
        selector = selectors.DefaultSelector()
        selector.register(proc.stderr, selectors.EVENT_READ)  # type: ignore[arg-type]
        deadline = time.monotonic() + timeout
        line = ""
        while banner not in line:
            assert selector.select(max(0.0, deadline - time.monotonic())), "the run never said where it serves"
            line = proc.stderr.readline()  # type: ignore[union-attr]
            assert line, "the run ended before serving"
        yield proc, line
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
