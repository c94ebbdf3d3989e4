"""Online grid SLAM: scan-to-map matching corrects odometry, the corrected pose builds a log-odds grid (as gmapping's best particle, or Hector SLAM).

Each new scan is placed with the odometry pose *at the scan's stamp*
(interpolated from a short odometry history, because the observation's
odometry is newer than its latest scan), predicted into ``map`` through the
current ``map → odom`` correction, matched against the grid built so far
(:mod:`homing.mapping.scan_match`), and fused into the grid at the matched
pose. ``map → odom`` then absorbs the correction, so between scans the pose in
``map`` is ``map_to_odom ⊕ odom``.

Two grids: the *live* grid takes every fused scan and is what the robot
navigates and explores on (a box that appears is there, one taken away is
gone); the *reference*, which scans are matched against, follows the live
grid cell by cell until the live grid is sure of a cell, and keeps it so. Localising
against settled walls, a robot can circle its building for days without the
map drifting under it, while new ground settles into the reference as it is
explored.

Lost and found: a scan that lands on mapped ground but fits it nowhere near
the predicted pose (a kidnapped robot) is not fused, so the map is not
redrawn at the wrong place; after two such scans the robot is *lost*, and
each second one scan is looked for in the whole map
(:mod:`homing.mapping.relocalize`) until an unambiguous fit is found.

Frames: ``map`` is the ``odom`` frame at the first scan (identity
``map_to_odom`` until the first correction). Do not use this when a tag
landmark SLAM is running and rebuilding the grid: that one owns the grid
(ARCHITECTURE.md, ``/map/grid``).
"""

from __future__ import annotations

import math

import numpy as np
from homing.mapping.grid import L_MAX, L_MIN, OccupancyGrid
from homing.mapping.grid import NOTHING as _NOTHING
from homing.mapping.relocalize import Relocalisation, relocalise
from homing.mapping.scan_match import GN_ANCHOR_XY, CorrelativeMatcher, MatchResult, ScanMatcher
from homing.robot import Odometry, Pose2, Scan
from homing.robot.frames import wrap_angle
from homing.robot.history import PoseHistory

