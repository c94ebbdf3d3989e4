"""Online landmark SLAM over keyframes and AprilTags with GTSAM's iSAM2 (Kaess et al., IJRR 2012).

A factor graph in the manner of the thesis's chapter 4: variables are
keyframe poses ``x_i`` (Pose2 in ``map``) and tag landmarks ``l_id`` (Pose2:
centre and face heading in ``map``). Factors:

- a prior on the first keyframe (``map`` is where the robot started);
- odometry between consecutive keyframes, its covariance from the robot's
  documented odometry model (:mod:`homing.robot.turtlebot`, stated in full in
  :mod:`homing.sim.odometry`): encoder slip along the path, gyro heading
  noise, bias and scale error, and the lateral error the heading error
  integrates into — not hand-tuned α's;
- one relative-pose factor per tag per keyframe (the tag seen from the
  keyframe), with the detector's covariance and a robust M-estimator
  (Huber or Cauchy), so that a wrong association is down-weighted instead
  of bending the map. A heading measured from the tag's own corners is
  weak and sometimes mirrored, so it is given ``TAG_YAW_SIGMA`` and the
  factor acts as a position (range-bearing) factor; a heading taken from the
  wall behind the tag (:mod:`homing.perception.tag_wall`) keeps its own σ;
- a tight prior on the dock's tag when it is first seen: the map's anchor,
  which every return to the dock re-observes;
- lidar links (:mod:`homing.mapping.scan_closure`): each new keyframe's
  scan is matched (point-to-line ICP from the odometry guess) to the last
  keyframe's scan and, every 4th keyframe, to the scan 4 keyframes back
  (``scan_links``), and each match is a robust between factor. Measured on ``homing bench slam``'s
  recorded runs, these matches are right to ≈ 3 mm and 0.02–0.03° per
  keyframe where the walls pin both axes, against 7.5 mm and 0.035°
  (biased) for the wheels and gyro: the lidar, not the odometry, carries
  the map between tags. A corridor's axis, which a match cannot see, is
  left free (``scan_closure.DEGENERATE``) and odometry keeps it;
- lidar loop closures: when a new keyframe (every ``closure_every``-th)
  comes within ``closure_radius`` of an old one, their scans are matched
  and the relative pose (heading only with ``closure_position=False``) is
  a robust between factor — the walls keep the stretches between tags,
  which only odometry linked, consistent with every earlier pass.
  A match's covariance is in the *old* keyframe's frame and GTSAM's
  between error in the measured pose's frame, so it is rotated by the
  match's heading before use: unrotated, a corridor's free axis and its
  tight one swapped whenever the two passes crossed at an angle, and
  position closures bent the map (why they were once heading-only);
- optionally, the scan-matched motion between consecutive keyframes (the
  grid SLAM's corrected pose, ``matched``) as a second, robust between
  factor: the lidar keeps the chain straight between tags, the tags close
  the loops the scan matcher cannot, and a failed match is down-weighted.

Association is by tag id. A new keyframe starts every ``keyframe_distance``
metres or ``keyframe_angle`` radians of odometry; tag sightings in between
are carried to the current keyframe through odometry (interpolated at the
image's stamp) and averaged per tag (:func:`fuse_sightings`), weighted as
the best-conditioned one. Each keyframe
keeps its scan, so the occupancy grid can be rebuilt from optimised poses.
The map → odom correction is the latest keyframe's optimised pose composed
with the inverse of its odometry pose.

Cost per keyframe is bounded: one iSAM2 update with a handful of factors,
relinearisation checked every ``relinearize_skip`` updates, and only the
latest pose and the landmarks read back; a closure attempt adds one scan
match (~3.5 ms) and a loop for iSAM2 to re-eliminate; the lidar links two short matches (~3 ms each). Not for: ambiguous (non-unique)
tag ids, or 3-D motion.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Protocol

import gtsam
import numpy as np
from homing.mapping import scan_closure
from homing.perception.apriltag import TagMeasurement
from homing.robot.frames import wrap_angle
from homing.robot.history import interpolate_pose
from homing.robot.turtlebot import (
    GYRO_BIAS_SIGMA,
    GYRO_NOISE,
    GYRO_SCALE_SIGMA,
    ODOM_K_S0,
    ODOM_K_SV,
    ODOM_K_SW,
)
from homing.robot.types import Pose2, Scan

KEYFRAME_DISTANCE = 0.25  # [m] odometry travelled before a new keyframe
KEYFRAME_ANGLE = 0.35  # [rad] (≈ 20°) odometry turn before a new keyframe
ODOM_SLIP_MARGIN = 4.0  # encoder variance × this: SLAM does not know where the floor is slippery
GYRO_BIAS_HORIZON = 120.0  # [s] the gyro bias, a constant, spread as white noise that matches its drift over this span
ODOM_SIGMA_MIN = (0.002, 0.002, 0.0005)  # [m, m, rad] floor so a standstill factor stays well-posed
SCAN_MATCH_SIGMA = (0.03, 0.03, 0.01)  # [m, m, rad] scan-matched motion between keyframes (5 cm cells, ≈ 1/2 cell)
TAG_YAW_SIGMA = 0.5  # [rad] heading σ of a tag measured from its corners alone (weak, sometimes mirrored)
FIRST_POSE_SIGMA = (1e-3, 1e-3, 1e-3)  # [m, m, rad] the map frame is the start pose
ANCHOR_SIGMA = (0.005, 0.005, 0.2)  # [m, m, rad] the dock's tag holds the map's origin; its yaw is a sighting's
ROBUST_K = {"huber": 1.345, "cauchy": 2.3849}  # 95 % efficiency tuning constants
RELINEARIZE_THRESHOLD = 0.05  # [m/rad] per-variable delta that triggers relinearisation
RELINEARIZE_SKIP = 10  # updates between relinearisation checks
CLOSURE_RADIUS = 1.0  # [m] an old keyframe this near a new one is matched to it by lidar (0: no closures)
CLOSURE_MIN_GAP = 60  # keyframes (≈ 15 m or 20 turns) before a keyframe may close a loop with an older one
CLOSURE_EVERY = 3  # keyframes between closure attempts: as accurate as every one on the loop world's recorded
# 30-min runs (3.5 ± 0.5 cm mean per tag either way) at 1/7 of the iSAM2 update time (median 0.27 vs 1.8 ms)
ODOM_HISTORY = 5.0  # [s] odometry kept to place an image's sightings at its stamp
CLOSURE_MIN_POINTS = 30  # returns both scans need for a lidar closure to be tried
# Keyframes back whose scans a new keyframe's scan is matched to: the last one, and every 4th keyframe the one
# 4 back (1 m, fewer steps for the heading to wander). A link from *every* keyframe 4 back was as accurate but
# cost 10-25x the iSAM2 update time over a 30-min explore run (its band of factors widens every clique).
SCAN_LINKS = (1, 4)
# Floors of a link's σ: its measured error (3.2 mm and 0.02-0.03° RMS per keyframe over four recorded bench
# slam runs, lab and loop world, where the match was not degenerate); the lidar-noise floor of a closure
# (scan_closure.SIGMA_MIN, 1 cm and 0.1°) would give the lidar less weight than the wheels.
SCAN_LINK_SIGMA_MIN = (0.003, math.radians(0.03))  # [m, rad]
SCAN_LINK_GATES = (0.2, 0.1)  # [m] correspondence gates of a link's match: the odometry guess is within ~2 cm
SCAN_LINK_ITERATIONS = 6  # steps before a link's match may count as converged


def X(i: int) -> int:
    """GTSAM key of keyframe ``i``."""
    return gtsam.symbol("x", i)


def L(tag_id: int) -> int:
    """GTSAM key of tag ``tag_id``."""
    return gtsam.symbol("l", tag_id)


def to_gtsam(p: Pose2) -> gtsam.Pose2:
    return gtsam.Pose2(p.x, p.y, p.theta)


def from_gtsam(p: gtsam.Pose2) -> Pose2:
    return Pose2(float(p.x()), float(p.y()), wrap_angle(float(p.theta())))


@dataclass(frozen=True)
class SlamConfig:
    """Parameters of :class:`LandmarkSlam` (defaults: the module constants).

    ``robust`` is ``"huber"``, ``"cauchy"`` or ``"none"``; ``anchor_tag`` is
    the dock's tag id (None: no anchor, the first pose alone fixes the map).
    """

    keyframe_distance: float = KEYFRAME_DISTANCE  # [m]
    keyframe_angle: float = KEYFRAME_ANGLE  # [rad]
    odom_slip_margin: float = ODOM_SLIP_MARGIN
    gyro_bias_horizon: float = GYRO_BIAS_HORIZON  # [s]
    tag_yaw_sigma: float = TAG_YAW_SIGMA  # [rad]
    robust: str = "cauchy"
    anchor_tag: int | None = 0
    relinearize_threshold: float = RELINEARIZE_THRESHOLD
    relinearize_skip: int = RELINEARIZE_SKIP
    closure_radius: float = CLOSURE_RADIUS  # [m]
    closure_min_gap: int = CLOSURE_MIN_GAP
    closure_every: int = CLOSURE_EVERY
    closure_position: bool = True  # lidar closures constrain position too, not only heading (see scan_closure)
    scan_links: tuple[int, ...] = SCAN_LINKS  # keyframes back a new scan is matched to (b > 1: every b-th); () none


@dataclass
class Keyframe:
    """A keyframe: its index, stamp [s], odometry pose (odom frame) and the scan taken there.

    ``scan_offset`` is where the robot was at the scan's stamp, seen from the
    keyframe (so a rebuilt grid places the scan exactly).
    """

    index: int
    stamp: float
    odom: Pose2
    scan: Scan | None = None
    scan_offset: Pose2 = field(default_factory=Pose2)
    matched: Pose2 | None = None  # the scan-matched pose at the keyframe (grid SLAM's frame), if given


@dataclass
class _Sighting:
    rel: Pose2  # tag seen from the keyframe
    cov: np.ndarray  # (3, 3) x, y, theta in the keyframe's frame
    others: list[tuple[Pose2, np.ndarray]] = field(default_factory=list)  # every sighting of it on this keyframe


def fuse_sightings(sightings: list[tuple[Pose2, np.ndarray]]) -> Pose2:
    """The information-weighted mean of one tag's sightings (pose, (3, 3) covariance) from one keyframe.

    Position by the inverse of each (2, 2) position covariance, heading by
    1/σ² about the first one's (a corner heading, σ ~ 0.5 rad, hardly
    counts beside a wall's, ~0.3°). A robot standing before a tag sees it
    in every frame: the mean uses them all, where keeping only the
    best-conditioned one threw the others away.
    """
    ref = sightings[0][0].theta
    info = np.zeros((2, 2))
    vec = np.zeros(2)
    w_th = d_th = 0.0
    for rel, cov in sightings:
        inv = np.linalg.inv(cov[:2, :2])
        info += inv
        vec += inv @ np.array([rel.x, rel.y])
        w = 1.0 / max(float(cov[2, 2]), 1e-12)
        w_th += w
        d_th += w * wrap_angle(rel.theta - ref)
    x, y = np.linalg.solve(info, vec)
    return Pose2(float(x), float(y), wrap_angle(ref + d_th / w_th))


class ScanSink(Protocol):
    """Anything a scan can be drawn into at a pose (the occupancy grid)."""

    def integrate(self, scan: Scan, pose: Pose2) -> None: ...


def odometry_covariance(delta: Pose2, path: float, turn: float, dt: float, cfg: SlamConfig) -> np.ndarray:
    """(3, 3) covariance of (x, y, θ) [m², rad²] of an odometry increment ``delta`` in its start frame.

    ``path`` [m] and ``turn`` [rad] are the distance and the absolute turn
    the odometry integrated on the way, ``dt`` [s] its duration. Encoder slip
    (× ``odom_slip_margin``) lies along the chord; the gyro's heading
    variance is its white noise over ``dt``, its scale error over ``turn``
    and its bias (a constant, see ``GYRO_BIAS_HORIZON``); a heading random
    walk over the path moves the end sideways (var θ·path²/3, correlated
    with θ by path/2).
    """
    dt = max(dt, 0.0)
    v = path / dt if dt > 0 else 0.0
    var_s = cfg.odom_slip_margin * ((ODOM_K_S0 + ODOM_K_SV * v) * path + ODOM_K_SW * turn)
    var_th = GYRO_NOISE**2 * dt + GYRO_BIAS_SIGMA**2 * dt * cfg.gyro_bias_horizon + (GYRO_SCALE_SIGMA * turn) ** 2
    chord = math.atan2(delta.y, delta.x) if math.hypot(delta.x, delta.y) > 1e-6 else 0.0
    local = np.array([
        [var_s, 0.0, 0.0],
        [0.0, var_th * path**2 / 3.0, var_th * path / 2.0],
        [0.0, var_th * path / 2.0, var_th],
    ])
    cov = rotate_covariance(local, -chord)
    return cov + np.diag(np.square(ODOM_SIGMA_MIN))


def rotate_covariance(cov: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) covariance of (x, y, θ) re-expressed in a frame rotated by ``angle`` [rad] from the original."""
    c, s = math.cos(angle), math.sin(angle)
    R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    return R @ cov @ R.T


