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
- optionally, the scan-matched motion between consecutive keyframes (the
  grid SLAM's corrected pose, ``matched``) as a second, robust between
  factor: the lidar keeps the chain straight between tags, the tags close
  the loops the scan matcher cannot, and a failed match is down-weighted.

Association is by tag id. A new keyframe starts every ``keyframe_distance``
metres or ``keyframe_angle`` radians of odometry; tag sightings in between
are carried to the current keyframe through odometry (interpolated at the
image's stamp) and the best-conditioned one per tag is kept. Each keyframe
keeps its scan, so the occupancy grid can be rebuilt from optimised poses.
The map → odom correction is the latest keyframe's optimised pose composed
with the inverse of its odometry pose.

Cost per keyframe is bounded: one iSAM2 update with a handful of factors,
relinearisation checked every ``relinearize_skip`` updates, and only the
latest pose and the landmarks read back. Not for: ambiguous (non-unique)
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
from homing.perception.apriltag import TagMeasurement
from homing.robot.frames import wrap_angle
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
ODOM_HISTORY = 5.0  # [s] odometry kept to place an image's sightings at its stamp


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


def interpolate_pose(history: Iterable[tuple[float, Pose2]], stamp: float) -> Pose2:
    """Odometry pose at ``stamp`` [s], linear between the two bracketing samples of ``history``.

    ``history`` is ordered by stamp; outside its span the nearest end is used.
    """
    items = list(history)
    if not items:
        raise ValueError("no odometry yet")
    if stamp <= items[0][0]:
        return items[0][1]
    for (t0, p0), (t1, p1) in zip(items, items[1:], strict=False):
        if t0 <= stamp <= t1:
            a = 0.0 if t1 <= t0 else (stamp - t0) / (t1 - t0)
            return Pose2(
                p0.x + a * (p1.x - p0.x), p0.y + a * (p1.y - p0.y),
                wrap_angle(p0.theta + a * wrap_angle(p1.theta - p0.theta)),
            )
    return items[-1][1]


class LandmarkSlam:
    """Incremental keyframe + tag-landmark SLAM (iSAM2). Feed it with :meth:`update` every tick.

    Frames: odometry poses are ``base_link`` in ``odom``; everything it
    returns is in ``map``. Deterministic: the same calls give the same map
    bit for bit, which is what makes offline replay equal the online run.
    """

    def __init__(self, config: SlamConfig | None = None) -> None:
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
        self._landmarks: dict[int, Pose2] = {}
        self._map_to_odom = Pose2()

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
        for m in tags:
            self._add_sighting(m)
        return added

    def flush(self) -> None:
        """Commit sightings waiting on the current keyframe without a new one (e.g. at a run's end)."""
        if self.keyframes and self._pending:
            self._commit(None)

    def _start(self, stamp: float, odom: Pose2, scan: Scan | None) -> None:
        kf = Keyframe(0, float(stamp), odom)
        self.keyframes.append(kf)
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        start = self._map_to_odom.compose(odom)
        graph.add(gtsam.PriorFactorPose2(X(0), to_gtsam(start), gtsam.noiseModel.Diagonal.Sigmas(np.array(FIRST_POSE_SIGMA))))
        values.insert(X(0), to_gtsam(start))
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
        if old is None or np.trace(cov[:2, :2]) < np.trace(old.cov[:2, :2]):
            self._pending[m.tag_id] = _Sighting(rel, cov)

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
        t0 = time.perf_counter()
        self.isam.update(graph, values)
        kf = self.keyframes[-1]
        self._latest_map_pose = from_gtsam(self.isam.calculateEstimatePose2(X(kf.index)))
        for tag_id in self.landmark_ids:
            self._landmarks[tag_id] = from_gtsam(self.isam.calculateEstimatePose2(L(tag_id)))
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
        return dict(self._landmarks)

    def keyframe_poses(self) -> list[Pose2]:
        """Every keyframe's optimised pose in ``map`` (reads the whole estimate: O(n), not every tick)."""
        est = self.isam.calculateEstimate()
        return [from_gtsam(est.atPose2(X(k.index))) for k in self.keyframes]

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


# -- a synthetic run, for the tests, the demo and the timing benchmark --------


@dataclass
class SyntheticRun:
    """A drive with known truth: per tick (stamp [s], true pose, odometry pose, sightings)."""

    tags: dict[int, Pose2]
    ticks: list[tuple[float, Pose2, Pose2, list[TagMeasurement]]]


def synthetic_loop(seed: int = 0, laps: int = 2, size: tuple[float, float] = (6.0, 4.0),
                   speed: float = 0.3, dt: float = 0.1, camera_period: float = 0.3,
                   slip: float = 0.04, yaw_bias: float = 0.002, tag_noise: float = 1.0,
                   yaw_noise: float = 0.002) -> SyntheticRun:
    """Drive ``laps`` laps of a rectangle (``size`` [m]) past tags on the walls around it.

    Odometry integrates the true motion with multiplicative noise ``slip``
    and a gyro scale error ``yaw_bias`` [rad/s per rad/s] (so it drifts like a
    real base) plus ``yaw_noise`` [rad/m] of heading noise per metre driven; ``tag_noise`` scales the sightings' noise. Tags within 3 m, ±29° and 60° of view are measured with the
    detector's covariance model at 320 px and noise drawn from it. Tag 0
    faces the start pose, like the dock's tag.
    """
    from homing.perception.apriltag import MAX_RANGE, MAX_VIEW_ANGLE, measurement_covariance

    rng = np.random.default_rng(seed)
    w, h = size
    fx = 0.5 * 320 / math.tan(math.radians(29.0))
    corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
    tags = {0: Pose2(-1.2, 0.0, 0.0)}
    for i in range(4):
        (ax, ay), (bx, by) = corners[i], corners[(i + 1) % 4]
        heading = math.atan2(by - ay, bx - ax)
        u = np.array([math.cos(heading), math.sin(heading)])
        left = np.array([-u[1], u[0]])
        for side, off in ((1, 0.4), (2, -0.4)):  # on the wall past the leg's end, facing back
            p = np.array([bx, by]) + 1.2 * u + off * left
            tags[3 * i + side] = Pose2(float(p[0]), float(p[1]), wrap_angle(heading + math.pi))
        mid = 0.5 * (np.array([ax, ay]) + np.array([bx, by])) + 1.0 * left
        face = -1.5 * u - 1.0 * left  # beside the leg's middle, turned towards the approach
        tags[3 * i + 3] = Pose2(float(mid[0]), float(mid[1]), math.atan2(face[1], face[0]))
    # Waypoints: drive the rectangle counter-clockwise, turning on the spot at corners.
    truth = Pose2(0.0, 0.0, math.pi)  # docked, facing the dock's tag
    odom = truth
    ticks: list[tuple[float, Pose2, Pose2, list[TagMeasurement]]] = []
    t, next_cam = 0.0, 0.0
    goals: list[tuple[tuple[float, float], tuple[str, ...]]] = [(c, ("turn", "drive")) for c in [corners[(i + 1) % 4] for i in range(4)] * laps]
    goals.append(((-1.0, 0.0), ("turn",)))  # back at the dock, facing its tag again
    for (gx, gy), phases in goals:
        for phase in phases:
            while True:
                dx, dy = gx - truth.x, gy - truth.y
                dist = math.hypot(dx, dy)
                err = wrap_angle(math.atan2(dy, dx) - truth.theta) if dist > 1e-6 else 0.0
                if phase == "turn":
                    if abs(err) < 1e-3:
                        break
                    v, om = 0.0, float(np.clip(err / dt, -0.8, 0.8))
                else:
                    if dist < 1e-3:
                        break
                    v, om = min(speed, dist / dt), float(np.clip(err / dt, -0.8, 0.8))
                truth = truth.compose(Pose2(v * dt, 0.0, om * dt))
                nv = v * (1.0 + slip * rng.normal())
                nom = om * (1.0 + yaw_bias + slip * rng.normal()) + yaw_noise * v * rng.normal()
                odom = odom.compose(Pose2(nv * dt, 0.0, nom * dt))
                t += dt
                seen: list[TagMeasurement] = []
                if t >= next_cam:
                    next_cam = t + camera_period
                    for tag_id, tag in tags.items():
                        rel = truth.between(tag)
                        r, b = math.hypot(rel.x, rel.y), math.atan2(rel.y, rel.x)
                        view = abs(wrap_angle(rel.theta - (b + math.pi)))
                        if r > MAX_RANGE or abs(b) > math.radians(29.0) or view > MAX_VIEW_ANGLE:
                            continue
                        cov = measurement_covariance(r, b, view, fx, 0.16)
                        noisy = rel.as_array() + tag_noise * rng.multivariate_normal(np.zeros(3), cov)
                        seen.append(TagMeasurement(
                            tag_id, t, Pose2.from_array(noisy), cov, r, b, view, 100.0, 0, 0.4,
                            np.eye(4), np.zeros((4, 2)),
                        ))
                ticks.append((t, truth, odom, seen))
    return SyntheticRun(tags, ticks)


def main() -> None:
    """Run SLAM on a synthetic loop and plot odometry, optimised and true trajectories and tags."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", metavar="PNG")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    run = synthetic_loop(args.seed)
    slam = LandmarkSlam()
    for stamp, _, odom, seen in run.ticks:
        slam.update(stamp, odom, None, seen)
    slam.flush()
    est = slam.landmarks()
    errs = [est[i].distance_to(p) for i, p in run.tags.items() if i in est]
    print(f"{len(slam.keyframes)} keyframes, {len(est)} tags, mean tag error {100 * np.mean(errs):.1f} cm, "
          f"iSAM2 update median {np.median(slam.update_ms):.2f} ms")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 6))
        tr = np.array([p.as_array() for _, p, _, _ in run.ticks])
        od = np.array([o.as_array() for _, _, o, _ in run.ticks])
        kf = np.array([p.as_array() for p in slam.keyframe_poses()])
        ax.plot(tr[:, 0], tr[:, 1], "g-", label="truth")
        ax.plot(od[:, 0], od[:, 1], "r:", label="odometry")
        ax.plot(kf[:, 0], kf[:, 1], "b.-", ms=3, label="iSAM2 keyframes")
        for i, p in run.tags.items():
            ax.plot(p.x, p.y, "gs")
            if i in est:
                ax.plot(est[i].x, est[i].y, "bx")
                ax.annotate(str(i), (est[i].x, est[i].y))
        ax.set_aspect("equal")
        ax.legend()
        fig.savefig(args.plot, dpi=90)


if __name__ == "__main__":
    main()
