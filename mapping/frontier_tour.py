"""A tour over frontier goals by path distance, so exploration plans beyond the next frontier (Kulich et al. 2011, "distance-based exploration" as a TSP; Zhou et al. 2021, FUEL's global tour over frontier clusters).

Greedy rules (nearest frontier; explore_lite's cost; travel − length) look
one goal ahead. In a building of rooms off a corridor that sends the robot
back and forth: the nearest door now, the corridor's open end next, then all
the way back for the door it passed. Ordering every frontier at once fixes
that:

1. every frontier cluster gets one goal: the cell the robot is sent to
   (explore_lite's centroid, moved onto a reachable cell);
2. the path distances between goals are measured on the free space the
   planner reaches, coarsened to ``COARSE`` m cells (one Dijkstra per goal
   over that graph, :func:`path_distances`); the robot's own distances are
   the planner's distance field;
3. the shortest open tour (it need not come back) from the robot through
   every goal is found by nearest-neighbour construction improved by 2-opt
   and or-opt moves (:func:`open_tour`; exact, by Held-Karp, up to ``EXACT_GOALS``);
4. which goal comes first also weighs what it opens: the way to it counts
   ``FIRST_GAIN`` × its frontier's length less (explore_lite's gain term, in
   the tour's metres). In a hall the long frontier at the lidar's reach
   opens the most and the crumbs behind a chair vanish on the way;
5. the robot drives to the tour's first goal. The tour is planned again
   whenever it is asked (every few seconds: frontiers grow and vanish as the
   lidar sees), but the current first goal is kept unless a tour without it
   first is shorter by ``HYSTERESIS_MIN`` m, or by ``HYSTERESIS`` of the
   way to the current goal if that is more, so it does not dither between two goals of nearly
   equal tours (:func:`keep_first`).

What that gives, on a corridor lined with rooms (robot R at the west end,
doors d1..d4 half seen, the corridor's unknown east end E)::

    +----+----+----+----+
    |    |    |    |    |
    +-d1-+-d2-+-d3-+-d4-+
    R ->  ->   ->   ->    E        tour R d1 d2 d3 d4 E : every room on the way
    +----+----+----+----+          greedy by travel−length: R E d4 d3 d2 d1 or R d1 E d4 ...

A robot inside a room with two frontiers left there and the door behind it
finishes the room first: leaving and coming back costs the way to the door
twice, which the tour counts and a one-step rule does not.

Plain numpy and scipy; cells are (row, col) of the planner's grid.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from homing.mapping.blocks import block_any
from homing.mapping.distance import distance_cells
from homing.mapping.frontier import OCCUPIED_AT
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from homing.map_server import FREE

COARSE = 0.2  # [m] cell size of the graph the distances between goals are measured on
HYSTERESIS_MIN = 3.0  # [m] the current first goal is dropped only for a tour this much shorter ...
HYSTERESIS = 0.25  # ... or this fraction of the way to the current goal, if more
EXACT_GOALS = 9  # up to this many goals the tour is the shortest (Held-Karp); beyond, local search
MAX_GOALS = 40
FIRST_GAIN = 1.0  # metres of way to the first goal one metre of its frontier is worth
DOOR_CLEARANCE = 0.7  # [m] a passage narrower than twice this (doors are 0.8-1.2 m; corridors 1.5 m and more) ...
DOOR_SPAN = 0.3  # [m] how far across and along a door its clearance is compared (more than a wall's thickness)
DOOR_REACH = 0.6  # [m] a door is the free space this close to its middle line (half the widest door)
SPECK = 0.3  # [m] walls shorter than this (chair legs, bins, specks of noise) are not door jambs
DOOR_TOLL = 3.0  # [m] ... costs this much more to pass: what lies beyond a door is unknown, and a room left
# unfinished means coming back through its door  # goals ordered at once (the nearest by travel distance; the rest wait their turn)


def path_distances(passable: np.ndarray, resolution: float, points: np.ndarray,
                   doors: np.ndarray | None = None, toll: float = 0.0) -> np.ndarray:
    """(K, K) float path distances [m] between ``points`` (K, 2) int (row, col) over the ``passable`` (H, W) bool
    cells, measured on a graph of ``COARSE`` m cells (a coarse cell is passable when any of its cells is),
    8-connected; ``inf`` between points not connected. ``doors`` (H, W) bool: crossing into or out of a coarse
    cell with a door cell costs ``toll`` / 2 [m] more (so passing through a door costs ``toll``)."""
    k = len(points)
    if k == 0:
        return np.zeros((0, 0))
    f = max(1, int(round(COARSE / resolution)))
    coarse = _coarsen(passable, f)
    hc, wc = coarse.shape
    door = _coarsen(doors & passable, f) if doors is not None else np.zeros_like(coarse)
    index = np.full((hc, wc), -1, np.int64)
    index[coarse] = np.arange(int(coarse.sum()))
    step = f * resolution  # [m] between coarse cell centres
    rows, cols, costs = [], [], []
    for dr, dc in ((0, 1), (1, 0), (1, 1), (1, -1)):
        sa = (slice(0, hc - dr), slice(max(0, -dc), wc - max(0, dc)))  # cell (r, c) ...
        sb = (slice(dr, hc), slice(max(0, dc), wc - max(0, -dc)))  # ... and its neighbour (r + dr, c + dc)
        a, b = index[sa], index[sb]
        both = (a >= 0) & (b >= 0)
        rows.append(a[both])
        cols.append(b[both])
        crossing = (door[sa] != door[sb])[both]
        costs.append(step * math.hypot(dr, dc) + 0.5 * toll * crossing)
    n = int(coarse.sum())
    graph = coo_matrix((np.concatenate(costs), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()
    nodes = index[points[:, 0] // f, points[:, 1] // f]
    out = np.full((k, k), np.inf)
    ok = nodes >= 0
    if ok.any():
        d = dijkstra(graph, directed=False, indices=nodes[ok])
        out[np.ix_(ok, ok)] = d[:, nodes[ok]]
    np.fill_diagonal(out, 0.0)
    return out


def _coarsen(mask: np.ndarray, f: int) -> np.ndarray:
    """(ceil(H/f), ceil(W/f)) bool: whether any cell of each f × f block of ``mask`` (H, W) is set."""
    return block_any(mask, f)


def door_cells(grid: np.ndarray, resolution: float) -> np.ndarray:
    """(H, W) bool: the doors of a map_server grid — the free cells within ``DOOR_REACH`` of cells where the clearance to the nearest wall is a saddle
    (Thrun 1998's critical points of the Voronoi diagram): ``DOOR_SPAN`` m to either side across the passage
    it falls, ``DOOR_SPAN`` m along it either way it rises, and it is below ``DOOR_CLEARANCE`` [m]. A corridor
    (no rise along it), a room's corner (a rise one way only) and a room's middle (too wide) are no doors; a
    gap between a desk and a wall is one. Unknown cells are not walls, nor are specks shorter than ``SPECK``."""
    wall = grid >= OCCUPIED_AT
    # Specks (chair legs, bins, noise) make no doors: only walls at least SPECK long count.
    n, labels, stats, _ = cv2.connectedComponentsWithStats(wall.astype(np.uint8), connectivity=8)
    long_enough = np.maximum(stats[:, cv2.CC_STAT_WIDTH], stats[:, cv2.CC_STAT_HEIGHT]) * resolution >= SPECK
    long_enough[0] = False
    wall = long_enough[labels]
    if not wall.any():
        return np.zeros(grid.shape, bool)
    clear = distance_cells(~wall) * resolution
    k = max(1, int(round(DOOR_SPAN / resolution)))
    kd = max(1, int(round(DOOR_SPAN / resolution / math.sqrt(2))))
    pad = np.pad(clear, k, mode="edge")
    h, w = clear.shape

    def at(dr: int, dc: int) -> np.ndarray:
        return pad[k + dr : k + dr + h, k + dc : k + dc + w]

    eps = 0.5 * resolution
    door = np.zeros(grid.shape, bool)
    for (ar, ac), (br, bc), n in (((0, 1), (1, 0), k), ((1, 0), (0, 1), k), ((1, 1), (1, -1), kd),
                                  ((1, -1), (1, 1), kd)):
        across = (at(n * ar, n * ac) < clear - eps) & (at(-n * ar, -n * ac) < clear - eps)
        along = (at(n * br, n * bc) > clear + eps) & (at(-n * br, -n * bc) > clear + eps)
        door |= across & along
    door &= (clear < DOOR_CLEARANCE) & (grid == FREE)
    # The saddle is the door's middle line; the door is the free space within DOOR_REACH of it, jamb to jamb,
    # so that no path slips past the middle line's cells.
    r = DOOR_REACH / resolution
    n = int(math.ceil(r))
    yy, xx = np.mgrid[-n : n + 1, -n : n + 1]
    disc = (xx * xx + yy * yy <= r * r).astype(np.uint8)
    return cv2.dilate(door.astype(np.uint8), disc).astype(bool) & (grid == FREE)


DOOR_DEPENDS = DOOR_CLEARANCE + DOOR_SPAN + DOOR_REACH + SPECK + 0.2  # [m] how far a map cell moves a door


class Doors:
    """:func:`door_cells` of a grid that changes a little between calls, kept up to date round what changed.

    A door cell depends only on the map within ``DOOR_DEPENDS`` of it (the
    clearance it compares, its span, its reach and a wall's speck length), so
    when the new grid has the old one's shape, only the cells within that of
    the box of changed cells are found again, on the map within twice that;
    the answer is the one :func:`door_cells` gives over the whole grid. Mapping
    changes the few metres round the robot between two decisions: on a large
    floor this is a window, not the floor. Another shape (the grid grew) is
    found whole.
    """

    def __init__(self) -> None:
        self._grid: np.ndarray | None = None
        self._doors: np.ndarray | None = None
        self._resolution = 0.0

    def __call__(self, grid: np.ndarray, resolution: float) -> np.ndarray:
        old, doors = self._grid, self._doors
        if old is None or doors is None or old.shape != grid.shape or resolution != self._resolution:
            doors = door_cells(grid, resolution)
        else:
            changed = old != grid
            if changed.any():
                rows, cols = np.flatnonzero(changed.any(axis=1)), np.flatnonzero(changed.any(axis=0))
                n = int(math.ceil(DOOR_DEPENDS / resolution))
                h, w = grid.shape
                a = (max(int(rows[0]) - n, 0), min(int(rows[-1]) + 1 + n, h),
                     max(int(cols[0]) - n, 0), min(int(cols[-1]) + 1 + n, w))  # cells found again
                b = (max(a[0] - n, 0), min(a[1] + n, h), max(a[2] - n, 0), min(a[3] + n, w))  # the map they see
                window = door_cells(grid[b[0]:b[1], b[2]:b[3]], resolution)
                doors = doors.copy()
                doors[a[0]:a[1], a[2]:a[3]] = window[a[0] - b[0]:a[1] - b[0], a[2] - b[2]:a[3] - b[2]]
        self._grid, self._doors, self._resolution = grid.copy(), doors, resolution
        return doors


def tour_length(order: list[int], start: np.ndarray, between: np.ndarray) -> float:
    """Length [m] of the open tour robot → ``order[0]`` → … → ``order[-1]`` (``start`` (K,) robot-to-goal,
    ``between`` (K, K) goal-to-goal distances)."""
    if not order:
        return 0.0
    return float(start[order[0]] + sum(between[a, b] for a, b in zip(order[:-1], order[1:], strict=True)))


def open_tour(start: np.ndarray, between: np.ndarray, first: int | None = None) -> list[int]:
    """A short open tour from the robot through every goal: the order (a permutation of ``range(K)``).

    ``start`` (K,) [m] robot-to-goal distances, ``between`` (K, K) [m] symmetric goal-to-goal distances (finite).
    ``first``: the goal the tour must begin with (None: any). Nearest-neighbour construction, then 2-opt
    (reverse a stretch) and or-opt (move a stretch of 1-3 goals elsewhere) until neither shortens it.
    """
    k = len(start)
    if k == 0:
        return []
    if k <= EXACT_GOALS:
        return _exact_tour(start, between, first)
    # Node 0 is the robot; goal i is node i + 1. The tour ends anywhere: no edge back.
    d = np.zeros((k + 1, k + 1))
    d[0, 1:] = d[1:, 0] = start
    d[1:, 1:] = between
    left = set(range(1, k + 1))
    path = [0]
    if first is not None:
        path.append(first + 1)
        left.discard(first + 1)
    while left:
        here = path[-1]
        nxt = min(left, key=lambda j: d[here, j])
        path.append(nxt)
        left.discard(nxt)
    fixed = 2 if first is not None else 1  # positions before this one never move
    improved = True
    while improved:
        improved = _two_opt(path, d, fixed) or _or_opt(path, d, fixed)
    return [p - 1 for p in path[1:]]


def _exact_tour(start: np.ndarray, between: np.ndarray, first: int | None) -> list[int]:
    """The shortest open tour, by Held-Karp dynamic programming over subsets (2^K·K² operations)."""
    k = len(start)
    full = 1 << k
    cost = np.full((full, k), np.inf)  # cost[mask, j]: shortest path from the robot through mask, ending at j
    parent = np.full((full, k), -1, np.int64)
    for j in range(k):
        if first is None or j == first:
            cost[1 << j, j] = start[j]
    bits = 1 << np.arange(k)
    for mask in range(1, full):
        row = cost[mask]
        if not np.isfinite(row).any():
            continue
        via = row[:, None] + between  # (from j, to m)
        best_from = np.argmin(via, axis=0)
        best = via[best_from, np.arange(k)]
        for m in np.flatnonzero((mask & bits) == 0):
            nxt = mask | int(bits[m])
            if best[m] < cost[nxt, m]:
                cost[nxt, m] = best[m]
                parent[nxt, m] = best_from[m]
    mask, j = full - 1, int(np.argmin(cost[full - 1]))
    order = []
    while j >= 0:
        order.append(j)
        mask, j = mask & ~(1 << j), int(parent[mask, j])
    return order[::-1]


def _edge(d: np.ndarray, path: list[int], i: int) -> float:
    """Length of the edge leaving position ``i`` (0 past the end: the tour is open)."""
    return float(d[path[i], path[i + 1]]) if i + 1 < len(path) else 0.0


def _two_opt(path: list[int], d: np.ndarray, fixed: int) -> bool:
    """Reverse the first stretch path[i..j] whose reversal shortens the tour; True if one was found."""
    n = len(path)
    for i in range(fixed, n - 1):
        for j in range(i + 1, n):
            old = d[path[i - 1], path[i]] + _edge(d, path, j)
            new = d[path[i - 1], path[j]] + (d[path[i], path[j + 1]] if j + 1 < n else 0.0)
            if new < old - 1e-9:
                path[i : j + 1] = path[i : j + 1][::-1]
                return True
    return False


def _or_opt(path: list[int], d: np.ndarray, fixed: int) -> bool:
    """Move the first stretch of 1-3 goals that is shorter elsewhere (either way round); True if one was."""
    n = len(path)
    for length in (1, 2, 3):
        for i in range(fixed, n - length + 1):
            j = i + length - 1  # the stretch is path[i..j]
            a, b = path[i], path[j]
            removed = d[path[i - 1], a] + _edge(d, path, j) - (d[path[i - 1], path[j + 1]] if j + 1 < n else 0.0)
            rest = path[:i] + path[j + 1 :]
            for p in range(fixed - 1, len(rest)):
                if p == i - 1:
                    continue
                nxt = rest[p + 1] if p + 1 < len(rest) else None
                base = d[rest[p], nxt] if nxt is not None else 0.0
                for x, y, seg in ((a, b, path[i : j + 1]), (b, a, path[i : j + 1][::-1])):
                    added = d[rest[p], x] + (d[y, nxt] if nxt is not None else 0.0) - base
                    if added < removed - 1e-9:
                        path[:] = rest[: p + 1] + seg + rest[p + 1 :]
                        return True
    return False


def keep_first(start: np.ndarray, between: np.ndarray, best: list[int], current: int | None) -> list[int]:
    """The tour to follow: ``best``, unless a tour beginning with the ``current`` goal (an index, or None) is
    within the hysteresis of it (module doc), in which case that one."""
    if current is None or not best or best[0] == current:
        return best
    held = open_tour(start, between, first=current)
    best_len, held_len = tour_length(best, start, between), tour_length(held, start, between)
    if held_len - best_len < max(HYSTERESIS * float(start[current]), HYSTERESIS_MIN):
        return held
    return best


def plan(robot: tuple[int, int], grid: np.ndarray, resolution: float, passable: np.ndarray, goals: np.ndarray,
         start: np.ndarray, current: int | None = None, lengths: np.ndarray | None = None,
         doors: np.ndarray | None = None) -> list[int]:
    """The order to visit ``goals`` (K, 2) (row, col) in, from the ``robot`` cell: ``grid`` (H, W) the map_server
    grid (for its doors), ``passable`` (H, W) bool the cells the planner reaches, ``start`` (K,) [m] the planner's
    travel distance to each goal (finite), ``current`` the goal now driven to (index or None), ``lengths`` (K,)
    [m] the goals' frontier lengths (the first goal's way counts ``FIRST_GAIN`` × its length less), ``doors``
    (H, W) bool the grid's doors if already found (:func:`door_cells`). At most
    ``MAX_GOALS`` goals, the nearest, are ordered; the rest follow, nearest first."""
    near = np.argsort(start, kind="stable")
    head, tail = near[:MAX_GOALS], near[MAX_GOALS:]
    points = np.vstack([np.array([robot], np.int64), goals[head]])
    if doors is None:
        doors = door_cells(grid, resolution)
    d = path_distances(passable, resolution, points, doors, DOOR_TOLL)
    # A goal the coarse graph cannot link (a one-cell passage lost in coarsening) is as far as the planner's
    # distances to both added: the triangle's bound.
    s = start[head]
    s_t = np.where(np.isfinite(d[0, 1:]), d[0, 1:], s)
    if lengths is not None:
        s_t = s_t - FIRST_GAIN * lengths[head]
    between = np.where(np.isfinite(d[1:, 1:]), d[1:, 1:], s[:, None] + s[None, :])
    cur = None
    if current is not None and current in head:
        cur = int(np.flatnonzero(head == current)[0])
    order = keep_first(s_t, between, open_tour(s_t, between), cur)
    return [int(head[i]) for i in order] + [int(i) for i in tail]
