"""End to end over Zenoh: ``homing emulate --ros2`` serves the lab as a ROS 2 robot; ``homing run --robot`` explores it.

The emulator is a Zenoh peer on 127.0.0.1 speaking rmw_zenoh's format
(LaserScan, Odometry, BatteryState, /tf, latched /tf_static; cmd_vel in);
the mission reaches it through Ros2Robot, a Zenoh client, on the wall clock.
The simulator's adapter running the same mission is the yardstick.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

pytest.importorskip("zenoh", reason="eclipse-zenoh (pip install 'homing[ros2]') is not installed")
pytest.importorskip("xxhash", reason="xxhash (pip install 'homing[ros2]') is not installed")

from homing.mapping.evaluate import cell_agreement  # noqa: E402
from homing.mapping.grid import UNKNOWN  # noqa: E402
from homing.mapping.map_io import load_grid  # noqa: E402
from homing.robot.ros2.node import Ros2Node  # noqa: E402
from homing.robot.ros2.wire import LATCHED, Qos, Received  # noqa: E402
from homing.sim import load_world  # noqa: E402

SECONDS = "25s"
MILESTONES = ("Undock: RUNNING -> SUCCESS", "SeedMap: RUNNING -> SUCCESS", "Explore: INVALID -> RUNNING")


def _homing(*args: str) -> list[str]:
    return [sys.executable, "-m", "homing.missions.cli", *args]


def _map_figures(path: Path) -> tuple[float, float]:
    """(cell agreement with the lab's floor plan, observed area [m²]) of a saved map."""
    world = load_world("lab")
    grid = load_grid(path, grow=False)
    return cell_agreement(grid, world.map, world.start), float((grid.data != UNKNOWN).sum()) * grid.resolution**2


@pytest.mark.slow
def test_explore_over_the_emulated_ros2_robot(tmp_path: Path) -> None:
    emu_dir = tmp_path / "emu"
    emulator = subprocess.Popen(_homing("emulate", "--world", "lab", "--seed", "1", "--ros2", "--dir", str(emu_dir)),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert emulator.stdout is not None
        endpoint = emulator.stdout.readline().strip()
        robot_line = emulator.stdout.readline().strip()
        assert re.fullmatch(r"tcp/127\.0\.0\.1:\d+", endpoint), endpoint
        assert robot_line == f"robot file: {emu_dir / 'robot.yaml'}"
        assert f"router: {endpoint}" in (emu_dir / "robot.yaml").read_text()
        probe = Ros2Node("probe", mode="client", connect=[endpoint])  # RViz on the robot's network, say
        heard: dict[str, list[Received]] = {"map": [], "status": [], "state": []}
        for name, topic, typename, qos in (
            ("map", "/map", "nav_msgs/msg/OccupancyGrid", LATCHED),
            ("status", "/tree/status", "diagnostic_msgs/msg/DiagnosticArray", Qos()),
            ("state", "/mission/state", "std_msgs/msg/String", LATCHED),
        ):
            probe.subscribe(topic, typename, qos, heard[name].append)
        t0 = time.monotonic()
        run = subprocess.run(_homing("run", "explore", "--robot", str(emu_dir / "robot.yaml"), "--until", SECONDS,
                                     "--no-view", "--save-map", str(tmp_path / "ros2")),
                             capture_output=True, text=True, timeout=180)  # fmt: skip
        wall = time.monotonic() - t0
        probe.close()
    finally:
        emulator.send_signal(signal.SIGINT)
        out, err = emulator.communicate(timeout=30)
    assert emulator.returncode == 0, err[-2000:]
    assert "robot at (" in out
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    for milestone in MILESTONES:
        assert milestone in run.stdout, milestone
    assert "(1.0× real time)" in run.stdout and wall < 60.0
    # homing's world model reached the robot's graph while it ran
    assert heard["map"] and heard["map"][-1].message.info.resolution == pytest.approx(0.05)
    assert (heard["map"][-1].message.data >= 0).sum() > 1000  # known cells
    assert {"Undocking", "Exploring"} <= {r.message.data for r in heard["state"]}
    assert any(s.name == "Explore" and s.level == 1 for r in heard["status"] for s in r.message.status)
    status = json.loads((emu_dir / "status.json").read_text())
    assert status["distance"] > 1.0 and status["commands"] > 100  # the commands drove the simulated base
    sim = subprocess.run(_homing("run", "explore", "--world", "lab", "--seed", "1", "--until", SECONDS, "--no-view",
                                 "--save-map", str(tmp_path / "sim")),
                         capture_output=True, text=True, timeout=180)  # fmt: skip
    assert sim.returncode == 0, sim.stderr[-2000:]
    agree, area = _map_figures(tmp_path / "ros2.yaml")
    sim_agree, sim_area = _map_figures(tmp_path / "sim.yaml")
    assert agree > 0.9 and agree > sim_agree - 0.05
    assert area > 0.5 * sim_area


CYCLE = ("Undock", "Explore", "GoHome", "ServoToStaging", "AutoDock")  # one cycle's leaves, in order
CHANGE = re.compile(r"^\[\s*([0-9.]+) s\] (\w+): (\w+) -> (\w+)$")


def _first_changes(stdout: str) -> list[tuple[str, str]]:
    """The cycle's leaves as (name, first final status), in the order they first finished."""
    done: dict[str, str] = {}
    for line in stdout.splitlines():
        m = CHANGE.match(line.strip())
        if m and m[2] in CYCLE and m[3] == "RUNNING" and m[2] not in done:
            done[m[2]] = m[4]
    return list(done.items())


@pytest.mark.slow
def test_a_persistent_cycle_over_the_emulated_ros2_robot(tmp_path: Path) -> None:
    """Undock, explore, go home, servo on the dock's tag (camera frames as sensor_msgs/Image) and IR-dock
    (kobuki_ros' DockInfraRed), docked by the BatteryState's word: over Zenoh only."""
    emu_dir = tmp_path / "emu"
    emulator = subprocess.Popen(_homing("emulate", "--world", "lab", "--seed", "1", "--ros2", "--dir", str(emu_dir)),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert emulator.stdout is not None
        emulator.stdout.readline()
        emulator.stdout.readline()
        run = subprocess.run(_homing("run", "persistent", "--robot", str(emu_dir / "robot.yaml"), "--set",
                                     "session=10s", "--set", "cycles=1", "--no-view", "--until", "150s"),
                             capture_output=True, text=True, timeout=240)  # fmt: skip
        status = json.loads((emu_dir / "status.json").read_text())
        deadline = time.monotonic() + 5.0  # status.json is rewritten every second: wait for the charger's word
        while not status["charging"] and time.monotonic() < deadline:
            time.sleep(0.1)
            status = json.loads((emu_dir / "status.json").read_text())
    finally:
        emulator.send_signal(signal.SIGINT)
        emulator.communicate(timeout=30)
    assert run.returncode == 0, run.stdout[-3000:] + run.stderr[-2000:]
    assert "stopped: success" in run.stdout and "root SUCCESS" in run.stdout
    # Explore is halted (INVALID) when the session ends; every other leaf of the cycle succeeds, in order
    assert _first_changes(run.stdout) == [(leaf, "INVALID" if leaf == "Explore" else "SUCCESS") for leaf in CYCLE]
    assert status["frames"] > 0 and status["distance"] > 1.0
    assert status["charging"] and status["from_dock"] < 0.05  # on the contacts, charging


def test_emulate_ros2_rejects_serial_only_options() -> None:
    done = subprocess.run(_homing("emulate", "--world", "lab", "--ros2", "--noise", "0.1"),
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.strip() == "--noise is for the emulated serial devices; it does not apply with --ros2"


ROUTER = """
import sys, threading
import zenoh
from homing.robot.ros2.node import session_config
session = zenoh.open(session_config("router", listen=[sys.argv[1]]))
print("listening", flush=True)
threading.Event().wait()
"""


def _router(endpoint: str) -> subprocess.Popen:
    """A Zenoh router in its own process, as ``rmw_zenohd`` is; returns once it listens."""
    router = subprocess.Popen([sys.executable, "-c", ROUTER, endpoint], stdout=subprocess.PIPE, text=True)
    assert router.stdout is not None and router.stdout.readline().strip() == "listening"
    return router


def _distance(emu_dir: Path) -> float:
    return float(json.loads((emu_dir / "status.json").read_text())["distance"])


def _until(predicate, timeout: float) -> bool:  # noqa: ANN001
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


def _settled(emu_dir: Path, quiet: float, timeout: float) -> float | None:
    """The distance travelled once it has not changed for ``quiet`` [s] (None if it still changes at ``timeout``)."""
    deadline = time.monotonic() + timeout
    last, since = _distance(emu_dir), time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(0.05)
        d = _distance(emu_dir)
        if d != last:
            last, since = d, time.monotonic()
        elif time.monotonic() - since >= quiet:
            return d
    return None


@pytest.mark.slow
def test_a_router_killed_mid_run_stops_the_robot_and_the_run_goes_on_when_it_is_back(tmp_path: Path) -> None:
    from homing.robot.ros2.node import free_port

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    emu_dir = tmp_path / "emu"
    router = _router(endpoint)
    emulator = subprocess.Popen(_homing("emulate", "--world", "lab", "--seed", "1", "--ros2", "--router", endpoint,
                                        "--no-camera", "--dir", str(emu_dir)),
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
    run = None
    errors: list[str] = []
    try:
        assert emulator.stdout is not None and emulator.stdout.readline().strip() == endpoint
        run = subprocess.Popen(_homing("run", "explore", "--robot", str(emu_dir / "robot.yaml"), "--until", "40s",
                                       "--no-view"), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)  # fmt: skip
        reader = threading.Thread(target=lambda: errors.extend(run.stderr), daemon=True)  # type: ignore[union-attr, arg-type]
        reader.start()
        assert _until(lambda: _distance(emu_dir) > 0.5, 30.0), "the robot never moved"
        router.kill()  # as a robot's computer losing power takes rmw_zenohd with it
        router.wait(10)
        assert _until(lambda: any("lost: router" in e for e in errors), 10.0), errors
        # zero commands and the base's watchdog (0.5 s): the robot stops and stays (status.json: once a second)
        stopped = _settled(emu_dir, quiet=2.5, timeout=8.0)
        assert stopped is not None, "the robot kept moving without its router"
        router = _router(endpoint)
        assert _until(lambda: any("back: " in e for e in errors), 30.0), errors
        assert _until(lambda: _distance(emu_dir) > stopped + 0.3, 25.0), "the run did not go on"
        out, _ = run.communicate(timeout=90)
        reader.join(10)
    finally:
        if run is not None and run.poll() is None:
            run.kill()
        emulator.send_signal(signal.SIGINT)
        emulator.communicate(timeout=30)
        router.kill()
        router.wait(10)
    assert run.returncode == 0, out[-2000:] + "".join(errors)[-2000:]
    assert "stopped: time_limit" in out
