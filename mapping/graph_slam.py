"""Lidar pose-graph SLAM over keyframes (Lu & Milios 1997; Grisetti et al., "A tutorial on graph-based SLAM", 2010) with GTSAM's iSAM2.

For logs of any planar laser (a SICK's 180° at 1°, a Hokuyo's 240°, the
RPLIDAR's 360°), robot unknown. Variables: keyframe poses in ``map`` (the
``odom`` frame at the first scan). Factors:

- a prior on the first keyframe;
- odometry between consecutive keyframes, with a generic wheel-odometry
  noise (``ODOM_SIGMA``: a floor plus shares of the distance and the turn);
- the scan-matched motion between consecutive keyframes (the *front end*):
  the new scan against a local map of the last ``local_keyframes`` scans,
  first by the correlative search of :mod:`homing.mapping.scan_match`
  (Olson 2009) on a grid of their end points around the odometry
  prediction — wide enough for the 0.4 m and the degrees odometry loses
  between sparse scans — then by the point-to-line ICP of
  :mod:`homing.mapping.scan_closure` (Censi 2008), whose covariance frees a
  corridor's unconstrained axis (there, odometry decides);
- lidar loop closures: when the new keyframe comes within
  ``closure_radius`` of a keyframe at least ``closure_gap`` metres of path
  older, it is matched the same way against that keyframe's neighbourhood,
  with a wider window (the drift of a loop), and the match becomes a
  between factor with a Cauchy kernel, so that a false match is
  down-weighted instead of bending the map.

Without closures (``closure_radius=0``) this is incremental scan matching:
the "scan matching" baseline of Kümmerle et al. 2009. At the end,
:meth:`GraphSlam.finish` re-optimises the whole graph in one batch
(Levenberg–Marquardt from iSAM2's estimate). A scan between keyframes
gets the pose of its keyframe moved by the odometry in between.

Not for: 3-D or tilted lasers, scans with fewer than ``scan_closure.MIN_PAIRS``
end points within ``max_range``, or a kidnapped robot (no global search).
"""

from __future__ import annotations

import math
import time
from collections import deque
from dataclasses import dataclass, field

import gtsam
import numpy as np
from homing.mapping import scan_closure
from homing.mapping.grid import L_MAX, OccupancyGrid
from homing.mapping.landmark_slam import (
    X,
    from_gtsam,
    interpolate_pose,
    rotate_covariance,
    to_gtsam,
)
from homing.mapping.scan_match import CorrelativeMatcher
from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2, Scan

KEYFRAME_DISTANCE = 0.3  # [m] odometry travelled before a new keyframe
KEYFRAME_ANGLE = math.radians(10.0)  # [rad]
MAX_RANGE = 20.0  # [m] end points farther than this are not matched (a SICK's 80 m would cost, not help)
LOCAL_KEYFRAMES = 8  # scans in the front end's local map
MATCH_RESOLUTION = 0.05  # [m] cells of the end-point grid the correlative search runs on
FRONT_WINDOW = (0.5, math.radians(12.0))  # [m, rad] half-widths of the front end's correlative search
CLOSURE_WINDOW = (2.5, math.radians(30.0))  # [m, rad] the same for loop closures (the drift of a loop)
CLOSURE_LEVELS = 3  # coarse levels of the closure search (its top level steps 40 cm and 4°)
CLOSURE_SCORE = 0.7  # mean likelihood-field value under an accepted closure's end points
CLOSURE_RADIUS = 4.0  # [m] an old keyframe this near (by the current estimate) is a closure candidate
CLOSURE_GAP = 10.0  # [m] of path at least between a keyframe and the keyframes it may close a loop with
CLOSURE_NEIGHBOURS = 4  # keyframes each side of the candidate in its local map
MIN_SCORE = 0.6  # mean likelihood-field value under an accepted match's end points
COVARIANCE_GATE = 0.25  # [m] pairs used for a match's covariance
ICP_GATES = (0.3, 0.25, 0.2, 0.2)  # [m] a SICK's 1° beams land 17 cm apart on a wall 10 m away
ICP_MAX_RMS = 0.05  # [m] point-to-line residual of an accepted refinement (real lasers: ≈ 1–2 cm)
ICP_MIN_OVERLAP = 0.3  # share of the scan's points paired (a 180° scan a metre on sees new walls)
ICP_MAX_SHIFT = (0.08, math.radians(1.5))  # [m, rad] the refinement may move the search's pose this far
ODOM_SIGMA = (0.02, 0.10, math.radians(1.0), 0.10, math.radians(2.0))  # [m], [m/m], [rad], [rad/rad], [rad/m]
MATCH_SIGMA_MIN = (0.01, math.radians(0.25))  # [m, rad] floors of a match's σ (the ICP's own is optimistic)
FIRST_SIGMA = (1e-3, 1e-3, 1e-3)  # [m, m, rad]
CAUCHY_K = 2.3849


