"""Pinhole camera model: intrinsics from a field of view, projection, and synthetic tag frames.

The camera is an ideal pinhole (Hartley & Zisserman, *Multiple View
Geometry*, ch. 6) with rectified images, as :class:`homing.robot.CameraInfo`
describes it. Frames: the *optical* frame is z forward, x right, y down
(OpenCV/ROS); ``CameraInfo.base_from_optical`` takes it to ``base_link``.

:func:`render_tag` warps an official tag36h11 image into a frame through the
homography of a known pose. It makes the frames the unit tests and the demo
check the detector against; the simulator renders the real camera images.
Do not use it as a camera model for anything else: no lighting, blur or
occlusion.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from homing.robot.frames import R_BODY_FROM_OPTICAL, homogeneous
from homing.robot.types import CameraInfo

TAG36H11_CELLS = 8  # black square edge in cells (1 black border + 6 data + 1 black border)
TAG36H11_TOTAL_CELLS = 10  # with the white quiet zone around it


def intrinsics_from_hfov(width: int, height: int, hfov: float) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) [px] of a square-pixel pinhole with horizontal field of view ``hfov`` [rad]."""
    fx = 0.5 * width / math.tan(0.5 * hfov)
    return fx, fx, 0.5 * (width - 1), 0.5 * (height - 1)


def camera_info(
    width: int, height: int, hfov: float, position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    yaw: float = 0.0,
) -> CameraInfo:
    """A :class:`CameraInfo` for a level camera at ``position`` [m] in base_link looking along ``yaw`` [rad]."""
    fx, fy, cx, cy = intrinsics_from_hfov(width, height, hfov)
    c, s = math.cos(yaw), math.sin(yaw)
    rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return CameraInfo(width, height, fx, fy, cx, cy, homogeneous(rz @ R_BODY_FROM_OPTICAL, np.array(position)))


def project(info: CameraInfo, points_optical: np.ndarray) -> np.ndarray:
    """(N, 2) pixel coordinates of (N, 3) points in the optical frame [m] (z must be > 0)."""
    p = np.asarray(points_optical, dtype=float).reshape(-1, 3)
    return np.column_stack([info.fx * p[:, 0] / p[:, 2] + info.cx, info.fy * p[:, 1] / p[:, 2] + info.cy])


def tag36h11_texture(tag_id: int, px_per_cell: int = 10) -> np.ndarray:
    """(10·c, 10·c) uint8 image of the official tag36h11 ``tag_id`` with its white quiet zone.

    OpenCV's ``DICT_APRILTAG_36h11`` marker is the official AprilTag rotated
    by 180°, so it is rotated back here; the tag's black square is the middle
    8 × 8 cells.
    """
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    inner = cv2.aruco.generateImageMarker(dictionary, int(tag_id), TAG36H11_CELLS * px_per_cell)
    inner = np.ascontiguousarray(np.rot90(inner, 2))
    return cv2.copyMakeBorder(inner, px_per_cell, px_per_cell, px_per_cell, px_per_cell, cv2.BORDER_CONSTANT, value=255)


def render_tag(
    info: CameraInfo, optical_from_tag: np.ndarray, tag_id: int, tag_size: float,
    background: int = 150, image: np.ndarray | None = None,
) -> np.ndarray:
    """(H, W) uint8 frame showing tag ``tag_id`` at ``optical_from_tag`` (4 × 4) in the optical frame.

    The tag frame is AprilTag's: origin at the centre, x right and y down as
    the tag is read, z into the tag (away from a viewer facing it).
    ``tag_size`` [m] is the black square's edge. Draws onto ``image`` if given
    (to place several tags), else onto a uniform ``background``.
    """
    tex = tag36h11_texture(tag_id)
    n = tex.shape[0]
    half = 0.5 * tag_size * TAG36H11_TOTAL_CELLS / TAG36H11_CELLS
    corners_tag = np.array([[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]])
    pts = corners_tag @ optical_from_tag[:3, :3].T + optical_from_tag[:3, 3]
    if np.any(pts[:, 2] <= 1e-3):
        raise ValueError("tag is behind the camera")
    dst = project(info, pts).astype(np.float32)
    src = np.array([[0, 0], [n, 0], [n, n], [0, n]], dtype=np.float32) - 0.5
    H = cv2.getPerspectiveTransform(src, dst)
    out = np.full((info.height, info.width), background, np.uint8) if image is None else image.copy()
    warped = cv2.warpPerspective(tex, H, (info.width, info.height), flags=cv2.INTER_AREA)
    mask = cv2.warpPerspective(np.full_like(tex, 255), H, (info.width, info.height), flags=cv2.INTER_AREA)
    alpha = mask.astype(np.float32) / 255.0
    blended = alpha * warped.astype(np.float32) + (1.0 - alpha) * out.astype(np.float32)
    return np.clip(blended + 0.5, 0, 255).astype(np.uint8)


def optical_from_base_pose(info: CameraInfo, base_from_tag: np.ndarray) -> np.ndarray:
    """4 × 4 optical←tag transform of a tag given as base_link←tag (inverse of the camera mount)."""
    return np.linalg.inv(info.base_from_optical) @ base_from_tag


def base_from_tag_planar(x: float, y: float, z: float, facing: float) -> np.ndarray:
    """4 × 4 base_link←tag of an upright tag centred at (x, y, z) [m] whose face looks along ``facing`` [rad].

    ``facing`` is the heading of the tag's outward normal (towards whoever
    reads it), the convention of :class:`homing.perception.apriltag.TagMeasurement`.
    AprilTag's z axis points into the tag, so it is the opposite direction;
    the tag's y axis points down.
    """
    z_axis = np.array([-math.cos(facing), -math.sin(facing), 0.0])
    y_axis = np.array([0.0, 0.0, -1.0])
    x_axis = np.cross(y_axis, z_axis)
    return homogeneous(np.column_stack([x_axis, y_axis, z_axis]), np.array([x, y, z]))
