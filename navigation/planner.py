"""Global planners on a costmap, chosen by name: Dijkstra (csgraph), fast marching (scikit-fmm), A* (pyastar2d).

All three minimise the path integral of a traversal cost ``1 + w·cost/252``
over cells the robot's footprint fits in (cost < ``INSCRIBED``), as Nav2's
NavFn does with its ``neutral_cost + cost_factor·cost`` (the thesis's planner,
section 2.4.3). Grid paths are then shortened by string pulling that never
lets a shortcut run through higher cost than the stretch it replaces, so the
path keeps its clearance and comes within a few per cent of the shortest
collision-free path.

- ``dijkstra``: scipy.sparse.csgraph Dijkstra on the 8-connected grid with
  √2-weighted diagonals (exact on its graph; builds the graph per call);
- ``fmm``: scikit-fmm travel time (Sethian's fast marching, an isotropic
  eikonal solution) from the goal, descended from the start;
- ``astar``: pyastar2d's C++ A* — fastest, but its diagonal steps cost the
  same as straight ones, so its raw paths are Chebyshev-optimal only; the
  string pulling repairs most of that.

:func:`distance_map` gives the geometric travel distance from a point to every
cell (fast marching), for frontier strategies that rank goals by travel;
with ``coarse`` it marches on blocks and keeps the reachable set exact, so
that a decision on a 2000 m² floor does not cost a march over every cell.
Failures are typed (:class:`StartOccupied`, :class:`GoalOccupied`,
:class:`NoPathFound`) so recoveries can choose by cause.
"""

from __future__ import annotations

import functools
import math
import weakref
from typing import Protocol

import cv2
import numpy as np
import pyastar2d
import skfmm
from homing.mapping.blocks import block_any
from homing.navigation.costmap import INSCRIBED, LETHAL, MAX_NON_OBSTACLE, NO_INFORMATION, Costmap
from homing.robot import Pose2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

COST_WEIGHT = 0.5  # traversal cost of a cell = 1 + COST_WEIGHT·cost/252 (NavFn: 1 + 0.8·cost/50; lighter keeps paths within 5 % of the shortest)
UNKNOWN_COST = 0.5  # traversal penalty of an unknown cell, as a fraction of MAX_NON_OBSTACLE
ESCAPE_RADIUS = 0.3  # [m] inscribed cells this close to the start may be crossed to get out
ESCAPE_PENALTY = 10.0  # traversal cost of such a cell
GRAZE_MARGIN = 0.05  # [m] band beyond the inscribed radius that paths avoid
GRAZE_PENALTY = 2.0  # extra traversal cost of a cell in that band
SMOOTHING_PASSES = 4  # string-pulling passes (see smooth_path)
SOURCE_RADIUS = 0.75  # [cells] fast marching starts from a circle this wide around the source
FIELD_BLOCK = 0.2  # [m] blocks the decision-time distance fields march on (distance_map's coarse; reach: every cell)


class PlanningError(Exception):
    """A global planner could not produce a path."""


class StartOccupied(PlanningError):
    """The start lies in a lethal cell or outside the costmap."""


class GoalOccupied(PlanningError):
    """The goal lies where the robot's footprint does not fit (and no free cell within tolerance)."""


class NoPathFound(PlanningError):
    """Start and goal are free but not connected through free space."""


class GlobalPlanner(Protocol):
    """Plans a path on a costmap: ``plan(costmap, start, goal)`` → (N, 2) float64 [m], map frame.

    The first point is the start, the last the goal (or the nearest free cell
    within ``goal_tolerance``). Raises a :class:`PlanningError` subclass.
    """

    name: str

    def plan(self, costmap: Costmap, start: Pose2, goal: Pose2) -> np.ndarray: ...


# -- shared steps ---------------------------------------------------------------------
def traversal_weights(costmap: Costmap, cost_weight: float = COST_WEIGHT,
                      allow_unknown: bool = True) -> np.ndarray:
    """(H, W) float64 cost of crossing each cell (≥ 1), ``inf`` where the footprint does not fit; read-only.

    A cell's weight depends on its own cost and clearance alone, so the
    array is kept with the costmap and redone only over the box of cells
    that changed since (:meth:`Costmap.changed_since`): a scan changes a few
    metres round the robot, not the whole floor.
    """
    return _weights(costmap, cost_weight, allow_unknown).w


