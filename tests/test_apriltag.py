"""Tag perception on synthetic frames: a tag warped into the image from a known pose."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.perception.apriltag import TagDetector, TagFilter, measurement_covariance
from homing.perception.camera import (
    base_from_tag_planar,
    camera_info,
    optical_from_base_pose,
    render_tag,
    tag36h11_texture,
)
from homing.robot.frames import wrap_angle
from homing.robot.types import CameraImage

HFOV = math.radians(58.0)
CAM_POS = (0.1, 0.0, 0.4)  # [m] camera in base_link
SIZE = 0.16  # [m]


def _frame(x: float, y: float, facing: float, tag_id: int = 5, size: float = SIZE, info=None,
           contrast: float = 1.0, rng: np.random.Generator | None = None) -> CameraImage:
    info = info or camera_info(320, 240, HFOV, CAM_POS)
    T = base_from_tag_planar(x, y, CAM_POS[2], facing)
    img = render_tag(info, optical_from_base_pose(info, T), tag_id, size).astype(float)
    img = 128.0 + contrast * (img - 128.0)
    if rng is not None:
        img += rng.normal(0.0, 6.0, img.shape)
    return CameraImage(1.5, np.clip(img, 0, 255).astype(np.uint8), info)


@pytest.mark.parametrize(
    "x, y, facing",
    [(1.1, 0.0, math.pi), (1.05, 0.25, math.pi - 0.5), (1.0, -0.3, math.pi + 0.7), (0.9, 0.1, math.pi + 0.2)],
)
def test_tag_at_one_metre_is_measured_within_2cm_and_2deg(x, y, facing):
    m = TagDetector().detect(_frame(x, y, facing))
    assert len(m) == 1
    assert m[0].tag_id == 5 and m[0].stamp == 1.5
    assert math.hypot(m[0].pose.x - x, m[0].pose.y - y) < 0.02
    assert abs(wrap_angle(m[0].pose.theta - facing)) < math.radians(2.0)
    assert abs(m[0].height - CAM_POS[2]) < 0.02


def test_measurement_is_in_base_link_for_a_turned_camera():
    info = camera_info(320, 240, HFOV, (0.05, 0.1, 0.3), yaw=math.radians(90.0))
    # The camera looks left: a tag 1 m to the robot's left, facing it (facing = −90°).
    m = TagDetector().detect(_frame(0.05, 1.1, -math.pi / 2, info=info))
    assert len(m) == 1
    assert math.hypot(m[0].pose.x - 0.05, m[0].pose.y - 1.1) < 0.02
    assert abs(wrap_angle(m[0].pose.theta + math.pi / 2)) < math.radians(2.0)
    assert abs(m[0].bearing - math.atan2(1.1, 0.05)) < math.radians(1.0)


def test_tag_size_is_the_black_square_and_can_differ_per_id():
    frame = _frame(1.5, 0.0, math.pi, tag_id=9, size=0.30)
    right = TagDetector(tag_size=SIZE, tag_sizes={9: 0.30}).detect(frame)
    wrong = TagDetector(tag_size=SIZE).detect(frame)
    assert abs(right[0].pose.x - 1.5) < 0.03
    # A pose from the wrong size scales the translation by the size ratio.
    cam_x = CAM_POS[0]
    assert abs((wrong[0].pose.x - cam_x) / (right[0].pose.x - cam_x) - SIZE / 0.30) < 0.01


def test_covariance_grows_with_range_and_viewing_angle():
    f = camera_info(320, 240, HFOV).fx
    traces = [np.trace(measurement_covariance(r, 0.0, 0.0, f, SIZE)[:2, :2]) for r in (0.5, 1.0, 2.0, 3.0)]
    assert all(b > a for a, b in zip(traces, traces[1:], strict=False))
    head_on = measurement_covariance(2.0, 0.0, 0.0, f, SIZE)
    oblique = measurement_covariance(2.0, 0.0, math.radians(50), f, SIZE)
    assert oblique[0, 0] > head_on[0, 0] and oblique[2, 2] > head_on[2, 2]
    # Range noise lies along the line of sight: at bearing 90° it is y's variance.
    side = measurement_covariance(3.0, math.pi / 2, 0.0, f, SIZE)
    assert side[1, 1] > side[0, 0]


def test_covariance_of_detections_grows_with_range():
    det = TagDetector()
    near = det.detect(_frame(1.0, 0.0, math.pi))[0]
    far = det.detect(_frame(2.5, 0.0, math.pi))[0]
    assert np.trace(far.covariance) > 2.0 * np.trace(near.covariance)
    # The error actually made stays within 3 σ of the model at both ranges.
    for m, x in ((near, 1.0), (far, 2.5)):
        assert abs(m.pose.x - x) < 3.0 * math.sqrt(m.covariance[0, 0]) + 0.01


def test_far_and_oblique_tags_are_rejected():
    det = TagDetector(filt=TagFilter(max_range=2.0, max_view_angle=math.radians(50)))
    assert det.detect(_frame(2.4, 0.0, math.pi)) == []
    assert [r.reason for r in det.last_rejections] == ["range"]
    assert det.detect(_frame(1.2, 0.0, math.pi + math.radians(60))) == []
    assert [r.reason for r in det.last_rejections] == ["view_angle"]
    assert len(det.detect(_frame(1.2, 0.0, math.pi + math.radians(40)))) == 1


def test_weak_decodes_are_rejected_by_decision_margin():
    rng = np.random.default_rng(3)
    det = TagDetector(filt=TagFilter(min_decision_margin=40.0))
    faint = det.detect_all(_frame(1.2, 0.0, math.pi, contrast=0.25, rng=rng))
    strong = det.detect_all(_frame(1.2, 0.0, math.pi))
    assert faint and strong
    assert faint[0].decision_margin < 40.0 < strong[0].decision_margin
    assert det.detect(_frame(1.2, 0.0, math.pi, contrast=0.25, rng=np.random.default_rng(3))) == []
    assert det.last_rejections[0].reason == "decision_margin"


def test_bit_errors_are_rejected_by_hamming(monkeypatch):
    import homing.perception.camera as camera

    clean = tag36h11_texture(5)

    def one_bit_flipped(tag_id: int, px_per_cell: int = 10) -> np.ndarray:
        tex = clean.copy()
        r, c = 3 * px_per_cell, 4 * px_per_cell  # a data cell (rows/cols 2..7 hold data)
        tex[r:r + px_per_cell, c:c + px_per_cell] = 255 - tex[r:r + px_per_cell, c:c + px_per_cell]
        return tex

    monkeypatch.setattr(camera, "tag36h11_texture", one_bit_flipped)
    frame = _frame(1.0, 0.0, math.pi)
    seen = TagDetector().detect_all(frame)
    assert [(m.tag_id, m.hamming) for m in seen] == [(5, 1)]
    assert TagDetector(filt=TagFilter(max_hamming=0)).detect(frame) == []
    assert len(TagDetector(filt=TagFilter(max_hamming=1)).detect(frame)) == 1


def test_several_tags_in_one_frame_are_told_apart_by_id():
    info = camera_info(320, 240, HFOV, CAM_POS)
    truth = {3: (1.2, 0.35), 11: (1.6, -0.4)}
    img = None
    for tag_id, (x, y) in truth.items():
        T = base_from_tag_planar(x, y, CAM_POS[2], math.pi)
        img = render_tag(info, optical_from_base_pose(info, T), tag_id, SIZE, image=img)
    found = {m.tag_id: m for m in TagDetector().detect(CameraImage(0.0, img, info))}
    assert set(found) == set(truth)
    for tag_id, (x, y) in truth.items():
        assert math.hypot(found[tag_id].pose.x - x, found[tag_id].pose.y - y) < 0.04


def test_c_stderr_is_silenced_only_inside_the_detection_window(capfd: pytest.CaptureFixture[str]) -> None:
    """libapriltag fprintf()s a harmless message to stderr per ambiguous pose, which would run into the terminal."""
    import ctypes
    import sys

    from homing.perception.apriltag import c_stderr_silenced

    libc = ctypes.CDLL(None)
    c_stderr = ctypes.c_void_p.in_dll(libc, "stderr")
    print("python before", file=sys.stderr)
    with c_stderr_silenced():
        libc.fprintf(c_stderr, b"Error, more than one new minima found.\n")
    libc.fprintf(c_stderr, b"C after\n")
    libc.fflush(None)
    err = capfd.readouterr().err
    assert "python before" in err
    assert "C after" in err
    assert "minima" not in err


@pytest.mark.parametrize("x, y, facing", [(1.1, 0.0, math.pi), (1.05, 0.25, math.pi - 0.5), (2.0, -0.3, math.pi + 0.4)])
def test_square_pose_from_the_detectors_corners_is_the_rendered_pose(x, y, facing):
    """The corners pupil-apriltags finds, in its order, give OpenCV's IPPE the tag's true pose in the optical frame
    (the corner order and the tag frame agree; the upright re-fit only polishes it)."""
    import pupil_apriltags
    from homing.perception.apriltag import square_pose

    frame = _frame(x, y, facing)
    info = frame.info
    dets = pupil_apriltags.Detector(families="tag36h11").detect(np.ascontiguousarray(frame.grey()))
    assert len(dets) == 1
    got = square_pose(np.asarray(dets[0].corners, float), info, SIZE)
    want = optical_from_base_pose(info, base_from_tag_planar(x, y, CAM_POS[2], facing))
    assert np.linalg.norm(got[:3, 3] - want[:3, 3]) < 0.02 * np.linalg.norm(want[:3, 3])  # 2 % of the range
    normal_error = math.degrees(math.acos(np.clip(got[:3, 2] @ want[:3, 2], -1.0, 1.0)))
    assert normal_error < 4.0, normal_error  # [deg] the face's direction (z into the tag)
