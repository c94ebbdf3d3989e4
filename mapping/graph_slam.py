"""Lidar pose-graph SLAM over keyframes (Lu & Milios 1997; Grisetti et al., "A tutorial on graph-based SLAM", 2010) with GTSAM's iSAM2.

For logs of any planar laser (a SICK's 180° at 1°, a Hokuyo's 240°, the
RPLIDAR's 360°), robot unknown. Variables: keyframe poses in ``map`` (the
``odom`` frame at the first scan). Factors:

- a prior on the first keyframe;
- odometry between consecutive keyframes, with a generic wheel-odometry
  noise (``ODOM_SIGMA``: a floor plus shares of the distance and the turn);
- the scan-matched motion between consecutive keyframes (the *front end*).
  Every scan, keyframe or not, is fitted to the submap of the last
  ``local_keyframes`` keyframes (:mod:`homing.mapping.submap`: correlative
  search around the last fitted pose moved by the odometry since, wide
  enough for the 0.4 m and the degrees odometry loses between sparse
  scans, then point-to-line ICP); a scan becomes a keyframe when its
  fitted pose is ``keyframe_distance`` or ``keyframe_angle`` from the last
  keyframe's, and the fit's covariance (a corridor's axis freed: there
  odometry decides) weighs its factor. Scans between keyframes keep their
  fitted pose relative to their keyframe, so wheels that lose degrees in a
  turn do not bend the trajectory between keyframes;
- lidar loop closures, gated by the graph's own uncertainty. The
  candidate is the nearest keyframe at least ``closure_gap`` metres of
  path older (by the current estimate) that faced within ``FOV − 90°`` of
  the new keyframe's heading (a 180° laser facing away sees other walls;
  a 360° one, any). iSAM2's marginal covariance of the new keyframe says
  how far the graph itself may have it from the truth; relative to the
  older, better-anchored parts of the map it is an upper bound. (The
  relative covariance of the pair from the joint marginal measured too
  tight — the fits' covariances are optimistic — and missed loops that
  freiburg-079 needs: 0.069 m against 0.043 m.) The candidate must lie
  within ``closure_radius`` plus ``CLOSURE_SIGMAS`` σ,
  and the new scan is fitted to the submap around it over a window of
  ``CLOSURE_SIGMAS`` σ (between ``CLOSURE_WINDOW_MIN`` and
  ``CLOSURE_WINDOW_MAX``), refining the best few peaks of the coarse
  search. An accepted fit becomes a between factor with a Cauchy kernel,
  so that a false match is down-weighted instead of bending the map. Right
  after a closure the relative uncertainty is small, so the next closures
  search small windows; a wide search (beyond ``CLOSURE_CONFIRM``) happens
  only when a long loop comes home, and its fit counts only once a second
  fit within ``CLOSURE_CONFIRM_WITHIN`` keyframes moves the map the same
  way (two false matches seldom agree).

An ill-posed step never ends a run: odometry across a gap of more than ``ODOM_GAP`` seconds (or an
increment whose σ would pass ``ODOM_SIGMA_MAX``) keeps only the weak
``ODOM_SIGMA_MAX`` between factor, so the chain stays connected and later
closures can still move it; a fit whose covariance is not finite and
positive definite (a degenerate scan) adds no factor; and if iSAM2's
Cholesky elimination still finds the system indeterminate, the graph is
rebuilt once with QR factorisation, which works on the Jacobian instead of
its square and so on the square root of the condition number (Dellaert &
Kaess, "Factor graphs for robot perception", 2017). Each case is counted in :class:`Stats` (``skipped``, by reason).

Without closures (``closure_radius=0``) this is incremental scan matching:
the "scan matching" baseline of Kümmerle et al. 2009. At the end,
:meth:`GraphSlam.finish` re-optimises the whole graph in one batch
(Levenberg–Marquardt from iSAM2's estimate).

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
from homing.mapping import submap
from homing.mapping.landmark_slam import (
    X,
    from_gtsam,
    interpolate_pose,
    rotate_covariance,
    to_gtsam,
)
from homing.mapping.scan_closure import Reference
from homing.mapping.scan_match import CorrelativeMatcher
from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2, Scan

KEYFRAME_DISTANCE = 0.3  # [m] fitted motion before a new keyframe
KEYFRAME_ANGLE = math.radians(10.0)  # [rad]
MAX_RANGE = 20.0  # [m] end points farther than this are not matched (a SICK's 80 m would cost, not help)
LOCAL_KEYFRAMES = 8  # keyframes in the front end's submap
FRONT_WINDOW = (0.5, math.radians(12.0))  # [m, rad] half-widths of the front end's correlative search
MIN_SCORE = 0.5  # mean likelihood-field value under an accepted front-end fit's end points (half the scan on mapped walls)
FRONT_REFINE = False  # Gauss–Newton on the field after the correlative search (before ICP)
CLOSURE_SIGMAS = 3.0  # closure search window and reach, in σ of the new keyframe's marginal
CLOSURE_WINDOW_MIN = (0.5, math.radians(8.0))  # [m, rad] closure search half-widths at least
CLOSURE_WINDOW_MAX = (4.0, math.radians(45.0))  # [m, rad] and at most
CLOSURE_TOP_STEPS = 3  # the coarse search's steps each side at most (sets the number of levels)
CLOSURE_CANDIDATES = 4  # coarse peaks refined in a closure search
CLOSURE_SCORE = 0.7  # mean likelihood-field value under an accepted closure's end points
CLOSURE_CONFIRM = (1.0, math.radians(15.0))  # [m, rad] a closure searched wider waits for a second one to agree
CLOSURE_CONFIRM_WITHIN = 3  # keyframes within which the second must come
CLOSURE_AGREE = (0.3, math.radians(3.0))  # [m, rad] two closures agree if they move the map alike
CLOSURE_RADIUS = 4.0  # [m] an old keyframe this near (plus the σ reach) is a closure candidate
CLOSURE_GAP = 10.0  # [m] of path at least between a keyframe and the keyframes it may close a loop with
CLOSURE_NEIGHBOURS = 4  # keyframes each side of the candidate in its submap
ODOM_SIGMA = (0.02, 0.10, math.radians(1.0), 0.10, math.radians(2.0))  # [m], [m/m], [rad], [rad/rad], [rad/m]
ODOM_SIGMA_MAX = (10.0, math.pi)  # [m, rad] an odometry factor's σ at most: across a gap, "somewhere near"
ODOM_GAP = 5.0  # [s] odometry silent this long (readings this far apart): the wheels did not see the step
ODOM_STALE = 1.0  # [s] no wheel reading this long before a scan: the front end predicts at constant velocity
COVARIANCE_MAX = 1e4  # [m², rad²] a fit's covariance eigenvalue beyond this (or not finite) is no measurement
MATCH_SIGMA_MIN = (0.01, math.radians(0.25))  # [m, rad] floors of a fit's σ (the ICP's own is optimistic)
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
    reference: Reference  # its points with their own scan's normals, for ICP


@dataclass
class _ScanPlace:
    """Where a scan was taken: its stamp, the keyframe before it and its pose relative to that keyframe."""

    stamp: float
    keyframe: int
    offset: Pose2


@dataclass(frozen=True)
class _Closure:
    """A loop-closure fit: keyframe k seen from keyframe j (``rel``), and where it puts k in the map."""

    j: int
    k: int
    rel: Pose2
    fit: submap.Fit
    estimate: Pose2  # k's estimate [map] before the fit


def agree(fit_a: Pose2, estimate_a: Pose2, fit_b: Pose2, estimate_b: Pose2) -> bool:
    """Whether a fit that moves a pose from ``estimate_a`` to ``fit_a`` [map] moves ``estimate_b`` to ``fit_b``
    too (within ``CLOSURE_AGREE``): two closures that correct the map alike."""
    moved = fit_a.compose(estimate_a.inverse()).compose(estimate_b)
    d = moved.between(fit_b)
    return math.hypot(d.x, d.y) <= CLOSURE_AGREE[0] and abs(d.theta) <= CLOSURE_AGREE[1]


def _agree(a: _Closure, b: _Closure) -> bool:
    """Whether closure ``a``'s correction of the map also puts ``b``'s keyframe where ``b``'s fit does."""
    return agree(a.fit.pose, a.estimate, b.fit.pose, b.estimate)