def _weights(costmap: Costmap, cost_weight: float, allow_unknown: bool) -> _Weights:
    """The kept weights of ``costmap`` for these parameters, brought up to its version."""
    kept = _KEPT.setdefault(costmap, {})
    key = (float(cost_weight), bool(allow_unknown), costmap.inscribed_radius)
    entry = kept.get(key)
    box = None if entry is None or entry.cost is not costmap.cost else costmap.changed_since(entry.version)
    if entry is None or box is None:
        entry = kept[key] = _Weights(costmap.version, costmap.cost, _weights_in(costmap, cost_weight, allow_unknown))
    elif box[1] > box[0] and box[3] > box[2]:
        window = (slice(box[0], box[1]), slice(box[2], box[3]))
        entry.update(window, _weights_in(costmap, cost_weight, allow_unknown, window))
    entry.version = costmap.version
    return entry


def _weights_in(costmap: Costmap, cost_weight: float, allow_unknown: bool,
                window: tuple[slice, slice] = (slice(None), slice(None))) -> np.ndarray:
    c = costmap.cost[window]
    w = _weight_table(cost_weight, allow_unknown)[c]  # one lookup per cell: the cost is a byte
    # A thin band just outside the inscribed radius is crossed only when nothing else will do:
    # a path grazing the inscribed edge leaves a tracking controller no room at corners.
    w[(costmap.clearance[window] < costmap.inscribed_radius + GRAZE_MARGIN) & (c < INSCRIBED)] += GRAZE_PENALTY
    return w


class _Weights:
    """One costmap's traversal weights for one set of parameters, float64 and (for A*) float32, read-only."""

    def __init__(self, version: int, cost: np.ndarray, w: np.ndarray) -> None:
        self.version, self.cost, self.w = version, cost, w
        self._w32: np.ndarray | None = None
        w.flags.writeable = False

    @property
    def w32(self) -> np.ndarray:
        if self._w32 is None:
            self._w32 = self.w.astype(np.float32)
            self._w32.flags.writeable = False
        return self._w32

    def update(self, window: tuple[slice, slice], values: np.ndarray) -> None:
        for a in (self.w, self._w32):
            if a is not None:
                a.flags.writeable = True
                a[window] = values
                a.flags.writeable = False


_KEPT: weakref.WeakKeyDictionary[Costmap, dict[tuple[float, bool, float], _Weights]] = weakref.WeakKeyDictionary()


@functools.lru_cache(maxsize=16)
def _weight_table(cost_weight: float, allow_unknown: bool) -> np.ndarray:
    """(256,) float64: the weight of a cell by its cost byte (``inf`` where the footprint does not fit; unknown
    cells as ``allow_unknown`` says)."""
    c = np.arange(256, dtype=np.float64)
    w = 1.0 + cost_weight * c / MAX_NON_OBSTACLE
    w[INSCRIBED:] = np.inf
    w[NO_INFORMATION] = (1.0 + cost_weight * UNKNOWN_COST) if allow_unknown else np.inf
    w.flags.writeable = False
    return w


