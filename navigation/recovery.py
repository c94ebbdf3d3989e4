"""Recovery motions chosen by name: clear costmap, spin, back up, wait (Nav2's behavior server).

Each recovery is a small state machine driven by the caller's clock: call
``start(now, odom)`` once, then ``step(now, odom, scan_points)`` every tick;
it returns ``(status, Twist2)`` and never blocks or sleeps. Progress is
measured on odometry (``odom`` frame), which is smooth even when the map
jumps. As in Nav2 (``nav2_behaviors``): ``spin`` turns by a relative angle,
``backup`` drives straight backwards a distance, ``wait`` holds still, and
``clear_costmap`` empties the obstacle layer in one tick. Spin and back-up
fail on their time allowance, and back-up stops and fails if the scan shows
something behind the robot.
"""

from __future__ import annotations

import enum
import math
from typing import Protocol

import numpy as np
from homing.navigation.controller import SAFETY_MARGIN, safe_speed
from homing.navigation.costmap import Costmap
from homing.robot import Pose2, Twist2
from homing.robot.frames import wrap_angle
from homing.robot.turtlebot import FOOTPRINT_RADIUS

SPIN_ANGLE = 2.0 * math.pi  # [rad] a full turn seeds and refreshes the costmap
SPIN_OMEGA = 1.0  # [rad/s] Nav2's max_rotational_vel
SPIN_ACCEL = 3.2  # [rad/s²] Nav2's rotational_acc_lim
SPIN_MIN_OMEGA = 0.4  # [rad/s] Nav2's min_rotational_vel
BACKUP_DISTANCE = 0.15  # [m] Nav2 BT default
BACKUP_SPEED = 0.025  # [m/s] Nav2 BT default
WAIT_TIME = 5.0  # [s]
TIME_ALLOWANCE = 20.0  # [s] Nav2 default


class MotionStatus(enum.Enum):
    """Where a recovery is."""

    RUNNING = "running"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


class Recovery(Protocol):
    """A clock-driven recovery motion (see the module doc)."""

    name: str
    message: str

    def start(self, now: float, odom: Pose2) -> None: ...

    def step(self, now: float, odom: Pose2, scan_points: np.ndarray | None = None) -> tuple[MotionStatus, Twist2]: ...


class Spin:
    """Turn in place by ``angle`` [rad] (sign = direction), trapezoidal speed, counting yaw on odometry."""

    name = "spin"

    def __init__(self, angle: float = SPIN_ANGLE, omega: float = SPIN_OMEGA, accel: float = SPIN_ACCEL,
                 time_allowance: float = TIME_ALLOWANCE) -> None:
        self.angle = angle  # [rad]
        self.omega = abs(omega)  # [rad/s]
        self.accel = accel  # [rad/s²]
        self.time_allowance = time_allowance  # [s]
        self.turned = 0.0  # [rad] so far, signed
        self.message = ""
        self._t0 = 0.0
        self._last: Pose2 | None = None

    def start(self, now: float, odom: Pose2) -> None:
        self._t0, self._last, self.turned, self.message = now, odom, 0.0, "spinning"

    def step(self, now: float, odom: Pose2, scan_points: np.ndarray | None = None) -> tuple[MotionStatus, Twist2]:
        assert self._last is not None, "start() first"
        self.turned += wrap_angle(odom.theta - self._last.theta)
        self._last = odom
        left = abs(self.angle) - math.copysign(1.0, self.angle) * self.turned
        if left <= 0.0:
            self.message = f"turned {math.degrees(self.turned):.0f}°"
            return MotionStatus.SUCCEEDED, Twist2()
        if now - self._t0 > self.time_allowance:
            self.message = f"spin timed out after {math.degrees(self.turned):.0f}°"
            return MotionStatus.FAILED, Twist2()
        # Brake so as to stop on the angle: ω ≤ √(2·α·left).
        w = max(SPIN_MIN_OMEGA, min(self.omega, math.sqrt(2.0 * self.accel * left)))
        return MotionStatus.RUNNING, Twist2(0.0, math.copysign(w, self.angle))