@dataclass
class Stats:
    """Counters and timings of a run."""

    matches: int = 0  # scans fitted to the front end's submap
    match_failures: int = 0  # scans placed by odometry alone
    closures: int = 0
    closure_attempts: int = 0
    skipped: dict[str, int] = field(default_factory=dict)  # factors weakened or left out, by reason
    qr_rebuilds: int = 0  # times an indeterminate Cholesky elimination made the graph switch to QR
    ms: list[float] = field(default_factory=list)  # wall time per scan [ms]

    def skip(self, reason: str) -> None:
        """Count one factor weakened or left out for ``reason``."""
        self.skipped[reason] = self.skipped.get(reason, 0) + 1


def odometry_sigmas(delta: Pose2, path: float, turn: float) -> np.ndarray:
    """(3,) σ of an odometry increment (x, y [m], θ [rad]) from its path [m] and absolute turn [rad]."""
    floor, per_m, th_floor, th_per_rad, th_per_m = ODOM_SIGMA
    s_xy = min(floor + per_m * path, ODOM_SIGMA_MAX[0])
    s_th = min(th_floor + th_per_rad * turn + th_per_m * path, ODOM_SIGMA_MAX[1])
    return np.array([s_xy, s_xy, s_th])


def max_turn(scan: Scan) -> float:
    """[rad] the largest heading difference at which two scans of this laser still share walls: FOV − 90°."""
    fov = abs(scan.angle_increment) * len(scan.ranges)
    return math.pi if fov >= 2 * math.pi - 1e-6 else max(fov - math.pi / 2, 0.0)


