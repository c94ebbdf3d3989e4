"""Global relocalisation of a scan in a known grid: where is the robot, when tracking has lost it?

A kidnapped robot (carried, pushed, or simply lost after a bad match) has a
pose that no longer fits what it sees. The map it built is still right, so
it can find itself in it again, as AMCL's global localisation or
Cartographer's global search does: score the scan at every pose the robot
could stand in, keep the best, refine it, and trust it only if nothing else
fits nearly as well.

1. The likelihood field of the whole grid (:func:`homing.mapping.scan_match.likelihood_field`)
   is max-pooled by ``2^COARSE_LEVEL`` (40 cm at 5 cm cells): a coarse cell's
   value bounds every fine pose in it, as in Olson's multi-resolution search.
2. Candidates: the coarse cells holding observed free space the robot fits in,
   at every ``HEADING_STEP`` of heading. Each is scored on the pooled field
   with a decimated scan, all at once.
3. The ``REFINE`` best are matched locally (:class:`~homing.mapping.scan_match.CorrelativeMatcher`,
   a window of a coarse cell) on the fine field.
4. The best refined pose is accepted when the scan fits there (its mean
   field score ≥ ``MIN_FIT``, most of it on observed cells) and the best *different* pose (another place,
   or the same place turned) fits clearly worse (``AMBIGUITY`` ratio): a
   symmetric room gives no answer rather than a wrong one; the caller tries
   again with the next scan, from a little further on.

Costs grow with the free area: 40-70 ms on the FHW museum's 84 × 33 m (the
candidates and pooled field are kept while the map does not change, as it
does not while the robot is lost). Not for tracking (see
:mod:`homing.mapping.scan_match`).
"""

from __future__ import annotations

import math
import weakref
from dataclasses import dataclass

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.mapping.scan_match import CorrelativeMatcher, GridField, MatchResult, likelihood_field
from homing.robot import Pose2
from homing.robot.turtlebot import FOOTPRINT_RADIUS
from scipy import ndimage

from homing.map_server import FREE, UNKNOWN

COARSE_LEVEL = 3  # the candidates' grid: cells pooled by 2^3 (0.4 m at 5 cm)
HEADING_STEP = math.radians(5.0)  # [rad]
COARSE_POINTS = 72  # scan points scored per candidate
REFINE = 12  # candidates refined on the fine field
MIN_FIT = 0.80  # known_score the answer must reach (a tracked robot scores ~0.98)
MIN_KNOWN = 0.6  # share of the scan that must land on observed cells
AMBIGUITY = 0.90  # the runner-up elsewhere must fit worse than this share of the best
DISTINCT_XY = 0.8  # [m] poses farther apart than this…
DISTINCT_THETA = math.radians(25.0)  # [rad] …or turned more than this are different answers
CHUNK = 16  # candidates scored at a time: the (chunk, headings × points) gather stays in cache (256: 15 % slower)


@dataclass(frozen=True)
class Relocalisation:
    """The outcome: ``pose`` (base_link in map) or None, the best fit, the runner-up's, and why not."""

    pose: Pose2 | None
    fit: float
    runner_up: float
    reason: str = ""


def candidates(grid: OccupancyGrid, level: int = COARSE_LEVEL,
               clearance: float = FOOTPRINT_RADIUS) -> np.ndarray:
    """(N, 2) [m] centres of the coarse cells that hold observed free space with ``clearance`` [m] to walls."""
    rows, cols = _candidate_cells(grid, level, clearance)
    size = grid.resolution * 2**level
    return np.column_stack([grid.origin[0] + (cols + 0.5) * size, grid.origin[1] + (rows + 0.5) * size])