def lidar_factor(j: int, k: int, found: scan_closure.Match) -> gtsam.BetweenFactorPose2:
    """A robust (Cauchy) between factor from keyframe ``j`` to ``k`` of a lidar match (``k``'s pose in ``j``'s frame).

    The match's covariance is in ``j``'s frame; GTSAM's between error is in
    the measured pose's (``k``'s as measured), so it is rotated by the
    match's heading first (as :meth:`LandmarkSlam._tag_noise` does for tags).
    """
    cov = rotate_covariance(found.covariance, found.pose.theta)
    noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(ROBUST_K["cauchy"]),
                                           gtsam.noiseModel.Gaussian.Covariance(cov))
    return gtsam.BetweenFactorPose2(X(j), X(k), to_gtsam(found.pose), noise)


class LandmarkSlam:
    """Incremental keyframe + tag-landmark SLAM (iSAM2). Feed it with :meth:`update` every tick.

    Frames: odometry poses are ``base_link`` in ``odom``; everything it
    returns is in ``map``. Deterministic: the same calls give the same map
    bit for bit, which is what makes offline replay equal the online run.
    """

    def __init__(self, config: SlamConfig | None = None, map_to_odom: Pose2 | None = None,
                 landmark_priors: dict[int, tuple[Pose2, np.ndarray]] | None = None) -> None:
        """``map_to_odom``: where ``map`` lies from ``odom`` at the start (another mapper's frame to estimate in);
        ``landmark_priors``: tag id → (pose in ``map``, (3, 3) covariance in the tag's frame) from an
        earlier session (:meth:`landmark_estimates`), so a new session starts from what is known."""
        self.cfg = config or SlamConfig()
        if self.cfg.robust not in ("huber", "cauchy", "none"):
            raise ValueError(f"unknown robust kernel '{self.cfg.robust}'")
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(self.cfg.relinearize_threshold)
        params.relinearizeSkip = self.cfg.relinearize_skip
        params.evaluateNonlinearError = False
        params.cacheLinearizedFactors = True
        self.isam = gtsam.ISAM2(params)
        self.keyframes: list[Keyframe] = []
        self.landmark_ids: list[int] = []
        self.anchored = False
        self.update_ms: list[float] = []  # wall time of each iSAM2 update and read-back [ms]
        self.n_tag_factors = 0
        self._pending: dict[int, _Sighting] = {}
        self._history: deque[tuple[float, Pose2]] = deque()
        self._path = 0.0  # [m] odometry path since the last keyframe
        self._match_noise = gtsam.noiseModel.Robust.Create(
            gtsam.noiseModel.mEstimator.Cauchy.Create(ROBUST_K["cauchy"]),
            gtsam.noiseModel.Diagonal.Sigmas(np.array(SCAN_MATCH_SIGMA)))
        self._turn = 0.0  # [rad] absolute odometry turn since the last keyframe
        self._latest_map_pose = Pose2()
        self._landmarks: dict[int, Pose2] = {}  # read back from iSAM2 lazily (see landmarks())
        self._landmarks_stale = False
        self.updates = 0  # iSAM2 updates so far: a reader can tell whether anything moved
        self._map_to_odom = map_to_odom or Pose2()
        self._priors = dict(landmark_priors or {})
        self._guesses: list[Pose2] = []  # each keyframe's map pose as estimated when it was added
        self._guess_xy = np.zeros((0, 2))  # [m] their positions, for the closure search
        self._references: dict[int, scan_closure.Reference] = {}  # keyframe index → its scan ready for matching
        self._recent: dict[int, scan_closure.Reference] = {}  # the last max(scan_links) keyframes' references
        self.n_links = 0
        self.link_ms: list[float] = []  # wall time of each keyframe's lidar links [ms]
        self._closures: list[gtsam.NonlinearFactor] = []  # lidar factors waiting for the next iSAM2 update
        self.n_closures = 0
        self.closure_ms: list[float] = []  # wall time of each scan match [ms]

    # -- input -------------------------------------------------------------

    def update(self, stamp: float, odom: Pose2, scan: Scan | None = None,
               tags: Iterable[TagMeasurement] = (), matched: Pose2 | None = None) -> bool:
        """Take one tick's odometry [odom frame], latest scan and new tag sightings; True if a keyframe was added.

        Tag measurements are in base_link at their own stamps (the image's).
        Pass each sighting once (only when the image is new). ``matched`` is
        the scan-matched pose of this tick in the grid SLAM's own frame (its
        motion between keyframes becomes a robust factor), or None.
        """
        if self._history:
            prev = self._history[-1][1]
            self._path += math.hypot(odom.x - prev.x, odom.y - prev.y)
            self._turn += abs(wrap_angle(odom.theta - prev.theta))
        self._history.append((float(stamp), odom))
        while self._history and self._history[0][0] < stamp - ODOM_HISTORY:
            self._history.popleft()
        added = False
        if not self.keyframes:
            self._start(stamp, odom, scan)
            self.keyframes[0].matched = matched
            added = True
        else:
            last = self.keyframes[-1]
            delta = last.odom.between(odom)
            if math.hypot(delta.x, delta.y) >= self.cfg.keyframe_distance or abs(delta.theta) >= self.cfg.keyframe_angle:
                self._commit(Keyframe(len(self.keyframes), float(stamp), odom, matched=matched))
                added = True
        if added:
            self._attach_scan(scan)
            self._guesses.append(self._latest_map_pose)
            if len(self._guesses) > len(self._guess_xy):  # grown by doubling: appending stays O(1)
                self._guess_xy = np.vstack([self._guess_xy, np.zeros((max(len(self._guess_xy), 64), 2))])
            self._guess_xy[len(self._guesses) - 1] = (self._latest_map_pose.x, self._latest_map_pose.y)
            self._link_scans()
            self._close_loop()
        for m in tags:
            self._add_sighting(m)
        return added

    def set_start_frame(self, map_to_odom: Pose2) -> None:
        """Before the first update: the first keyframe's prior is ``map_to_odom ∘ odom`` (another mapper's frame)."""
        if self.keyframes:
            raise RuntimeError("the graph has started: its frame is fixed")
        self._map_to_odom = map_to_odom

    def flush(self) -> None:
        """Commit sightings waiting on the current keyframe without a new one (e.g. at a run's end)."""
        if self.keyframes and (self._pending or self._closures):
            self._commit(None)

    def _start(self, stamp: float, odom: Pose2, scan: Scan | None) -> None:
        kf = Keyframe(0, float(stamp), odom)
        self.keyframes.append(kf)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        start = self._map_to_odom.compose(odom)
        graph.add(gtsam.PriorFactorPose2(X(0), to_gtsam(start), gtsam.noiseModel.Diagonal.Sigmas(np.array(FIRST_POSE_SIGMA))))
        values.insert(X(0), to_gtsam(start))
        for tag_id in sorted(self._priors):
            pose, cov = self._priors[tag_id]
            graph.add(gtsam.PriorFactorPose2(L(tag_id), to_gtsam(pose), gtsam.noiseModel.Gaussian.Covariance(cov)))
            values.insert(L(tag_id), to_gtsam(pose))
            self._landmarks[tag_id] = pose
            self.landmark_ids.append(tag_id)
        self._run(graph, values)

    def _attach_scan(self, scan: Scan | None) -> None:
        kf = self.keyframes[-1]
        if scan is None:
            return
        kf.scan = scan
        kf.scan_offset = kf.odom.between(interpolate_pose(self._history, scan.stamp))

    def _add_sighting(self, m: TagMeasurement) -> None:
        kf = self.keyframes[-1]
        at_image = kf.odom.between(interpolate_pose(self._history, m.stamp))
        rel = at_image.compose(m.pose)
        meas = np.array(m.covariance, dtype=float, copy=True)
        if m.yaw_source != "wall" and meas[2, 2] < self.cfg.tag_yaw_sigma**2:
            meas[2, :2] = meas[:2, 2] = 0.0
            meas[2, 2] = self.cfg.tag_yaw_sigma**2
        cov = rotate_covariance(meas, -at_image.theta)
        # The odometry between keyframe and image adds to the sighting's noise.
        d = math.hypot(at_image.x, at_image.y)
        cov = cov + odometry_covariance(at_image, d, abs(at_image.theta), abs(m.stamp - kf.stamp), self.cfg)
        old = self._pending.get(m.tag_id)
        if old is None:
            self._pending[m.tag_id] = _Sighting(rel, cov, [(rel, cov)])
            return
        old.others.append((rel, cov))
        if np.trace(cov[:2, :2]) < np.trace(old.cov[:2, :2]):
            old.cov = cov  # the factor's weight stays the best single sighting's: repeats share systematic errors

    def _close_loop(self) -> None:
        """Match the newest keyframe's scan to the nearest old keyframe's; queue the factor if it converged."""
        kf = self.keyframes[-1]
        if self.cfg.closure_radius <= 0.0 or kf.scan is None or kf.index % max(self.cfg.closure_every, 1):
            return
        here = self._guesses[-1]
        xy = self._guess_xy[: len(self._guesses) - 1]
        j = scan_closure.nearest_old(xy, np.array([here.x, here.y]), self.cfg.closure_radius, self.cfg.closure_min_gap)
        old = self.keyframes[j] if j is not None else None
        if j is None or old is None or old.scan is None:
            return
        if min(int(old.scan.valid().sum()), int(kf.scan.valid().sum())) < CLOSURE_MIN_POINTS:
            return  # a scan blanked by a lidar dropout has nothing to match
        t0 = time.perf_counter()
        if j not in self._references:
            self._references[j] = self._recent.get(j) or self._reference(old)
        found = scan_closure.match(self._references[j], kf.scan_offset.transform_points(kf.scan.points()),
                                   self._guesses[j].between(here), self.cfg.closure_position)
        self.closure_ms.append(1e3 * (time.perf_counter() - t0))
        if found is None:
            return
        self._closures.append(lidar_factor(j, kf.index, found))
        self.n_closures += 1

    @staticmethod
    def _reference(kf: Keyframe) -> scan_closure.Reference:
        assert kf.scan is not None
        return scan_closure.reference(kf.scan_offset.transform_points(kf.scan.points()))

    def _link_scans(self) -> None:
        """Match the newest keyframe's scan to the ``scan_links``-back keyframes' scans; queue the factors."""
        kf = self.keyframes[-1]
        links = self.cfg.scan_links
        if not links:
            return
        t0 = time.perf_counter()
        if kf.scan is not None and int(kf.scan.valid().sum()) >= CLOSURE_MIN_POINTS:
            self._recent[kf.index] = self._reference(kf)
            points = kf.scan_offset.transform_points(kf.scan.points())
            for back in links:
                ref = self._recent.get(kf.index - back)
                if ref is None or kf.index % back:
                    continue  # a longer link only from every back-th keyframe: chained, they keep iSAM2's cliques small
                old = self.keyframes[kf.index - back]
                found = scan_closure.match(ref, points, old.odom.between(kf.odom), True, gates=SCAN_LINK_GATES,
                                           min_iterations=SCAN_LINK_ITERATIONS, floor=SCAN_LINK_SIGMA_MIN)
                if found is not None:
                    self._closures.append(lidar_factor(old.index, kf.index, found))
                    self.n_links += 1
        for i in [i for i in self._recent if i <= kf.index - max(links)]:
            del self._recent[i]
        self.link_ms.append(1e3 * (time.perf_counter() - t0))

    # -- the graph ---------------------------------------------------------

    def _tag_noise(self, s: _Sighting) -> gtsam.noiseModel.Base:
        # BetweenFactor's error lives in the measured tag's frame.
        gauss = gtsam.noiseModel.Gaussian.Covariance(rotate_covariance(s.cov, s.rel.theta))
        if self.cfg.robust == "none":
            return gauss
        est = gtsam.noiseModel.mEstimator
        kernel = est.Huber.Create(ROBUST_K["huber"]) if self.cfg.robust == "huber" else est.Cauchy.Create(ROBUST_K["cauchy"])
        return gtsam.noiseModel.Robust.Create(kernel, gauss)

    def _commit(self, new: Keyframe | None) -> None:
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        last = self.keyframes[-1]
        last_map = self._latest_map_pose
        for tag_id in sorted(self._pending):
            s = self._pending[tag_id]
            s.rel = fuse_sightings(s.others)
            graph.add(gtsam.BetweenFactorPose2(X(last.index), L(tag_id), to_gtsam(s.rel), self._tag_noise(s)))
            self.n_tag_factors += 1
            if tag_id not in self._landmarks:
                guess = last_map.compose(s.rel)
                values.insert(L(tag_id), to_gtsam(guess))
                self._landmarks[tag_id] = guess
                self.landmark_ids.append(tag_id)
                if tag_id == self.cfg.anchor_tag:
                    graph.add(gtsam.PriorFactorPose2(L(tag_id), to_gtsam(guess), gtsam.noiseModel.Diagonal.Sigmas(np.array(ANCHOR_SIGMA))))
                    self.anchored = True
        self._pending.clear()
        if new is not None:
            delta = last.odom.between(new.odom)
            cov = odometry_covariance(delta, self._path, self._turn, new.stamp - last.stamp, self.cfg)
            noise = gtsam.noiseModel.Gaussian.Covariance(cov)
            self._path = self._turn = 0.0
            graph.add(gtsam.BetweenFactorPose2(X(last.index), X(new.index), to_gtsam(delta), noise))
            if last.matched is not None and new.matched is not None:
                graph.add(gtsam.BetweenFactorPose2(X(last.index), X(new.index), to_gtsam(last.matched.between(new.matched)),
                                                   self._match_noise))
            values.insert(X(new.index), to_gtsam(last_map.compose(delta)))
            self.keyframes.append(new)
        self._run(graph, values)

    def _run(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> None:
        for factor in self._closures:
            graph.add(factor)
        self._closures.clear()
        t0 = time.perf_counter()
        self.isam.update(graph, values)
        kf = self.keyframes[-1]
        self._latest_map_pose = from_gtsam(self.isam.calculateEstimatePose2(X(kf.index)))
        self._landmarks_stale = True  # every tag may have moved: read back when asked, not after every update
        self.updates += 1
        self._map_to_odom = self._latest_map_pose.compose(kf.odom.inverse())
        self.update_ms.append(1e3 * (time.perf_counter() - t0))

    # -- output ------------------------------------------------------------

    @property
    def map_to_odom(self) -> Pose2:
        """The ``map → odom`` correction: map pose = map_to_odom ∘ odometry pose."""
        return self._map_to_odom

    def pose(self, odom: Pose2) -> Pose2:
        """The robot's pose in ``map`` given its current odometry pose."""
        return self._map_to_odom.compose(odom)

    def landmarks(self) -> dict[int, Pose2]:
        """Tag id → optimised tag pose (centre, face heading) in ``map``."""
        if self._landmarks_stale:
            for tag_id in self.landmark_ids:
                self._landmarks[tag_id] = from_gtsam(self.isam.calculateEstimatePose2(L(tag_id)))
            self._landmarks_stale = False
        return dict(self._landmarks)

    def keyframe_poses(self) -> list[Pose2]:
        """Every keyframe's optimised pose in ``map`` (reads the whole estimate: O(n), not every tick)."""
        est = self.isam.calculateEstimate()
        return [from_gtsam(est.atPose2(X(k.index))) for k in self.keyframes]

    def landmark_estimates(self) -> dict[int, tuple[Pose2, np.ndarray]]:
        """Tag id → (pose in ``map``, (3, 3) marginal covariance): what a next session starts from (costly)."""
        return {i: (p, self.landmark_covariance(i)) for i, p in self.landmarks().items()}

    def landmark_covariance(self, tag_id: int) -> np.ndarray:
        """(3, 3) marginal covariance of tag ``tag_id`` in its own frame (costly: for reports, not ticks)."""
        return np.asarray(self.isam.marginalCovariance(L(tag_id)))

    def rebuild_grid(self, make_grid: Callable[[], ScanSink]) -> ScanSink:
        """A fresh grid from ``make_grid()`` with every keyframe's scan drawn at its optimised pose."""
        grid = make_grid()
        for kf, pose in zip(self.keyframes, self.keyframe_poses(), strict=False):
            if kf.scan is not None:
                grid.integrate(kf.scan, pose.compose(kf.scan_offset))
        return grid


BACKENDS: dict[str, type[LandmarkSlam]] = {"isam2": LandmarkSlam}
