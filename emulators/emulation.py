"""A simulated TurtleBot 2 served as real devices on pseudo-terminals, on the wall clock.

:class:`Emulation` owns a :class:`homing.sim.SimRobot` and, in one thread,
every ``PERIOD`` (the Kobuki's 20 ms) of wall-clock time:

1. reads the bytes the adapter sent to the base and the lidar, and applies
   them (base control sets the wheels' speeds; SCAN starts the stream);
2. commands the simulator with the wheels' velocity and steps it by the
   wall-clock time that really passed, so simulated time is real time;
3. sends the base's feedback packet and the lidar nodes that are due;
4. once a second, rewrites the computer battery's power_supply files.

Folder layout (``folder`` given by the caller): ``kobuki`` and ``rplidar``
(symlinks to the ptys), ``computer_battery/`` (``capacity``, ``status``,
``voltage_now``), ``robot.yaml`` naming them, and ``status.json`` (the
simulator's truth, for tests and benchmarks only) rewritten each second.
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any

from homing.emulators.kobuki import KobukiFirmware
from homing.emulators.pty_link import LineNoise, PtyLink
from homing.emulators.rplidar import RplidarFirmware
from homing.robot.types import BatteryState, ChargingState
from homing.sim.world import World

from homing.atomic import atomic_write

PERIOD = 0.02  # [s] the Kobuki's feedback period
MAX_STEP = 0.1  # [s] a stall longer than this is not simulated all at once
STATUS_PERIOD = 1.0  # [s]

ROBOT_FILE = """\
# Written by 'homing emulate': the emulated TurtleBot 2's devices.
base:
  port: kobuki
  baud: 115200
lidar:
  port: rplidar
  baud: 115200
  pose: [0.0, 0.0, 0.0]
computer_battery: computer_battery
"""


def power_supply_files(state: BatteryState | None) -> dict[str, str]:
    """Linux power_supply attribute files for a battery reading."""
    if state is None:
        return {}
    if state.state in (ChargingState.DOCKING_CHARGED, ChargingState.ADAPTER_CHARGED):
        status = "Full"
    elif state.charging:
        status = "Charging"
    else:
        status = "Discharging"
    return {"capacity": f"{round(state.percent)}\n", "status": f"{status}\n",
            "voltage_now": f"{round(state.voltage * 1e6)}\n"}  # fmt: skip


class Emulation:
    """The simulated robot behind emulated serial devices in ``folder``."""

    def __init__(self, world: World, folder: str | Path, seed: int = 0, noise: LineNoise | None = None,
                 command_noise: LineNoise | None = None):
        from homing.sim.robot import SimRobot

        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.robot = SimRobot(world, seed=seed, camera=False)
        self.base = KobukiFirmware()
        self.lidar = RplidarFirmware()
        self.base_link = PtyLink(self.folder / "kobuki", noise)
        self.lidar_link = PtyLink(self.folder / "rplidar", noise)
        self.command_noise = command_noise or LineNoise()
        self.packets = 0
        self.distance = 0.0  # [m] travelled (truth)
        self.first_motion: float | None = None  # [s] wall clock when the wheels first turned after a command
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_scan = -math.inf
        self._next_status = 0.0

    @property
    def robot_file(self) -> Path:
        return self.folder / "robot.yaml"

    def start(self) -> None:
        self.base_link.open()
        self.lidar_link.open()
        atomic_write(self.robot_file, ROBOT_FILE)
        self._write_files()
        self._thread = threading.Thread(target=self._run, name="homing-emulation", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.base_link.unplug()
        self.lidar_link.unplug()
        self._write_files()
        self.robot.close()

    def link(self, device: str) -> PtyLink:
        """The link of ``device``: 'base' or 'lidar'."""
        return {"base": self.base_link, "lidar": self.lidar_link}[device]

    def unplug(self, device: str) -> None:
        """Pull ``device``'s cable ('base' or 'lidar'): its pty closes and its link disappears."""
        with self.lock:
            self.link(device).unplug()
            if device == "lidar":
                self.lidar.receive(bytes((0xA5, 0x25)))  # a lidar without power stops scanning

    def replug(self, device: str) -> None:
        """Plug ``device`` back in: a new pty behind the same link."""
        with self.lock:
            self.link(device).replug()

    def _run(self) -> None:
        start = last = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            with self.lock:
                self._tick(min(now - last, MAX_STEP), now - start)
            last = now
            time.sleep(max(0.0, PERIOD - (time.monotonic() - now)))

    def _tick(self, dt: float, wall: float) -> None:
        self.base.receive(self.command_noise(self.base_link.read()))
        self.lidar.receive(self.command_noise(self.lidar_link.read()))
        v, omega = self.base.velocity()
        before = self.robot.truth_pose()
        self.robot.command(v, omega)
        self.robot.step(dt)
        self.distance += before.distance_to(self.robot.truth_pose())
        obs = self.robot.observe()
        if self.base_link.plugged:
            self.base_link.write(self.base.feedback(obs, round(obs.stamp * 1000.0)))
            self.packets += 1
        if obs.scan is not None and obs.scan.stamp != self._last_scan:
            self._last_scan = obs.scan.stamp
            self.lidar.new_scan(obs.scan.ranges, wall)
        out = self.lidar.output(wall)
        if self.lidar_link.plugged:
            self.lidar_link.write(out)
        if wall >= self._next_status:
            self._next_status = wall + STATUS_PERIOD
            self._write_files(obs.computer_battery)

    def status(self) -> dict[str, Any]:
        """The simulator's truth and the lines' counters (evaluation only)."""
        pose = self.robot.truth_pose()
        dock = self.robot.world.dock_pose
        return {
            "time": self.robot.clock.now(), "truth": [pose.x, pose.y, pose.theta],
            "from_dock": pose.distance_to(dock), "distance": self.distance, "charging": self.robot.charging,
            "packets": self.packets, "commands": self.base.commands,
            "command_errors": self.base.reader.stats.checksum_errors,
            "lidar_requests": len(self.lidar.requests),
            "written": {"base": self.base_link.written, "lidar": self.lidar_link.written},
            "dropped": {"base": self.base_link.dropped, "lidar": self.lidar_link.dropped},
        }  # fmt: skip

    def _write_files(self, battery: BatteryState | None = None) -> None:
        state = battery if battery is not None else self.robot.observe().computer_battery
        for name, text in power_supply_files(state).items():
            atomic_write(self.folder / "computer_battery" / name, text)
        atomic_write(self.folder / "status.json", json.dumps(self.status(), indent=1) + "\n")
