"""Facts about the TurtleBot 2 (Kobuki base, RPLIDAR A1, Asus Xtion): DESIGN.md.

Shared by the simulator and the hardware adapters so that both model the
same robot; nothing here is an algorithm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

# Kobuki base
BASE_RADIUS = 0.176  # [m]
FOOTPRINT_RADIUS = 0.19  # [m] costmap footprint (0.18–0.20 in DESIGN.md)
WHEEL_SEPARATION = 0.230  # [m]
WHEEL_RADIUS = 0.035  # [m]
MAX_V = 0.7  # [m/s] hardware limit
MAX_OMEGA = math.radians(180.0)  # [rad/s] hardware limit
NAV_MAX_V = 0.5  # [m/s] navigation never asks for more

# Bumper sectors in base_link [rad]: left (30°, 90°], centre [−30°, 30°], right [−90°, −30°)
BUMPER_CENTRE_HALF = math.radians(30.0)
BUMPER_SIDE_LIMIT = math.radians(90.0)

# The Kobuki docking station (kobuki docs): a box in front of the wall, its front face where the
# docked robot's rim stops; its AprilTag hangs on the wall above it, on its centre line (thesis §3.3.5).
DOCK_DEPTH = 0.12  # [m] wall face to the dock's front face
DOCK_WIDTH = 0.30  # [m]
DOCKED_FROM_WALL = DOCK_DEPTH + BASE_RADIUS  # [m] wall face to the docked robot's centre

# RPLIDAR A1 as used in the thesis
LIDAR_HEIGHT = 0.5  # [m]
LIDAR_RAYS = 360
LIDAR_RATE = 5.5  # [Hz]
LIDAR_RANGE_MIN = 0.15  # [m]
LIDAR_RANGE_MAX = 6.0  # [m]

# Kobuki odometry (kobuki_node with use_imu_heading): heading from the factory-calibrated
# gyro, distance from the wheel encoders. Documented here so that the simulator
# and the estimators assume the same model (homing.sim.odometry states it in full).
ODOM_K_S0 = 1.0e-4  # [m] encoder along-track variance per metre travelled
ODOM_K_SV = 5.0e-4  # [s] … extra per metre, per m/s of speed (slip grows with speed)
ODOM_K_SW = 1.0e-5  # [m²/rad] along-track variance per radian turned (scrub)
GYRO_NOISE = 5.0e-4  # [rad/√s] angle random walk of the integrated heading
GYRO_BIAS_SIGMA = 3.0e-5  # [rad/s] residual rate bias after factory calibration (≈ 0.1°/min), per power-up
GYRO_SCALE_SIGMA = 2.0e-3  # residual scale-factor error (0.2 %, ≈ 0.7° per full turn), per power-up

# Asus Xtion RGB
CAMERA_HFOV = math.radians(58.0)  # [rad]
CAMERA_VFOV = math.radians(45.0)  # [rad]

# Kobuki battery: Li-ion 4S, 2200 mAh
BATTERY_FULL_V = 16.5  # [V]
BATTERY_NOMINAL_V = 14.8  # [V]
BATTERY_LOW_V = 14.0  # [V]
BATTERY_DANGEROUS_V = 13.2  # [V]
BATTERY_CAPACITY_AH = 2.2  # [Ah]


def battery_percent(voltage: float) -> float:
    """Kobuki's battery percentage from voltage: 95·(V − 13.2)/(16.5 − 13.2) + 5, clipped to [0, 100]."""
    pct = 95.0 * (voltage - BATTERY_DANGEROUS_V) / (BATTERY_FULL_V - BATTERY_DANGEROUS_V) + 5.0
    return min(100.0, max(0.0, pct))


def battery_voltage(percent: float) -> float:
    """Inverse of :func:`battery_percent` on its unclipped range [V]."""
    return BATTERY_DANGEROUS_V + (percent - 5.0) * (BATTERY_FULL_V - BATTERY_DANGEROUS_V) / 95.0


def bumper_sector(angle: float) -> str | None:
    """Which bumper a contact at ``angle`` [rad] in base_link presses: 'left', 'centre', 'right' or None."""
    a = math.atan2(math.sin(angle), math.cos(angle))
    if -BUMPER_CENTRE_HALF <= a <= BUMPER_CENTRE_HALF:
        return "centre"
    if BUMPER_CENTRE_HALF < a <= BUMPER_SIDE_LIMIT:
        return "left"
    if -BUMPER_SIDE_LIMIT <= a < -BUMPER_CENTRE_HALF:
        return "right"
    return None


@dataclass(frozen=True)
class RobotLimits:
    """Velocity limits an adapter clips commands to, and the robot's size."""

    max_v: float = MAX_V  # [m/s]
    max_omega: float = MAX_OMEGA  # [rad/s]
    radius: float = BASE_RADIUS  # [m]

    def clip(self, v: float, omega: float) -> tuple[float, float]:
        return (
            min(self.max_v, max(-self.max_v, float(v))),
            min(self.max_omega, max(-self.max_omega, float(omega))),
        )
