"""The data types every adapter speaks: poses, twists and sensor readings.

All are frozen dataclasses so an observation can be logged, compared and
replayed without anyone mutating it behind the tree's back. Arrays inside
them are treated as read-only by convention. Units are SI (metres, radians,
seconds, volts); frames follow REP-103/105 (:mod:`homing.robot.frames`).
"""

from __future__ import annotations

import enum
import functools
import math
from dataclasses import dataclass, field

import numpy as np
from homing.robot.frames import wrap_angle, wrap_angles


@dataclass(frozen=True, slots=True)
class Pose2:
    """A planar pose: position (x, y) [m] and heading theta [rad], in some parent frame.

    ``a.compose(b)`` is ``a ⊕ b``: b expressed in a's frame, taken to a's
    parent. ``a.between(b)`` is ``a⁻¹ ⊕ b``, b seen from a.
    """

    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0

    def compose(self, other: Pose2) -> Pose2:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            wrap_angle(self.theta + other.theta),
        )

    def inverse(self) -> Pose2:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2(-c * self.x - s * self.y, s * self.x - c * self.y, wrap_angle(-self.theta))

    def between(self, other: Pose2) -> Pose2:
        return self.inverse().compose(other)

    def transform_points(self, points: np.ndarray) -> np.ndarray:
        """Map (N, 2) points from this pose's frame into its parent frame."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        c, s = math.cos(self.theta), math.sin(self.theta)
        x, y = pts[:, 0], pts[:, 1]
        out = np.empty_like(pts)
        # Written out rather than ``pts @ R.T``: a matrix product of a tall (N, 2) array with a 2 × 2 one is
        # several times slower than four scaled columns (a coverage check moves a million cell centres).
        out[:, 0] = c * x - s * y + self.x
        out[:, 1] = s * x + c * y + self.y
        return out

    def distance_to(self, other: Pose2) -> float:
        return math.hypot(other.x - self.x, other.y - self.y)

    def as_array(self) -> np.ndarray:
        return np.array([self.x, self.y, self.theta])

    @staticmethod
    def from_array(a: np.ndarray | list[float] | tuple[float, ...]) -> Pose2:
        return Pose2(float(a[0]), float(a[1]), wrap_angle(float(a[2])))

    def matrix(self) -> np.ndarray:
        """3 × 3 homogeneous matrix of this pose."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return np.array([[c, -s, self.x], [s, c, self.y], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, slots=True)
class Twist2:
    """A planar velocity in ``base_link``: forward speed v [m/s], yaw rate omega [rad/s]."""

    v: float = 0.0
    omega: float = 0.0


@dataclass(frozen=True, slots=True)
class Odometry:
    """Wheel odometry: the pose of ``base_link`` in ``odom`` and its twist, at ``stamp`` [s]."""

    stamp: float
    pose: Pose2
    twist: Twist2


@functools.lru_cache(maxsize=16)
def _ray_angles(angle_min: float, angle_increment: float, n: int) -> np.ndarray:
    """:attr:`Scan.angles`, worked out once per lidar (every scan of one asks for them several times)."""
    angles = wrap_angles(angle_min + angle_increment * np.arange(n))
    angles.flags.writeable = False
    return angles


@dataclass(frozen=True)
class Scan:
    """One planar lidar sweep in the ``laser`` frame (REP-103: x forward, counter-clockwise).

    ``ranges`` is (N,) float32 [m]; ray i points at ``angle_min + i·angle_increment``
    [rad]. A ray with no return (dropout, beyond ``range_max``, under
    ``range_min``) holds ``inf``. ``laser_pose`` is the laser in ``base_link``.
    """

    stamp: float
    angle_min: float
    angle_increment: float
    ranges: np.ndarray
    range_min: float
    range_max: float
    laser_pose: Pose2 = field(default_factory=Pose2)

    @property
    def angles(self) -> np.ndarray:
        """(N,) ray angles in the laser frame [rad] (read-only: one array per lidar, kept)."""
        return _ray_angles(self.angle_min, self.angle_increment, len(self.ranges))

    def valid(self) -> np.ndarray:
        """(N,) bool mask of rays with a return inside [range_min, range_max]."""
        r = self.ranges
        return np.isfinite(r) & (r >= self.range_min) & (r <= self.range_max)

    def points(self, frame_pose: Pose2 | None = None) -> np.ndarray:
        """(M, 2) end points of valid rays, in ``base_link`` (or through ``frame_pose``
        if given, e.g. the robot's pose in ``odom``)."""
        ok = self.valid()
        a = self.angles[ok]
        r = self.ranges[ok].astype(float)
        pts = self.laser_pose.transform_points(np.column_stack([r * np.cos(a), r * np.sin(a)]))
        return frame_pose.transform_points(pts) if frame_pose is not None else pts


