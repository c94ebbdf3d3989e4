"""A tag's heading from the wall it hangs on: a total-least-squares line through the lidar points around it.

A tag's yaw from its own four corners is weak: at 1–3 m a 16 cm tag spans
15–45 px, and its heading shows only through sub-pixel foreshortening, so
single sightings scatter by ±5–15° and now and then flip to the mirrored
pose (measured on the simulator's rendered frames: ``homing bench slam``'s
notes). Tags hang flat on walls and furniture the lidar sees, and a line fit
through the scan points within ``HALF_SPAN`` of the tag's centre gives the
surface's normal to a fraction of a degree. :func:`refine_yaw` replaces the
measurement's heading and its variance with the wall's when the fit is good
(enough points, straight, through the tag, roughly agreeing with the
detector), and leaves it untouched otherwise (a tag on a pillar, a corner,
a wall the lidar does not see).

The longer the stretch of wall, the better its heading: the error falls as
the stretch's length to the power 1.5. Measured against the truth on ``homing
bench slam``'s recorded runs (lab and loop world, every sighting), a line
through ±0.45 m of wall was off by 0.35–0.41° RMS, ±0.9 m by 0.17–0.20°,
±1.5 m by 0.09–0.14°. And the sightings of one visit share most of their
error (one place, one stretch of wall): the dock tag's heading, on which a
whole map is aligned, was 0.25° off after a visit, 8 cm at 19 m. So the
widest of ``HALF_SPANS`` whose line passes every check is taken, the
narrower ones only where a wide stretch is not one straight surface (a
desk's front, a cabinet, a corner within reach).

Frames: the scan is in ``laser`` at its own stamp; ``image_from_scan`` is
base_link at the scan's stamp seen from base_link at the image's stamp (the
odometry between the two), so a robot turning between scan and image does
not tilt the wall. Not for: tags on curved surfaces or free-standing boards
thinner than the lidar's beam spacing.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from homing.perception.apriltag import TagMeasurement
from homing.robot.frames import wrap_angle
from homing.robot.history import interpolate_pose
from homing.robot.types import Pose2, Scan

HALF_SPANS = (1.5, 0.9, 0.45)  # [m] scan points this close to the tag's centre are the wall candidates, widest first
HALF_SPAN = HALF_SPANS[-1]  # [m] the narrowest: the least a tag's surface must span
HYPOTHESIS_POINTS = 40  # points whose pairs are the candidate lines of the consensus (evenly picked)
MIN_POINTS = 8  # fewer points than this: no fit
MIN_EXTENT = 0.25  # [m] the points must spread this far along the wall
INLIER = 0.025  # [m] a point this close to a candidate line supports it (lidar σ ≈ 1 cm)
MAX_RMS = 0.02  # [m] residual of a straight wall (lidar σ ≈ 1 cm)
MAX_OFFSET = 0.06  # [m] the tag's centre must lie this close to the wall line
MAX_DISAGREEMENT = math.radians(40.0)  # [rad] wall normal vs the detector's yaw (wrong surface beyond)
LIDAR_SIGMA = 0.01  # [m] range noise floor of the residual
YAW_SIGMA_MIN = math.radians(0.3)  # [rad] floor: walls are not perfectly flat, tags not perfectly flush


def fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Total-least-squares line through (N, 2) points: (centroid, unit direction, RMS residual [m], extent [m])."""
    c = points.mean(axis=0)
    d = points - c
    _, s, vt = np.linalg.svd(d, full_matrices=False)
    u = vt[0]
    along = d @ u
    rms = float(s[1] / math.sqrt(len(points))) if len(s) > 1 else 0.0
    return c, u, rms, float(along.max() - along.min())


def consensus(points: np.ndarray) -> np.ndarray:
    """(N,) bool: the points within ``INLIER`` of the line through two of them that most points support.

    Exhaustive over the pairs of ``HYPOTHESIS_POINTS`` evenly picked points
    (RANSAC without the randomness: 40 points make 780 pairs, each scored
    on all N), so the result repeats exactly.
    """
    n = len(points)
    pick = np.unique(np.linspace(0, n - 1, min(n, HYPOTHESIS_POINTS)).round().astype(int))
    i, j = np.triu_indices(len(pick), k=1)
    i, j = pick[i], pick[j]
    d = points[j] - points[i]
    length = np.linalg.norm(d, axis=1)
    keep = length > 0.05  # [m] too short a pair gives a poor direction
    i, j, d, length = i[keep], j[keep], d[keep], length[keep]
    if len(i) == 0:
        return np.zeros(n, dtype=bool)
    normals = np.column_stack([-d[:, 1], d[:, 0]]) / length[:, None]
    dist = np.abs(np.einsum("pk,pnk->pn", normals, points[None, :, :] - points[i][:, None, :]))  # (pairs, N)
    support = dist <= INLIER
    return support[int(np.argmax(support.sum(axis=1)))]