HISTORY = 2.0  # [s] of odometry kept to look up the pose at a scan's stamp
# A scan is matched and fused once the robot has moved this far or turned this much since the last one, or
# this long has passed (gmapping's linearUpdate / angularUpdate / temporalUpdate, 1 m / 0.5 rad / off there:
# its particles are costly; Hector SLAM updates its map every 0.4 m / 0.9 rad). Between them odometry carries
# the pose, which it does to millimetres over a few centimetres; a standing robot still refreshes its map.
UPDATE_TRAVEL = 0.2  # [m]
UPDATE_TURN = 0.1  # [rad]
UPDATE_PERIOD = 1.0  # [s]
# Lost: a scan whose end points on observed cells (at least MISFIT_POINTS of them: the rest may be new ground) fit
# them poorly (MISFIT_SCORE; a tracked robot scores ~0.98, a kidnapped one ~0.05) is not fused; LOST_AFTER of them
# in a row and the robot is lost, and each RELOCALISE_PERIOD a scan is looked for in the whole map
# (homing.mapping.relocalize).
MISFIT_POINTS = 40
MISFIT_SCORE = 0.5
LOST_AFTER = 2
RELOCALISE_PERIOD = 1.0  # [s]
MIN_RETURNS = 30  # a scan with fewer returns (a lidar dropout) is neither matched nor drawn
# The reference the scans are matched against takes a cell of the live grid once its log-odds reach this
# (about 4 hits of a wall, 8 rays through free floor) and keeps it: a robot that lives for days in one map
# matches against walls it is sure of instead of redrawing them at its own slowly drifting pose (on the lab,
# matching against the live grid drifted 0.6 m in 40 minutes and doubled its walls). What changes (a box,
# a chair, a door) still changes in the live grid, which navigation and exploration use.
SETTLE_AT = 3.0
MAX_CORRECTION_XY = 0.30  # [m] a larger jump between consecutive scans is rejected as a false match
MAX_CORRECTION_THETA = math.radians(10.0)  # [rad]
WARMUP_SCANS = 3  # scans fused at the odometry pose before matching starts
MATCH_RANGE_MARGIN = 1.0  # [m] end points this close to the sensor's reach are not matched (scan_match)
# [m] std-dev of the pull towards the odometry-predicted pose, scan to scan. Odometry drifts by millimetres
# between two scans, while a corridor gives the matcher nothing along its axis: with the one-shot default
# (0.10 m) the pose slid metres down the shared "loop" world's corridors; 0.03 m keeps it within ~5 cm.
TRACKING_PRIOR_XY = 0.03
# [rad] the same for heading. The gyro drifts by hundredths of a degree between two scans, while the
# correlative search's 0.5° steps barely change the score in a room (the likelihood field is 10 cm wide):
# with the one-shot default (3°) noise alone turned the map by 0.5–1° in the first seconds, and every
# later scan was matched to that turned map (mean pose error 2× odometry's on twelve recorded runs).
TRACKING_PRIOR_THETA = math.radians(0.5)
# The heading's prior weighs as on a scan of at least this many end points (CorrelativeMatcher's prior_points): a
# room's scan (180 and more after decimation) as before; an open hall's scan of 40 returns, whose mean field value a
# 0.5° step off the gyro gains by chance, is held 4.5 times as tightly (as 0.24° would hold it per point).
TRACKING_PRIOR_POINTS = 180
# Sub-cell Gauss–Newton refinement after the correlative search (scan_match): with the heading held by
# the prior above it no longer slides along corridors, and it removes the search's 5 cm / 0.5° steps.
TRACKING_REFINE = True
# Slipping wheels (a polished floor, a rug, the sim's wheel_slip fault) turn without the base moving as far: the
# encoders then over-count the travel by up to 2× while the gyro keeps the heading. The tight prior above pulls
# a match towards that over-counted travel (at 50 % slip, tracking slid 4 cm a scan and the map with it). So
# the travel of a prediction is scaled by ``odom_scale``, one rung of SLIP_SCALES, and a scan taken after at
# least SLIP_MIN_TRAVEL of odometry is also matched (with the same tight prior) from the predictions of the
# neighbouring rungs: if the walls fit one of them better by SLIP_MARGIN (mean likelihood), the robot steps to
# that rung. Each hypothesis keeps the tight prior, so none can slide along a corridor; a corridor that fits
# all alike keeps the rung it is on. (A single loosened match instead, measuring the scale, made runs without
# slip worse, up to 0.12 → 2.7 m on a corridor plan: its noise slides along corridors.)
SLIP_SCALES = (1.0, 0.75, 0.5, 0.25)  # travel of the base / travel the encoders count
SLIP_MIN_TRAVEL = 0.05  # [m]
SLIP_MARGIN = 0.03  # mean likelihood-field value, in [0, 1]
# A rung must also fit the end points that land on mapped cells (MatchResult.known_score) no worse: a score counts
# the points on new ground too, where the field is only the distance to the nearest wall mapped so far. Driving
# into an unmapped corridor (bench persist, office:1, seed 3, 24.5 s: half the points on new ground) ¾ scored
# 0.730 against 0.688 there while its points on mapped walls fitted worse (0.931 against 0.946); tracking stepped
# onto ¾ with no slip, jumped 13 cm along the corridor and drew it there: the map ended turned 1.07° about the
# dock (agreement at the docks 0.937-0.943, 0.98 once turned back); 0.50-0.59° and 0.962-0.968 with this rule.
# Back towards 1 (wheels that grip, the usual floor) the evidence asked is less: SLIP_RETURN. A false step onto
# ¾ (a straight scan 0.033 better there, no slip) under-predicted each scan by 5 cm along a corridor, where the
# tight prior could not undo it: the pose was 0.9 m out in 11 s before rung 1 won back by SLIP_MARGIN
# (bench persist, lab, day 4). Ties do not go back: on the slip test's loop a rung left at the first tie lost 9.8 m.
SLIP_RETURN = 0.005  # mean likelihood-field value
# Consecutive matches reuse one likelihood field while the grid has taken at most this many scans since:
# the field is most of a match's cost, and two scans more of map do not move a tracking match.
FIELD_MAX_AGE = 2
# The refinement above is pulled towards the correlative optimum by GN_ANCHOR_XY per end point (5 cm, about
# 3 mm over a scan's few hundred points): it hardly moves, so tracking was odometry plus the search's 5 cm
# steps, and 5-12 cm built up before a step won. On bench persist's first trip (lab, seed 1) the mean error was
# 7 cm, the reference settled with it and the map sat ~5 cm off the world for the rest of the week. So the
# chosen match is polished: Gauss-Newton again from it, pulled to it by POLISH_XY per end point (about the
# 3 cm of TRACKING_PRIOR_XY over the scan), kept when it moves the pose by at most a cell. First trips of seeds
# 1-3: mean error 7.0 / 3.9 / 3.5 cm before, 3.1 / 2.9 / 3.9 cm after; agreement at the first dock 0.965 /
# 0.991 / 0.994 before, 0.995 / 0.992 / 0.993 after. Not while the wheels slip (a rung below 1): its fit on
# the current rung then hid the better one of the next (the slip test's room: 4.7 m out, never on rung 1/2).
# Only where the scan fits the map cleanly (POLISH_MIN_SCORE): the sim's matches score 0.95-0.99, the Radish
# logs' 0.66-0.85 (people, glass, clutter), and polishing those moved bench slam-logs' FHW from 1.78 to 4.78 m
# mean relation error and ACES's std from 0.23 to 0.42 m (Edmonton, Freiburg 079/101 within 5 mm either way).
POLISH_XY = 0.5  # [m] per end point
# [rad] per end point: once a match is chosen, Gauss-Newton again from it with the heading held only this tightly (the
# position held as the match holds it, GN_ANCHOR_XY). The match's own refinement pulls towards the correlative optimum
# by 2° a point (scan_match's GN_ANCHOR_THETA); that optimum lies on the search's 0.5° steps and is tied to the gyro by
# the tight prior above, and near a fit the likelihood field is flat (a wall's Gaussian has no slope at its crest), so
# the pull outweighed the walls and tracking turned with the gyro: each room and corridor was drawn as turned as the
# robot was when it first saw it. Replaying six recorded explorations (the same odometry and scans each time), mean
# heading error [°] and the map's agreement, before → after: slam_office:1 0.48 → 0.16 (0.951 → 0.955) and 0.23 → 0.10
# (0.989 → 0.988), office:1 0.29 → 0.11 (0.977 → 0.983), atrium:2 0.51 → 0.42 (0.982 → 0.981), the loop world 0.34 →
# 0.18 (0.961 → 0.972); floor:6 3.7° off six minutes in, then lost and found turned 85° (0.928, 0.40 of the floor
# covered) → within 2.1° all the way (0.975). Loosening the match's own refinement instead (5° or 10°) changed how the
# slip rungs below compare: on the loop world a false step onto ¾ put the robot 1.7 m out and lost it for good. Only on
# rung 1, as the polish below.
TRACKING_ANCHOR_THETA = math.radians(5.0)
POLISH_MIN_SCORE = 0.9  # mean likelihood-field value of the chosen match