@dataclass(frozen=True)
class GraphConfig:
    """Parameters of :class:`GraphSlam` (defaults: the module constants)."""

    keyframe_distance: float = KEYFRAME_DISTANCE  # [m]
    keyframe_angle: float = KEYFRAME_ANGLE  # [rad]
    max_range: float = MAX_RANGE  # [m]
    local_keyframes: int = LOCAL_KEYFRAMES
    closure_radius: float = CLOSURE_RADIUS  # [m]; 0 turns closures off (incremental scan matching)
    closure_gap: float = CLOSURE_GAP  # [m]
    scan_matching: bool = True  # False: odometry alone (the baseline)


@dataclass
class Keyframe:
    """A keyframe: stamp [s], odometry pose (odom frame), scan end points (M, 2) in base_link [m]."""

    index: int
    stamp: float
    odom: Pose2
    points: np.ndarray
    scan: Scan
    path: float  # [m] odometry path from the first keyframe


@dataclass
class _ScanPlace:
    """Where a scan was taken: its stamp, the keyframe before it and the odometry from that keyframe."""

    stamp: float
    keyframe: int
    offset: Pose2


@dataclass
class Stats:
    """Counters and timings of a run."""

    matches: int = 0
    match_failures: int = 0
    closures: int = 0
    closure_attempts: int = 0
    ms: list[float] = field(default_factory=list)  # wall time per scan [ms]


def odometry_sigmas(delta: Pose2, path: float, turn: float) -> np.ndarray:
    """(3,) σ of an odometry increment (x, y [m], θ [rad]) from its path [m] and absolute turn [rad]."""
    floor, per_m, th_floor, th_per_rad, th_per_m = ODOM_SIGMA
    s_xy = floor + per_m * path
    s_th = th_floor + th_per_rad * turn + th_per_m * path
    return np.array([s_xy, s_xy, s_th])


def end_points_grid(points: np.ndarray, resolution: float = MATCH_RESOLUTION) -> OccupancyGrid:
    """A grid whose only occupied cells hold ``points`` (N, 2) [m, map]: what the correlative search matches to."""
    lo = points.min(axis=0) - 1.0
    hi = points.max(axis=0) + 1.0
    shape = (int(math.ceil((hi[1] - lo[1]) / resolution)), int(math.ceil((hi[0] - lo[0]) / resolution)))
    grid = OccupancyGrid(resolution, (float(lo[0]), float(lo[1])), shape, grow=False)
    r, c = grid.world_to_cell(points[:, 0], points[:, 1])
    grid.logodds[r, c] = L_MAX
    grid.version += 1
    return grid