def wall_normal(points: np.ndarray, centre: np.ndarray, viewer: np.ndarray,
                half_span: float = HALF_SPAN) -> tuple[float, float] | None:
    """(heading [rad] of the wall's normal towards ``viewer``, its σ [rad]) from (N, 2) points near ``centre``, or None.

    The wall's points are the largest consensus set of a line through two
    of them (:func:`consensus`) among those within ``half_span`` [m] of
    ``centre``, so a corner's other wall or a furniture leg does not tilt it.
    """
    near = points[np.linalg.norm(points - centre, axis=1) <= half_span]
    if len(near) < MIN_POINTS:
        return None
    near = near[consensus(near)]
    if len(near) < MIN_POINTS:
        return None
    c, u, rms, extent = fit_line(near)
    n = np.array([-u[1], u[0]])
    if rms > MAX_RMS or extent < MIN_EXTENT or abs(float((centre - c) @ n)) > MAX_OFFSET:
        return None
    if float((viewer - c) @ n) < 0.0:
        n = -n
    along = (near - c) @ u
    sigma = math.hypot(YAW_SIGMA_MIN, max(rms, LIDAR_SIGMA) / math.sqrt(float(np.sum(along**2))))
    return math.atan2(n[1], n[0]), sigma


def refine_yaw(m: TagMeasurement, scan: Scan | None, image_from_scan: Pose2 | None = None) -> TagMeasurement:
    """``m`` with its heading [rad] and heading variance taken from the wall behind it, when one is found.

    ``scan`` is the latest lidar sweep; ``image_from_scan`` the robot's
    motion from the image's stamp to the scan's (identity if None). The
    position and its covariance are kept; heading–position cross terms are
    dropped (the wall's heading is independent of the corners').
    """
    if scan is None:
        return m
    points = scan.points()
    if len(points) < MIN_POINTS:
        return m
    if image_from_scan is not None:
        points = image_from_scan.transform_points(points)
    centre = np.array([m.pose.x, m.pose.y])
    for half_span in HALF_SPANS:  # the widest stretch of straight wall through the tag gives the best heading
        fit = wall_normal(points, centre, np.zeros(2), half_span)
        if fit is not None and abs(wrap_angle(fit[0] - m.pose.theta)) <= MAX_DISAGREEMENT:
            break
    else:
        return m
    yaw, sigma = fit
    cov = np.array(m.covariance, dtype=float, copy=True)
    cov[2, :2] = cov[:2, 2] = 0.0
    cov[2, 2] = sigma**2
    return replace(m, pose=Pose2(m.pose.x, m.pose.y, yaw), covariance=cov, yaw_source="wall")


class TagPerception:
    """Tags of each *new* camera image, measured in base_link, headings refined by the wall (one per robot).

    ``measure(obs)`` returns an empty list on ticks without a new image. It
    keeps ``HISTORY`` seconds of odometry to relate the scan's stamp to the
    image's. The ``tag_slam`` service and ``homing bench slam`` both use it,
    so that every mapper compared is fed the same sightings.
    """

    HISTORY = 3.0  # [s] odometry kept

    def __init__(self, detector: object, wall_yaw: bool = True) -> None:
        self.detector = detector
        self.wall_yaw = wall_yaw
        self._last_image = -math.inf
        self._history: list[tuple[float, Pose2]] = []

    def measure(self, obs: object, detect: bool = True) -> list[TagMeasurement]:
        """Accepted tag measurements of ``obs.image`` if it is new, else []; ``detect=False`` only keeps odometry."""
        stamp, pose = obs.odom.stamp, obs.odom.pose  # type: ignore[attr-defined]
        self._history = [h for h in self._history if h[0] >= stamp - self.HISTORY] + [(stamp, pose)]
        image, scan = obs.image, obs.scan  # type: ignore[attr-defined]
        if not detect or image is None or image.stamp <= self._last_image:
            return []
        self._last_image = image.stamp
        tags = self.detector.detect(image)  # type: ignore[attr-defined]
        if not self.wall_yaw or scan is None or not tags:
            return tags
        image_from_scan = interpolate_pose(self._history, image.stamp).between(interpolate_pose(self._history, scan.stamp))
        return [refine_yaw(m, scan, image_from_scan) for m in tags]
