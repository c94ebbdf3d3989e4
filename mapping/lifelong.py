"""Lifelong online SLAM: grid tracking as the front end, an iSAM2 keyframe graph that closes loops, keyframes only where the map has none yet.

The robot's :class:`~homing.mapping.grid_slam.GridSlam` tracks every scan
against its grid, as before. On top of it, a pose graph (Lu & Milios 1997,
with iSAM2 and the loop closures of :mod:`homing.mapping.graph_slam`)
holds *keyframes*: a scan and the pose it was taken at. The robot stands
at a keyframe (its *anchor*) plus the front end's motion since. Each
time the front end has travelled ``keyframe_distance``::

      front end travelled ≥ keyframe_distance since the last step, and this scan's match was not refused
                │
                ▼
      a keyframe within cover_radius of here (facing alike), or one closure_gap of path older within tie_radius?
       ├─ within cover_radius, already tied to the anchor ──► it becomes the anchor  (the scan: its newest view)
       ├─ the scan fits the submap around it ──► tie anchor→it (robust; none if tied already); it becomes the anchor
       └─ no ──► new keyframe, tied to the anchor by the front end's motion
                   └─ loop closure: the new keyframe fitted to the submap around the nearest
                      keyframe ``closure_gap`` of path older, searched over the graph's own
                      uncertainty (its iSAM2 marginal), wide fits confirmed by a second one from elsewhere
                │
                ▼  a tie or closure moved the keyframes more than rebuild_shift from where the grid has them
      the grid is redrawn from the keyframes' scans at their optimised poses and the
      front end is moved onto the graph (the grid it tracks against is now the graph's)

So a place the robot has mapped adds no keyframe when it comes back (as
slam_toolbox's lifelong mode, Macenski & Jambrecic 2021, replaces nodes
instead of adding them): keyframes, factors and ties grow with the area
mapped, not with the time spent there. A patrol passing between old
keyframes ties to one up to ``tie_radius`` away, so that once the map
stops growing the keyframes stop too, and with them the redraw's cost. A
route driven again and again hops from one tied keyframe to the next and
costs the graph nothing; each keyframe it passes keeps the newest scan of its
place, which redraws use (a parcel taken away stays away in the redrawn map).

The front end keeps what made it trustworthy: the settled reference grid,
the slip rungs, lost-and-found relocalisation. :meth:`set_pose` (the dock
anchor, a relocalisation, a restart on a saved map) means "the robot is
known to stand here": the next scan becomes a keyframe with a robust prior
there, tied to the previous one by the motion tracked as if there had been
no jump when the jump lies within the graph's own uncertainty (tracking had
drifted: the prior closes the loop), only weakly when it does not (a
kidnapped robot's way was not tracked).
After :meth:`adopt` (a saved map) the graph starts afresh, anchored on the
adopted grid, which every redraw starts from.

Frames: ``map`` as in :class:`GridSlam`. Costs: one iSAM2 update and one
marginal per keyframe, a submap fit per new tie or closure search, and a
redraw (one ``integrate`` per keyframe) only when a closure moved the map,
and then rationed (``REBUILD_*``) to one ``integrate`` per keyframe step
on average. The redrawn grid holds the keyframes' scans only, not every
scan the front end fused since.
Not for: a tag landmark SLAM that owns the grid (as GridSlam).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import gtsam
import numpy as np
from homing.mapping import submap
from homing.mapping.graph_slam import (
    CAUCHY_K,
    CLOSURE_CONFIRM,
    CLOSURE_CONFIRM_WITHIN,
    CLOSURE_GAP,
    CLOSURE_NEIGHBOURS,
    CLOSURE_RADIUS,
    CLOSURE_SCORE,
    CLOSURE_WINDOW_MAX,
    FIRST_SIGMA,
    MAX_RANGE,
    ODOM_SIGMA_MAX,
    PoseGraph,
    Stats,
    agree,
    closure_matcher,
    closure_window,
    max_turn,
)
from homing.mapping.grid import OccupancyGrid
from homing.mapping.grid_slam import GridSlam
from homing.mapping.landmark_slam import X, from_gtsam, to_gtsam
from homing.mapping.scan_closure import Reference
from homing.mapping.scan_match import GN_ANCHOR_THETA, CorrelativeMatcher
from homing.robot import Odometry, Pose2, Scan
from homing.robot.frames import wrap_angle

KEYFRAME_DISTANCE = 0.5  # [m] front-end motion from the anchor before a keyframe is considered
KEYFRAME_ANGLE = math.radians(30.0)  # [rad] the same in heading, for a laser that sees less than all round
COVER_RADIUS = 0.45  # [m] an old keyframe this near covers the place: no new one (< KEYFRAME_DISTANCE)
COVER_ANGLE = math.radians(20.0)  # [rad] and, for a laser that sees less than all round, facing this alike
# [m] an old keyframe (closure_gap of path older) this near, whose submap the scan fits, covers the place too. With
# cover_radius alone, patrol routes that passed between old keyframes, more than 0.45 m from each, added keyframes
# long after the map was complete (bench persist --days 1, lab, seeds 1-3: 490 / 182 / 367 keyframes at 23 h, with
# it 392 / 109 / 229). Only old ones: on new ground the keyframes just made would cover every step and space them
# this far apart.
TIE_RADIUS = 1.0
REBUILD_SHIFT = 0.05  # [m] keyframes moved this far from where the grid has them: redraw it (a cell)
REBUILD_REACH = 2.0  # [m] a heading change counts as the shift it gives a wall this far away
# A redraw costs one ray trace per keyframe (the whole map's worth), and while a loop is being closed, closure
# after closure moves the map a little. So a map moved by more than REBUILD_URGENT (about what the front end's
# tracking window can still take up) is redrawn at most every REBUILD_EVERY keyframe steps; a smaller move waits
# until as many steps have passed as there are keyframes over REBUILD_BUDGET, so that redrawing costs at most
# REBUILD_BUDGET ray traces per step on average, as much again as the front end's own. But a closure that moves the
# robot's own keyframe (the anchor) by more than REBUILD_URGENT is redrawn at once: until then the robot's pose is
# the front end's, that far from where the graph has it (test_lifelong's lap: a closure 6 steps after the last
# redraw left the robot 0.93 m out at the lap's end, the graph's pose for it 1 cm).
REBUILD_EVERY = 10
REBUILD_URGENT = 0.25  # [m]
REBUILD_BUDGET = 1.0  # keyframes redrawn per keyframe step, on average
# σ of the front end's motion between two keyframes: [m], [m/m] along the way, [m/m] across it, [rad], [rad/rad],
# [rad/m]. The grid tracks the heading and the offset from walls closely, but along a corridor it has little more
# than the wheels (a drive that slips there drifts along it): an isotropic σ let a closure bend the loop by turning
# it at its corners rather than stretch it where it slipped (test_lifelong: 1.2 m out instead of centimetres).
FRONT_SIGMA = (0.01, 0.08, 0.02, math.radians(0.1), 0.02, math.radians(0.2))
JUMP = (0.1, math.radians(3.0))  # [m, rad] a set_pose moving the pose this far is a jump, not motion
KNOWN_SIGMA = (0.05, 0.05, math.radians(2.0))  # [m, m, rad] σ of the prior where set_pose puts the robot
# [rad] the front end's hold on its heading once a match is chosen: the match's own 2°, so that the grid SLAM's looser
# TRACKING_ANCHOR_THETA (5°) is not applied here until the graph has been measured with it. With it, test_lifelong's
# loop ended 0.95 m out (its last closures came after the lap's last redraw) and its five lanes 0.23 m out at worst
# (0.12 m before): which keyframes a closure compares, and when the grid is redrawn, move with every change of the
# front end.
FRONT_ANCHOR_THETA = GN_ANCHOR_THETA
# [m] of path at least between a wide fit and the scan that confirms it (graph_slam's CLOSURE_CONFIRM_*): scans
# taken turning on one spot see the same walls, and where one fits a look-alike place so does the next (Radish
# Freiburg 079, 804 s: two keyframes 0.12 m apart fitted a wall 2.5 m along it, and confirmed each other). The same
# scan fitted to a second submap (a revisit's tie, then its keyframe's closure) still confirms. Not applied to the
# offline graph_slam, where it was measured worse on Freiburg 079 (0.042 → 0.046 m; the other four within 1 mm).
CLOSURE_CONFIRM_APART = 0.5
SETTLE_ITERATIONS = 2  # extra iSAM2 iterations after a tie or closure (relinearise around the new optimum)

@dataclass(frozen=True)
class LifelongConfig:
    """Parameters of :class:`LifelongSlam` (defaults: the module constants); checked on construction."""

    keyframe_distance: float = KEYFRAME_DISTANCE  # [m]
    keyframe_angle: float = KEYFRAME_ANGLE  # [rad]
    cover_radius: float = COVER_RADIUS  # [m]
    tie_radius: float = TIE_RADIUS  # [m] ≥ cover_radius
    closure_radius: float = CLOSURE_RADIUS  # [m]; 0 turns loop closures (and ties) off: the graph is the chain
    closure_gap: float = CLOSURE_GAP  # [m] of path between a keyframe and those it may close a loop with
    rebuild_shift: float = REBUILD_SHIFT  # [m]
    max_range: float = MAX_RANGE  # [m] keyframe end points kept for fits

    def __post_init__(self) -> None:
        for name in ("keyframe_distance", "keyframe_angle", "cover_radius", "rebuild_shift", "max_range"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, not {getattr(self, name)}")
        for name in ("closure_radius", "closure_gap"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be ≥ 0, not {getattr(self, name)}")
        if self.cover_radius >= self.keyframe_distance:
            raise ValueError(f"cover_radius ({self.cover_radius} m) must be under keyframe_distance "
                             f"({self.keyframe_distance} m), or a keyframe would cover the next one")
        if self.tie_radius < self.cover_radius:
            raise ValueError(f"tie_radius ({self.tie_radius} m) must be at least cover_radius ({self.cover_radius} m)")


@dataclass
class Node:
    """A keyframe: its scan, its end points (M, 2) [m, base_link] within reach, the path [m] when it was made.

    ``view`` is the newest scan of its place and where it was taken from the keyframe (``view_at``): what the
    grid is redrawn from, so that a redrawn map shows the place as it was last seen (a parcel taken away stays
    away), while fits keep the keyframe's own points.
    """

    index: int
    scan: Scan
    points: np.ndarray
    path: float
    reference: Reference | None = None  # its points with normals, made when first fitted against
    view: Scan | None = None
    view_at: Pose2 = field(default_factory=Pose2)

    def ref(self) -> Reference:
        """Its points with their normals, for fits (made on first use)."""
        if self.reference is None:
            self.reference = submap.scan_reference(self.points)
        return self.reference


@dataclass(frozen=True)
class _Tie:
    """A fit of the scan at ``estimate`` [map] (pose ``fit``) near keyframe j: the factor X_i⁻¹·X_j = ``rel``."""

    i: int
    j: int
    rel: Pose2
    noise: Any  # gtsam noise model
    fit: Pose2
    estimate: Pose2
    count: int  # the keyframe step it was made at
    path: float  # [m] the front end's path when its scan was taken


@dataclass
class LifelongStats(Stats):
    """Counters of :class:`LifelongSlam` (those of :class:`~homing.mapping.graph_slam.Stats` and its own)."""

    ties: int = 0  # factors to a keyframe that covered the place (a revisit)
    hops: int = 0  # revisits to a keyframe already tied to the anchor (beyond cover_radius: placed by a fit): no
    # factor, only its newest view kept
    rebuilds: int = 0  # grids redrawn from the keyframes
    jumps: int = 0  # set_pose calls that moved the robot (dock anchor, relocalisation)
    steps: int = 0  # keyframe steps (front end moved keyframe_distance)
    rebuild_keyframes: list[int] = field(default_factory=list)  # keyframes redrawn at each rebuild


def front_covariance(delta: Pose2) -> np.ndarray:
    """(3, 3) covariance (x, y [m²], θ [rad²], in the frame ``delta`` ends in, as a between factor's error) of the
    front end's motion ``delta`` between two keyframes (FRONT_SIGMA)."""
    floor, along, across, th_floor, th_per_rad, th_per_m = FRONT_SIGMA
    d = math.hypot(delta.x, delta.y)
    s_th = th_floor + th_per_rad * abs(wrap_angle(delta.theta)) + th_per_m * d
    way = math.atan2(delta.y, delta.x) - delta.theta if d > 0 else 0.0
    return _rotated(np.diag([(floor + along * d) ** 2, (floor + across * d) ** 2, s_th**2]), way)


def _robust(noise: gtsam.noiseModel.Base) -> gtsam.noiseModel.Base:
    return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(CAUCHY_K), noise)


