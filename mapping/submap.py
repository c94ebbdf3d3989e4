"""Scan-to-submap matching: a few keyframes' scans joined into one local map, searched correlatively and refined by ICP.

A *submap* is the end points of several keyframe scans placed at their
current pose estimates, in ``map``: the front end of
:class:`homing.mapping.graph_slam.GraphSlam` matches every new scan to the
submap of the last keyframes (as Cartographer's local SLAM matches scans
to its active submap, Hess et al., ICRA 2016), and its loop closures
match a keyframe to the submap around an old one. Built once, a submap is
matched many times: its likelihood field, the field's max-pooled levels
and the points' k-d tree are computed when it is built.

A fit is found in two steps:

1. the multi-resolution correlative search of
   :mod:`homing.mapping.scan_match` (Olson, ICRA 2009) over a window
   around the prior — robust to the tens of centimetres and degrees the
   prior may be off by;
2. point-to-line ICP (:mod:`homing.mapping.scan_closure`, Censi 2008)
   from there, for the sub-cell fit the search's 5 cm / 0.5° steps cannot
   give, kept only if it stays within ``ICP_MAX_SHIFT`` of the search's
   pose; its covariance is the point-to-line Jacobian's at the fitted
   pose, degenerate axes freed (a corridor's axis: there odometry decides).

The normals of each keyframe's points come from its own scan (computed
once, moved with it): normals of points drawn from several scans that do
not yet line up are noise.

Not for: a scan with fewer than ``scan_closure.MIN_PAIRS`` points in
reach, or a prior farther off than the search window (no global search).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from homing.mapping import scan_closure
from homing.mapping.scan_match import CorrelativeMatcher, LikelihoodField, points_field
from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2

RESOLUTION = 0.05  # [m] cells of the likelihood field the correlative search runs on
FOCUS_REACH = 3.0  # [m] a focused submap's field reaches this far beyond its focus keyframe's view
COVARIANCE_GATE = 0.25  # [m] pairs used for a fit's covariance
ICP_GATES = (0.3, 0.2)  # [m] pairing distance, tightened after 5 steps (a SICK's 1° beams land 17 cm apart at 10 m)
ICP_MIN_ITERATIONS = 6  # steps before the refinement may stop
ICP_CONVERGED = 1e-4  # [m, rad] a step this small ends the refinement (0.1 mm, 0.006°)
ICP_MAX_RMS = 0.05  # [m] point-to-line residual of an accepted refinement (real lasers: ≈ 1–2 cm)
ICP_MIN_OVERLAP = 0.3  # share of the scan's points paired (a 180° scan a metre on sees new walls)
ICP_MAX_SHIFT = (0.08, math.radians(1.5))  # [m, rad] the refinement may move the search's pose this far
ICP_MAX_POINTS = 400  # scan points the refinement and the covariance use at most (a 0.25° scan: every other beam)


@dataclass(frozen=True)
class Submap:
    """Keyframe scans joined in ``map``: their points with normals (for ICP) and their likelihood field."""

    reference: scan_closure.Reference
    field: LikelihoodField


@dataclass(frozen=True)
class Fit:
    """A scan's fitted pose of base_link in ``map``, its (3, 3) covariance (map axes) and the search's score."""

    pose: Pose2
    covariance: np.ndarray  # [m², rad²], degenerate position axes freed
    score: float  # mean likelihood-field value under the scan's end points, in [0, 1]


def scan_reference(points: np.ndarray) -> scan_closure.Reference:
    """A keyframe's points (M, 2) [m, base_link] ready to join a submap (normals from its own scan)."""
    if len(points) < scan_closure.MIN_PAIRS:
        return scan_closure.Reference(points.reshape(-1, 2), np.zeros((len(points), 2)), np.zeros(len(points), bool),
                                      scan_closure.cKDTree(points.reshape(-1, 2)))
    return scan_closure.reference(points)


def build(references: Sequence[scan_closure.Reference], poses: Sequence[Pose2],
          resolution: float = RESOLUTION, focus: int | None = None, reach: float = FOCUS_REACH) -> Submap | None:
    """The submap of keyframe scans (``references``, each in its base_link) at ``poses`` [map]; None if empty.

    ``focus``: the index of the keyframe whose view the scans to be fitted
    will share (the newest, for tracking): the likelihood field covers the
    box of its points and position, widened by ``reach`` [m], only — the
    field is the costly part, and walls the scans cannot reach need none.
    """
    ref = scan_closure.merge(references, poses)
    if len(ref.points) < scan_closure.MIN_PAIRS:
        return None
    within = None
    if focus is not None:
        n = np.cumsum([0] + [len(r.points) for r in references])
        view = np.vstack([ref.points[n[focus]:n[focus + 1]], [[poses[focus].x, poses[focus].y]]])
        within = (view.min(axis=0) - reach, view.max(axis=0) + reach)
    return Submap(ref, points_field(ref.points, resolution, within=within))


def fit(submap: Submap, points: np.ndarray, prior: Pose2, matcher: CorrelativeMatcher,
        min_score: float) -> Fit | None:
    """The pose of a scan's points (M, 2) [m, base_link] in the submap, searched around ``prior`` [map].

    None if the search's best score is under ``min_score`` or too few
    points pair with the submap for a covariance.
    """
    if len(points) < scan_closure.MIN_PAIRS:
        return None
    found = matcher.match_field(submap.field, points, prior)
    if found.score < min_score:
        return None
    pose = found.pose
    points = points[:: -(-len(points) // ICP_MAX_POINTS)]
    icp = scan_closure.match(submap.reference, points, pose, max_rms=ICP_MAX_RMS, gates=ICP_GATES,
                             min_overlap=ICP_MIN_OVERLAP, min_iterations=ICP_MIN_ITERATIONS,
                             converged=ICP_CONVERGED)
    if icp is not None and icp.pose.distance_to(pose) <= ICP_MAX_SHIFT[0] and \
            abs(wrap_angle(icp.pose.theta - pose.theta)) <= ICP_MAX_SHIFT[1]:
        pose = icp.pose
    cov = scan_closure.covariance_at(submap.reference, points, pose, COVARIANCE_GATE)
    if cov is None:
        return None
    return Fit(pose, cov, found.score)

