"""The run directory: what a robot that lives for days keeps, saved at every dock and read back to resume.

A snapshot holds what the robot has learnt and counted, not how it got there:

- ``grid.npz``: the occupancy grid's log-odds, resolution and origin (resumes
  exactly), and ``map.yaml`` + ``map.pgm`` beside it (map_server, for people
  and other tools);
- ``state.json``: the format version, adapter time, the mission's counters and
  blackboard entries worth keeping (``/mission/cycles``, ``/nav/dock``), the
  tags' estimates with their covariances (the SLAM graph folded into priors,
  :class:`~homing.behaviours.tag_slam_service.TagSlamService`), and the
  simulator's own state when the robot is simulated (so the simulated world
  resumes where it was too).

Layout: ``DIR/snapshots/000017/…`` written completely first, then ``DIR/latest``
(one line: the snapshot's name) replaced atomically, then snapshots older than
the last ``KEEP`` removed. A run killed at any moment leaves ``latest``
naming a complete snapshot. Every mistake in a directory a user points at
(missing, not a run directory, a damaged file, a newer format) is a
:class:`~homing.errors.UserError` naming the file and what is wrong.
"""

from __future__ import annotations

import io
import json
import math
import shutil
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.mapping.map_io import save_grid
from homing.robot import Pose2

from homing.atomic import atomic_write
from homing.errors import UserError

FORMAT = 1  # state.json's format version
KEEP = 2  # snapshots kept
LATEST = "latest"


@dataclass
class Snapshot:
    """One dock's worth of what the robot keeps (see the module doc)."""

    time: float  # [s] adapter clock
    cycles: int = 0
    dock: Pose2 | None = None  # docked pose in map
    grid: OccupancyGrid | None = None
    landmarks: dict[int, tuple[Pose2, np.ndarray]] = field(default_factory=dict)  # tag id → (pose, (3, 3) cov)
    meta: dict[str, Any] = field(default_factory=dict)  # mission, world, seed: what the run was
    sim: dict[str, Any] | None = None  # the simulator's state (simulated robots only)
    pose: Pose2 | None = None  # where the robot stands in map when it starts off the dock, if known (not saved)


class RunDir:
    """A run directory at ``path``: :meth:`save` a snapshot, :meth:`load` the latest."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    # ---------------------------------------------------------------------------- checks
    def check_writable(self) -> None:
        """Before a run: the directory can be made and written (raises UserError otherwise)."""
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            probe = self.path / ".homing-probe"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as err:
            raise UserError(f"run directory: cannot write there: {err.strerror}", self.path) from None

    def has_run(self) -> bool:
        return (self.path / LATEST).is_file()

    # ------------------------------------------------------------------------------ save
    def save(self, snap: Snapshot) -> Path:
        """Write ``snap`` as the next snapshot and point ``latest`` at it; returns its folder."""
        folder_root = self.path / "snapshots"
        number = 1 + max((int(p.name) for p in folder_root.glob("[0-9]" * 6)), default=0)
        folder = folder_root / f"{number:06d}"
        folder.mkdir(parents=True, exist_ok=False)
        state: dict[str, Any] = {
            "format": FORMAT, "time": float(snap.time), "cycles": int(snap.cycles),
            "dock": None if snap.dock is None else [snap.dock.x, snap.dock.y, snap.dock.theta],
            "landmarks": {str(i): {"pose": [p.x, p.y, p.theta], "cov": np.asarray(c, float).tolist()}
                          for i, (p, c) in sorted(snap.landmarks.items())},
            "meta": snap.meta, "sim": snap.sim,
        }
        if snap.grid is not None:
            buf = io.BytesIO()
            np.savez_compressed(buf, logodds=snap.grid.logodds, resolution=np.float64(snap.grid.resolution),
                                origin=np.asarray(snap.grid.origin, dtype=np.float64))
            atomic_write(folder / "grid.npz", buf.getvalue())
            save_grid(folder / "map.yaml", snap.grid)
        atomic_write(folder / "state.json", json.dumps(state, indent=1, allow_nan=True))
        atomic_write(self.path / LATEST, folder.name + "\n")
        older = sorted(p for p in folder_root.glob("[0-9]" * 6) if p != folder)
        for old in older[: max(len(older) - (KEEP - 1), 0)]:
            shutil.rmtree(old, ignore_errors=True)
        return folder

    # ------------------------------------------------------------------------------ load
    def load(self) -> Snapshot:
        """The latest snapshot (raises UserError for anything a user could have got wrong or broken)."""
        if not self.path.exists():
            raise UserError("no such run directory", self.path)
        if not self.path.is_dir():
            raise UserError("not a run directory (a file)", self.path)
        latest = self.path / LATEST
        if not latest.is_file():
            raise UserError("not a run directory: no 'latest' snapshot (was it made with --run-dir?)", self.path)
        name = latest.read_text(errors="replace").strip()
        if not name.isdigit():
            raise UserError(f"damaged: names snapshot {name!r}", latest)
        folder = self.path / "snapshots" / name
        state_file = folder / "state.json"
        try:
            state = json.loads(state_file.read_text())
        except FileNotFoundError:
            raise UserError("damaged: the snapshot 'latest' names is missing", state_file) from None
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise UserError(f"damaged: not valid JSON ({err})", state_file) from None
        if not isinstance(state, dict) or not isinstance(state.get("format"), int):
            raise UserError("damaged: no format version", state_file)
        if state["format"] > FORMAT:
            raise UserError(f"written by a newer homing (format {state['format']}, this one reads {FORMAT})",
                            state_file)
        try:
            snap = Snapshot(
                time=_finite(state["time"], "time"), cycles=int(state.get("cycles", 0)),
                dock=_pose(state.get("dock")), meta=dict(state.get("meta") or {}), sim=state.get("sim"),
                landmarks={int(i): (_pose(v["pose"]) or Pose2(), _cov(v["cov"])) for i, v in
                           (state.get("landmarks") or {}).items()},
            )
        except (KeyError, TypeError, ValueError) as err:
            raise UserError(f"damaged: {err}", state_file) from None
        grid_file = folder / "grid.npz"
        if grid_file.exists():
            snap.grid = _grid(grid_file)
        return snap


def _finite(value: Any, name: str) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise ValueError(f"{name} is not a finite number")
    return v


def _pose(value: Any) -> Pose2 | None:
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 3:
        raise ValueError(f"a pose is three numbers, not {value!r}")
    return Pose2(*(_finite(v, "a pose") for v in value))


def _cov(value: Any) -> np.ndarray:
    cov = np.asarray(value, dtype=float)
    if cov.shape != (3, 3) or not np.all(np.isfinite(cov)):
        raise ValueError("a covariance is a 3 × 3 matrix of finite numbers")
    return cov


def _grid(path: Path) -> OccupancyGrid:
    try:
        with np.load(path, allow_pickle=False) as data:
            logodds = np.asarray(data["logodds"], dtype=np.float32)
            res = float(data["resolution"])
            origin = tuple(float(v) for v in np.asarray(data["origin"]).reshape(-1))
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as err:
        raise UserError(f"damaged grid: {err}", path) from None
    if logodds.ndim != 2 or not (res > 0 and math.isfinite(res)) or len(origin) != 2 or not np.all(np.isfinite(logodds)):
        raise UserError("damaged grid: wrong shape or values", path)
    grid = OccupancyGrid(res, (origin[0], origin[1]), (int(logodds.shape[0]), int(logodds.shape[1])))
    grid.logodds[:] = logodds
    grid.clear_cache()
    return grid
