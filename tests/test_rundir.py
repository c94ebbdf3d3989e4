"""The run directory: snapshots saved whole at every dock, read back exactly; a killed run resumes on its map."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from homing.lifecycle.rundir import FORMAT, KEEP, RunDir, Snapshot
from homing.mapping.grid import OccupancyGrid
from homing.robot import Pose2

from homing.errors import UserError
from tests.conftest import REPO


def _snapshot(cycles: int = 3) -> Snapshot:
    grid = OccupancyGrid(0.05, (-2.0, -3.0), (40, 60))
    grid.logodds[:] = np.random.default_rng(cycles).uniform(-4, 4, grid.logodds.shape).astype(np.float32)
    cov = np.diag([1e-4, 2e-4, 3e-4])
    return Snapshot(time=1234.5, cycles=cycles, dock=Pose2(0.1, -0.2, 3.0), grid=grid,
                    landmarks={0: (Pose2(0.3, 0.0, math.pi), cov), 7: (Pose2(4.0, 2.0, 1.0), 2 * cov)},
                    meta={"mission": "persistent", "world": "lab", "seed": 4}, sim={"t": 1234.5})


def test_a_snapshot_reads_back_exactly_and_only_the_last_ones_are_kept(tmp_path: Path) -> None:
    rd = RunDir(tmp_path / "run")
    for k in range(1, 5):
        rd.save(_snapshot(k))
    snap, want = rd.load(), _snapshot(4)
    assert (snap.time, snap.cycles, snap.dock, snap.meta, snap.sim) == (want.time, 4, want.dock, want.meta, want.sim)
    assert np.array_equal(snap.grid.logodds, want.grid.logodds) and snap.grid.origin == want.grid.origin
    assert snap.landmarks.keys() == {0, 7}
    assert snap.landmarks[7][0] == want.landmarks[7][0] and np.array_equal(snap.landmarks[7][1], want.landmarks[7][1])
    assert len(list((tmp_path / "run" / "snapshots").iterdir())) == KEEP
    assert (tmp_path / "run" / "snapshots" / "000004" / "map.yaml").is_file()  # a map_server map for people too


@pytest.mark.parametrize(("damage", "message"), [
    (lambda d: (d / "latest").unlink(), "no 'latest' snapshot"),
    (lambda d: (d / "latest").write_text("../x\n"), "damaged: names snapshot"),
    (lambda d: (d / "latest").write_text("000099\n"), "snapshot 'latest' names is missing"),
    (lambda d: (d / "snapshots/000001/state.json").write_text('{"format": 1, "time": '), "not valid JSON"),
    (lambda d: (d / "snapshots/000001/state.json").write_bytes(b"\xff\xfe\x00"), "not valid JSON"),
    (lambda d: (d / "snapshots/000001/state.json").write_text(json.dumps({"format": FORMAT + 1, "time": 0})),
     "newer homing"),
    (lambda d: (d / "snapshots/000001/state.json").write_text(json.dumps({"format": 1, "time": "soon"})), "damaged"),
    (lambda d: (d / "snapshots/000001/state.json").write_text(json.dumps({"format": 1, "time": 1, "dock": [1, 2]})),
     "three numbers"),
    (lambda d: (d / "snapshots/000001/grid.npz").write_bytes(b"PK\x03\x04 not a zip"), "damaged grid"),
])
def test_a_damaged_run_directory_is_one_line_naming_the_file(tmp_path: Path, damage, message: str) -> None:
    rd = RunDir(tmp_path / "run")
    rd.save(_snapshot())
    damage(tmp_path / "run")
    with pytest.raises(UserError) as err:
        rd.load()
    assert message in str(err.value) and "\n" not in str(err.value)
    assert str(tmp_path / "run") in str(err.value)


def _homing(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "homing.missions.cli", *args], capture_output=True, text=True,
                          timeout=timeout, cwd=REPO)


def test_run_dir_and_resume_mistakes_are_one_line_errors(tmp_path: Path) -> None:
    rd = RunDir(tmp_path / "taken")
    rd.save(_snapshot())
    cases = [
        (["--resume", str(tmp_path / "nowhere")], "no such run directory"),
        (["--resume", str(REPO / "README.md")], "not a run directory"),
        (["--resume", str(tmp_path)], "no 'latest' snapshot"),
        (["--world", "lab", "--run-dir", str(tmp_path / "taken")], "already holds a run"),
        (["--world", "lab", "--run-dir", "/proc/homing-run"], "cannot write there"),
        ([], "say which robot to run on"),
    ]
    for extra, message in cases:
        out = _homing("run", "persistent", "--no-view", "--until", "1s", *extra)
        assert out.returncode == 2, (extra, out.stderr)
        assert message in out.stderr and "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1


@pytest.mark.slow
def test_a_killed_run_resumes_on_its_saved_map_without_exploring_again(tmp_path: Path) -> None:
    run = tmp_path / "run"
    cmd = [sys.executable, "-m", "homing.missions.cli", "run", "persistent", "--world", "lab", "--seed", "5",
           "--no-view", "--set", "session=300s", "--run-dir", str(run)]  # long enough to finish exploring
    proc = subprocess.Popen(cmd, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 600
        while not (run / "latest").is_file():  # the first dock's snapshot
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "no snapshot within 10 minutes"
            time.sleep(0.2)
        os.kill(proc.pid, signal.SIGKILL)  # no chance to tidy up
    finally:
        proc.wait(timeout=60)
    saved = RunDir(run).load()
    assert saved.cycles == 1 and saved.grid is not None and saved.dock is not None
    known = (saved.grid.data != -1).sum()
    out = _homing("run", "persistent", "--resume", str(run), "--no-view", "--until", "90s", "--set", "session=60s")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    changes = [ln for ln in lines if ln.startswith("[")]
    start = next(ln for ln in changes if "MissionState: INVALID -> SUCCESS" in ln)
    assert float(start.split("]")[0].strip("[ s")) == pytest.approx(saved.time, abs=0.5)  # the world carried on
    # It starts on its saved map, not from nothing: the first status line already has the saved free area.
    # (Whether exploration then ends at once depends on how the first session ended: explored, or incomplete
    # with places given up, which a later round - this one - tries again.)
    first = next(ln for ln in lines if "] state " in ln and " mapped " in ln)
    mapped = float(first.split(" mapped ")[1].split(" m²")[0])
    assert mapped >= 0.95 * (saved.grid.data == 0).sum() * saved.grid.resolution**2, first
    began = [ln for ln in changes if ln.split("] ")[1].startswith("Explore: INVALID -> ")]
    assert began, "the resumed run never got out of the dock"
    # The explorer worked on the saved map: its end report counts the saved free area, not a fresh spin's. (An
    # ExploreError may come and go: a frontier the costmap cuts off is the recoveries' to act on, then given up.)
    for report in (ln for ln in lines if ln.startswith("Explore: ") and "% of " in ln):  # if it gave a verdict
        free = float(report.split("% of ")[1].split(" m²")[0])
        assert free >= 0.95 * (saved.grid.data == 0).sum() * saved.grid.resolution**2, report
    resumed = RunDir(run).load()
    assert resumed.cycles >= 1 and (resumed.grid.data != -1).sum() >= 0.95 * known
    assert "resumed at t=" in lines[-1]