@dataclass(frozen=True, slots=True)
class CameraInfo:
    """Pinhole intrinsics and where the camera sits on the robot.

    ``fx, fy, cx, cy`` in pixels; no distortion (rectified images).
    ``base_from_optical`` is the 4 × 4 transform from the camera's optical
    frame (z forward, x right, y down) to ``base_link``.
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float
    base_from_optical: np.ndarray

    def K(self) -> np.ndarray:
        """3 × 3 camera matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])


@dataclass(frozen=True)
class CameraImage:
    """One camera frame: (H, W) uint8 grey or (H, W, 3) uint8 RGB, with its intrinsics."""

    stamp: float
    image: np.ndarray
    info: CameraInfo

    def grey(self) -> np.ndarray:
        """The frame as (H, W) uint8 grey (ITU-R 601 luma)."""
        img = self.image
        if img.ndim == 2:
            return img
        w = np.array([0.299, 0.587, 0.114])
        return np.clip(img[..., :3].astype(np.float32) @ w, 0, 255).astype(np.uint8)


@dataclass(frozen=True, slots=True)
class Bumpers:
    """Kobuki's three bumpers: left (30°, 90°], centre [−30°, 30°], right [−90°, −30°)."""

    left: bool = False
    centre: bool = False
    right: bool = False

    def any(self) -> bool:
        return self.left or self.centre or self.right


class IR(enum.IntFlag):
    """Kobuki dock IR bit codes (kobuki_msgs/DockInfraRed)."""

    NONE = 0
    NEAR_LEFT = 1
    NEAR_CENTER = 2
    NEAR_RIGHT = 4
    FAR_CENTER = 8
    FAR_LEFT = 16
    FAR_RIGHT = 32


@dataclass(frozen=True, slots=True)
class DockIR:
    """What each of the robot's three IR receivers sees of the dock's emitters.

    Each field is an :class:`IR` bit set. Receivers as kobuki reports them:
    right, centre, left (``data[0..2]`` of DockInfraRed).
    """

    right: IR = IR.NONE
    centre: IR = IR.NONE
    left: IR = IR.NONE

    def any(self) -> bool:
        return bool(self.right or self.centre or self.left)


class ChargingState(enum.Enum):
    """Battery charging state as kobuki reports it."""

    DISCHARGING = "discharging"
    DOCKING_CHARGING = "docking_charging"
    DOCKING_CHARGED = "docking_charged"
    ADAPTER_CHARGING = "adapter_charging"
    ADAPTER_CHARGED = "adapter_charged"


class ChargingSource(enum.Enum):
    """Where charge comes from, if anywhere."""

    NONE = "none"
    DOCK = "dock"
    ADAPTER = "adapter"


@dataclass(frozen=True, slots=True)
class BatteryState:
    """A battery's voltage [V], percent [0..100], charge source and state."""

    voltage: float
    percent: float
    source: ChargingSource = ChargingSource.NONE
    state: ChargingState = ChargingState.DISCHARGING

    @property
    def charging(self) -> bool:
        return self.state in (ChargingState.DOCKING_CHARGING, ChargingState.ADAPTER_CHARGING)

    @property
    def on_dock(self) -> bool:
        return self.source is ChargingSource.DOCK


@dataclass(frozen=True, slots=True)
class BaseSwitches:
    """The Kobuki base's other switches: wheel drops (left, right), cliff sensors (left, centre, right)
    and the three buttons B0, B1, B2 (True while pressed). The simulator raises none of them."""

    wheel_drop_left: bool = False
    wheel_drop_right: bool = False
    cliff_left: bool = False
    cliff_centre: bool = False
    cliff_right: bool = False
    buttons: tuple[bool, bool, bool] = (False, False, False)

    def wheel_drop(self) -> bool:
        return self.wheel_drop_left or self.wheel_drop_right


@dataclass(frozen=True)
class Observation:
    """One snapshot of everything the robot senses, at ``stamp`` [s] on the adapter's clock.

    ``scan`` and ``image`` are the *latest* ones (their own stamps say when they
    were taken; an unchanged stamp means nothing new arrived). ``image`` is
    ``None`` when the camera has produced nothing (off, or nothing to render).
    ``computer_battery`` is the on-board computer's battery, ``None`` if unknown.
    ``devices_lost`` names the devices a hardware adapter has lost (unplugged,
    silent): while it is not empty the adapter keeps the base stopped, and the
    readings of the lost devices are their last ones.
    """

    stamp: float
    odom: Odometry
    scan: Scan | None
    image: CameraImage | None
    bumpers: Bumpers
    dock_ir: DockIR
    battery: BatteryState
    computer_battery: BatteryState | None = None
    switches: BaseSwitches = field(default_factory=BaseSwitches)
    devices_lost: tuple[str, ...] = ()