def closure_window(covariance: np.ndarray) -> tuple[float, float]:
    """Closure search half-widths ([m], [rad]) from a keyframe's (3, 3) marginal covariance (``CLOSURE_SIGMAS`` σ)."""
    s_xy = math.sqrt(max(float(np.linalg.eigvalsh(covariance[:2, :2])[-1]), 0.0))
    s_th = math.sqrt(max(float(covariance[2, 2]), 0.0))
    return (float(np.clip(CLOSURE_SIGMAS * s_xy, CLOSURE_WINDOW_MIN[0], CLOSURE_WINDOW_MAX[0])),
            float(np.clip(CLOSURE_SIGMAS * s_th, CLOSURE_WINDOW_MIN[1], CLOSURE_WINDOW_MAX[1])))


def closure_matcher(window: tuple[float, float]) -> CorrelativeMatcher:
    """A correlative matcher for a closure window ([m], [rad]): levels enough for ≤ ``CLOSURE_TOP_STEPS`` coarse steps."""
    levels = int(np.clip(math.ceil(math.log2(max(window[0] / (CLOSURE_TOP_STEPS * submap.RESOLUTION), 1.0))), 1, 5))
    return CorrelativeMatcher(window_xy=window[0], window_theta=window[1], levels=levels, min_score=0.0,
                              prior_xy=3.0, prior_theta=math.radians(45.0), candidates=CLOSURE_CANDIDATES)


def _isam(qr: bool = False) -> gtsam.ISAM2:
    """iSAM2 as the graph runs it (Cholesky, or QR for an ill-conditioned graph)."""
    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(0.01)
    params.relinearizeSkip = 1
    if qr:
        params.setFactorization("QR")
    return gtsam.ISAM2(params)


class PoseGraph:
    """iSAM2 over keyframe poses ``X(i)`` that survives an ill-posed step (module doc).

    Keeps every factor it was given, so that if Cholesky elimination finds the
    system indeterminate the whole graph is rebuilt once with QR; turns a
    fit's covariance into a factor's noise (or none, counted in ``stats``).
    """

    def __init__(self, stats: Stats) -> None:
        self.isam = _isam()
        self.factors = gtsam.NonlinearFactorGraph()  # every factor iSAM2 holds, to rebuild it with QR
        self.qr = False
        self.stats = stats

    def update(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, estimate: list[Pose2]) -> None:
        """iSAM2's update; on an indeterminate Cholesky elimination, the whole graph again with QR (once),
        started from ``estimate`` (the current pose of every keyframe already in the graph) and ``values``."""
        try:
            self.isam.update(graph, values)
        except RuntimeError as err:
            if self.qr or "ndetermina" not in str(err):  # GTSAM spells it "Indeterminant" in places
                raise
            self.qr = True
            self.stats.qr_rebuilds += 1
            everything = gtsam.NonlinearFactorGraph(self.factors)
            everything.push_back(graph)
            start = gtsam.Values(values)
            for i, p in enumerate(estimate):
                start.insert(X(i), to_gtsam(p))
            self.isam = _isam(qr=True)
            self.isam.update(everything, start)
        self.factors.push_back(graph)

    def noise(self, cov: np.ndarray, pose: Pose2, robust: bool = False) -> gtsam.noiseModel.Base | None:
        """The factor's noise from a fit's (3, 3) covariance [map axes], or None (counted) if it is no measurement."""
        w = np.linalg.eigvalsh(cov) if np.all(np.isfinite(cov)) else np.array([np.nan])
        if not np.all(np.isfinite(w)) or w.min() < 0.0 or w.max() > COVARIANCE_MAX:
            self.stats.skip("degenerate fit: no factor")
            return None
        # The fit's covariance is of the pose in map axes; the factor's error lives in the pose's own frame.
        c = rotate_covariance(cov, pose.theta)
        c = c + np.diag([MATCH_SIGMA_MIN[0] ** 2, MATCH_SIGMA_MIN[0] ** 2, MATCH_SIGMA_MIN[1] ** 2])
        gauss = gtsam.noiseModel.Gaussian.Covariance(c)
        if not robust:
            return gauss
        return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(CAUCHY_K), gauss)

    def marginal(self, i: int) -> np.ndarray | None:
        """(3, 3) marginal covariance of keyframe ``i`` [its own frame], or None (counted) if indeterminate."""
        try:
            return np.asarray(self.isam.marginalCovariance(X(i)))
        except RuntimeError:  # an indeterminate marginal: no bound on a search
            self.stats.skip("indeterminate marginal: no closure search")
            return None