class LifelongSlam(GridSlam):
    """Grid SLAM whose map is kept consistent by a lifelong keyframe pose graph (see module doc).

    Used as :class:`GridSlam` (``update``, ``pose``, ``map_to_odom``,
    ``grid``, ``set_pose``, ``adopt``, ``forget_pose``); ``front`` are
    GridSlam's keyword arguments. ``record=True`` keeps every fused scan's
    place for :meth:`trajectory` (offline scoring: it grows with time).
    """

    def __init__(self, config: LifelongConfig | None = None, record: bool = False, **front: Any) -> None:
        super().__init__(**{"anchor_theta": FRONT_ANCHOR_THETA, **front})
        self.cfg = config or LifelongConfig()
        self.record = record
        self._restart(None)

    def _restart(self, base: OccupancyGrid | None) -> None:
        """An empty graph; redraws start from ``base`` (an adopted map) or from nothing."""
        self.stats = LifelongStats()
        self.graph = PoseGraph(self.stats)
        self.nodes: list[Node] = []
        self._est: list[Pose2] = []  # every keyframe's estimate [map]
        self._xy = np.zeros((0, 2))
        self._theta = np.zeros(0)
        self._paths = np.zeros(0)  # [m] every keyframe's path when it was made
        self._drawn = np.zeros((0, 3))  # (N, 3) where each keyframe's scan is drawn in the grid [m, m, rad; map]
        self._moved = False  # the estimates may have left the drawn poses
        self._rebuilt_at = -REBUILD_EVERY  # keyframe step of the last redraw
        self._ties: set[tuple[int, int]] = set()  # keyframe pairs a factor joins (i < j)
        self._anchor = -1
        self._anchor_front = Pose2()  # the front end's pose of the anchor keyframe [map]
        self._path = 0.0  # [m] front-end path since the start
        self._stepped = 0.0  # [m] the path at the last keyframe step
        self._last_front: Pose2 | None = None
        self._known: Pose2 | None = None  # set_pose moved the map by this: a prior on the next keyframe
        self._wide: _Tie | None = None  # a wide fit awaiting a second to agree
        self._base = base
        self.places: list[tuple[float, int, Pose2]] = []  # (stamp, keyframe, offset) of every fused scan (record)

    # ----------------------------------------------------------------- inputs
    def update(self, odom: Odometry, scan: Scan | None) -> bool:
        """As :meth:`GridSlam.update`; a fused scan also moves the graph on (module doc)."""
        fused = super().update(odom, scan)
        if fused and scan is not None:
            self._step(scan)
        return fused

    def set_pose(self, pose: Pose2, odom_pose: Pose2) -> None:
        """As :meth:`GridSlam.set_pose`; a move of more than ``JUMP`` is a known pose for the graph (module doc)."""
        jumped = self.pose.distance_to(pose) > JUMP[0] or abs(wrap_angle(pose.theta - self.pose.theta)) > JUMP[1]
        correction = pose.compose(self.pose.inverse())  # map as tracked → map as now known
        super().set_pose(pose, odom_pose)
        if jumped and hasattr(self, "nodes"):
            self._known = correction.compose(self._known or Pose2())
            self._last_front = None
            self.stats.jumps += 1

    def adopt(self, grid: OccupancyGrid) -> None:
        """As :meth:`GridSlam.adopt`; the graph starts afresh on ``grid``, which every redraw starts from."""
        super().adopt(grid)
        self._restart(grid.copy())

    # ------------------------------------------------------------------- graph
    def _step(self, scan: Scan) -> None:
        front = self.scan_pose
        if self._last_front is not None:
            self._path += front.distance_to(self._last_front)
        self._last_front = front
        if not self.nodes:
            self._known = None  # the first keyframe is where the map starts anyway
            self._new_node(scan, front, prior=(front, FIRST_SIGMA, False))
            return
        chain = self._anchor_front.between(front)
        all_round = max_turn(scan) >= math.pi
        # Travelled keyframe_distance since the last step (not: that far from the anchor, which a revisit of a
        # keyframe up to tie_radius away would leave standing, a fit a scan).
        due = self._path - self._stepped >= self.cfg.keyframe_distance or \
            (not all_round and abs(wrap_angle(chain.theta)) >= self.cfg.keyframe_angle)
        # A scan whose match the front end refused, or that misfits the map, was drawn where the wheels put it: a
        # keyframe of it would tie that error into the graph by the front end's own tight motion (Radish ACES,
        # 630 s: a keyframe 14° off; 500 s later every closure against its submap failed, 1.6 m left open). The
        # step waits for a scan matched.
        due = due and self.matched
        if self._known is not None:
            self._known_pose(scan, front, self._known)
            self._known = None
        elif not due:
            self._place(scan.stamp, self._anchor, chain)
        else:
            self.stats.steps += 1
            self._stepped = self._path
            if not self._revisit(scan, front, chain):
                self._new_node(scan, front)
        self._maybe_rebuild()

    def _known_pose(self, scan: Scan, front: Pose2, correction: Pose2) -> None:
        """A keyframe where set_pose put the robot (``front``), after moving the map by ``correction``.

        Its motion from the anchor is what the front end tracked as if there had been no jump. If the jump is
        within the graph's own uncertainty (``closure_window`` of the anchor's marginal), the robot was where
        tracking had drifted from, and the motion ties the keyframe as any other: the prior then closes the
        loop. A larger jump (a kidnapped robot, carried) says nothing of the way it went: a weak tie only.
        """
        a = self._anchor
        chain = self._anchor_front.between(correction.inverse().compose(front))
        cov = front_covariance(chain)
        marginal = self.graph.marginal(a)
        gap = self._est[a].compose(chain).between(front)
        window = closure_window(marginal + cov) if marginal is not None else (0.0, 0.0)
        within = math.hypot(gap.x, gap.y) <= window[0] and abs(wrap_angle(gap.theta)) <= window[1]
        if not within:
            cov = np.diag([ODOM_SIGMA_MAX[0] ** 2, ODOM_SIGMA_MAX[0] ** 2, ODOM_SIGMA_MAX[1] ** 2])
        self._new_node(scan, front, prior=(front, KNOWN_SIGMA, True), chain=(chain, cov))

    def _place(self, stamp: float, node: int, offset: Pose2) -> None:
        if self.record:
            self.places.append((stamp, node, offset))

    def _points(self, scan: Scan) -> np.ndarray:
        pts = scan.points()
        return pts[np.hypot(pts[:, 0], pts[:, 1]) <= self.cfg.max_range]

    def _new_node(self, scan: Scan, front: Pose2, prior: tuple[Pose2, tuple[float, float, float], bool] | None = None,
                  chain: tuple[Pose2, np.ndarray] | None = None) -> None:
        """A keyframe at the front end's pose ``front``, tied to the anchor by the front end's motion (or ``chain``:
        a motion and its covariance), and/or with ``prior`` (pose, σ, robust)."""
        k = len(self.nodes)
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        if self._anchor >= 0:
            motion = self._anchor_front.between(front) if chain is None else chain[0]
            cov = front_covariance(motion) if chain is None else chain[1]
            graph.add(gtsam.BetweenFactorPose2(X(self._anchor), X(k), to_gtsam(motion),
                                               gtsam.noiseModel.Gaussian.Covariance(cov)))
            guess = self._est[self._anchor].compose(motion)
            self._ties.add((self._anchor, k))
        if prior is not None:
            at, sigmas, robust = prior
            noise = gtsam.noiseModel.Diagonal.Sigmas(np.array(sigmas))
            graph.add(gtsam.PriorFactorPose2(X(k), to_gtsam(at), _robust(noise) if robust else noise))
            guess = at
        values.insert(X(k), to_gtsam(guess))
        self.nodes.append(Node(k, scan, self._points(scan), self._path))
        self.graph.update(graph, values, self._est)
        est = from_gtsam(self.graph.isam.calculateEstimatePose2(X(k)))
        self._est.append(est)
        self._drawn = np.vstack([self._drawn, [front.x, front.y, front.theta]])  # the front end drew it there
        self._moved = self._moved or prior is not None
        self._xy = np.vstack([self._xy, [est.x, est.y]])
        self._theta = np.append(self._theta, est.theta)
        self._paths = np.append(self._paths, self._path)
        self._stepped = self._path
        self._anchor, self._anchor_front = k, front
        self._place(scan.stamp, k, Pose2())
        if k > 0:
            self._close_loop(k)

    def _revisit(self, scan: Scan, front: Pose2, chain: Pose2) -> bool:
        """Whether an old keyframe covers the place (module doc); if so it becomes the anchor, tied if it was not."""
        if self.cfg.closure_radius <= 0:
            return False
        a = self._anchor
        here = self._est[a].compose(chain)
        d = np.hypot(self._xy[:, 0] - here.x, self._xy[:, 1] - here.y)
        if max_turn(scan) < math.pi:
            d[np.abs(np.angle(np.exp(1j * (self._theta - here.theta)))) > COVER_ANGLE] = np.inf
        d[a] = np.inf
        d[(d > self.cfg.cover_radius) & (self._paths > self._path - self.cfg.closure_gap)] = np.inf
        j = int(np.argmin(d))
        if not d[j] <= self.cfg.tie_radius:
            return False
        tied = (min(a, j), max(a, j)) in self._ties
        if tied and d[j] <= self.cfg.cover_radius:  # a route driven before: hop along it
            self.stats.hops += 1
            self._hop(j, front, here.between(self._est[j]).inverse(), scan)
            return True
        # A scan that does not fit makes a keyframe even where one covers the place (a changed place, or a drift
        # wider than the search): its closure search is what finds a drift. (Keeping the anchor instead, its
        # chain growing, lost ACES's closures: 0.068 → 0.142 m.)
        return self._tie(j, scan, front, chain, tied)

    def _tie(self, j: int, scan: Scan, front: Pose2, chain: Pose2, tied: bool) -> bool:
        """Whether the scan, ``chain`` from the anchor, fits the submap around keyframe j; if so j becomes the anchor,
        tied to the old one unless it was (``tied``)."""
        a = self._anchor
        here = self._est[a].compose(chain)
        marginal = self.graph.marginal(a)
        if marginal is None:
            return False
        chain_cov = front_covariance(chain)
        window = closure_window(marginal + chain_cov)
        fit = self._fit(j, self._points(scan), here, window, before=len(self.nodes))
        if fit is None:
            return False
        seen = self._est[j].between(fit.pose)  # here, seen from keyframe j
        if tied:  # farther than cover_radius: placed by the fit, and the pair has its factor already
            self.stats.hops += 1
            self._hop(j, front, seen, scan)
            return True
        # The anchor seen from j: chain⁻¹ after `seen`; its error in the anchor's frame.
        rel = seen.compose(chain.inverse())
        cov = fit.covariance + _rotated(chain_cov, here.theta)
        noise = self.graph.noise(cov, Pose2(0.0, 0.0, self._est[a].theta), robust=True)
        if noise is None:
            return False
        tie = _Tie(j, a, rel, noise, fit.pose, here, self.stats.steps, self._path)
        if not self._confirmed(tie, window):
            return False
        self.stats.ties += 1
        self._hop(j, front, seen, scan)
        return True

    def _hop(self, j: int, front: Pose2, seen: Pose2, scan: Scan) -> None:
        """Keyframe j becomes the anchor; the robot (front end at ``front``) stands at ``seen`` from it, and ``scan``
        is j's newest view."""
        self._anchor, self._anchor_front = j, front.compose(seen.inverse())
        self._place(scan.stamp, j, seen)
        self.nodes[j].view, self.nodes[j].view_at = scan, seen

    def _close_loop(self, k: int) -> None:
        """Fit the new keyframe to the submap around the nearest one ``closure_gap`` older (graph_slam's search)."""
        if self.cfg.closure_radius <= 0:
            return
        node = self.nodes[k]
        paths = self._paths[:k]
        old = paths <= node.path - self.cfg.closure_gap
        if not old.any():
            return
        here = self._est[k]
        d = np.hypot(self._xy[:k, 0] - here.x, self._xy[:k, 1] - here.y)
        turn = np.abs(np.angle(np.exp(1j * (self._theta[:k] - here.theta))))
        d[~old | (turn > max_turn(node.scan))] = np.inf
        j = int(np.argmin(d))
        if not d[j] <= self.cfg.closure_radius + CLOSURE_WINDOW_MAX[0]:
            return
        marginal = self.graph.marginal(k)
        if marginal is None:
            return
        window = closure_window(marginal)
        if not d[j] <= self.cfg.closure_radius + window[0]:
            return
        self.stats.closure_attempts += 1
        fit = self._fit(j, node.points, here, window, before=int(np.searchsorted(paths, node.path - self.cfg.closure_gap,
                                                                                   "right")))
        if fit is None:
            return
        noise = self.graph.noise(fit.covariance, fit.pose, robust=True)
        if noise is None:
            return
        tie = _Tie(j, k, self._est[j].between(fit.pose), noise, fit.pose, here, self.stats.steps, node.path)
        if self._confirmed(tie, window):
            self.stats.closures += 1

    def _fit(self, j: int, points: np.ndarray, prior: Pose2, window: tuple[float, float],
             before: int) -> submap.Fit | None:
        """The scan ``points`` fitted to the submap of keyframe j and its neighbours (index < ``before``)."""
        lo, hi = max(0, j - CLOSURE_NEIGHBOURS), min(j + CLOSURE_NEIGHBOURS + 1, max(before, j + 1))
        idx = [i for i in range(lo, hi) if i != self._anchor or i == j]
        around = submap.build([self.nodes[i].ref() for i in idx], [self._est[i] for i in idx])
        if around is None:
            return None
        return submap.fit(around, points, prior, closure_matcher(window), CLOSURE_SCORE)

    def _confirmed(self, tie: _Tie, window: tuple[float, float]) -> bool:
        """Add ``tie`` if its search was narrow, or once a second wide one agrees (graph_slam's confirmation)."""
        if window[0] > CLOSURE_CONFIRM[0] or window[1] > CLOSURE_CONFIRM[1]:
            pending, self._wide = self._wide, tie
            if pending is not None and 0 < tie.count - pending.count <= CLOSURE_CONFIRM_WITHIN and \
                    tie.path - pending.path < CLOSURE_CONFIRM_APART:
                self._wide = pending  # another scan from the same spot: it neither confirms nor replaces
                return False
            if pending is None or tie.count - pending.count > CLOSURE_CONFIRM_WITHIN or \
                    not agree(pending.fit, pending.estimate, tie.fit, tie.estimate):
                return False
            self._wide = None
            self._add(pending)
        self._add(tie)
        return True

    def _add(self, tie: _Tie) -> None:
        graph = gtsam.NonlinearFactorGraph()
        graph.add(gtsam.BetweenFactorPose2(X(tie.i), X(tie.j), to_gtsam(tie.rel), tie.noise))
        self.graph.update(graph, gtsam.Values(), self._est)
        for _ in range(SETTLE_ITERATIONS):
            self.graph.update(gtsam.NonlinearFactorGraph(), gtsam.Values(), self._est)
        self._ties.add((min(tie.i, tie.j), max(tie.i, tie.j)))
        self._refresh()

    def _refresh(self) -> None:
        """Every keyframe's estimate from iSAM2."""
        est = self.graph.isam.calculateEstimate()
        self._est = [from_gtsam(est.atPose2(X(i))) for i in range(len(self.nodes))]
        self._xy = np.array([(p.x, p.y) for p in self._est]).reshape(-1, 2)
        self._theta = np.array([p.theta for p in self._est])
        self._moved = True

    # ------------------------------------------------------------------- grid
    def _maybe_rebuild(self) -> None:
        """Redraw the grid from the keyframes at their estimates if they moved ``rebuild_shift`` from it."""
        if not self.nodes or not self._moved:
            return
        drawn = self._drawn
        shift = (np.hypot(self._xy[:, 0] - drawn[:, 0], self._xy[:, 1] - drawn[:, 1]) +
                 REBUILD_REACH * np.abs(np.angle(np.exp(1j * (self._theta - drawn[:, 2])))))  # each keyframe's
        moved = float(shift.max())
        if moved <= self.cfg.rebuild_shift:
            self._moved = False
            return
        wait = REBUILD_EVERY if moved > REBUILD_URGENT else max(REBUILD_EVERY, len(self.nodes) / REBUILD_BUDGET)
        if self.stats.steps - self._rebuilt_at < wait and shift[self._anchor] <= REBUILD_URGENT:
            return  # later: keep _moved
        self.redraw()

    def redraw(self) -> None:
        """Redraw the grid from the keyframes' scans at their estimates (on the adopted map, if any), and move the
        front end onto the graph."""
        if not self.nodes:
            return
        self._moved = False
        self._rebuilt_at = self.stats.steps
        # Where the graph has the robot now: the anchor's estimate moved by the front end's motion since.
        now = self._est[self._anchor].compose(self._anchor_front.between(self.scan_pose))
        shift = now.compose(self.scan_pose.inverse())  # map as the front end had it → map as the graph has it
        grid = self.grid
        if self._base is not None:
            grid.logodds, grid.origin = self._base.logodds.copy(), self._base.origin
        else:
            grid.logodds = np.zeros_like(grid.logodds)
        grid.clear_cache()
        for node, at in zip(self.nodes, self._est, strict=True):
            if node.view is None:
                grid.integrate(node.scan, at)
            else:
                grid.integrate(node.view, at.compose(node.view_at))
        GridSlam.adopt(self, grid)  # the reference settles from the redrawn grid
        if isinstance(self.matcher, CorrelativeMatcher):
            self.matcher.forget()
        self.map_to_odom = shift.compose(self.map_to_odom)
        self.scan_pose = now
        self.pose = shift.compose(self.pose)
        self._anchor_front = self._est[self._anchor]
        self._last_front = now
        self._drawn = np.column_stack([self._xy, self._theta])
        self.stats.rebuilds += 1
        self.stats.rebuild_keyframes.append(len(self.nodes))

    # ----------------------------------------------------------------- output
    def keyframe_poses(self) -> list[Pose2]:
        """Every keyframe's current estimate [map]."""
        if self.nodes:
            self._refresh()
        return list(self._est)

    def trajectory(self) -> tuple[list[float], list[Pose2]]:
        """Every fused scan's stamp [s] and pose [map] by the graph now (``record=True`` only)."""
        self.keyframe_poses()
        return [s for s, _, _ in self.places], [self._est[k].compose(off) for _, k, off in self.places]


def _rotated(cov: np.ndarray, angle: float) -> np.ndarray:
    """(3, 3) covariance in a frame turned by ``angle`` [rad] expressed in the outer frame's axes."""
    c, s = math.cos(angle), math.sin(angle)
    r = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return r @ cov @ r.T
