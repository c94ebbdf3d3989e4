"""Frames and angle helpers (REP-103 / REP-105).

Units are SI: metres, radians, seconds. Frames: ``map`` → ``odom`` →
``base_link`` → ``laser`` / ``camera``. In ``base_link`` x points forward,
y left, z up. The camera's *optical* frame follows the OpenCV/ROS optical
convention instead: z forward (out of the lens), x right, y down.
"""

from __future__ import annotations

import math

import numpy as np

MAP = "map"
ODOM = "odom"
BASE_LINK = "base_link"
LASER = "laser"
CAMERA = "camera"

# Rotation taking vectors in the camera optical frame (z forward, x right,
# y down) into a body frame looking along the body's +x (x forward, y left, z up).
R_BODY_FROM_OPTICAL = np.array(
    [[0.0, 0.0, 1.0],
     [-1.0, 0.0, 0.0],
     [0.0, -1.0, 0.0]]
)


def wrap_angle(a: float) -> float:
    """Wrap an angle to [-π, π) [rad]."""
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def wrap_angles(a: np.ndarray) -> np.ndarray:
    """Vectorised :func:`wrap_angle` over an array of angles [rad]."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def rot_z(yaw: float) -> np.ndarray:
    """3 × 3 rotation about z by ``yaw`` [rad]."""
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_y(pitch: float) -> np.ndarray:
    """3 × 3 rotation about y by ``pitch`` [rad] (positive pitches the x axis down)."""
    c, s = math.cos(pitch), math.sin(pitch)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def homogeneous(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """4 × 4 homogeneous transform from a 3 × 3 rotation and a translation."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(t, dtype=float).reshape(3)
    return T
