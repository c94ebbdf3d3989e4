"""The UVC camera adapter on a video file: ROS camera_info read at file:line:col, frames rectified onto P."""

from __future__ import annotations

import time
from pathlib import Path

import cv2
import numpy as np
import pytest
from homing.robot.hardware.camera import UvcCamera, load_calibration

from homing.errors import UserError

INFO = """\
image_width: 320
image_height: 240
camera_name: xtion_rgb
camera_matrix: {rows: 3, cols: 3, data: [290.0, 0.0, 161.0, 0.0, 292.0, 118.0, 0.0, 0.0, 1.0]}
distortion_model: plumb_bob
distortion_coefficients: {rows: 1, cols: 5, data: [-0.25, 0.08, 0.001, -0.002, 0.0]}
rectification_matrix: {rows: 3, cols: 3, data: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]}
projection_matrix: {rows: 3, cols: 4, data: [270.0, 0.0, 160.0, 0.0, 0.0, 272.0, 120.0, 0.0, 0.0, 0.0, 1.0, 0.0]}
"""


def _dots(cal, points: np.ndarray) -> np.ndarray:  # noqa: ANN001 - a Calibration
    """Pixel positions of 3-D points (N, 3) in the optical frame through the raw, distorted camera."""
    px, _ = cv2.projectPoints(points, np.zeros(3), np.zeros(3), cal.K, cal.D)
    return px.reshape(-1, 2)


def test_camera_info_is_read_as_ros_writes_it(tmp_path: Path) -> None:
    path = tmp_path / "xtion.yaml"
    path.write_text(INFO)
    cal = load_calibration(path)
    assert (cal.width, cal.height, cal.model) == (320, 240, "plumb_bob")
    assert cal.K[0, 0] == 290.0 and cal.D.tolist() == [-0.25, 0.08, 0.001, -0.002, 0.0]
    info = cal.info(np.eye(4))
    assert (info.fx, info.fy, info.cx, info.cy) == (270.0, 272.0, 160.0, 120.0)  # the rectified image's: P's
    path.write_text(INFO.replace("[290.0, 0.0, 161.0, 0.0, 292.0, 118.0, 0.0, 0.0, 1.0]", "[290.0, 0.0]"))
    with pytest.raises(UserError) as err:
        load_calibration(path)
    assert str(err.value) == f"{path}:4:41: 'camera_matrix.data' must be a list of 9 numbers"
    path.write_text(INFO.replace("plumb_bob", "plumb_bobb"))
    with pytest.raises(UserError, match=r":5:19: 'distortion_model' must be one of"):
        load_calibration(path)


def test_frames_from_a_video_file_are_rectified_onto_the_projection_matrix(tmp_path: Path) -> None:
    (tmp_path / "xtion.yaml").write_text(INFO)
    cal = load_calibration(tmp_path / "xtion.yaml")
    # A grid of points on a wall 2 m ahead, drawn as white dots where the distorted camera sees them
    xs, ys = np.meshgrid(np.linspace(-1.0, 1.0, 7), np.linspace(-0.7, 0.7, 5))
    points = np.column_stack([xs.ravel(), ys.ravel(), np.full(xs.size, 2.0)])
    raw = _dots(cal, points)
    frame = np.zeros((240, 320, 3), np.uint8)
    for u, v in raw:
        cv2.circle(frame, (round(u), round(v)), 3, (255, 255, 255), -1)
    video = tmp_path / "wall.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (320, 240))
    for _ in range(5):
        writer.write(frame)
    writer.release()
    camera = UvcCamera(str(video), cal, np.eye(4), time.monotonic, rate=20.0)
    camera.open()
    try:
        deadline = time.monotonic() + 5.0
        while camera.frames < 3 and time.monotonic() < deadline:
            time.sleep(0.02)
        image = camera.latest()
    finally:
        camera.close()
    assert image is not None and image.image.shape == (240, 320, 3) and camera.frames >= 3
    grey = image.grey()
    n, _, _, centres = cv2.connectedComponentsWithStats((grey > 128).astype(np.uint8))
    found = centres[1:]
    P = cal.P
    ideal = (points @ P[:, :3].T)[:, :2] / points[:, 2:3]  # the pinhole camera P projects them here
    inside = (ideal[:, 0] > 5) & (ideal[:, 0] < 315) & (ideal[:, 1] > 5) & (ideal[:, 1] < 235)
    err = np.linalg.norm(found[:, None, :] - ideal[None, inside, :], axis=2).min(axis=0)
    assert inside.sum() >= 30 and err.max() < 1.0  # within a pixel after undistortion
    straight_raw = np.linalg.norm(raw[inside] - ideal[inside], axis=1).max()
    assert straight_raw > 5.0  # and the raw frame was far off: the rectification did the work