class GraphSlam:
    """Keyframe pose-graph SLAM over odometry and scans (see module doc).

    Call :meth:`update` for every odometry sample (with the latest scan, or
    None), then :meth:`finish`; read :meth:`trajectory` (every scan's pose)
    and :meth:`keyframe_poses`. Deterministic.
    """

    def __init__(self, config: GraphConfig | None = None) -> None:
        self.cfg = config or GraphConfig()
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(0.01)
        params.relinearizeSkip = 1
        self.isam = gtsam.ISAM2(params)
        self.keyframes: list[Keyframe] = []
        self.places: list[_ScanPlace] = []
        self.stats = Stats()
        self._est: list[Pose2] = []  # current estimate of every keyframe [map]
        self._xy = np.zeros((0, 2))
        self._history: deque[tuple[float, Pose2]] = deque(maxlen=256)
        self._last_scan = -math.inf
        self._path = 0.0
        self._turn = 0.0
        self._front = CorrelativeMatcher(window_xy=FRONT_WINDOW[0], window_theta=FRONT_WINDOW[1], min_score=0.0,
                                         refine=True)
        self._wide = CorrelativeMatcher(window_xy=CLOSURE_WINDOW[0], window_theta=CLOSURE_WINDOW[1], min_score=0.0,
                                        levels=CLOSURE_LEVELS, prior_xy=3.0, prior_theta=math.radians(45.0),
                                        refine=True)
        self._final: list[Pose2] | None = None

    # -- input -------------------------------------------------------------

    def update(self, stamp: float, odom: Pose2, scan: Scan | None) -> bool:
        """One odometry sample (base_link in odom) and the latest scan; True if a keyframe was added."""
        if self._history:
            prev = self._history[-1][1]
            self._path += math.hypot(odom.x - prev.x, odom.y - prev.y)
            self._turn += abs(wrap_angle(odom.theta - prev.theta))
        if not self._history or stamp > self._history[-1][0]:
            self._history.append((float(stamp), odom))
        if scan is None or scan.stamp <= self._last_scan:
            return False
        self._last_scan = scan.stamp
        t0 = time.perf_counter()
        at_scan = interpolate_pose(self._history, scan.stamp)
        added = self._add_scan(scan, at_scan)
        self.stats.ms.append(1e3 * (time.perf_counter() - t0))
        return added

    def _add_scan(self, scan: Scan, odom: Pose2) -> bool:
        pts = scan.points()
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= self.cfg.max_range]
        if not self.keyframes:
            self._start(scan, odom, pts)
            return True
        last = self.keyframes[-1]
        delta = last.odom.between(odom)
        if math.hypot(delta.x, delta.y) < self.cfg.keyframe_distance and abs(delta.theta) < self.cfg.keyframe_angle:
            self.places.append(_ScanPlace(scan.stamp, last.index, delta))
            return False
        kf = Keyframe(len(self.keyframes), scan.stamp, odom, pts, scan, last.path + self._path)
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        sig = odometry_sigmas(delta, self._path, self._turn)
        self._path = self._turn = 0.0
        graph.add(gtsam.BetweenFactorPose2(X(last.index), X(kf.index), to_gtsam(delta),
                                           gtsam.noiseModel.Diagonal.Sigmas(sig)))
        predicted = self._est[last.index].compose(delta)
        guess = predicted
        if self.cfg.scan_matching:
            matched = self._match(pts, predicted, range(max(0, kf.index - self.cfg.local_keyframes), kf.index),
                                  self._front)
            if matched is not None:
                pose, cov = matched
                guess = pose
                rel = self._est[last.index].between(pose)
                graph.add(gtsam.BetweenFactorPose2(X(last.index), X(kf.index), to_gtsam(rel), self._noise(cov, pose)))
                self.stats.matches += 1
            else:
                self.stats.match_failures += 1
        values.insert(X(kf.index), to_gtsam(guess))
        self.keyframes.append(kf)
        self.places.append(_ScanPlace(scan.stamp, kf.index, Pose2()))
        self._est.append(guess)
        self._xy = np.vstack([self._xy, [guess.x, guess.y]])
        closed = self._close_loop(kf, graph)
        self.isam.update(graph, values)
        if closed:
            self._refresh()
        else:
            self._est[kf.index] = from_gtsam(self.isam.calculateEstimatePose2(X(kf.index)))
            self._xy[kf.index] = (self._est[kf.index].x, self._est[kf.index].y)
        return True

    def _start(self, scan: Scan, odom: Pose2, pts: np.ndarray) -> None:
        kf = Keyframe(0, scan.stamp, odom, pts, scan, 0.0)
        self.keyframes.append(kf)
        self.places.append(_ScanPlace(scan.stamp, 0, Pose2()))
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        graph.add(gtsam.PriorFactorPose2(X(0), to_gtsam(odom), gtsam.noiseModel.Diagonal.Sigmas(np.array(FIRST_SIGMA))))
        values.insert(X(0), to_gtsam(odom))
        self.isam.update(graph, values)
        self._est.append(odom)
        self._xy = np.array([[odom.x, odom.y]])
        self._path = self._turn = 0.0

    # -- matching ----------------------------------------------------------

    def _local_map(self, indices: range) -> np.ndarray:
        return np.vstack([self._est[i].transform_points(self.keyframes[i].points) for i in indices])

    def _match(self, pts: np.ndarray, prior: Pose2, indices: range, matcher: CorrelativeMatcher,
               min_score: float = MIN_SCORE) -> tuple[Pose2, np.ndarray] | None:
        """The scan's pose in ``map`` against the local map of keyframes ``indices``, and its covariance; or None."""
        if len(pts) < scan_closure.MIN_PAIRS or len(indices) == 0:
            return None
        local = self._local_map(indices)
        found = matcher.match(end_points_grid(local), pts, prior, self.cfg.max_range)
        if found.score < min_score:
            return None
        # The correlative search says where the scan fits, not how well each direction is pinned: the
        # point-to-line Jacobian there does (a corridor's axis gets a free σ, and odometry decides along it).
        ref = scan_closure.reference(local)
        pose = found.pose
        # Point-to-line ICP from there, for the sub-cell fit the search's 5 cm / 0.5° steps cannot give; kept only
        # if it stays in the search's cell.
        icp = scan_closure.match(ref, pts, pose, max_rms=ICP_MAX_RMS, gates=ICP_GATES, min_overlap=ICP_MIN_OVERLAP)
        if icp is not None and icp.pose.distance_to(pose) <= ICP_MAX_SHIFT[0] and \
                abs(wrap_angle(icp.pose.theta - pose.theta)) <= ICP_MAX_SHIFT[1]:
            pose = icp.pose
        cov = scan_closure.covariance_at(ref, pts, pose, COVARIANCE_GATE)
        if cov is None:
            return None
        return pose, cov

    def _noise(self, cov: np.ndarray, pose: Pose2, robust: bool = False) -> gtsam.noiseModel.Base:
        # The match's covariance is of the pose in map axes; the factor's error lives in the pose's own frame.
        c = rotate_covariance(cov, pose.theta)
        c = c + np.diag([MATCH_SIGMA_MIN[0] ** 2, MATCH_SIGMA_MIN[0] ** 2, MATCH_SIGMA_MIN[1] ** 2])
        gauss = gtsam.noiseModel.Gaussian.Covariance(c)
        if not robust:
            return gauss
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(CAUCHY_K), gauss)

    def _close_loop(self, kf: Keyframe, graph: gtsam.NonlinearFactorGraph) -> bool:
        """Match the new keyframe to the nearest old one within reach; add the factor to ``graph`` if it holds."""
        if self.cfg.closure_radius <= 0 or not self.cfg.scan_matching:
            return False
        old = np.array([k.path <= kf.path - self.cfg.closure_gap for k in self.keyframes[:-1]], dtype=bool)
        if not old.any():
            return False
        here = self._est[kf.index]
        d = np.hypot(self._xy[:-1, 0] - here.x, self._xy[:-1, 1] - here.y)
        d[~old] = np.inf
        j = int(np.argmin(d))
        if not d[j] <= self.cfg.closure_radius:
            return False
        self.stats.closure_attempts += 1
        lo, hi = max(0, j - CLOSURE_NEIGHBOURS), min(len(self.keyframes) - 1, j + CLOSURE_NEIGHBOURS + 1)
        hi = min(hi, int(np.searchsorted([k.path for k in self.keyframes], kf.path - self.cfg.closure_gap, "right")))
        matched = self._match(kf.points, here, range(lo, max(hi, j + 1)), self._wide, CLOSURE_SCORE)
        if matched is None:
            return False
        pose, cov = matched
        rel = self._est[j].between(pose)
        graph.add(gtsam.BetweenFactorPose2(X(j), X(kf.index), to_gtsam(rel), self._noise(cov, pose, robust=True)))
        self.stats.closures += 1
        return True

    def _refresh(self) -> None:
        est = self.isam.calculateEstimate()
        self._est = [from_gtsam(est.atPose2(X(k.index))) for k in self.keyframes]
        self._xy = np.array([(p.x, p.y) for p in self._est])

    # -- output ------------------------------------------------------------

    def finish(self) -> None:
        """Re-optimise the whole graph in one batch (Levenberg–Marquardt from iSAM2's estimate)."""
        if not self.keyframes:
            self._final = []
            return
        t0 = time.perf_counter()
        graph = self.isam.getFactorsUnsafe()
        result = gtsam.LevenbergMarquardtOptimizer(graph, self.isam.calculateEstimate()).optimize()
        self._final = [from_gtsam(result.atPose2(X(k.index))) for k in self.keyframes]
        if self.stats.ms:
            self.stats.ms[-1] += 1e3 * (time.perf_counter() - t0)

    def keyframe_poses(self) -> list[Pose2]:
        """Every keyframe's pose in ``map`` (after :meth:`finish`, the batch optimum)."""
        if self._final is not None:
            return list(self._final)
        self._refresh()
        return list(self._est)

    def trajectory(self) -> tuple[list[float], list[Pose2]]:
        """Every scan's stamp [s] and pose in ``map``: its keyframe's pose moved by the odometry since."""
        kf = self.keyframe_poses()
        return [p.stamp for p in self.places], [kf[p.keyframe].compose(p.offset) for p in self.places]
