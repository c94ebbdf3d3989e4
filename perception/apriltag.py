"""AprilTag (tag36h11) detection and tag measurements in ``base_link`` (Wang & Olson, IROS 2016).

Detection is pupil-apriltags (the AprilTag 3 C library). Each detection's
pose comes from its four corners, the intrinsics and the tag's size — the
edge of the *black square*, not of the printed paper — by OpenCV's IPPE for
squares, then re-fitted upright. Weak detections are rejected (low
decision margin, bit errors, too far, seen too obliquely), and what is left
becomes a planar measurement of the tag in ``base_link``: where its centre
is and which way its face looks, with a covariance that grows with range
and viewing angle.

Conventions. AprilTag's tag frame has x right and y down as the tag is read
and z *into* the tag. A tag's planar pose here is its centre (x, y) and the
heading ``theta`` of its outward normal — the direction its face looks. A
tag on a wall ahead of the robot that faces it therefore has ``theta ≈ π``.

Not for: tags lying flat (floor, ceiling) — the planar pose assumes upright
tags — or images with lens distortion (rectify first).

Demo: ``python -m homing.perception.apriltag --plot tags.png``.
"""

from __future__ import annotations

import argparse
import ctypes
import math
import os
import sys
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from functools import cache

import numpy as np
from homing.robot.frames import homogeneous, wrap_angle
from homing.robot.types import CameraImage, CameraInfo, Pose2

FAMILY = "tag36h11"
TAG_SIZE = 0.16  # [m] black square's edge of the default printed tag
MIN_DECISION_MARGIN = 25.0  # below this a decode is likely noise (clean tags score 60–120)
MAX_HAMMING = 1  # [bits] corrected bit errors tolerated
MAX_RANGE = 3.0  # [m] beyond it a 16 cm tag spans < 15 px at 320 px width
MAX_VIEW_ANGLE = math.radians(60.0)  # [rad] between the tag's normal and the line of sight
PIXEL_SIGMA = 0.5  # [px] corner localisation noise, the root of the covariance model
RANGE_SIGMA_MIN = 0.01  # [m] floor on range noise (calibration, tag mounting)
BEARING_SIGMA_MIN = math.radians(0.5)  # [rad] floor on bearing noise
YAW_SIGMA_MIN = math.radians(1.5)  # [rad] floor on the tag's yaw noise


@dataclass(frozen=True)
class TagMeasurement:
    """One accepted tag detection, expressed in ``base_link`` at ``stamp`` [s].

    ``pose``: the tag's centre (x, y) [m] and face heading theta [rad] in
    base_link. ``covariance``: (3, 3) of (x, y, theta) in base_link [m², rad²].
    ``range_m`` and ``bearing`` [rad] locate the centre from base_link's
    origin; ``view_angle`` [rad] is between the tag's normal and the line of
    sight (0 = seen head-on). ``base_from_tag`` is the full 4 × 4 pose.
    ``yaw_source`` says where theta came from: the tag's corners (weak,
    see :mod:`homing.perception.tag_wall`) or the wall it hangs on.
    """

    tag_id: int
    stamp: float
    pose: Pose2
    covariance: np.ndarray
    range_m: float
    bearing: float
    view_angle: float
    decision_margin: float
    hamming: int
    height: float
    base_from_tag: np.ndarray = field(repr=False)
    corners: np.ndarray = field(repr=False)
    yaw_source: str = "tag"  # "tag": from the corners; "wall": from the lidar (homing.perception.tag_wall)


@dataclass(frozen=True)
class Rejection:
    """A detection the filter dropped, and why (for logs and the view)."""

    tag_id: int
    reason: str
    value: float


@cache
def _safe_detector_class(base: type) -> type:
    """``pupil_apriltags.Detector`` whose destructor does not read a freed tag family (pupil-labs/apriltags#46).

    Its ``__del__`` frees the family first and then calls
    ``apriltag_detector_destroy``, which walks the families again
    (``quick_decode_uninit``): a use-after-free that now and then segfaults
    (seen in ``homing bench slam`` between scenarios: ``segfault at 58 … in
    libapriltag.so.3``). Clearing the detector's family list first leaves
    the destroy nothing to walk.
    """

    class SafeDetector(base):  # type: ignore[misc, valid-type]
        def __del__(self) -> None:
            if getattr(self, "tag_detector_ptr", None) is not None:
                self.libc.apriltag_detector_clear_families.restype = None
                self.libc.apriltag_detector_clear_families(self.tag_detector_ptr)
            super().__del__()

    return SafeDetector


