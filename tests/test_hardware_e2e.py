"""End to end on the wall clock: ``homing emulate`` serves the lab; ``homing run explore --robot`` drives it.

The real adapters read the real byte streams over pseudo-terminals; the
same mission on the simulator's adapter, for the same time, is the yardstick
(undock, seed the map, explore; a map that agrees with the floor plan).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from homing.mapping.evaluate import cell_agreement
from homing.mapping.grid import UNKNOWN
from homing.mapping.map_io import load_grid
from homing.sim import load_world

SECONDS = "25s"
MILESTONES = ("Undock: RUNNING -> SUCCESS", "SeedMap: RUNNING -> SUCCESS", "Explore: INVALID -> RUNNING")


def _homing(*args: str, **kw: object) -> list[str]:
    return [sys.executable, "-m", "homing.missions.cli", *args]


def _map_figures(path: Path) -> tuple[float, float]:
    """(cell agreement with the lab's floor plan, observed area [m²]) of a saved map."""
    world = load_world("lab")
    grid = load_grid(path, grow=False)
    area = float((grid.data != UNKNOWN).sum()) * grid.resolution**2
    return cell_agreement(grid, world.map, world.start), area


@pytest.mark.slow
def test_explore_over_the_emulated_serial_ports(tmp_path: Path) -> None:
    emu_dir = tmp_path / "emu"
    emulator = subprocess.Popen(_homing("emulate", "--world", "lab", "--seed", "1", "--dir", str(emu_dir)),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        lines = []
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and not any(x.startswith("robot file:") for x in lines):
            line = emulator.stdout.readline() if emulator.stdout else ""
            if not line:
                break
            lines.append(line.strip())
        assert f"kobuki: {emu_dir / 'kobuki'}" in lines and f"rplidar: {emu_dir / 'rplidar'}" in lines
        robot_file = lines[-1].split(": ", 1)[1]
        hw = subprocess.run(_homing("run", "explore", "--robot", robot_file, "--until", SECONDS, "--no-view",
                                    "--save-map", str(tmp_path / "hw")),
                            capture_output=True, text=True, timeout=180)  # fmt: skip
    finally:
        emulator.send_signal(signal.SIGINT)
        out, err = emulator.communicate(timeout=30)
    assert hw.returncode == 0, hw.stdout[-2000:] + hw.stderr[-2000:]
    assert emulator.returncode == 0, err[-2000:]
    assert "robot at (" in out  # the emulator's closing line
    status = json.loads((emu_dir / "status.json").read_text())
    sim = subprocess.run(_homing("run", "explore", "--world", "lab", "--seed", "1", "--until", SECONDS, "--no-view",
                                 "--save-map", str(tmp_path / "sim")),
                         capture_output=True, text=True, timeout=180, env={**os.environ})  # fmt: skip
    assert sim.returncode == 0, sim.stderr[-2000:]
    for milestone in MILESTONES:
        assert milestone in hw.stdout and milestone in sim.stdout, milestone
    assert "(1.0× real time)" in hw.stdout  # the wall clock
    assert status["distance"] > 1.0 and status["command_errors"] == 0
    hw_agree, hw_area = _map_figures(tmp_path / "hw.yaml")
    sim_agree, sim_area = _map_figures(tmp_path / "sim.yaml")
    assert hw_agree > 0.9 and hw_agree > sim_agree - 0.05
    assert hw_area > 0.5 * sim_area and np.isfinite(hw_area)