def _candidate_cells(grid: OccupancyGrid, level: int = COARSE_LEVEL,
                     clearance: float = FOOTPRINT_RADIUS) -> tuple[np.ndarray, np.ndarray]:
    """(rows, cols) (N,) int64 of the coarse cells (pooled by 2^level) of :func:`candidates`."""
    data = grid.data
    free = data == FREE
    room = ndimage.distance_transform_edt(data != 100) * grid.resolution >= clearance  # away from walls
    ok = free & room
    f = 2**level
    h, w = ok.shape
    H, W = -(-h // f), -(-w // f)
    padded = np.zeros((H * f, W * f), dtype=bool)
    padded[:h, :w] = ok
    coarse = padded.reshape(H, f, W, f).any(axis=(1, 3))
    rows, cols = np.nonzero(coarse)
    return rows, cols


@dataclass
class _Coarse:
    """What a grid's version gives every relocalisation: the candidates' cells and the pooled field."""

    version: int
    rows: np.ndarray  # (N,) int64 coarse cells of the candidates
    cols: np.ndarray
    pooled: np.ndarray  # (H, W) float32, the field max-pooled by 2^COARSE_LEVEL


# A lost robot looks for itself every second in a map that does not change while it is lost: the candidates
# and fields are kept per grid (weakly) until the grid changes.
_COARSE: weakref.WeakKeyDictionary[OccupancyGrid, _Coarse] = weakref.WeakKeyDictionary()


def _coarse(grid: OccupancyGrid, whole: GridField | None) -> _Coarse:
    kept = _COARSE.get(grid)
    if kept is not None and kept.version == grid.version:
        return kept
    rows, cols = _candidate_cells(grid)
    h, w = grid.shape
    centre = (grid.origin[0] + 0.5 * w * grid.resolution, grid.origin[1] + 0.5 * h * grid.resolution)
    field = likelihood_field(grid, centre, 0.5 * max(h, w) * grid.resolution + 1.0, whole=whole, copy=False)
    f = 2**COARSE_LEVEL
    vals = field.values
    H, W = -(-vals.shape[0] // f), -(-vals.shape[1] // f)
    pooled = np.zeros((H * f, W * f), dtype=vals.dtype)
    pooled[: vals.shape[0], : vals.shape[1]] = vals
    pooled = pooled.reshape(H, f, W, f).max(axis=(1, 3))
    kept = _Coarse(grid.version, rows, cols, pooled)
    _COARSE[grid] = kept
    return kept


def relocalise(grid: OccupancyGrid, points: np.ndarray, max_range: float = 5.0,
               whole: GridField | None = None) -> Relocalisation:
    """Find the scan ``points`` (M, 2) [m, base_link] in ``grid`` anywhere (see the module doc).

    ``whole``: the grid's field kept up to date by its tracker (:class:`~homing.mapping.scan_match.GridField`),
    used instead of computing the whole grid's field afresh (the same values).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    pts = pts[np.hypot(pts[:, 0], pts[:, 1]) <= max_range]
    kept = _COARSE.get(grid)
    fresh = kept is not None and kept.version == grid.version  # then the map was found not empty
    if len(pts) < 30 or not (fresh or (grid.data != UNKNOWN).any()):
        return Relocalisation(None, 0.0, 0.0, "too few points or an empty map")
    coarse = _coarse(grid, whole)
    if len(coarse.rows) == 0:
        return Relocalisation(None, 0.0, 0.0, "no free space in the map")
    # 1–2: every candidate position × heading on the pooled field of the whole grid.
    size = grid.resolution * 2**COARSE_LEVEL
    cands = np.column_stack([grid.origin[0] + (coarse.cols + 0.5) * size,
                             grid.origin[1] + (coarse.rows + 0.5) * size])
    sub = pts[:: max(1, len(pts) // COARSE_POINTS)]
    thetas = np.arange(0.0, 2 * math.pi, HEADING_STEP)
    scores = coarse_scores(coarse.pooled, coarse.rows, coarse.cols, size, sub, thetas)
    order = best_first(scores, REFINE * 4)
    # 3: refine the best few, at most one per position (the pooled bound favours many headings of one spot).
    matcher = CorrelativeMatcher(window_xy=size, window_theta=HEADING_STEP, levels=COARSE_LEVEL,
                                 prior_xy=1e3, prior_theta=1e3, refine=True, min_score=0.0)
    matcher.whole = whole
    tried: set[int] = set()
    results: list[MatchResult] = []
    for k in order:
        n, t = np.unravel_index(int(k), scores.shape)
        if n in tried:
            continue
        tried.add(int(n))
        results.append(matcher.match(grid, pts, Pose2(float(cands[n, 0]), float(cands[n, 1]), float(thetas[t])),
                                     max_range))
        if len(results) >= REFINE:
            break
    # 4: the best, if it fits and nothing different fits nearly as well. The fit counts every point (one that
    # lands on unknown ground scores nothing): a wrong pose that puts half the scan outside the map fits half.
    results.sort(key=lambda r: r.score if r.known >= MIN_KNOWN else 0.0, reverse=True)
    best = results[0]
    fit = best.score if best.known >= MIN_KNOWN else 0.0
    runner_up = max((r.score for r in results[1:] if r.known >= MIN_KNOWN and _distinct(r.pose, best.pose)),
                    default=0.0)
    if fit < MIN_FIT:
        return Relocalisation(None, fit, runner_up, f"best fit {fit:.2f} < {MIN_FIT}")
    if runner_up >= AMBIGUITY * fit:
        return Relocalisation(None, fit, runner_up, f"ambiguous: another pose fits {runner_up:.2f} vs {fit:.2f}")
    return Relocalisation(best.pose, fit, runner_up)


def coarse_scores(pooled: np.ndarray, rows: np.ndarray, cols: np.ndarray, size: float, pts: np.ndarray,
                  thetas: np.ndarray) -> np.ndarray:
    """(N, T) float32 mean ``pooled`` value under ``pts`` (M, 2) [m] turned by each of ``thetas`` (T,) [rad] and
    centred on each coarse cell (``rows``, ``cols``) (N,) of ``pooled`` (H, W), cells ``size`` [m]; off it scores 0.

    A candidate is a coarse cell's centre, so a turned point falls in the candidate's cell moved by a whole
    number of cells, the same for every candidate: one table of (heading, point) steps, one gather per candidate.
    """
    c, s = np.cos(thetas), np.sin(thetas)
    rx = c[:, None] * pts[None, :, 0] - s[:, None] * pts[None, :, 1]  # (T, M)
    ry = s[:, None] * pts[None, :, 0] + c[:, None] * pts[None, :, 1]
    dc = np.floor(rx / size + 0.5).astype(np.int64)  # (T, M) cells from the candidate's
    dr = np.floor(ry / size + 0.5).astype(np.int64)
    h, w = pooled.shape
    pad = int(max(np.abs(dc).max(), np.abs(dr).max())) + 1
    padded = np.zeros((h + 2 * pad, w + 2 * pad), np.float32)
    padded[pad:pad + h, pad:pad + w] = pooled
    flat = padded.ravel()
    steps = (dr * (w + 2 * pad) + dc).ravel()  # (T·M,)
    base = (rows + pad) * (w + 2 * pad) + cols + pad  # (N,)
    n_t, n_m = rx.shape
    scores = np.empty((len(base), n_t), np.float32)
    for a in range(0, len(base), CHUNK):
        idx = base[a:a + CHUNK, None] + steps[None, :]
        scores[a:a + CHUNK] = np.take(flat, idx).reshape(-1, n_t, n_m).mean(axis=2)
    return scores


def best_first(scores: np.ndarray, keep: int) -> np.ndarray:
    """Flat indices of the ``keep`` largest of ``scores``, largest first: ``np.argsort(scores, axis=None)[::-1][:keep]``.

    Sorting every (candidate, heading) costs more than scoring a few of them; the ``keep`` largest are found by
    partition and only they are sorted. Where ties make the order among them (or the last one taken) depend on
    the sort's own choices, the whole array is sorted as before, so the answer is argsort's in every case.
    """
    flat = scores.ravel()
    if keep >= flat.size:
        return np.argsort(flat)[::-1][:keep]
    kth = np.partition(flat, flat.size - keep)[flat.size - keep]
    top = np.flatnonzero(flat >= kth)
    if len(top) == keep and len(np.unique(flat[top])) == keep:
        return top[np.argsort(flat[top])[::-1]]
    return np.argsort(flat)[::-1][:keep]


def _distinct(a: Pose2, b: Pose2) -> bool:
    return a.distance_to(b) > DISTINCT_XY or abs(math.remainder(a.theta - b.theta, 2 * math.pi)) > DISTINCT_THETA