_LIBC = ctypes.CDLL(None)  # the process's C library: fflush() for c_stderr_silenced


@contextmanager
def c_stderr_silenced() -> Iterator[None]:
    """Send what C code writes to stderr (file descriptor 2) to /dev/null for the duration.

    libapriltag's pose estimation ``fprintf(stderr, …)``s "Error, more than
    one new minima found." whenever a tag's two pose solutions nearly tie —
    harmless, and hundreds of times in a run, into the terminal under the
    live view. Python's buffer is flushed first and C's before the
    descriptor is put back, so nothing written before is lost and nothing
    written inside leaks out afterwards.
    """
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        yield
    finally:
        _LIBC.fflush(None)
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


@dataclass(frozen=True)
class TagFilter:
    """Thresholds for accepting a detection (defaults: the module constants)."""

    min_decision_margin: float = MIN_DECISION_MARGIN
    max_hamming: int = MAX_HAMMING
    max_range: float = MAX_RANGE  # [m]
    max_view_angle: float = MAX_VIEW_ANGLE  # [rad]


def measurement_covariance(
    range_m: float, bearing: float, view_angle: float, focal_px: float, tag_size: float,
    pixel_sigma: float = PIXEL_SIGMA,
) -> np.ndarray:
    """(3, 3) covariance of (x, y, theta) in base_link of a tag seen at ``range_m`` [m], ``bearing`` [rad].

    First-order propagation of ``pixel_sigma`` corner noise: the tag spans
    ``focal·size/range`` pixels, so range noise grows as range², and it and
    the yaw noise grow as 1/cos(view angle) as the tag foreshortens. Bearing
    noise is a pixel's angle; yaw noise grows with range² (foreshortening of
    the tag's vertical edges). Each has a floor for what the pixel model misses.
    """
    span_px = max(focal_px * tag_size / max(range_m, 1e-3), 1e-3)
    oblique = 1.0 / max(math.cos(view_angle), 0.2)
    sigma_r = math.hypot(RANGE_SIGMA_MIN, range_m * pixel_sigma / span_px * oblique)
    sigma_b = math.hypot(BEARING_SIGMA_MIN, pixel_sigma / focal_px)
    # Yaw shows only through foreshortening: the two vertical edges' depths differ
    # by size·sin(yaw), each known to range·σ_px/span — weak for small, far tags
    # (and where pupil-apriltags may pick the mirrored pose of the planar ambiguity).
    sigma_yaw = math.hypot(YAW_SIGMA_MIN, math.sqrt(2.0) * range_m * pixel_sigma / (span_px * tag_size) * oblique)
    c, s = math.cos(bearing), math.sin(bearing)
    rot = np.array([[c, -s], [s, c]])
    cov = np.zeros((3, 3))
    cov[:2, :2] = rot @ np.diag([sigma_r**2, (range_m * sigma_b) ** 2]) @ rot.T
    cov[2, 2] = sigma_yaw**2
    return cov


def planar_measurement(
    tag_id: int, stamp: float, base_from_tag: np.ndarray, info: CameraInfo, tag_size: float,
    decision_margin: float = 100.0, hamming: int = 0, corners: np.ndarray | None = None,
) -> TagMeasurement:
    """The planar :class:`TagMeasurement` of a tag at ``base_from_tag`` (4 × 4) seen by ``info``'s camera."""
    centre = base_from_tag[:3, 3]
    normal = -base_from_tag[:3, 2]  # AprilTag's z points into the tag
    facing = math.atan2(normal[1], normal[0])
    cam = info.base_from_optical[:3, 3]
    sight = cam - centre
    cos_view = float(np.dot(sight, normal) / max(np.linalg.norm(sight) * np.linalg.norm(normal), 1e-9))
    view_angle = math.acos(max(-1.0, min(1.0, cos_view)))
    rng = math.hypot(centre[0], centre[1])
    bearing = math.atan2(centre[1], centre[0])
    cov = measurement_covariance(rng, bearing, view_angle, info.fx, tag_size)
    return TagMeasurement(
        tag_id=int(tag_id), stamp=float(stamp), pose=Pose2(float(centre[0]), float(centre[1]), wrap_angle(facing)),
        covariance=cov, range_m=rng, bearing=bearing, view_angle=view_angle,
        decision_margin=float(decision_margin), hamming=int(hamming), height=float(centre[2]),
        base_from_tag=base_from_tag, corners=np.zeros((4, 2)) if corners is None else corners,
    )


