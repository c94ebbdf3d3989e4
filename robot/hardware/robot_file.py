"""The robot file (``robot.yaml``): which ports the devices are on, their baud rates and calibration.

``homing run MISSION --robot robot.yaml`` drives the real robot described by
it on the wall clock. Every mistake is reported at ``file:line:col``.
Relative paths (ports, camera info, the computer's battery) are taken
relative to the robot file's folder. Example (the bundled
``robot.example.yaml`` beside this module)::

    base:                         # Kobuki, kobuki_core's udev rule names it /dev/kobuki
      port: /dev/kobuki
      baud: 115200
      wheel_separation: 0.230     # [m] the firmware's bias for speed/radius
      wheel_radius: 0.035         # [m]
      cmd_timeout: 0.6            # [s] stop when no command came for this long
    lidar:                        # RPLIDAR A1
      port: /dev/rplidar
      baud: 115200
      pose: [0.0, 0.0, 0.0]       # laser in base_link: x [m], y [m], yaw [rad]
      range_min: 0.15             # [m]
      range_max: 6.0              # [m]
    camera:                       # optional: a camera through OpenCV
      source: 0                   # device index (/dev/video0), device path, stream URL, or a video file
      info: xtion_rgb.yaml        # ROS camera_info YAML
      rate: 5                     # [Hz]
      delay: 0.0                  # [s] capture-to-arrival latency, taken off each frame's stamp
      pose: [0.10, 0.0, 0.30, 0.0]  # optical centre x, y, z [m] in base_link, and yaw [rad]; level
    computer_battery: /sys/class/power_supply/BAT0  # optional: the laptop's Linux power_supply
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from homing.robot.hardware.camera import is_url
from homing.robot.turtlebot import LIDAR_RANGE_MAX, LIDAR_RANGE_MIN, WHEEL_RADIUS, WHEEL_SEPARATION
from homing.robot.types import Pose2

from homing.section import Section
from homing.yamlfile import load, where

BAUDS = (9600, 19200, 38400, 57600, 115200, 230400, 256000, 460800, 921600)


@dataclass(frozen=True)
class Where:
    """Where a value sits in the robot file, for one-line errors about it."""

    file: Path
    line: int = 0
    col: int = 0


@dataclass(frozen=True)
class BaseConfig:
    port: str
    at: Where
    baud: int = 115200
    wheel_separation: float = WHEEL_SEPARATION  # [m]
    wheel_radius: float = WHEEL_RADIUS  # [m]
    cmd_timeout: float = 0.6  # [s]


@dataclass(frozen=True)
class LidarConfig:
    port: str
    at: Where
    baud: int = 115200
    pose: Pose2 = Pose2()  # laser in base_link
    range_min: float = LIDAR_RANGE_MIN  # [m]
    range_max: float = LIDAR_RANGE_MAX  # [m]


@dataclass(frozen=True)
class CameraConfig:
    source: int | str
    info: Path
    at: Where
    info_at: Where
    rate: float = 5.0  # [Hz]
    pose: tuple[float, float, float, float] = (0.10, 0.0, 0.30, 0.0)  # x, y, z [m], yaw [rad]
    delay: float = 0.0  # [s] taken off each frame's arrival time


@dataclass(frozen=True)
class RobotConfig:
    """A parsed robot file."""

    file: Path
    base: BaseConfig
    lidar: LidarConfig
    camera: CameraConfig | None = None
    computer_battery: Path | None = None


def _where(sec: Section, key: str) -> Where:
    line, col = where(sec.doc, key)
    return Where(sec.file, line, col)


def _path(folder: Path, text: str) -> str:
    p = Path(text).expanduser()
    return str(p if p.is_absolute() else folder / p)


def load_robot(path: str | Path) -> RobotConfig:
    """Read and check a robot file (ports are not opened here)."""
    path = Path(path)
    folder = path.resolve().parent
    top = Section(load(path), path, "robot file")
    top.only(("kind", "base", "lidar", "camera", "computer_battery"))
    kind = top.string("kind", "turtlebot2")
    if kind != "turtlebot2":  # kind: ros2 is read by homing.robot.ros2.robot_file
        hint = " (a ros2 robot file is opened by homing.robot.ros2)" if kind == "ros2" else ""
        raise top.error("kind", f"'kind' must be turtlebot2 or ros2, not {kind!r}{hint}")
    for key in ("base", "lidar"):
        if not top.has(key):
            raise top.error(key, f"robot file: missing required section '{key}'")

    b = top.section("base")
    b.only(("port", "baud", "wheel_separation", "wheel_radius", "cmd_timeout"))
    base = BaseConfig(
        _path(folder, b.string("port")), _where(b, "port"), _baud(b),
        b.number("wheel_separation", WHEEL_SEPARATION, positive=True, hi=1.0),
        b.number("wheel_radius", WHEEL_RADIUS, positive=True, hi=0.5),
        b.number("cmd_timeout", 0.6, positive=True, hi=10.0),
    )  # fmt: skip

    li = top.section("lidar")
    li.only(("port", "baud", "pose", "range_min", "range_max"))
    pose = li.vector("pose", 3) if li.has("pose") else (0.0, 0.0, 0.0)
    rmin = li.number("range_min", LIDAR_RANGE_MIN, lo=0.0)
    rmax = li.number("range_max", LIDAR_RANGE_MAX, positive=True, hi=16.0)
    if rmax <= rmin:
        raise li.error("range_max", f"'range_max' ({rmax:g} m) must exceed 'range_min' ({rmin:g} m)")
    lidar = LidarConfig(_path(folder, li.string("port")), _where(li, "port"), _baud(li), Pose2(*pose), rmin, rmax)

    camera = None
    if top.has("camera"):
        c = top.section("camera")
        c.only(("source", "info", "rate", "pose", "delay"))
        raw = c.raw("source")
        if isinstance(raw, bool) or not isinstance(raw, (int, str)) or raw == "":
            raise c.error("source", f"'source' must be a device index, a path or a URL, not {raw!r}")
        source: int | str = raw if isinstance(raw, int) or is_url(raw) else _path(folder, raw)
        camera = CameraConfig(
            source, Path(_path(folder, c.string("info"))), _where(c, "source"), _where(c, "info"),
            c.number("rate", 5.0, positive=True, hi=60.0),
            c.vector("pose", 4) if c.has("pose") else (0.10, 0.0, 0.30, 0.0),  # type: ignore[arg-type]
            c.number("delay", 0.0, lo=0.0, hi=1.0),
        )  # fmt: skip

    battery = None
    if top.has("computer_battery"):
        battery = Path(_path(folder, top.string("computer_battery")))
    return RobotConfig(path, base, lidar, camera, battery)


def _baud(sec: Section) -> int:
    baud = sec.integer("baud", 115200)
    if baud not in BAUDS:
        raise sec.error("baud", f"'baud' must be one of {', '.join(map(str, BAUDS))}, not {baud}")
    return baud