def _endpoints(costmap: Costmap, weights: np.ndarray, start: Pose2, goal: Pose2,
               goal_tolerance: float) -> tuple[tuple[int, int], tuple[int, int], np.ndarray]:
    """Start and goal cells, checked, and the weights to plan on: ``weights`` itself, or a copy that lets the
    robot plan out of an inscribed start."""
    if costmap.cost.size == 0:
        raise StartOccupied("the costmap is empty")
    s = costmap.world_to_cell(np.array([start.x, start.y]))
    g = costmap.world_to_cell(np.array([goal.x, goal.y]))
    if not costmap.inside(s)[0]:
        raise StartOccupied(f"start ({start.x:.2f}, {start.y:.2f}) is outside the costmap")
    sr, sc = int(s[0, 0]), int(s[0, 1])
    if costmap.cost[sr, sc] == LETHAL:
        raise StartOccupied(f"start ({start.x:.2f}, {start.y:.2f}) is in an obstacle")
    if not np.isfinite(weights[sr, sc]):
        # A robot grazing a wall must still be able to plan its way out (NavFn frees the start too).
        n = int(math.ceil(ESCAPE_RADIUS / costmap.resolution))
        weights = weights.copy()
        r0, r1 = max(sr - n, 0), min(sr + n + 1, weights.shape[0])
        c0, c1 = max(sc - n, 0), min(sc + n + 1, weights.shape[1])
        win = weights[r0:r1, c0:c1]
        # Only cells no closer to the obstacle than the start: a way out, never a short cut past what it grazes
        # (after a bump the robot stands in the inflation of the mark, and the escape must not lead into it).
        away = costmap.clearance[r0:r1, c0:c1] >= costmap.clearance[sr, sc] - 1e-6
        esc = ~np.isfinite(win) & (costmap.cost[r0:r1, c0:c1] == INSCRIBED) & away
        if costmap.cost[sr, sc] == NO_INFORMATION:
            # The robot stands on cells the map has not seen (the lidar sees nothing within its minimum range,
            # and a ray gap far off may leave a cell unknown): where its footprint is is free, whatever the map
            # says, as Nav2's footprint clearing has it. The unknown cells under the footprint may be crossed.
            rr, cc = np.ogrid[r0 - sr : r1 - sr, c0 - sc : c1 - sc]
            under = (rr * rr + cc * cc) * costmap.resolution**2 <= costmap.inscribed_radius**2
            esc |= ~np.isfinite(win) & (costmap.cost[r0:r1, c0:c1] == NO_INFORMATION) & under
        win[esc] = ESCAPE_PENALTY
    gr, gc = (int(g[0, 0]), int(g[0, 1]))
    if not costmap.inside(g)[0] or not np.isfinite(weights[gr, gc]):
        cell = _nearest_free(costmap, weights, gr, gc, goal_tolerance)
        if cell is None:
            raise GoalOccupied(f"goal ({goal.x:.2f}, {goal.y:.2f}) is occupied or outside the costmap")
        gr, gc = cell
    return (sr, sc), (gr, gc), weights


def _nearest_free(costmap: Costmap, weights: np.ndarray, r: int, c: int,
                  tolerance: float) -> tuple[int, int] | None:
    n = int(math.floor(tolerance / costmap.resolution))
    if n <= 0:
        return None
    rr, cc = np.mgrid[r - n : r + n + 1, c - n : c + n + 1]
    d2 = (rr - r) ** 2 + (cc - c) ** 2
    h, w = weights.shape
    ok = (rr >= 0) & (rr < h) & (cc >= 0) & (cc < w) & (d2 <= n * n)
    ok[ok] = np.isfinite(weights[rr[ok], cc[ok]])
    if not ok.any():
        return None
    i = np.argmin(np.where(ok, d2, np.iinfo(np.int64).max))
    return int(rr.ravel()[i]), int(cc.ravel()[i])


@functools.lru_cache(maxsize=4096)
def _fractions(n: int) -> np.ndarray:
    """``np.linspace(0, 1, n)``, kept: the path smoother asks for the same few lengths thousands of times."""
    t = np.linspace(0.0, 1.0, n)
    t.flags.writeable = False
    return t