class BackUp:
    """Drive straight backwards ``distance`` [m] at ``speed`` [m/s], measured on odometry; stop if the scan sees something behind."""

    name = "backup"

    def __init__(self, distance: float = BACKUP_DISTANCE, speed: float = BACKUP_SPEED,
                 time_allowance: float = TIME_ALLOWANCE, radius: float = FOOTPRINT_RADIUS + SAFETY_MARGIN) -> None:
        self.distance = abs(distance)  # [m]
        self.speed = abs(speed)  # [m/s]
        self.time_allowance = time_allowance  # [s]
        self.radius = radius  # [m]
        self.travelled = 0.0  # [m]
        self.message = ""
        self._t0 = 0.0
        self._origin = Pose2()

    def start(self, now: float, odom: Pose2) -> None:
        self._t0, self._origin, self.travelled, self.message = now, odom, 0.0, "backing up"

    def step(self, now: float, odom: Pose2, scan_points: np.ndarray | None = None) -> tuple[MotionStatus, Twist2]:
        self.travelled = self._origin.distance_to(odom)
        if self.travelled >= self.distance:
            self.message = f"backed up {self.travelled:.2f} m"
            return MotionStatus.SUCCEEDED, Twist2()
        if now - self._t0 > self.time_allowance:
            self.message = f"back-up timed out after {self.travelled:.2f} m"
            return MotionStatus.FAILED, Twist2()
        v = -min(self.speed, max(0.02, self.distance - self.travelled))
        if scan_points is not None and len(scan_points):
            # Check just the stretch still to go; back-up is slow, so the scan check is about contact.
            v_safe = safe_speed(v, 0.0, scan_points, self.radius)
            if v_safe > -1e-3:
                self.message = "obstacle behind: cannot back up"
                return MotionStatus.FAILED, Twist2()
            v = v_safe
        return MotionStatus.RUNNING, Twist2(v, 0.0)


class Wait:
    """Hold still for ``duration`` [s] of the caller's clock."""

    name = "wait"

    def __init__(self, duration: float = WAIT_TIME) -> None:
        self.duration = duration  # [s]
        self.message = ""
        self._t0 = 0.0

    def start(self, now: float, odom: Pose2) -> None:
        self._t0, self.message = now, "waiting"

    def step(self, now: float, odom: Pose2, scan_points: np.ndarray | None = None) -> tuple[MotionStatus, Twist2]:
        if now - self._t0 >= self.duration:
            self.message = f"waited {now - self._t0:.1f} s"
            return MotionStatus.SUCCEEDED, Twist2()
        return MotionStatus.RUNNING, Twist2()


class ClearCostmap:
    """Empty the costmap's obstacle layer (the static map stays) and succeed at once."""

    name = "clear_costmap"

    def __init__(self, costmap: Costmap | None = None) -> None:
        self.costmap = costmap
        self.message = ""

    def start(self, now: float, odom: Pose2) -> None:
        self.message = "clearing the costmap"

    def step(self, now: float, odom: Pose2, scan_points: np.ndarray | None = None) -> tuple[MotionStatus, Twist2]:
        if self.costmap is None:
            self.message = "no costmap to clear"
            return MotionStatus.FAILED, Twist2()
        self.costmap.clear()
        self.message = "costmap cleared"
        return MotionStatus.SUCCEEDED, Twist2()


RECOVERIES: dict[str, type] = {
    "spin": Spin,
    "backup": BackUp,
    "wait": Wait,
    "clear_costmap": ClearCostmap,
}


def make_recovery(name: str, **params: object) -> Recovery:
    """The recovery registered as ``name`` (``spin``, ``backup``, ``wait``, ``clear_costmap``)."""
    if name not in RECOVERIES:
        raise KeyError(f"unknown recovery '{name}' (known: {', '.join(sorted(RECOVERIES))})")
    rec: Recovery = RECOVERIES[name](**params)
    return rec
