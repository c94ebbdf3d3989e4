"""Scan-to-map matching: multi-resolution correlative search (Olson, ICRA 2009) refined by Gauss–Newton on a likelihood field (Kohlbrecher et al., Hector SLAM, 2011).

The map is turned into a likelihood field — each cell scores
``exp(−d²/2σ²)`` for its distance ``d`` to the nearest occupied cell — and a
scan's end points are scored by summing the field under them. The search:

1. correlative, coarse to fine: at the top level the field is max-pooled by
   2^L (so a coarse score bounds every finer pose under it) and every pose
   of a window around the odometry prior is scored at once as one
   (angles × offsets × points) gather; each finer level searches ±1 step
   around the best pose of the level above;
2. optionally (``refine=True``) Gauss–Newton on the bilinearly interpolated
   fine field from the best correlative pose, anchored to it, for sub-cell
   accuracy (the finest correlative step is one cell and 0.5°). It is off
   by default: with a loose heading prior it slid the pose along corridors
   of a drifting loop. Grid SLAM's scan-to-scan tracking turns it on
   together with a tight heading prior (:mod:`homing.mapping.grid_slam`).
   A small penalty for leaving the odometry prior breaks the ties a
   featureless corridor produces.

The result is accepted only if enough of the scan lands on known walls
(``min_score``); otherwise the caller should keep odometry. Matching is done
on a crop of the grid around the prior (sensor range plus window), so its cost
does not grow with the map.

Do not use this for global relocalisation: the window is local (tens of cm,
a few degrees), as between consecutive scans.
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass
from typing import Any, Protocol

import cv2
import numpy as np
from homing.mapping.blocks import block_any
from homing.mapping.grid import OccupancyGrid
from homing.robot import Pose2
from scipy import ndimage

from homing.map_server import OCCUPIED, UNKNOWN

SIGMA = 0.10  # [m] likelihood-field spread
DISTANCE_MASK = 5  # OpenCV's distance-transform mask for end-point fields (5: exact along the axes, within 2 % elsewhere)
WINDOW_XY = 0.20  # [m] half-width of the translational search window
WINDOW_THETA = math.radians(8.0)  # [rad] half-width of the angular search window
ANGLE_STEP = math.radians(0.5)  # [rad] at the finest correlative level
LEVELS = 2  # coarse levels above the finest (each halves the resolution)
MAX_POINTS = 180  # scan end points used by the correlative search (decimated)
GN_ITERATIONS = 8
PRIOR_XY = 0.10  # [m] std-dev of the odometry prior in the correlative score (one-shot matching)
PRIOR_THETA = math.radians(3.0)  # [rad] same, for heading
PRIOR_PENALTY = 0.01  # weight of the prior in the correlative score, per point
GN_ANCHOR_XY = 0.05  # [m] std-dev of the pull towards the correlative optimum in Gauss–Newton
GN_ANCHOR_THETA = math.radians(2.0)  # [rad]
GN_ANCHOR_INFO = np.diag([1 / GN_ANCHOR_XY**2, 1 / GN_ANCHOR_XY**2, 1 / GN_ANCHOR_THETA**2])  # per end point
MIN_SCORE = 0.25  # mean field value the best pose must reach to be trusted
MIN_POINTS = 30  # fewer scan end points than this: no match
FIELD_MARGIN = 1.0  # [m] a reusable field is computed this much wider than one match needs


@dataclass(frozen=True)
class MatchResult:
    """The matched pose of ``base_link`` in ``map``, its mean field score in [0, 1], and whether to trust it.

    ``known`` is the share of the scan's end points that land on cells the
    grid has observed, and ``known_score`` their mean field score: a scan of
    new ground lands on unknown cells (nothing to match, nothing wrong),
    while one that lands on observed cells far from any mapped wall does not
    fit the map (a wrong pose — a kidnapped robot — or a changed world).
    """

    pose: Pose2
    score: float
    ok: bool
    known: float = 0.0
    known_score: float = 0.0
    known_points: int = 0


class ScanMatcher(Protocol):
    """Finds the pose of a scan in a map, near a prior."""

    def match(self, grid: OccupancyGrid, points: np.ndarray, prior: Pose2, max_range: float = 5.0) -> MatchResult:
        """``points`` (M, 2) scan end points in ``base_link`` [m]; ``prior`` the predicted pose in ``map``;
        points beyond ``max_range`` [m] ignored."""
        ...


@dataclass
class LikelihoodField:
    """A likelihood field over a crop of a map: (H, W) float32 values and its lower-left corner [m].

    Build one with :func:`likelihood_field` (from an occupancy grid) or
    :func:`points_field` (from end points), then match many scans against it
    with :meth:`CorrelativeMatcher.match_field`: the field and its max-pooled
    levels are computed once.
    """

    values: np.ndarray
    origin: tuple[float, float]
    resolution: float
    known: np.ndarray | None = None  # (H, W) bool: the grid has observed the cell (None: every cell)

    def __post_init__(self) -> None:
        self._levels = [self.values]

    def level(self, k: int) -> np.ndarray:
        """The values max-pooled by 2^k (level 0: the field itself); each level is pooled once and kept."""
        while len(self._levels) <= k:
            self._levels.append(_pool(self._levels[-1]))
        return self._levels[k]


def likelihood_field(grid: OccupancyGrid, centre: tuple[float, float], half: float, sigma: float = SIGMA,
                     whole: GridField | None = None, copy: bool = True) -> LikelihoodField:
    """The likelihood field of ``grid`` on the square crop of half-size ``half`` [m] around ``centre``.

    ``whole``: the grid's kept-up-to-date field (:class:`GridField`), cut instead of computing the crop
    afresh. Its values are those of the whole grid: they equal a fresh crop's wherever the crop's edge is
    more than the field's reach (10 σ) away, and are truer near the edge (walls just outside count).
    ``copy=False`` gives views of it instead, valid until the grid next changes.
    """
    res = grid.resolution
    lo = grid.world_to_cell(centre[0] - half, centre[1] - half)
    hi = grid.world_to_cell(centre[0] + half, centre[1] + half)
    h, w = grid.shape
    r0, c0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
    r1, c1 = min(int(hi[0]) + 1, h), min(int(hi[1]) + 1, w)
    if r1 <= r0 or c1 <= c0:
        return LikelihoodField(np.zeros((1, 1), np.float32), grid.origin, res)
    origin = (float(grid.origin[0] + c0 * res), float(grid.origin[1] + r0 * res))
    if whole is not None:
        values, known = whole.update(grid)[r0:r1, c0:c1], whole.known[r0:r1, c0:c1]
        if copy:
            values, known = values.copy(), known.copy()
        return LikelihoodField(values, origin, res, known)
    values = _field_values(grid.data[r0:r1, c0:c1] == OCCUPIED, res, sigma)
    return LikelihoodField(values, origin, res, grid.data[r0:r1, c0:c1] != UNKNOWN)


def _field_values(occ: np.ndarray, res: float, sigma: float) -> np.ndarray:
    """(H, W) float32 likelihood field of the occupied mask ``occ`` (H, W) bool, cells of ``res`` [m]."""
    # distanceTransform measures to the nearest zero pixel: zeros at walls.
    dist = cv2.distanceTransform((~occ).astype(np.uint8), cv2.DIST_L2, 5) * res
    return np.exp(-0.5 * (np.minimum(dist, 10 * sigma) / sigma) ** 2).astype(np.float32)


class GridField:
    """The likelihood field of a whole growing grid, recomputed after each change only where walls changed.

    A scan changes the walls of a few places; the field (a wall's reach is 10 σ) changes only within that
    reach of them. The grid is cut into tiles of ``TILE`` cells; a tile whose walls changed is recomputed
    with its neighbours, on a crop that reaches 10 σ beyond them so that every value written is the one a
    computation over the whole grid would give, bit for bit (the distance transform's mask-5 distance
    between two cells depends only on their offset, and the exponential is taken cell by cell). When the
    grid grows, the new cells start far from any wall and the walls near the old border are recomputed.

    Use it for a grid that is matched against again and again as it changes (a SLAM's map): for a grid
    matched once, a crop (:func:`likelihood_field` without ``whole``) is cheaper.
    """

    TILE = 32  # cells per tile side (at least the field's reach: 10 σ / resolution, 20 cells at 10 cm / 5 cm)

    def __init__(self, sigma: float = SIGMA) -> None:
        self.sigma = sigma
        self.values = np.zeros((0, 0), np.float32)  # (H, W) float32 over the whole grid
        self.known = np.zeros((0, 0), bool)  # (H, W) the grid has observed the cell
        self.tiles_recomputed = 0  # (statistics) tiles recomputed since the start
        self._occ = np.zeros((0, 0), bool)
        self._origin = (math.nan, math.nan)
        self._resolution = math.nan
        self._version = -1
        self._grid: weakref.ref[OccupancyGrid] | None = None

    def update(self, grid: OccupancyGrid) -> np.ndarray:
        """The field of ``grid`` as it is now, (H, W) float32 (updated in place: copy what you keep)."""
        same = self._grid is not None and self._grid() is grid
        if same and grid.version == self._version:
            return self.values
        res = grid.resolution
        reach = int(math.ceil(10 * self.sigma / res)) + 1  # [cells] how far a wall shapes the field
        if not same or res != self._resolution or not self._grows_into(grid):
            self._occ = grid.data == OCCUPIED
            self.values = _field_values(self._occ, res, self.sigma)
            self.known = grid.data != UNKNOWN
        else:
            grew = self._pad(grid, reach)
            region = None if grew else grid.changed_since(self._version)
            self._recompute(grid, res, reach, region if region is not None else (0, grid.shape[0], 0, grid.shape[1]))
        self._origin, self._resolution = grid.origin, res
        self._version, self._grid = grid.version, weakref.ref(grid)
        return self.values

    def _grows_into(self, grid: OccupancyGrid) -> bool:
        """Whether ``grid`` holds the extent kept so far, on the same cell boundaries (it grew or stayed)."""
        res = grid.resolution
        left = (self._origin[0] - grid.origin[0]) / res
        below = (self._origin[1] - grid.origin[1]) / res
        if abs(left - round(left)) > 1e-6 or abs(below - round(below)) > 1e-6 or left < 0 or below < 0:
            return False
        h, w = self.values.shape
        return round(below) + h <= grid.shape[0] and round(left) + w <= grid.shape[1]

    def _pad(self, grid: OccupancyGrid, reach: int) -> bool:
        """Grow the kept field and walls to ``grid``'s extent; walls within ``reach`` of the old border are
        forgotten, so that they count as changed and the new cells near them are computed. Whether it grew."""
        res = grid.resolution
        left = int(round((self._origin[0] - grid.origin[0]) / res))
        below = int(round((self._origin[1] - grid.origin[1]) / res))
        h, w = self.values.shape
        if (below, left) == (0, 0) and (h, w) == grid.shape:
            return False
        far = _field_values(np.zeros((1, 64), bool), res, self.sigma)[0, 0]  # 10 σ or more from any wall
        pad = ((below, grid.shape[0] - h - below), (left, grid.shape[1] - w - left))
        self.values = np.pad(self.values, pad, constant_values=np.float32(far))
        self.known = np.pad(self.known, pad)
        occ = self._occ.copy()
        band = np.ones((h, w), bool)
        band[reach:h - reach, reach:w - reach] = False
        occ[band] = False
        self._occ = np.pad(occ, pad)
        return True

    def _recompute(self, grid: OccupancyGrid, res: float, reach: int, region: tuple[int, int, int, int]) -> None:
        """Take the walls of ``grid`` in ``region`` (row0, row1, col0, col1; none changed outside it) and recompute
        the tiles within a tile of a changed wall, each group of them on a crop ``reach`` wider."""
        t = max(self.TILE, reach)
        h, w = grid.shape
        # The region widened to whole tiles, and a tile more each side for the changes' reach.
        t0, t1, u0, u1 = region[0] // t, -(-region[1] // t), region[2] // t, -(-region[3] // t)
        if t1 <= t0 or u1 <= u0:
            return
        r0, r1, c0, c1 = t0 * t, min(t1 * t, h), u0 * t, min(u1 * t, w)
        data = grid.data[r0:r1, c0:c1]
        self.known[r0:r1, c0:c1] = data != UNKNOWN
        occ = data == OCCUPIED
        changed = np.zeros(((t1 - t0) * t, (u1 - u0) * t), bool)
        changed[:r1 - r0, :c1 - c0] = self._occ[r0:r1, c0:c1] != occ
        if not changed.any():
            return
        self._occ[r0:r1, c0:c1] = occ
        tiles = np.zeros((t1 - t0 + 2, u1 - u0 + 2), bool)
        tiles[1:-1, 1:-1] = block_any(changed, t)
        dirty = ndimage.binary_dilation(tiles, np.ones((3, 3), bool))
        labels, _ = ndimage.label(dirty, np.ones((3, 3), int))
        for box in ndimage.find_objects(labels):
            r0, r1 = max((t0 - 1 + box[0].start) * t, 0), min((t0 - 1 + box[0].stop) * t, h)
            c0, c1 = max((u0 - 1 + box[1].start) * t, 0), min((u0 - 1 + box[1].stop) * t, w)
            if r1 <= r0 or c1 <= c0:
                continue
            a0, a1 = max(r0 - reach, 0), min(r1 + reach, h)
            b0, b1 = max(c0 - reach, 0), min(c1 + reach, w)
            crop = _field_values(self._occ[a0:a1, b0:b1], res, self.sigma)
            self.values[r0:r1, c0:c1] = crop[r0 - a0:r1 - a0, c0 - b0:c1 - b0]
            self.tiles_recomputed += int(np.count_nonzero(dirty[box]))


def points_field(points: np.ndarray, resolution: float, sigma: float = SIGMA, margin: float = 1.0,
                 within: tuple[np.ndarray, np.ndarray] | None = None) -> LikelihoodField:
    """The likelihood field of end points (N, 2) [m, map]: every point a wall, over their bounding box plus ``margin`` [m].

    ``within`` (lower-left, upper-right corners [m]) crops the field to that
    box: values inside it are those of all the points.
    """
    lo, hi = points.min(axis=0) - margin, points.max(axis=0) + margin
    if within is not None:
        lo, hi = np.maximum(lo, within[0]), np.minimum(hi, within[1])
        # Walls within the field's reach of the box still shape it.
        near = np.all((points >= lo - 10 * sigma) & (points <= hi + 10 * sigma), axis=1)
        points = points[near]
        lo, hi = lo - 10 * sigma, hi + 10 * sigma
    shape = (max(int(math.ceil((hi[1] - lo[1]) / resolution)), 1), max(int(math.ceil((hi[0] - lo[0]) / resolution)), 1))
    free = np.ones(shape, np.uint8)
    r = ((points[:, 1] - lo[1]) / resolution).astype(np.int64)
    c = ((points[:, 0] - lo[0]) / resolution).astype(np.int64)
    ok = (r >= 0) & (r < shape[0]) & (c >= 0) & (c < shape[1])
    free[r[ok], c[ok]] = 0
    dist = cv2.distanceTransform(free, cv2.DIST_L2, DISTANCE_MASK) * resolution
    values = np.exp(-0.5 * (np.minimum(dist, 10 * sigma) / sigma) ** 2).astype(np.float32)
    return LikelihoodField(values, (float(lo[0]), float(lo[1])), resolution)


def _pool(values: np.ndarray) -> np.ndarray:
    """Max-pool (H, W) by 2 (padding with zeros): a coarse cell bounds the four fine cells in it."""
    h, w = values.shape
    h2, w2 = h // 2, w // 2
    out = np.zeros((h - h2, w - w2), dtype=values.dtype)
    # Four strided views: far faster than a reshape's max over two axes (max is exact in any order). An odd
    # last row or column is pooled with the zeros it is padded with, without copying the whole array.
    even = out[:h2, :w2]
    np.maximum(values[0:2 * h2:2, 0:2 * w2:2], values[1:2 * h2:2, 0:2 * w2:2], out=even)
    np.maximum(even, values[0:2 * h2:2, 1:2 * w2:2], out=even)
    np.maximum(even, values[1:2 * h2:2, 1:2 * w2:2], out=even)
    if h % 2:
        np.maximum(np.maximum(values[h - 1, 0:2 * w2:2], values[h - 1, 1:2 * w2:2]), out[h2, :w2], out=out[h2, :w2])
    if w % 2:
        np.maximum(np.maximum(values[0:2 * h2:2, w - 1], values[1:2 * h2:2, w - 1]), out[:h2, w2], out=out[:h2, w2])
    if h % 2 and w % 2:
        out[h2, w2] = max(values[h - 1, w - 1], out[h2, w2])
    return out


class CorrelativeMatcher:
    """Multi-resolution correlative scan matcher with Gauss–Newton refinement (see module doc)."""

    def __init__(
        self,
        window_xy: float = WINDOW_XY,
        window_theta: float = WINDOW_THETA,
        levels: int = LEVELS,
        sigma: float = SIGMA,
        min_score: float = MIN_SCORE,
        refine: bool = False,
        prior_xy: float = PRIOR_XY,
        prior_theta: float = PRIOR_THETA,
        field_max_age: int = 0,
        candidates: int = 1,
        whole_field: bool = False,
        anchor_theta: float = GN_ANCHOR_THETA,
        prior_points: int = 0,
    ) -> None:
        self.window_xy = window_xy
        # The heading's prior (PRIOR_PENALTY's heading term, the Gauss-Newton anchor's) weighs as if the scan had
        # at least this many end points (0: as many as it has). A scan's fit is a sum over its points, the gyro's
        # prior one term: weighed per point, a sparse scan (an open hall's 40 returns) outweighs the gyro as easily
        # as a room's 300 do, though its fit is far noisier for the same heading.
        self.prior_points = prior_points
        # [rad] per end point: how hard Gauss-Newton holds the correlative optimum's heading (its position is
        # held by GN_ANCHOR_XY, so that it does not slide along a corridor, whose walls still give the heading).
        self.anchor_theta = anchor_theta
        self._anchor = np.diag([1 / GN_ANCHOR_XY**2, 1 / GN_ANCHOR_XY**2, 1 / anchor_theta**2])
        self.candidates = candidates  # top-level poses refined (more: a wide window's peaks not lost to a coarse tie)
        self.prior_xy = prior_xy  # [m]
        self.prior_theta = prior_theta  # [rad]
        self.window_theta = window_theta
        self.levels = levels
        self.sigma = sigma
        self.min_score = min_score
        self.refine = refine
        self.field_max_age = field_max_age
        self._cache: tuple[int, int, tuple[float, float], float, LikelihoodField] | None = None
        # The field of the whole grid kept up to date (GridField), cut for each match: for a grid matched again
        # and again as it grows (a SLAM's map), where computing each match's crop afresh is most of the cost.
        self.whole: GridField | None = GridField(sigma) if whole_field else None

    def forget(self) -> None:
        """Drop the field kept for reuse (``field_max_age``): the grid matched against was redrawn."""
        self._cache = None

    def match(self, grid: OccupancyGrid, points: np.ndarray, prior: Pose2, max_range: float = 5.0) -> MatchResult:
        """Best pose of the scan ``points`` (M, 2) [m, base_link] in ``grid`` near ``prior`` [map].

        Points farther than ``max_range`` [m] are not used: set it a metre
        or so under the sensor's range (see the comment in the code).
        """
        prepared = self._prepare(grid, points, prior, max_range)
        if prepared is None:
            return MatchResult(prior, 0.0, False)
        return self.match_field(prepared[1], prepared[0], prior)

    def _prepare(self, grid: OccupancyGrid, points: np.ndarray, near: Pose2,
                 max_range: float) -> tuple[np.ndarray, LikelihoodField] | None:
        """The end points within ``max_range`` and the field around ``near`` they are matched on (None: too few)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        # End points near the edge of the sensor's reach land where earlier scans did not reach:
        # they would pull the pose backwards onto walls already mapped.
        pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= max_range]
        if len(pts) < MIN_POINTS:
            return None
        reach = min(float(np.max(np.hypot(pts[:, 0], pts[:, 1]))), max_range)
        return pts, self._field(grid, near, reach + self.window_xy + 4 * self.sigma)

    def match_field(self, field: LikelihoodField, points: np.ndarray, prior: Pose2) -> MatchResult:
        """Best pose of ``points`` (M, 2) [m, base_link] on a prepared ``field`` near ``prior`` [map]."""
        pts = np.asarray(points, dtype=float).reshape(-1, 2)
        if len(pts) < MIN_POINTS:
            return MatchResult(prior, 0.0, False)
        sub = pts[:: max(1, len(pts) // MAX_POINTS)]
        best = self._correlative(field, sub, prior)
        if self.refine:
            best, score = self._gauss_newton_scored(field, pts, best, self._anchor)
        else:
            score = float(_score(field, pts, best))
        known, known_score = _known_fit(field, pts, best)
        return MatchResult(best, score, score >= self.min_score, known, known_score, int(round(known * len(pts))))

    def _field(self, grid: OccupancyGrid, prior: Pose2, half: float) -> LikelihoodField:
        """The likelihood field around ``prior`` (its max-pooled levels kept with it), reused while fresh enough.

        With ``field_max_age`` > 0 a field is computed over a crop ``FIELD_MARGIN`` wider than needed and
        reused for the next matches while the grid has changed at most that many times (each fused scan
        changes it once) and the needed crop still lies inside it: the field is the bulk of a match's cost,
        and a few scans more or less of map do not move a tracking match.
        """
        c = self._cache
        if (self.field_max_age > 0 and c is not None and c[0] == id(grid)
                and 0 <= grid.version - c[1] <= self.field_max_age
                and abs(prior.x - c[2][0]) + half <= c[3] and abs(prior.y - c[2][1]) + half <= c[3]):
            return c[4]
        margin = FIELD_MARGIN if self.field_max_age > 0 else 0.0
        field = likelihood_field(grid, (prior.x, prior.y), half + margin, self.sigma, self.whole,
                                 copy=self.field_max_age > 0)
        if self.field_max_age > 0:
            self._cache = (id(grid), grid.version, (prior.x, prior.y), half + margin, field)
        return field

    # ------------------------------------------------------------ correlative
    def _correlative(self, field: LikelihoodField, pts: np.ndarray, prior: Pose2) -> Pose2:
        res = field.resolution
        # Top level: the whole window, on the field max-pooled by 2^levels.
        top_res = res * 2**self.levels
        n_xy = max(1, int(math.ceil(self.window_xy / top_res)))
        a_step = ANGLE_STEP * 2**self.levels
        n_a = max(1, int(math.ceil(self.window_theta / a_step)))
        offs = np.arange(-n_xy, n_xy + 1) * top_res
        thetas = prior.theta + np.arange(-n_a, n_a + 1) * a_step
        n_prior = max(len(pts), self.prior_points)
        starts = _search(field.level(self.levels), top_res, field.origin, pts, prior.x + offs, prior.y + offs,
                         thetas, prior, self.prior_xy, self.prior_theta, self.candidates, n_prior)
        # Finer levels: ±1 step around the best of the coarser level, from each of the top level's best poses.
        found = []
        for x, y, th, score in starts:
            for k in range(self.levels - 1, -1, -1):
                lres = res * 2**k
                a_step = ANGLE_STEP * 2**k
                step = np.array([-1.0, 0.0, 1.0])
                x, y, th, score = _search(field.level(k), lres, field.origin, pts, x + step * lres, y + step * lres,
                                          th + step * a_step, prior, self.prior_xy, self.prior_theta, 1, n_prior)[0]
            found.append((score, x, y, th))
        _, x, y, th = max(found)
        return Pose2(x, y, th)

    # ----------------------------------------------------------- Gauss–Newton
    def polish(self, grid: OccupancyGrid, points: np.ndarray, pose: Pose2, max_range: float,
               anchor_xy: float, anchor_theta: float | None = None) -> Pose2:
        """Gauss–Newton on ``grid`` from ``pose``, pulled towards it by ``anchor_xy`` [m] and ``anchor_theta`` [rad]
        (default: the matcher's own) per end point.

        :meth:`match` refines its correlative optimum with a tight pull (``GN_ANCHOR_XY``, for a fair
        comparison of matches from different predictions); a tracker that has chosen one polishes it with a
        looser pull. Returns ``pose`` if the fit does not improve.
        """
        prepared = self._prepare(grid, points, pose, max_range)
        if prepared is None:
            return pose
        theta = self.anchor_theta if anchor_theta is None else anchor_theta
        anchor = np.diag([1 / anchor_xy**2, 1 / anchor_xy**2, 1 / theta**2])
        return self._gauss_newton(prepared[1], prepared[0], pose, anchor)

    def _gauss_newton(self, field: LikelihoodField, pts: np.ndarray, start: Pose2,
                      anchor: np.ndarray = GN_ANCHOR_INFO) -> Pose2:
        """Refine ``start`` on ``field``, pulled towards it with information ``anchor`` (3, 3) per end point."""
        return self._gauss_newton_scored(field, pts, start, anchor)[0]

    def _gauss_newton_scored(self, field: LikelihoodField, pts: np.ndarray, start: Pose2,
                             anchor: np.ndarray = GN_ANCHOR_INFO) -> tuple[Pose2, float]:
        """:meth:`_gauss_newton`'s pose and its :func:`_score` (worked out there to choose it)."""
        xi = start.as_array().astype(float)
        # Anchor at the correlative optimum (itself tied to odometry where the scan is ambiguous): the
        # refinement is for sub-cell accuracy and must not slide along a corridor.
        p0 = start.as_array()
        w_prior = anchor * len(pts)
        if self.prior_points > len(pts):
            w_prior[2, 2] = anchor[2, 2] * self.prior_points
        for _ in range(GN_ITERATIONS):
            J, r = _residuals(field, pts, xi)
            H = J.T @ J + w_prior
            d = p0 - xi
            d[2] = math.atan2(math.sin(d[2]), math.cos(d[2]))
            g = J.T @ r + w_prior @ d
            try:
                delta = np.linalg.solve(H, g)
            except np.linalg.LinAlgError:
                break
            # Never step further than a cell or a degree at a time: the field is only locally smooth.
            # (min and max, not np.clip: the same numbers without its overhead, this runs thousands of times)
            step = field.resolution
            delta[0], delta[1] = min(max(delta[0], -step), step), min(max(delta[1], -step), step)
            delta[2] = float(min(max(delta[2], -ANGLE_STEP), ANGLE_STEP))
            xi = xi + delta
            if abs(delta[0]) + abs(delta[1]) < 1e-4 and abs(delta[2]) < 1e-4:
                break
        out = Pose2.from_array(xi)
        # Keep the refinement only if it does not make the fit worse.
        refined, kept = float(_score(field, pts, out)), float(_score(field, pts, start))
        return (out, refined) if refined >= kept else (start, kept)


def _residuals(field: LikelihoodField, pts: np.ndarray, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Jacobian (M, 3) of the field value at each end point w.r.t. the pose ``xi``, and residuals 1 − value.

    Points on cells never observed carry no evidence, only a pull towards mapped walls: both are zero there.
    """
    c, s = math.cos(xi[2]), math.sin(xi[2])
    wx = xi[0] + c * pts[:, 0] - s * pts[:, 1]
    wy = xi[1] + s * pts[:, 0] + c * pts[:, 1]
    u, v = _field_cells(field, wx, wy)
    m, gx, gy = _interpolate(field, u, v)
    # d(world point)/d(theta) = (−s·px − c·py, c·px − s·py)
    dth = gx * (-s * pts[:, 0] - c * pts[:, 1]) + gy * (c * pts[:, 0] - s * pts[:, 1])
    k = _known_cells(field, u, v)
    return np.column_stack([gx, gy, dth]) * k[:, None], (1.0 - m) * k


def _search(
    values: np.ndarray,
    res: float,
    origin: tuple[float, float],
    pts: np.ndarray,
    xs: np.ndarray,
    ys: np.ndarray,
    thetas: np.ndarray,
    prior: Pose2,
    prior_xy: float,
    prior_theta: float,
    keep: int = 1,
    n_prior: int | None = None,
) -> list[tuple[float, float, float, float]]:
    """Score every pose of the grid xs × ys × thetas at once; return the ``keep`` best (x, y, θ, score), best first.

    With ``keep`` > 1 the poses kept are local maxima: none is next to a
    better one (one step in x, y or θ).

    A small penalty for straying from ``prior`` breaks ties (a featureless
    corridor scores the same all along it) in favour of odometry; its heading term weighs as ``n_prior``
    points' worth (default: as many as ``pts`` has).
    """
    c, s = np.cos(thetas), np.sin(thetas)
    # Rotated points (T, M). ``xs`` and ``ys`` step by one cell, so a point's cell under offset (i, j) is its
    # cell under the first offset moved by (i, j) cells: one flat index per (angle, point), plus an offset table.
    rx = c[:, None] * pts[None, :, 0] - s[:, None] * pts[None, :, 1]
    ry = s[:, None] * pts[None, :, 0] + c[:, None] * pts[None, :, 1]
    col0 = np.floor((rx + xs[0] - origin[0]) / res).astype(np.int64)
    row0 = np.floor((ry + ys[0] - origin[1]) / res).astype(np.int64)
    h, w = values.shape
    n_x, n_y = len(xs), len(ys)
    flat = values.ravel()
    offsets = np.arange(n_x)[:, None] + w * np.arange(n_y)[None, :]  # (X, Y) flat steps
    # Points whose every offset stays on the field: gathered without bounds checks.
    whole = (row0 >= 0) & (row0 + n_y <= h) & (col0 >= 0) & (col0 + n_x <= w)
    base = np.where(whole, row0 * w + col0, 0)
    vals = np.take(flat, base[:, None, None, :] + offsets[None, :, :, None], mode="clip")  # (T, X, Y, M)
    sums = np.einsum("txym,tm->txy", vals, whole.astype(values.dtype))
    # Points that straddle the field's edge (few): each offset checked; off the field scores 0.
    edge_t, edge_m = np.nonzero(~whole & (row0 + n_y > 0) & (row0 < h) & (col0 + n_x > 0) & (col0 < w))
    if len(edge_t):
        cols = col0[edge_t, edge_m][:, None, None] + np.arange(n_x)[None, :, None]
        rows = row0[edge_t, edge_m][:, None, None] + np.arange(n_y)[None, None, :]
        ok = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
        v = np.where(ok, values[np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)], 0.0)
        # np.nonzero lists edge_t in ascending order: sum each angle's run of points at once.
        first = np.flatnonzero(np.r_[True, edge_t[1:] != edge_t[:-1]])
        sums[edge_t[first]] += np.add.reduceat(v, first, axis=0)
    dth = np.arctan2(np.sin(thetas - prior.theta), np.cos(thetas - prior.theta))
    penalty = PRIOR_PENALTY * (
        len(pts) * ((xs[None, :, None] - prior.x) ** 2 + (ys[None, None, :] - prior.y) ** 2) / prior_xy**2
        + (len(pts) if n_prior is None else n_prior) * (dth[:, None, None] / prior_theta) ** 2
    )
    scores = sums - penalty  # (T, X, Y)
    if keep == 1:
        order = [int(np.argmax(scores))]
    else:
        # Local maxima over the 3 × 3 × 3 neighbourhood, best first.
        peak = scores >= ndimage.maximum_filter(scores, size=3, mode="nearest")
        flat_peaks = np.flatnonzero(peak)
        order = flat_peaks[np.argsort(-scores.ravel()[flat_peaks], kind="stable")][:keep].tolist()
    out = []
    for f in order:
        t, i, j = np.unravel_index(f, scores.shape)
        out.append((float(xs[i]), float(ys[j]), float(thetas[t]), float(scores[t, i, j])))
    return out


def _bilinear(field: LikelihoodField, x: np.ndarray, y: np.ndarray,
              gradient: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Field value and its gradient (per metre) at world points, bilinearly interpolated between cell centres
    (``gradient=False``: the value alone, the gradient's two arrays None)."""
    u, v = _field_cells(field, x, y)
    return _interpolate(field, u, v, gradient)


def _field_cells(field: LikelihoodField, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World points [m] in the field's cells (fractional columns, rows from its lower-left corner)."""
    return (x - field.origin[0]) / field.resolution, (y - field.origin[1]) / field.resolution


def _gather(values: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``values[rows, cols]`` for in-bounds cells; by one flat index where the array is contiguous (faster)."""
    if values.flags.c_contiguous:
        return values.ravel().take(rows * values.shape[1] + cols)
    return values[rows, cols]


def _interpolate(field: LikelihoodField, u: np.ndarray, v: np.ndarray,
                 gradient: bool = True) -> tuple[np.ndarray, Any, Any]:
    """:func:`_bilinear` at points given in the field's cells (:func:`_field_cells`)."""
    res = field.resolution
    h, w = field.values.shape
    if h < 2 or w < 2:
        z = np.zeros_like(u)
        return z, z, z
    fx = u - 0.5
    fy = v - 0.5
    x0 = np.floor(fx).astype(np.int64)
    y0 = np.floor(fy).astype(np.int64)
    ax, ay = fx - x0, fy - y0
    bx, by = 1 - ax, 1 - ay
    ok = (x0 >= 0) & (x0 < w - 1) & (y0 >= 0) & (y0 < h - 1)
    x0c, y0c = np.minimum(np.maximum(x0, 0), w - 2), np.minimum(np.maximum(y0, 0), h - 2)
    vals = field.values
    if vals.flags.c_contiguous:
        flat, i = vals.ravel(), y0c * w + x0c
        v00, v01, v10, v11 = flat.take(i), flat.take(i + 1), flat.take(i + w), flat.take(i + (w + 1))
    else:
        v00, v01 = vals[y0c, x0c], vals[y0c, x0c + 1]
        v10, v11 = vals[y0c + 1, x0c], vals[y0c + 1, x0c + 1]
    m = by * (bx * v00 + ax * v01) + ay * (bx * v10 + ax * v11)
    if not gradient:
        return np.where(ok, m, 0.0), None, None
    gx = (by * (v01 - v00) + ay * (v11 - v10)) / res
    gy = (bx * (v10 - v00) + ax * (v11 - v01)) / res
    return np.where(ok, m, 0.0), np.where(ok, gx, 0.0), np.where(ok, gy, 0.0)


def _known(field: LikelihoodField, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """(M,) float 1.0 where the world point lies on an observed cell of the crop, else 0.0."""
    if field.known is None:
        return np.ones_like(x)
    return _known_cells(field, *_field_cells(field, x, y))


def _known_cells(field: LikelihoodField, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """:func:`_known` at points given in the field's cells (:func:`_field_cells`)."""
    if field.known is None:
        return np.ones_like(u)
    col = np.floor(u).astype(np.int64)
    row = np.floor(v).astype(np.int64)
    h, w = field.known.shape
    ok = (row >= 0) & (row < h) & (col >= 0) & (col < w)
    on = _gather(field.known, np.minimum(np.maximum(row, 0), h - 1), np.minimum(np.maximum(col, 0), w - 1))
    return (on & ok).astype(float)


def _known_fit(field: LikelihoodField, pts: np.ndarray, pose: Pose2) -> tuple[float, float]:
    """(share of points on observed cells, their mean field value) with the scan placed at ``pose``."""
    wpts = pose.transform_points(pts)
    k = _known(field, wpts[:, 0], wpts[:, 1]) > 0
    if not k.any():
        return 0.0, 0.0
    m, _, _ = _bilinear(field, wpts[k, 0], wpts[k, 1], gradient=False)
    return float(k.mean()), float(m.mean())


def _score(field: LikelihoodField, pts: np.ndarray, pose: Pose2) -> float:
    """Mean interpolated field value under the scan placed at ``pose``."""
    wpts = pose.transform_points(pts)
    m, _, _ = _bilinear(field, wpts[:, 0], wpts[:, 1], gradient=False)
    return float(m.mean()) if len(m) else 0.0


MATCHERS: dict[str, type[CorrelativeMatcher]] = {"correlative": CorrelativeMatcher}
