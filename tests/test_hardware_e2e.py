"""End to end on the wall clock: ``homing emulate`` serves the lab; ``homing run MISSION --robot`` drives it.

The real adapters read the real byte streams over pseudo-terminals and the
camera's MJPEG stream over HTTP; the same mission on the simulator's
adapter is the yardstick: for exploration, a map that agrees with the floor
plan; for the persistent lifecycle, one whole cycle (undock, explore, go
home, servo on the dock's tag, IR-dock), docked by the charger's word.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest
from homing.mapping.evaluate import cell_agreement
from homing.mapping.grid import UNKNOWN
from homing.mapping.map_io import load_grid
from homing.robot.hardware.kobuki import KobukiBase
from homing.robot.types import ChargingSource
from homing.sim import load_world

SECONDS = "25s"
MILESTONES = ("Undock: RUNNING -> SUCCESS", "SeedMap: RUNNING -> SUCCESS", "Explore: INVALID -> RUNNING")
SESSION = "10s"  # the persistent mission's time away from the dock: one cycle takes under a minute
CYCLE = ("Undock", "Explore", "GoHome", "ServoToStaging", "AutoDock")  # the leaves one cycle runs, in order
CHANGE = re.compile(r"^\[\s*([0-9.]+) s\] (\w+): (\w+) -> (\w+)$")


def _homing(*args: str) -> list[str]:
    return [sys.executable, "-m", "homing.missions.cli", *args]


@contextmanager
def _emulator(folder: Path) -> Iterator[dict[str, str]]:
    """``homing emulate --world lab`` in a subprocess: the devices it printed, by name; stopped with Ctrl-C."""
    emulator = subprocess.Popen(_homing("emulate", "--world", "lab", "--seed", "1", "--dir", str(folder)),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    devices: dict[str, str] = {}
    try:
        deadline = time.monotonic() + 60.0
        while time.monotonic() < deadline and "robot file" not in devices:
            line = emulator.stdout.readline() if emulator.stdout else ""
            if not line:
                break
            name, _, value = line.strip().partition(": ")
            devices[name] = value
        yield devices
    finally:
        emulator.send_signal(signal.SIGINT)
        out, err = emulator.communicate(timeout=30)
        devices["closing"] = out
    assert emulator.returncode == 0, err[-2000:]
    assert "robot at (" in out  # the emulator's closing line


def _map_figures(path: Path) -> tuple[float, float]:
    """(cell agreement with the lab's floor plan, observed area [m²]) of a saved map."""
    world = load_world("lab")
    grid = load_grid(path, grow=False)
    area = float((grid.data != UNKNOWN).sum()) * grid.resolution**2
    return cell_agreement(grid, world.map, world.start), area


@pytest.mark.slow
def test_explore_over_the_emulated_serial_ports(tmp_path: Path) -> None:
    emu_dir = tmp_path / "emu"
    with _emulator(emu_dir) as devices:
        assert devices["kobuki"] == str(emu_dir / "kobuki") and devices["rplidar"] == str(emu_dir / "rplidar")
        hw = subprocess.run(_homing("run", "explore", "--robot", devices["robot file"], "--until", SECONDS,
                                    "--no-view", "--save-map", str(tmp_path / "hw")),
                            capture_output=True, text=True, timeout=180)  # fmt: skip
    assert hw.returncode == 0, hw.stdout[-2000:] + hw.stderr[-2000:]
    status = json.loads((emu_dir / "status.json").read_text())
    sim = subprocess.run(_homing("run", "explore", "--world", "lab", "--seed", "1", "--until", SECONDS, "--no-view",
                                 "--save-map", str(tmp_path / "sim")),
                         capture_output=True, text=True, timeout=180)  # fmt: skip
    assert sim.returncode == 0, sim.stderr[-2000:]
    for milestone in MILESTONES:
        assert milestone in hw.stdout and milestone in sim.stdout, milestone
    assert "(1.0× real time)" in hw.stdout  # the wall clock
    assert status["distance"] > 1.0 and status["command_errors"] == 0
    hw_agree, hw_area = _map_figures(tmp_path / "hw.yaml")
    sim_agree, sim_area = _map_figures(tmp_path / "sim.yaml")
    assert hw_agree > 0.9 and hw_agree > sim_agree - 0.05
    assert hw_area > 0.5 * sim_area and np.isfinite(hw_area)


def cycle_phases(stdout: str) -> list[tuple[str, float, float, str]]:
    """The cycle's leaves as (name, start [s], end [s], final status), in the order they first started."""
    starts: dict[str, float] = {}
    phases = []
    for line in stdout.splitlines():
        m = CHANGE.match(line.strip())
        if m is None or m[2] not in CYCLE:
            continue
        t, node, new = float(m[1]), m[2], m[4]
        if new == "RUNNING" and node not in starts:
            starts[node] = t
        elif node in starts and new in ("SUCCESS", "FAILURE", "INVALID") and all(p[0] != node for p in phases):
            phases.append((node, starts[node], t, new))
    return phases


def _charger_over_the_protocol(port: str) -> ChargingSource:
    """The charging source the base reports in its feedback packets, read with the Kobuki adapter."""
    base = KobukiBase(port, time.monotonic)
    base.open()
    try:
        deadline = time.monotonic() + 5.0
        while not base.ready and time.monotonic() < deadline:
            time.sleep(0.02)
        assert base.ready
        return base.battery.source
    finally:
        base.close()


@pytest.mark.slow
def test_a_persistent_cycle_over_the_emulated_devices_as_in_the_simulator(tmp_path: Path) -> None:
    emu_dir = tmp_path / "emu"
    args = ("--set", f"session={SESSION}", "--set", "cycles=1", "--no-view", "--until", "150s")
    with _emulator(emu_dir) as devices:
        assert re.fullmatch(r"http://127\.0\.0\.1:\d+/stream\.mjpg", devices["camera"]), devices
        t0 = time.monotonic()
        hw = subprocess.run(_homing("run", "persistent", "--robot", devices["robot file"], *args),
                            capture_output=True, text=True, timeout=240)  # fmt: skip
        wall = time.monotonic() - t0
        charger = _charger_over_the_protocol(devices["kobuki"])
    status = json.loads((emu_dir / "status.json").read_text())
    assert hw.returncode == 0, hw.stdout[-3000:] + hw.stderr[-2000:]
    assert "stopped: success" in hw.stdout and "root SUCCESS" in hw.stdout and "(1.0× real time)" in hw.stdout
    assert "lost:" not in hw.stderr  # no device fell silent on the way
    phases = cycle_phases(hw.stdout)
    assert [p[0] for p in phases] == list(CYCLE) and all(p[3] == "SUCCESS" for p in phases if p[0] != "Explore"), (
        phases, hw.stdout[-4000:])
    # Docked: the charger says so over the Kobuki protocol, and the simulator's truth agrees.
    assert charger is ChargingSource.DOCK
    assert status["charging"] and status["from_dock"] < 0.01 and status["command_errors"] == 0
    assert status["frames_sent"] > 10  # the dock's tag was seen through the MJPEG stream
    sim = subprocess.run(_homing("run", "persistent", "--world", "lab", "--seed", "1", *args),
                         capture_output=True, text=True, timeout=240)  # fmt: skip
    assert sim.returncode == 0 and "stopped: success" in sim.stdout, sim.stdout[-3000:]
    sim_phases = cycle_phases(sim.stdout)
    assert [p[0] for p in sim_phases] == [p[0] for p in phases]
    hw_end, sim_end = phases[-1][2], sim_phases[-1][2]
    assert hw_end < 1.5 * sim_end + 10.0, (phases, sim_phases)  # on the wall clock about as fast
    print(f"\nwall {wall:.1f} s; hardware {[(n, round(b - a, 1)) for n, a, b, _ in phases]}; "
          f"sim {[(n, round(b - a, 1)) for n, a, b, _ in sim_phases]}")