class GridSlam:
    """Grid SLAM over a stream of odometry and scans (see module doc).

    ``update(odom, scan)`` once per observation; read ``pose`` (base_link in
    ``map``), ``map_to_odom`` and ``grid``. ``matcher=None`` gives the
    odometry-only baseline (the grid is built from raw odometry).
    """

    def __init__(
        self,
        resolution: float = 0.05,
        matcher: ScanMatcher | None = None,
        use_matcher: bool = True,
        grid: OccupancyGrid | None = None,
        max_correction: tuple[float, float] = (MAX_CORRECTION_XY, MAX_CORRECTION_THETA),
        match_range: float | None = None,
        update_travel: float = UPDATE_TRAVEL,
        update_turn: float = UPDATE_TURN,
        update_period: float = UPDATE_PERIOD,
        relocalise_when_lost: bool = True,
        anchor_theta: float = TRACKING_ANCHOR_THETA,
    ) -> None:
        self.grid = grid if grid is not None else OccupancyGrid(resolution)
        # What scans are matched against: the live grid, but a cell it has been sure of (SETTLE_AT) stays as it was.
        self.reference, self._settled = _reference(self.grid)
        # [m, map] (xmin, ymin, xmax, ymax) where the live grid changed outside the windows settled since (None:
        # not known), and its version at the last settling.
        self._pending: tuple[float, float, float, float] | None = _NOTHING
        self._synced = self.grid.version
        self.matcher: ScanMatcher | None = (
            (matcher or CorrelativeMatcher(prior_xy=TRACKING_PRIOR_XY, prior_theta=TRACKING_PRIOR_THETA,
                                           refine=TRACKING_REFINE, field_max_age=FIELD_MAX_AGE,
                                           whole_field=True, prior_points=TRACKING_PRIOR_POINTS))
            if use_matcher
            else None
        )
        self.max_correction = max_correction  # [m, rad] a larger jump from the prediction is a false match
        self.match_range = match_range  # [m] end points matched (None: the scan's range_max − MATCH_RANGE_MARGIN)
        self.anchor_theta = anchor_theta  # [rad] per end point: the heading's hold once a match is chosen
        self.map_to_odom: Pose2 = Pose2()
        self.pose: Pose2 = Pose2()
        self.scan_pose: Pose2 = Pose2()  # base_link in map where the last scan was fused
        self.scans_fused = 0
        self.matches_rejected = 0
        # The last fused scan's pose is a match's that fits the map (False: refused, the prediction's; or a misfit)
        self.matched = True
        self.last_score = float("nan")
        self._last_scan_stamp = -math.inf
        self._odom = PoseHistory(HISTORY)
        self.update_travel, self.update_turn, self.update_period = update_travel, update_turn, update_period
        self.relocalise = relocalise_when_lost
        self.lost = False  # tracking has lost the robot: nothing is fused until it is found again
        self.misfits = 0
        self.times_lost = 0
        self.last_relocalisation: Relocalisation | None = None
        self._next_relocalise = -math.inf
        self._last_fused: tuple[float, Pose2] | None = None  # (stamp, odometry pose) of the last fused scan
        self.odom_scale = 1.0  # travel of the base / travel the encoders count (< 1 while the wheels slip)
        self.slip_switches = 0  # steps from one rung of SLIP_SCALES to another

    # ----------------------------------------------------------------- inputs
    def update(self, odom: Odometry, scan: Scan | None) -> bool:
        """Feed one observation's odometry and latest scan; returns True if a new scan was fused into the map (not:
        a dropout, a misfit, a scan spent looking for a lost robot)."""
        self._odom.add(odom.stamp, odom.pose)
        before = self.scans_fused
        if scan is not None and scan.stamp > self._last_scan_stamp:
            self._last_scan_stamp = scan.stamp
            at = self._odom.at(scan.stamp)
            if self._due(scan.stamp, at):
                self._fuse(scan, at)
                self._last_fused = (scan.stamp, at)
        self.pose = self.map_to_odom.compose(odom.pose)
        return self.scans_fused > before

    def _due(self, stamp: float, odom_pose: Pose2) -> bool:
        """Whether a scan taken at ``odom_pose`` is worth matching and fusing (see UPDATE_*)."""
        if self._last_fused is None or self.scans_fused < WARMUP_SCANS:
            return True
        t0, p0 = self._last_fused
        d = p0.between(odom_pose)
        return (math.hypot(d.x, d.y) >= self.update_travel or abs(d.theta) >= self.update_turn
                or stamp - t0 >= self.update_period or stamp < t0)

    # ------------------------------------------------------------------ core
    def _fuse(self, scan: Scan, odom_pose: Pose2) -> None:
        if int(scan.valid().sum()) < MIN_RETURNS:
            return  # a dropout: nothing to match, and its no-returns are no evidence of free space
        predicted = self._predict(odom_pose)
        corrected = predicted
        if self.matcher is not None and self.scans_fused >= WARMUP_SCANS:
            points = scan.points()
            max_range = scan.range_max - MATCH_RANGE_MARGIN if self.match_range is None else self.match_range
            if self.lost:
                self._relocalise(scan.stamp, points, odom_pose, max_range)
                return
            result = self.matcher.match(self.reference, points, predicted, max_range)
            result, scale = self._slip_match(result, points, odom_pose, max_range)
            self.last_score = result.score
            misfit = result.known_points >= MISFIT_POINTS and result.known_score < MISFIT_SCORE
            if self.relocalise and misfit:
                # The scan lands on mapped ground but fits nowhere near the prediction: the robot is not where
                # it thinks. Fusing it would draw the room at the wrong place; after LOST_AFTER such scans, look
                # for the robot in the whole map instead. Nor does it say anything of slip: the rung stays.
                self.misfits += 1
                if self.misfits >= LOST_AFTER:
                    self.lost = True
                    self.times_lost += 1
                return
            self.misfits = 0
            if scale != self.odom_scale:
                self.odom_scale = scale
                self.slip_switches += 1
            jump = predicted.between(result.pose)
            plausible = (
                math.hypot(jump.x, jump.y) <= self.max_correction[0]
                and abs(wrap_angle(jump.theta)) <= self.max_correction[1]
            )
            if result.ok and plausible:
                corrected = result.pose
                if scale == 1.0 and isinstance(self.matcher, CorrelativeMatcher) and \
                        self.anchor_theta > self.matcher.anchor_theta:
                    # The heading from the walls, not the gyro (TRACKING_ANCHOR_THETA): the chosen match again, its
                    # position held as tightly as the match holds it, its heading let go.
                    corrected = self.matcher.polish(self.reference, points, corrected, max_range, GN_ANCHOR_XY,
                                                    self.anchor_theta)
                if scale == 1.0 and result.score >= POLISH_MIN_SCORE and isinstance(self.matcher, CorrelativeMatcher):
                    polished = self.matcher.polish(self.reference, points, corrected, max_range, POLISH_XY)
                    if math.hypot(polished.x - corrected.x, polished.y - corrected.y) <= self.grid.resolution:
                        corrected = polished
            else:
                self.matches_rejected += 1
            self.matched = result.ok and plausible and not misfit
        self.map_to_odom = corrected.compose(odom_pose.inverse())
        self.scan_pose = corrected
        self.grid.integrate(scan, corrected)
        self._settle(corrected, scan.range_max)
        self.scans_fused += 1

    def _predict(self, odom_pose: Pose2, scale: float | None = None) -> Pose2:
        """The pose in map the odometry predicts for ``odom_pose``, its travel since the last scan scaled by
        ``scale`` (default ``odom_scale``)."""
        scale = self.odom_scale if scale is None else scale
        if self._last_fused is None or scale == 1.0:
            return self.map_to_odom.compose(odom_pose)
        last = self._last_fused[1]
        d = last.between(odom_pose)
        return self.map_to_odom.compose(last.compose(Pose2(d.x * scale, d.y * scale, d.theta)))

    def _slip_match(self, tight: MatchResult, points: np.ndarray, odom_pose: Pose2,
                    max_range: float) -> tuple[MatchResult, float]:
        """The match on the current rung of SLIP_SCALES, or on a neighbouring one the walls fit better (see SLIP_*),
        and that rung's scale."""
        if self._last_fused is None or self.matcher is None:
            return tight, self.odom_scale
        last = self._last_fused[1]
        d = last.between(odom_pose)
        if math.hypot(d.x, d.y) < SLIP_MIN_TRAVEL:
            return tight, self.odom_scale
        rung = SLIP_SCALES.index(self.odom_scale)
        best, best_scale = tight, self.odom_scale
        for k in (rung - 1, rung + 1):
            margin = SLIP_RETURN if k < rung else SLIP_MARGIN
            # A score is a mean of field values, none above 1: a match that good leaves no rung room to win.
            if 0 <= k < len(SLIP_SCALES) and best.score + margin <= 1.0 + 1e-6:
                other = self.matcher.match(self.reference, points, self._predict(odom_pose, SLIP_SCALES[k]), max_range)
                # and fit the end points on mapped cells no worse (see SLIP_MARGIN's comment)
                if other.ok and other.score >= best.score + margin and other.known_score >= best.known_score:
                    best, best_scale = other, SLIP_SCALES[k]
        return best, best_scale

    def _settle(self, pose: Pose2, reach: float) -> None:
        """Copy the cells the live grid has become sure of into the reference, where they then stay."""
        ref, live = self.reference, self.grid
        if ref.origin != live.origin or ref.shape != live.shape:  # the live grid grew: grow the reference alike
            res = live.resolution
            left = int(round((ref.origin[0] - live.origin[0]) / res))
            below = int(round((ref.origin[1] - live.origin[1]) / res))
            pad = ((below, live.shape[0] - ref.shape[0] - below), (left, live.shape[1] - ref.shape[1] - left))
            ref.logodds = np.pad(ref.logodds, pad)
            self._settled = np.pad(self._settled, pad)
            ref.origin = live.origin
        res, (ox, oy) = live.resolution, live.origin
        r, c = live.world_to_cell(pose.x, pose.y)
        n = int(math.ceil(reach / res)) + 2
        win = [max(int(r) - n, 0), min(int(r) + n + 1, live.shape[0]), max(int(c) - n, 0),
               min(int(c) + n + 1, live.shape[1])]
        # Only the cells the live grid changed since they were last taken can differ from it: those it changed
        # since the last call (a scan's rays may reach past the window: what is left out waits for a later one).
        changed = live.changed_extent(self._synced)
        self._synced = live.version
        box = None if changed is None or self._pending is None else _union(self._pending, changed)
        if box is None:  # changed from outside, nobody said where: the whole window, from now on
            r0, r1, c0, c1 = win
            self._pending = None
        elif box[0] > box[2] or box[1] > box[3]:
            r0 = r1 = c0 = c1 = 0
        else:
            r0 = max(win[0], int(math.floor((box[1] - oy) / res)) - 1)
            r1 = min(win[1], int(math.floor((box[3] - oy) / res)) + 2)
            c0 = max(win[2], int(math.floor((box[0] - ox) / res)) - 1)
            c1 = min(win[3], int(math.floor((box[2] - ox) / res)) + 2)
            window = (ox + win[2] * res, oy + win[0] * res, ox + win[3] * res, oy + win[1] * res)
            inside = window[0] <= box[0] and window[1] <= box[1] and box[2] <= window[2] and box[3] <= window[3]
            self._pending = _NOTHING if inside else box
        if r1 <= r0 or c1 <= c0:
            ref.clear_cache(_NOTHING)
            return
        live_w, ref_w, settled_w = live.logodds[r0:r1, c0:c1], ref.logodds[r0:r1, c0:c1], self._settled[r0:r1, c0:c1]
        # Until a cell settles it follows the live grid; once sure, it takes the clamp and keeps it.
        sure = np.abs(live_w) >= SETTLE_AT
        ref_w[...] = np.where(settled_w, ref_w, np.where(sure, np.where(live_w > 0, L_MAX, L_MIN), live_w))
        settled_w |= sure
        ref.clear_cache((ox + c0 * res, oy + r0 * res, ox + c1 * res, oy + r1 * res))

    def _relocalise(self, stamp: float, points: np.ndarray, odom_pose: Pose2, max_range: float) -> None:
        """While lost, look for the scan in the whole map every RELOCALISE_PERIOD; fuse nothing until found."""
        if stamp < self._next_relocalise:
            return
        self._next_relocalise = stamp + RELOCALISE_PERIOD
        whole = self.matcher.whole if isinstance(self.matcher, CorrelativeMatcher) else None
        found = relocalise(self.reference, points, max_range, whole)
        self.last_relocalisation = found
        if found.pose is not None:
            # Found: track from here as from a known pose; the slip rung belonged to the floor it was lifted from.
            self.set_pose(found.pose, odom_pose)

    def adopt(self, grid: OccupancyGrid) -> None:
        """Carry on with ``grid`` (a saved map): scans are matched against it from the first one."""
        self.grid = grid
        self.reference, self._settled = _reference(grid)
        self._pending, self._synced = _NOTHING, grid.version
        self.scans_fused = max(self.scans_fused, WARMUP_SCANS)

    def forget_pose(self) -> bool:
        """Count the robot as lost: the next scan is looked for in the whole map. Whether it was (a map to search).

        Does nothing before matching starts (``WARMUP_SCANS``): an empty map has nowhere to look.
        """
        if self.matcher is None or self.scans_fused < WARMUP_SCANS:
            return False
        self.lost, self.misfits = True, 0
        self._next_relocalise = -math.inf
        return True

    def set_pose(self, pose: Pose2, odom_pose: Pose2) -> None:
        """The robot is known to stand at ``pose`` in map (docked, or restarted on a saved map): track from there."""
        self.map_to_odom = pose.compose(odom_pose.inverse())
        self.pose = pose
        self.lost, self.misfits = False, 0
        self.odom_scale = 1.0

    # ------------------------------------------------------------ utilities
    def trajectory_point(self) -> np.ndarray:
        """The current pose as a (3,) array [m, m, rad] in ``map``."""
        return self.pose.as_array()


def _reference(grid: OccupancyGrid) -> tuple[OccupancyGrid, np.ndarray]:
    """The reference of a live ``grid`` (a copy, its sure cells settled) and the mask of settled cells."""
    ref = grid.copy()
    settled = np.abs(grid.logodds) >= SETTLE_AT
    ref.logodds[settled] = np.where(grid.logodds[settled] > 0, L_MAX, L_MIN)
    ref.clear_cache()
    return ref, settled


def _union(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The extent (xmin, ymin, xmax, ymax) holding both extents."""
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
