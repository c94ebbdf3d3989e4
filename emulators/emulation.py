"""A simulated TurtleBot 2 served as real devices on pseudo-terminals and HTTP, on the wall clock.

:class:`Emulation` owns a :class:`homing.sim.SimRobot` and, in one thread,
every ``PERIOD`` (the Kobuki's 20 ms) of wall-clock time:

1. reads the bytes the adapter sent to the base and the lidar, and applies
   them (base control sets the wheels' speeds; SCAN starts the stream);
2. commands the simulator with the wheels' velocity and steps it by the
   wall-clock time that really passed, so simulated time is real time;
3. sends the base's feedback packet and the lidar nodes that are due;
4. publishes the camera's new frame on the MJPEG stream
   (:mod:`homing.emulators.camera_stream`): the simulator renders at its
   camera rate while a tag can be in view, as it does for the sim adapter;
   otherwise a frame is rendered at ``IDLE_FRAME_RATE`` so the stream stays
   alive, as a real camera's does (a ``camera_off`` fault stops it);
5. once a second, rewrites the computer battery's power_supply files.

Folder layout (``folder`` given by the caller): ``kobuki`` and ``rplidar``
(symlinks to the ptys), ``computer_battery/`` (``capacity``, ``status``,
``voltage_now``), ``camera_info.yaml`` (the simulated camera's intrinsics,
ROS format), ``robot.yaml`` naming them all (the camera by its stream's
URL, ``http://127.0.0.1:PORT/stream.mjpg``), and ``status.json`` (the
simulator's truth, for tests and benchmarks only) rewritten each second.
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any

from homing.emulators.camera_stream import MjpegServer
from homing.emulators.kobuki import DEAD_TIME, KobukiFirmware
from homing.emulators.pty_link import LineNoise, PtyLink
from homing.emulators.rplidar import RplidarFirmware
from homing.robot.hardware.camera import calibration_yaml, pinhole
from homing.robot.types import BatteryState, CameraImage, ChargingState
from homing.sim.world import World

from homing.atomic import atomic_write

PERIOD = 0.02  # [s] the Kobuki's feedback period
MAX_STEP = 0.1  # [s] a stall longer than this is not simulated all at once
STATUS_PERIOD = 1.0  # [s]
IDLE_FRAME_RATE = 1.0  # [Hz] frames rendered while no tag can be in view (the stream stays alive)

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

CAMERA_SECTION = """\
camera:
  source: {url}
  info: camera_info.yaml
  rate: {rate:g}
  pose: [{x:g}, {y:g}, {z:g}, 0.0]
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
                 command_noise: LineNoise | None = None, camera: bool = True, camera_port: int = 0,
                 dead_time: float = DEAD_TIME):
        from homing.sim.robot import SimRobot

        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.robot = SimRobot(world, seed=seed, camera=camera)
        self.base = KobukiFirmware(dead_time=dead_time)
        self.lidar = RplidarFirmware()
        self.base_link = PtyLink(self.folder / "kobuki", noise)
        self.lidar_link = PtyLink(self.folder / "rplidar", noise)
        self.stream = MjpegServer(port=camera_port) if camera else None
        self._frame_stamp: float | None = None  # [s] sim time of the last frame published
        self._next_idle_frame = 0.0  # [s] wall clock
        self.command_noise = command_noise or LineNoise()
        self.packets = 0
        self.distance = 0.0  # [m] travelled (truth)
        self.lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_scan = -math.inf
        self._next_status = 0.0

    @property
    def robot_file(self) -> Path:
        return self.folder / "robot.yaml"

    @property
    def camera_url(self) -> str | None:
        return self.stream.url if self.stream is not None else None

    def start(self) -> None:
        """Open the ptys and the camera's stream (OSError if its port cannot be had), write the files, run."""
        text = ROBOT_FILE
        if self.stream is not None:
            self.stream.start()
            self._publish(self.robot.render())  # a frame from the start, as a camera that is on
            text += self._camera_files()
        self.base_link.open()
        self.lidar_link.open()
        atomic_write(self.robot_file, text)
        self._write_files()
        self._thread = threading.Thread(target=self._run, name="homing-emulation", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self.base_link.unplug()
        self.lidar_link.unplug()
        if self.stream is not None:
            self.stream.stop()
        self._write_files()
        self.robot.close()

    def link(self, device: str) -> PtyLink:
        """The link of ``device``: 'base' or 'lidar'."""
        return {"base": self.base_link, "lidar": self.lidar_link}[device]

    def unplug(self, device: str) -> None:
        """Pull ``device``'s cable ('base', 'lidar' or 'camera'): its pty closes and its link disappears,
        or the camera's stream stops and its clients are cut off."""
        with self.lock:
            if device == "camera":
                if self.stream is not None:
                    self.stream.stop()
                return
            self.link(device).unplug()
            if device == "lidar":
                self.lidar.receive(bytes((0xA5, 0x25)))  # a lidar without power stops scanning

    def replug(self, device: str) -> None:
        """Plug ``device`` back in: a new pty behind the same link, or the stream on the same port."""
        with self.lock:
            if device == "camera":
                if self.stream is not None:
                    self.stream.start()
                return
            self.link(device).replug()

    def _camera_files(self) -> str:
        """Write the simulated camera's ``camera_info.yaml``; the robot file's camera section."""
        assert self.stream is not None and self.robot.camera is not None
        info = self.robot.camera.info
        cal = pinhole(info.width, info.height, info.fx, info.fy, info.cx, info.cy)
        atomic_write(self.folder / "camera_info.yaml", calibration_yaml(cal, "emulated_xtion_rgb"))
        x, y, z = (float(v) for v in info.base_from_optical[:3, 3])
        # Keep up to twice the camera's rate: every frame passes, even an idle frame just before a new one.
        return CAMERA_SECTION.format(url=self.stream.url, rate=2.0 / self.robot.camera_period, x=x, y=y, z=z)

    def _publish(self, image: CameraImage) -> None:
        assert self.stream is not None
        self._frame_stamp = image.stamp
        self.stream.publish(image.image, image.stamp)

    def _camera(self, image: CameraImage | None, wall: float) -> None:
        """Publish the simulator's new frame, or render one if the stream has been idle too long."""
        if self.stream is None or not self.stream.running:
            return
        t = self.robot.clock.now()
        if any(f.name == "camera_off" and f.active(t) for f in self.robot.faults):
            return
        if image is not None and image.stamp != self._frame_stamp:
            self._publish(image)
        elif wall >= self._next_idle_frame:
            self._publish(self.robot.render())
        else:
            return
        self._next_idle_frame = wall + 1.0 / IDLE_FRAME_RATE

    def _run(self) -> None:
        start = last = deadline = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            with self.lock:
                self._tick(min(now - last, MAX_STEP), now - start)
            last = now
            # Keep the firmware's 50 Hz on average: a late tick (a frame rendered, the CPU busy) is
            # followed by a shorter wait; after a stall longer than MAX_STEP, start counting again.
            deadline = max(deadline + PERIOD, time.monotonic() - MAX_STEP)
            time.sleep(max(0.0, deadline - time.monotonic()))

    def _tick(self, dt: float, wall: float) -> None:
        self.base.receive(self.command_noise(self.base_link.read()), wall)
        self.lidar.receive(self.command_noise(self.lidar_link.read()))
        v, omega = self.base.velocity(wall)
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
        self._camera(obs.image, wall)
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
            "frames": self.stream.frames if self.stream is not None else 0,
            "frames_sent": self.stream.sent if self.stream is not None else 0,
            "written": {"base": self.base_link.written, "lidar": self.lidar_link.written},
            "dropped": {"base": self.base_link.dropped, "lidar": self.lidar_link.dropped},
        }  # fmt: skip

    def _write_files(self, battery: BatteryState | None = None) -> None:
        state = battery if battery is not None else self.robot.observe().computer_battery
        for name, text in power_supply_files(state).items():
            atomic_write(self.folder / "computer_battery" / name, text)
        atomic_write(self.folder / "status.json", json.dumps(self.status(), indent=1) + "\n")