class GraphSlam:
    """Keyframe pose-graph SLAM over odometry and scans (see module doc).

    Call :meth:`update` for every odometry sample (with the latest scan, or
    None), then :meth:`finish`; read :meth:`trajectory` (every scan's pose)
    and :meth:`keyframe_poses`. Deterministic.
    """

    def __init__(self, config: GraphConfig | None = None) -> None:
        self.cfg = config or GraphConfig()
        self.keyframes: list[Keyframe] = []
        self.places: list[_ScanPlace] = []
        self.stats = Stats()
        self.graph = PoseGraph(self.stats)
        self._est: list[Pose2] = []  # current estimate of every keyframe [map]
        self._xy = np.zeros((0, 2))  # keyframes' estimated positions [m, map]
        self._theta = np.zeros(0)  # and headings [rad]
        self._history: deque[tuple[float, Pose2]] = deque(maxlen=256)
        self._last_scan = -math.inf
        self._last_odom = Pose2()  # odometry at the last scan
        self._path = 0.0
        self._turn = 0.0
        self._front = CorrelativeMatcher(window_xy=FRONT_WINDOW[0], window_theta=FRONT_WINDOW[1], min_score=0.0,
                                         refine=FRONT_REFINE)
        self._submap: submap.Submap | None = None  # the front end's, built on first use after a change
        self._final: list[Pose2] | None = None
        self._pending: _Closure | None = None  # a wide closure awaiting a second to agree
        self._gap = False  # the wheels missed part of the motion since the last keyframe
        self._resumed = False  # the wheels spoke again after a gap since the last scan

    @property
    def isam(self) -> gtsam.ISAM2:
        """The graph's iSAM2 (:class:`PoseGraph`)."""
        return self.graph.isam

    @isam.setter
    def isam(self, isam: gtsam.ISAM2) -> None:
        self.graph.isam = isam

    # -- input -------------------------------------------------------------

    def update(self, stamp: float, odom: Pose2, scan: Scan | None) -> bool:
        """One odometry sample (base_link in odom) and the latest scan; True if a keyframe was added."""
        if self._history:
            prev = self._history[-1][1]
            self._path += math.hypot(odom.x - prev.x, odom.y - prev.y)
            self._turn += abs(wrap_angle(odom.theta - prev.theta))
        if not self._history or stamp > self._history[-1][0]:
            # A reading after more than ODOM_GAP of silence: the increment since spans motion nobody measured.
            resumed = bool(self._history) and stamp - self._history[-1][0] > ODOM_GAP
            self._gap, self._resumed = self._gap or resumed, self._resumed or resumed
            self._history.append((float(stamp), odom))
        if scan is None or scan.stamp <= self._last_scan:
            return False
        self._last_scan = scan.stamp
        t0 = time.perf_counter()
        at_scan = interpolate_pose(self._history, scan.stamp)
        self._gap = self._gap or scan.stamp - self._history[-1][0] > ODOM_GAP  # the wheels are silent
        added = self._add_scan(scan, at_scan)
        self.stats.ms.append(1e3 * (time.perf_counter() - t0))
        return added

    def _add_scan(self, scan: Scan, odom: Pose2) -> bool:
        pts = scan.points()
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= self.cfg.max_range]
        if not self.keyframes:
            self._start(scan, odom, pts)
            return True
        # The last scan's pose moved by the wheels since: the front end's prior.
        place = self.places[-1]
        # With the wheels silent (or back after a gap, their increment spanning all of it): constant velocity.
        moved = self._last_odom.between(odom)
        if self._resumed or scan.stamp - self._history[-1][0] > ODOM_STALE:
            moved = self._last_step()
        predicted = self._est[place.keyframe].compose(place.offset).compose(moved)
        self._last_odom, self._resumed = odom, False
        fitted = self._fit_front(pts, predicted) if self.cfg.scan_matching else None
        pose = fitted.pose if fitted is not None else predicted
        last = self.keyframes[-1]
        rel = self._est[last.index].between(pose)
        if math.hypot(rel.x, rel.y) < self.cfg.keyframe_distance and abs(rel.theta) < self.cfg.keyframe_angle:
            self.places.append(_ScanPlace(scan.stamp, last.index, rel))
            return False
        kf = Keyframe(len(self.keyframes), scan.stamp, odom, pts, scan, last.path + self._path,
                      submap.scan_reference(pts))
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        delta = last.odom.between(odom)
        sig = odometry_sigmas(delta, self._path, self._turn)
        if self._gap or sig[0] >= ODOM_SIGMA_MAX[0] or sig[2] >= ODOM_SIGMA_MAX[1]:
            # The wheels missed the step (or claim a path no σ model covers): keep the chain, say nothing more.
            sig = np.array([ODOM_SIGMA_MAX[0], ODOM_SIGMA_MAX[0], ODOM_SIGMA_MAX[1]])
            self.stats.skip("odometry gap: weak factor")
        self._path = self._turn = 0.0
        self._gap = False
        graph.add(gtsam.BetweenFactorPose2(X(last.index), X(kf.index), to_gtsam(delta),
                                           gtsam.noiseModel.Diagonal.Sigmas(sig)))
        noise = None if fitted is None else self.graph.noise(fitted.covariance, pose)
        if noise is not None:
            graph.add(gtsam.BetweenFactorPose2(X(last.index), X(kf.index), to_gtsam(rel), noise))
        values.insert(X(kf.index), to_gtsam(pose))
        self.keyframes.append(kf)
        self.places.append(_ScanPlace(scan.stamp, kf.index, Pose2()))
        self._update(graph, values)
        self._est.append(from_gtsam(self.isam.calculateEstimatePose2(X(kf.index))))
        self._xy = np.vstack([self._xy, [self._est[-1].x, self._est[-1].y]])
        self._theta = np.append(self._theta, self._est[-1].theta)
        self._submap = None
        if self._close_loop(kf):
            self._refresh()
        return True

    def _last_step(self) -> Pose2:
        """The motion between the last two scans' poses (none before the second scan)."""
        if len(self.places) < 2:
            return Pose2()
        a, b = self.places[-2], self.places[-1]
        return self._est[a.keyframe].compose(a.offset).between(self._est[b.keyframe].compose(b.offset))

    def _start(self, scan: Scan, odom: Pose2, pts: np.ndarray) -> None:
        kf = Keyframe(0, scan.stamp, odom, pts, scan, 0.0, submap.scan_reference(pts))
        self.keyframes.append(kf)
        self.places.append(_ScanPlace(scan.stamp, 0, Pose2()))
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        graph.add(gtsam.PriorFactorPose2(X(0), to_gtsam(odom), gtsam.noiseModel.Diagonal.Sigmas(np.array(FIRST_SIGMA))))
        values.insert(X(0), to_gtsam(odom))
        self._update(graph, values)
        self._est.append(odom)
        self._xy = np.array([[odom.x, odom.y]])
        self._theta = np.array([odom.theta])
        self._last_odom = odom
        self._path = self._turn = 0.0

    # -- matching ----------------------------------------------------------

    def _submap_of(self, indices: range, focus: int | None = None) -> submap.Submap | None:
        """The keyframes ``indices`` joined at their current estimates (``focus``: see :func:`submap.build`)."""
        return submap.build([self.keyframes[i].reference for i in indices], [self._est[i] for i in indices],
                            focus=None if focus is None else focus - indices.start)

    def _fit_front(self, pts: np.ndarray, prior: Pose2) -> submap.Fit | None:
        """The scan fitted to the last keyframes' submap around ``prior``, or None (then odometry places it)."""
        if self._submap is None:
            n = len(self.keyframes)
            self._submap = self._submap_of(range(max(0, n - self.cfg.local_keyframes), n), focus=n - 1)
        found = None if self._submap is None else submap.fit(self._submap, pts, prior, self._front, MIN_SCORE)
        if found is None:
            self.stats.match_failures += 1
        else:
            self.stats.matches += 1
        return found

    def _close_loop(self, kf: Keyframe) -> bool:
        """Fit the new keyframe to the submap around the nearest old one within reach; add the factor if it holds."""
        if self.cfg.closure_radius <= 0 or not self.cfg.scan_matching:
            return False
        paths = np.array([k.path for k in self.keyframes])
        old = paths[:-1] <= kf.path - self.cfg.closure_gap
        if not old.any():
            return False
        here = self._est[kf.index]
        d = np.hypot(self._xy[:-1, 0] - here.x, self._xy[:-1, 1] - here.y)
        # A laser that sees less than all round sees other walls when it faces away from where it was.
        turn = np.abs(np.angle(np.exp(1j * (self._theta[:-1] - here.theta))))
        d[~old | (turn > max_turn(kf.scan))] = np.inf
        j = int(np.argmin(d))
        if not d[j] <= self.cfg.closure_radius + CLOSURE_WINDOW_MAX[0]:
            return False
        # How far the graph itself says the new keyframe may be from where it has it.
        marginal = self.graph.marginal(kf.index)
        if marginal is None:  # no bound on the search, so no closure here
            return False
        window = closure_window(marginal)
        if not d[j] <= self.cfg.closure_radius + window[0]:
            return False
        self.stats.closure_attempts += 1
        lo = max(0, j - CLOSURE_NEIGHBOURS)
        hi = min(j + CLOSURE_NEIGHBOURS + 1, int(np.searchsorted(paths, kf.path - self.cfg.closure_gap, "right")))
        around = self._submap_of(range(lo, max(hi, j + 1)))
        found = None if around is None else submap.fit(around, kf.points, here, closure_matcher(window), CLOSURE_SCORE)
        if found is None:
            return False
        rel = self._est[j].between(found.pose)
        closure = _Closure(j, kf.index, rel, found, here)
        if window[0] > CLOSURE_CONFIRM[0] or window[1] > CLOSURE_CONFIRM[1]:
            # A wide search may find a false match as well as the true one: wait for the next keyframes' fit
            # to move the map the same way (two false matches seldom agree).
            pending, self._pending = self._pending, closure
            if pending is None or kf.index - pending.k > CLOSURE_CONFIRM_WITHIN or \
                    not _agree(pending, closure):
                return False
            self._pending = None
            self._add_closure(pending)
        self._add_closure(closure)
        return True

    def _add_closure(self, c: _Closure) -> None:
        noise = self.graph.noise(c.fit.covariance, c.fit.pose, robust=True)
        if noise is None:
            return
        graph = gtsam.NonlinearFactorGraph()
        graph.add(gtsam.BetweenFactorPose2(X(c.j), X(c.k), to_gtsam(c.rel), noise))
        self._update(graph, gtsam.Values())
        self.stats.closures += 1

    def _update(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> None:
        self.graph.update(graph, values, self._est)

    def _refresh(self) -> None:
        est = self.isam.calculateEstimate()
        self._est = [from_gtsam(est.atPose2(X(k.index))) for k in self.keyframes]
        self._xy = np.array([(p.x, p.y) for p in self._est])
        self._theta = np.array([p.theta for p in self._est])
        self._submap = None

    # -- output ------------------------------------------------------------

    def finish(self) -> None:
        """Re-optimise the whole graph in one batch (Levenberg–Marquardt from iSAM2's estimate)."""
        if not self.keyframes:
            self._final = []
            return
        t0 = time.perf_counter()
        start = self.isam.calculateEstimate()
        params = gtsam.LevenbergMarquardtParams()
        if self.graph.qr:
            params.setLinearSolverType("MULTIFRONTAL_QR")
        try:
            result = gtsam.LevenbergMarquardtOptimizer(self.graph.factors, start, params).optimize()
        except RuntimeError:  # the batch could not improve on iSAM2's estimate: keep that
            self.stats.skip("indeterminate batch: iSAM2's estimate kept")
            result = start
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
        """Every scan's stamp [s] and pose in ``map``: its keyframe's pose moved by the scan's fitted offset."""
        kf = self.keyframe_poses()
        return [p.stamp for p in self.places], [kf[p.keyframe].compose(p.offset) for p in self.places]