QUAD_SIGMA = 0.8  # [px] Gaussian blur for quad segmentation (apriltag: "very noisy images benefit from 0.8")
LM_ITERATIONS = 50  # Levenberg–Marquardt steps at most in an upright fit
LM_DAMPING = 1e-3  # its initial damping
LM_STEP_M = 1e-6  # [m] converged when a step moves the centre less than this…
LM_STEP_RAD = 1e-6  # [rad] …and turns it less than this


def _upright_pose(x: float, y: float, z: float, facing: float) -> np.ndarray:
    """4 × 4 base_link←tag of an upright tag (AprilTag axes: x right, y down, z into the tag)."""
    c, s = math.cos(facing), math.sin(facing)
    return np.array([[-s, 0.0, -c, x], [c, 0.0, -s, y], [0.0, -1.0, 0.0, z], [0.0, 0.0, 0.0, 1.0]])


def _fit_upright(params: np.ndarray, corners: np.ndarray, optical_from_base: np.ndarray, info: CameraInfo,
                 size: float, iterations: int = LM_ITERATIONS) -> tuple[np.ndarray, float]:
    """Levenberg–Marquardt on (x, y, z, yaw) of an upright tag against its 4 corners [px]; (params, cost).

    The residuals are the 8 corner reprojection errors [px], with the
    Jacobian in closed form (the pose is a rotation about z and a
    translation), so a fit costs a few hundred microseconds.
    """
    h = 0.5 * size
    obj = np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])  # corners in the tag frame
    R_ob, t_ob = optical_from_base[:3, :3], optical_from_base[:3, 3]
    target = np.asarray(corners, dtype=float).reshape(4, 2)

    def residuals(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        c, s = math.cos(p[3]), math.sin(p[3])
        R = np.array([[-s, 0.0, -c], [c, 0.0, -s], [0.0, -1.0, 0.0]])  # columns: the tag's axes in base_link
        dR = np.array([[-c, 0.0, s], [-s, 0.0, -c], [0.0, 0.0, 0.0]])
        Po = (obj @ R.T + p[:3]) @ R_ob.T + t_ob  # (4, 3) corners in the optical frame
        z = np.maximum(Po[:, 2], 1e-6)
        uv = np.column_stack([info.fx * Po[:, 0] / z + info.cx, info.fy * Po[:, 1] / z + info.cy])
        # d(optical point)/d(x, y, z) = R_ob (the same for every corner); d/d(yaw) = R_ob · dR · corner.
        dP = np.empty((4, 3, 4))
        dP[:, :, :3] = R_ob
        dP[:, :, 3] = obj @ dR.T @ R_ob.T
        du = info.fx * (dP[:, 0, :] / z[:, None] - (Po[:, 0] / z**2)[:, None] * dP[:, 2, :])
        dv = info.fy * (dP[:, 1, :] / z[:, None] - (Po[:, 1] / z**2)[:, None] * dP[:, 2, :])
        J = np.empty((8, 4))
        J[0::2], J[1::2] = du, dv
        return (uv - target).ravel(), J

    p = np.asarray(params, dtype=float).copy()
    r, J = residuals(p)
    cost, damping = 0.5 * float(r @ r), LM_DAMPING
    for _ in range(iterations):
        A = J.T @ J
        g = J.T @ r
        try:
            step = np.linalg.solve(A + damping * np.diag(np.diag(A) + 1e-12), -g)
        except np.linalg.LinAlgError:
            break
        if float(np.max(np.abs(step[:3]))) < LM_STEP_M and abs(float(step[3])) < LM_STEP_RAD:
            break  # converged: a step of micrometres and microradians changes nothing
        trial = p + step
        r_t, J_t = residuals(trial)
        cost_t = 0.5 * float(r_t @ r_t)
        if cost_t < cost:
            p, r, J, cost = trial, r_t, J_t, cost_t
            damping = max(damping / 10.0, 1e-9)
        else:
            damping *= 10.0
            if damping > 1e8:
                break
    return p, cost


# The unit square's corners in AprilTag's tag frame (x right, y down, z into the tag), in the order
# pupil-apriltags gives a detection's corners, and OpenCV's SOLVEPNP_IPPE_SQUARE wants them.
UNIT_SQUARE = np.array([[-0.5, 0.5, 0.0], [0.5, 0.5, 0.0], [0.5, -0.5, 0.0], [-0.5, -0.5, 0.0]])


def square_pose(corners: np.ndarray, info: CameraInfo, size: float) -> np.ndarray:
    """4 × 4 optical←tag of a square tag of edge ``size`` [m] from its four ``corners`` [px] (pupil's order).

    OpenCV's IPPE for squares (Collins & Bartoli 2014), not pupil-apriltags' own estimate: that one's SVDs
    (``matd_svd_tall``) leave blocks behind in the AprilTag C library, 0.4 MB a simulated day of the persistent
    mission (heaptrack). The translation scales with the size and the rotation does not, so the unit square
    serves every size. Of the planar pose's two solutions this is one; :func:`refine_upright` tries both.
    """
    import cv2

    _, rvec, tvec = cv2.solvePnP(UNIT_SQUARE, np.ascontiguousarray(corners, float).reshape(4, 1, 2), info.K(), None,
                                 flags=cv2.SOLVEPNP_IPPE_SQUARE)
    return homogeneous(cv2.Rodrigues(rvec)[0], tvec.reshape(3) * size)


def refine_upright(base_from_tag: np.ndarray, corners: np.ndarray, info: CameraInfo, size: float) -> np.ndarray:
    """Re-fit an upright tag's pose (centre and yaw; no roll or pitch) to its four corners [px].

    Tags hang upright on walls and the camera is level, so two of the six
    degrees of freedom are known. Fitting only the other four removes most of
    the planar pose ambiguity of small, distant tags (the mirrored yaw that
    pupil-apriltags sometimes returns): both the detector's yaw and its mirror
    about the line of sight are tried, and the lower reprojection error wins.
    """
    x, y, z = base_from_tag[:3, 3]
    normal = -base_from_tag[:3, 2]
    facing = math.atan2(normal[1], normal[0])
    sight = math.atan2(info.base_from_optical[1, 3] - y, info.base_from_optical[0, 3] - x)
    optical_from_base = np.linalg.inv(info.base_from_optical)
    fits = [_fit_upright(np.array([x, y, z, yaw]), corners, optical_from_base, info, size)
            for yaw in (facing, wrap_angle(2.0 * sight - facing))]
    best, _ = min(fits, key=lambda fit: fit[1])
    return _upright_pose(*best)


def reject_reason(m: TagMeasurement, filt: TagFilter) -> Rejection | None:
    """Why ``m`` fails ``filt``, or None if it passes (checked in order of cheapness)."""
    if m.hamming > filt.max_hamming:
        return Rejection(m.tag_id, "hamming", m.hamming)
    if m.decision_margin < filt.min_decision_margin:
        return Rejection(m.tag_id, "decision_margin", m.decision_margin)
    if m.range_m > filt.max_range:
        return Rejection(m.tag_id, "range", m.range_m)
    if m.view_angle > filt.max_view_angle:
        return Rejection(m.tag_id, "view_angle", m.view_angle)
    return None


class TagDetector:
    """Detect tag36h11 tags in camera frames and measure them in ``base_link``.

    ``tag_size`` [m] is the black square's edge; ``tag_sizes`` overrides it
    per id (e.g. a larger dock tag). ``quad_decimate`` trades range for speed
    (1.0 finds ~15 px tags at 320 × 240; 2.0 halves the cost). ``quad_sigma`` [px]
    blurs the image the quads are segmented in (not the one the edges are
    refined on): apriltag's advice for noisy images, and on the simulated
    camera's (σ = 2 grey levels per pixel) it cuts the detector's time
    fourfold (32 → 8 ms a frame) at one tag in twenty missed. ``upright``
    re-fits each pose with roll and pitch fixed (:func:`refine_upright`);
    turn it off for tags that do not hang upright or a camera that is not
    level. One instance per camera; not thread-safe.
    """

    def __init__(
        self, tag_size: float = TAG_SIZE, tag_sizes: Mapping[int, float] | None = None,
        filt: TagFilter | None = None, quad_decimate: float = 1.0, family: str = FAMILY,
        upright: bool = True, quad_sigma: float = QUAD_SIGMA,
    ) -> None:
        import pupil_apriltags

        self.tag_size = float(tag_size)
        self.tag_sizes = {int(k): float(v) for k, v in (tag_sizes or {}).items()}
        self.filter = filt or TagFilter()
        self.upright = upright
        self._detector = _safe_detector_class(pupil_apriltags.Detector)(
            families=family, quad_decimate=quad_decimate, quad_sigma=quad_sigma, nthreads=1)
        self.last_rejections: list[Rejection] = []

    def size_of(self, tag_id: int) -> float:
        """The black square's edge [m] of tag ``tag_id``."""
        return self.tag_sizes.get(int(tag_id), self.tag_size)

    def detect_all(self, frame: CameraImage) -> list[TagMeasurement]:
        """Every decoded tag in ``frame``, measured in base_link, before filtering."""
        info = frame.info
        grey = np.ascontiguousarray(frame.grey())
        with c_stderr_silenced():
            dets = self._detector.detect(grey)
        out = []
        for d in dets:
            size = self.size_of(d.tag_id)
            optical_from_tag = square_pose(np.asarray(d.corners, float), info, size)
            base_from_tag = info.base_from_optical @ optical_from_tag
            if self.upright:
                base_from_tag = refine_upright(base_from_tag, np.asarray(d.corners, float), info, size)
            out.append(planar_measurement(
                d.tag_id, frame.stamp, base_from_tag, info, size, d.decision_margin, d.hamming,
                np.asarray(d.corners, dtype=float),
            ))
        return out

    def detect(self, frame: CameraImage) -> list[TagMeasurement]:
        """Accepted tags in ``frame`` (rejections are kept in ``last_rejections``)."""
        accepted, self.last_rejections = [], []
        for m in self.detect_all(frame):
            why = reject_reason(m, self.filter)
            if why is None:
                accepted.append(m)
            else:
                self.last_rejections.append(why)
        return accepted


def main() -> None:
    """Render tags at known poses, detect them and plot measured against true positions."""
    from homing.perception.camera import (
        base_from_tag_planar,
        camera_info,
        optical_from_base_pose,
        render_tag,
    )

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", metavar="PNG", help="write the frame and the measurements here")
    args = parser.parse_args()
    info = camera_info(320, 240, math.radians(58.0), (0.1, 0.0, 0.4))
    truth = [(0, 1.0, 0.0, math.pi), (1, 1.8, 0.5, math.pi - 0.6), (2, 2.6, -0.6, math.pi + 0.4)]
    image = None
    for tag_id, x, y, face in truth:
        T = base_from_tag_planar(x, y, 0.4, face)
        image = render_tag(info, optical_from_base_pose(info, T), tag_id, TAG_SIZE, image=image)
    assert image is not None
    found = {m.tag_id: m for m in TagDetector().detect(CameraImage(0.0, image, info))}
    for tag_id, x, y, _ in truth:
        m = found.get(tag_id)
        err = "missed" if m is None else f"{100 * math.hypot(m.pose.x - x, m.pose.y - y):.1f} cm, " \
            f"σ_xy {100 * math.sqrt(np.trace(m.covariance[:2, :2])):.1f} cm"
        print(f"tag {tag_id} at {x:.1f}, {y:.1f} m: {err}")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, (a, b) = plt.subplots(1, 2, figsize=(10, 4))
        a.imshow(image, cmap="gray")
        a.set_title("synthetic frame")
        for tag_id, x, y, _ in truth:
            b.plot(x, y, "g+", ms=12)
            if tag_id in found:
                m = found[tag_id]
                b.plot(m.pose.x, m.pose.y, "bx")
                b.annotate(str(tag_id), (m.pose.x, m.pose.y))
        b.plot(0, 0, "k^")
        b.set_aspect("equal")
        b.set_title("base_link: truth (+) and measured (x) [m]")
        fig.savefig(args.plot, dpi=90)


if __name__ == "__main__":
    main()