def _segment_cells(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cells (rows, cols) a straight segment between cell-coordinate points crosses (sampled at ¼ cell)."""
    ar, ac = float(a[0]), float(a[1])
    dr, dc = float(b[0]) - ar, float(b[1]) - ac
    t = _fractions(max(2, int(math.ceil(4.0 * math.hypot(dr, dc))) + 1))
    return np.floor(ar + 0.5 + t * dr).astype(np.intp), np.floor(ac + 0.5 + t * dc).astype(np.intp)


def shortcut(cells: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """String-pull a (N, 2) cell path: replace stretches by straight segments that are no costlier per cell.

    A segment i→j is taken when every cell it crosses is passable and no
    costlier than the costliest cell of the stretch it replaces, so clearance
    is kept. Returns the (M, 2) float cell coordinates of the kept vertices.
    """
    n = len(cells)
    if n <= 2:
        return cells.astype(float)
    pts = cells.astype(float)
    rc = np.floor(pts + 0.5).astype(np.int64)
    wpath = weights[rc[:, 0], rc[:, 1]]
    # A re-sampled point may round into a blocked cell; it must not license crossing blocked cells.
    wpath = np.where(np.isfinite(wpath), wpath, 0.0)
    # Running maxima over stretches come from a sparse table of log2(n) levels.
    table = [wpath]
    k = 1
    while (1 << k) <= n:
        prev = table[-1]
        half = 1 << (k - 1)
        table.append(np.maximum(prev[:-half], prev[half:]))
        k += 1

    def stretch_max(i: int, j: int) -> float:
        lvl = int(math.log2(j - i + 1))
        return float(max(table[lvl][i], table[lvl][j - (1 << lvl) + 1]))

    def ok(i: int, j: int) -> bool:
        r, c = _segment_cells(pts[i], pts[j])
        w = weights[r, c]
        top = float(w.max())  # one reduction; a blocked cell (inf) anywhere, ends included, refuses the segment
        return top != math.inf and top <= max(stretch_max(i, j), float(w[0]), float(w[-1])) + 1e-9

    out = [0]
    i = 0
    while i < n - 1:
        # Gallop then bisect for the farthest visible vertex (visibility is near-monotone here).
        step, j = 1, i + 1
        while j + step < n and ok(i, j + step):
            j += step
            step *= 2
        lo, hi = j, min(j + step, n - 1)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if ok(i, mid):
                lo = mid
            else:
                hi = mid
        if hi != lo and ok(i, hi):
            lo = hi
        out.append(lo)
        i = lo
    return pts[out]


def smooth_path(cells: np.ndarray, weights: np.ndarray, passes: int = SMOOTHING_PASSES) -> np.ndarray:
    """Repeated :func:`shortcut`: each pass re-samples the pulled polyline every cell and pulls it again.

    One greedy pass only joins vertices of the grid path; later passes let
    the corners slide along it, so the path tightens towards the taut string.
    (N, 2) cells in, (M, 2) float cell coordinates out.
    """
    pts = shortcut(cells, weights)
    for it in range(passes - 1):
        if len(pts) < 2:
            break  # a path of one cell: nothing to pull
        # Each leg a → b sampled at a + j/k·(b − a), j = 1..k, k its length in cells rounded up: all legs at once.
        legs = pts[1:] - pts[:-1]
        ks = np.maximum(np.ceil(np.hypot(legs[:, 0], legs[:, 1])).astype(int), 1)
        fractions = np.concatenate([_fractions(k + 1)[1:] for k in ks.tolist()])
        dense_pts = np.concatenate([pts[:1], np.repeat(pts[:-1], ks, axis=0)
                                    + fractions[:, None] * np.repeat(legs, ks, axis=0)])
        # Alternate directions: a corner slides towards the end the pass starts from.
        tighter = shortcut(dense_pts[::-1], weights)[::-1] if it % 2 == 0 else shortcut(dense_pts, weights)
        if len(tighter) >= len(pts) and _length(tighter) >= _length(pts) - 1e-9:
            break
        pts = tighter
    return pts


def _length(p: np.ndarray) -> float:
    return float(np.hypot(*np.diff(p, axis=0).T).sum())


def _finish(costmap: Costmap, weights: np.ndarray, cells: np.ndarray, start: Pose2, goal: Pose2,
            goal_cell: tuple[int, int], smooth: bool) -> np.ndarray:
    pts = smooth_path(cells, weights) if smooth else cells.astype(float)
    xy = costmap.cell_to_world(pts)
    xy[0] = (start.x, start.y)
    gw = costmap.cell_to_world(np.array([goal_cell]))[0]
    # Keep the exact goal when it lies in the goal cell itself.
    gc = costmap.world_to_cell(np.array([goal.x, goal.y]))[0]
    xy[-1] = (goal.x, goal.y) if tuple(gc) == goal_cell else gw
    return xy


# -- the planners -----------------------------------------------------------------------
class GridPlanner:
    """What every grid planner is configured with; subclasses implement ``plan``.

    ``cost_weight`` scales how much the inflation cost lengthens a cell,
    ``allow_unknown`` lets paths cross unknown cells (Nav2's meaning),
    ``goal_tolerance`` [m] accepts a free cell that near an occupied goal, and
    ``smooth`` shortens the grid path by string pulling.
    """

    name = ""

    def __init__(self, cost_weight: float = COST_WEIGHT, allow_unknown: bool = True,
                 goal_tolerance: float = 0.0, smooth: bool = True) -> None:
        self.cost_weight = cost_weight
        self.allow_unknown = allow_unknown
        self.goal_tolerance = goal_tolerance  # [m]
        self.smooth = smooth


class DijkstraPlanner(GridPlanner):
    """Dijkstra over the 8-connected cell graph (scipy.sparse.csgraph), √2 diagonals."""

    name = "dijkstra"

    def plan(self, costmap: Costmap, start: Pose2, goal: Pose2) -> np.ndarray:
        w = traversal_weights(costmap, self.cost_weight, self.allow_unknown)
        s, g, w = _endpoints(costmap, w, start, goal, self.goal_tolerance)
        graph, index, cells = grid_graph(w)
        dist, pred = dijkstra(graph, directed=False, indices=index[s], return_predecessors=True)
        gi = index[g]
        if gi < 0 or not np.isfinite(dist[gi]):
            raise NoPathFound("no free path from start to goal")
        chain = [gi]
        while chain[-1] != index[s]:
            chain.append(pred[chain[-1]])
        path = cells[np.array(chain[::-1])]
        return _finish(costmap, w, path, start, goal, g, self.smooth)


def grid_graph(weights: np.ndarray) -> tuple[coo_matrix, np.ndarray, np.ndarray]:
    """Undirected 8-connected graph over finite-weight cells; edge = length [cells] × mean weight.

    Returns the sparse graph, an (H, W) int index of each cell's node (−1 if
    impassable), and the (N, 2) (row, col) of each node.
    """
    ok = np.isfinite(weights)
    index = np.full(weights.shape, -1, dtype=np.int64)
    cells = np.argwhere(ok)
    index[ok] = np.arange(len(cells))
    rows, cols, vals = [], [], []
    h, w = weights.shape
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        a = (slice(0, h - dr), slice(max(0, -dc), w - max(0, dc)))
        b = (slice(dr, h), slice(max(0, dc), w - max(0, -dc)))
        both = ok[a] & ok[b]
        length = math.hypot(dr, dc)
        rows.append(index[a][both])
        cols.append(index[b][both])
        vals.append(0.5 * length * (weights[a][both] + weights[b][both]))
    n = len(cells)
    graph = coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return graph.tocsr(), index, cells


class FastMarchingPlanner(GridPlanner):
    """Travel time from the goal by fast marching (scikit-fmm), speed = 1/weight; descend from the start."""

    name = "fmm"

    def plan(self, costmap: Costmap, start: Pose2, goal: Pose2) -> np.ndarray:
        w = traversal_weights(costmap, self.cost_weight, self.allow_unknown)
        s, g, w = _endpoints(costmap, w, start, goal, self.goal_tolerance)
        t = _march(w, g, speed=True)
        if not np.isfinite(t[s]):
            raise NoPathFound("no free path from start to goal")
        path = _descend(t, s, g)
        return _finish(costmap, w, path, start, goal, g, self.smooth)


def _march(weights: np.ndarray, source: tuple[int, int], speed: bool,
           exact: tuple[float, float] | None = None) -> np.ndarray:
    """(H, W) fast-marching arrival from ``source`` [cells] (or the sub-cell point ``exact``); ``inf`` where unreachable."""
    blocked = ~np.isfinite(weights)
    rows, cols = np.flatnonzero(~blocked.all(axis=1)), np.flatnonzero(~blocked.all(axis=0))
    if len(rows):
        # March only over the box of open cells (and the source), a blocked cell round it: the arrays built
        # round the march then cover only that box, and the arrival times inside are the same to the bit.
        r0, c0 = max(min(int(rows[0]), source[0]) - 1, 0), max(min(int(cols[0]), source[1]) - 1, 0)
        r1, c1 = max(int(rows[-1]), source[0]) + 2, max(int(cols[-1]), source[1]) + 2
        if (r1 - r0) * (c1 - c0) < blocked.size:
            er, ec = exact if exact is not None else source
            out = np.full(weights.shape, np.inf)
            out[r0:r1, c0:c1] = _march(weights[r0:r1, c0:c1], (source[0] - r0, source[1] - c0), speed,
                                       (er - r0, ec - c0))
            return out
    rr, cc = np.indices(weights.shape)
    # A zero contour around the source point, wide enough to enclose a cell centre; added back below.
    er, ec = exact if exact is not None else source
    phi = np.hypot(rr - er, cc - ec) - SOURCE_RADIUS
    phi = np.ma.MaskedArray(phi, mask=blocked)
    try:
        if speed:
            out = skfmm.travel_time(phi, 1.0 / np.where(blocked, 1.0, weights), dx=1.0)
        else:
            out = skfmm.distance(phi, dx=1.0)
    except ValueError as err:
        if "zero contour" not in str(err):
            raise
        # Every cell the circle reaches beyond the source is blocked (a start in a pocket its footprint does
        # not fit, freed alone by the escape): nothing but the source is reachable.
        out = np.ma.masked_all(weights.shape)
    t = np.ma.filled(np.ma.MaskedArray(out).astype(np.float64), np.inf) + SOURCE_RADIUS
    t[source] = math.hypot(source[0] - er, source[1] - ec)
    return t


_NEIGHBOURS = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)])
_STEP = np.hypot(_NEIGHBOURS[:, 0], _NEIGHBOURS[:, 1])


def _descend(t: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> np.ndarray:
    """Steepest descent of an arrival-time field over 8-neighbours, from ``start`` to ``goal``."""
    h, w = t.shape
    pad = np.pad(t, 1, constant_values=np.inf)
    cur = np.array(start)
    path = [cur]
    for _ in range(h * w):  # bounded: each step strictly lowers t
        if tuple(cur) == goal:
            break
        nb = cur[None, :] + _NEIGHBOURS
        tn = pad[nb[:, 0] + 1, nb[:, 1] + 1]
        slope = (t[cur[0], cur[1]] - tn) / _STEP
        k = int(np.argmax(slope))
        if not slope[k] > 0:
            raise NoPathFound("fast-marching field has no descent (start cut off)")
        cur = nb[k]
        path.append(cur)
    return np.array(path)


class AStarPlanner(GridPlanner):
    """pyastar2d's A* on the 8-connected grid (its diagonal steps cost as much as straight ones)."""

    name = "astar"

    def plan(self, costmap: Costmap, start: Pose2, goal: Pose2) -> np.ndarray:
        kept = _weights(costmap, self.cost_weight, self.allow_unknown)
        s, g, w = _endpoints(costmap, kept.w, start, goal, self.goal_tolerance)
        w32 = kept.w32 if w is kept.w else w.astype(np.float32)
        h, wd = w.shape
        # pyastar2d's own wrapper would check the minimum and copy the whole floor's weights at every plan:
        # they are ≥ 1 by construction (the table's and the escape's), and a C-contiguous ravel is a view.
        path = pyastar2d.astar.astar(np.ascontiguousarray(w32).ravel(), h, wd, s[0] * wd + s[1], g[0] * wd + g[1],
                                     True, 0)
        if path is None:
            raise NoPathFound("no free path from start to goal")
        return _finish(costmap, w, np.asarray(path), start, goal, g, self.smooth)


PLANNERS: dict[str, type] = {
    "dijkstra": DijkstraPlanner,
    "fmm": FastMarchingPlanner,
    "astar": AStarPlanner,
}


def make_planner(name: str, **params: object) -> GlobalPlanner:
    """The planner registered as ``name`` (``dijkstra``, ``fmm``, ``astar``) with its parameters."""
    if name not in PLANNERS:
        raise KeyError(f"unknown planner '{name}' (known: {', '.join(sorted(PLANNERS))})")
    planner: GlobalPlanner = PLANNERS[name](**params)
    return planner


def path_length(path: np.ndarray) -> float:
    """Length [m] of an (N, 2) polyline."""
    p = np.asarray(path, dtype=float)
    return float(np.hypot(*np.diff(p, axis=0).T).sum()) if len(p) > 1 else 0.0


def distance_map(costmap: Costmap, start: Pose2 | tuple[float, float],
                 allow_unknown: bool = False, coarse: float = 0.0) -> np.ndarray:
    """(H, W) float64 travel distance [m] from ``start`` through cells the robot fits in; inf elsewhere.

    Fast marching on the geometric metric (isotropic, so within ~1–2 % of
    Euclidean in the open, unlike 8-connected Dijkstra's up to 8 %).
    Unknown cells are crossed only with ``allow_unknown``. A start outside
    the costmap or in an obstacle gives all ``inf``.

    ``coarse`` [m] (more than the cell size): which cells are reachable is
    still found cell by cell (the 4-connected piece of the cells the robot
    fits in that holds the start, the set fast marching reaches), but the
    distances are marched on blocks of about ``coarse`` metres (a block is
    open when any of its reachable cells is) and each reachable cell takes
    the blocks' round it, bilinear over the open ones: within about a block
    of the fine field, growing smoothly from cell to cell, at a fraction of
    the cost on a large floor (a 0.2 m block holds 16 cells of 5 cm). The
    blocks cannot join two sides of a wall: the footprint keeps a band of
    twice the inscribed radius (0.4 m and more) of unreachable cells along
    every wall, wider than a block's diagonal.
    """
    sx, sy = (start.x, start.y) if isinstance(start, Pose2) else (float(start[0]), float(start[1]))
    w = traversal_weights(costmap, 0.0, allow_unknown)
    out = np.full(costmap.shape, np.inf)
    try:
        s, _, w = _endpoints(costmap, w, Pose2(sx, sy), Pose2(sx, sy), 0.0)
    except PlanningError:
        return out
    exact = ((sy - costmap.origin[1]) / costmap.resolution - 0.5, (sx - costmap.origin[0]) / costmap.resolution - 0.5)
    f = int(round(coarse / costmap.resolution))
    if f < 2:
        return _march(w, s, speed=False, exact=exact) * costmap.resolution
    _, labels = cv2.connectedComponents(np.isfinite(w).astype(np.uint8), connectivity=4)
    reach = labels == labels[s]
    h, wd = reach.shape
    open_blocks = block_any(reach, f)
    hc, wc = open_blocks.shape
    # The start's block, and the start as a point in block coordinates (block centres at integers).
    t = _march(np.where(open_blocks, 1.0, np.inf), (s[0] // f, s[1] // f), speed=False,
               exact=((exact[0] + 0.5) / f - 0.5, (exact[1] + 0.5) / f - 0.5)) * (f * costmap.resolution)
    # Each cell's distance: the blocks' round it, bilinear at its centre over the open ones (normalised
    # convolution: the closed blocks' weight left out), so that distances still grow smoothly cell by cell.
    # Only the blocks round the open ones are resized (a block more each side, so that every open cell's
    # interpolation reads the same blocks as over the whole floor; a whole number of blocks off, the same
    # weights: the same values to the bit).
    rows, cols = np.flatnonzero(open_blocks.any(axis=1)), np.flatnonzero(open_blocks.any(axis=0))
    b0, b1 = max(int(rows[0]) - 1, 0), min(int(rows[-1]) + 2, hc)
    a0, a1 = max(int(cols[0]) - 1, 0), min(int(cols[-1]) + 2, wc)
    r0, r1, c0, c1 = b0 * f, min(b1 * f, h), a0 * f, min(a1 * f, wd)
    known = np.isfinite(t[b0:b1, a0:a1])
    size = ((a1 - a0) * f, (b1 - b0) * f)
    value = cv2.resize(np.where(known, t[b0:b1, a0:a1], 0.0), size, interpolation=cv2.INTER_LINEAR)
    weight = cv2.resize(known.astype(np.float64), size, interpolation=cv2.INTER_LINEAR)
    np.divide(value[:r1 - r0, :c1 - c0], np.maximum(weight[:r1 - r0, :c1 - c0], 1e-12), out=out[r0:r1, c0:c1],
              where=reach[r0:r1, c0:c1])
    return out
