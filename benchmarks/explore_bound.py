"""The physical bound on exploration time: a short route from the start from which the lidar sees 95 per cent of the reachable free area, driven at the navigation speed limit (ground truth; evaluation only).

No strategy, however clever, explores faster than a robot that knows the
floor plan beforehand and drives the shortest route from which its lidar
sees the target share of the place. This computes such a route on the true
map, for a world of ``homing bench explore``:

1. the cells to see: the navigable area from the start (the coverage
   figure's denominator, :func:`homing.mapping.evaluate.navigable_truth`:
   the costmap's rule for where the footprint fits; space behind passages
   narrower than the robot is reported beside it, not counted);
2. viewpoints: cells of that area where the robot's centre fits, on a
   ``SPACING`` lattice, and the start; each sees every free cell in sight within ``LIDAR_RANGE`` (rays
   stopping at the first wall: ``RAYS``, or more on a map so fine that neighbouring rays would pass more than
   a cell apart at that range — a robot's scans from the poses on its way fill the gaps between one
   scan's rays, and a floor must not charge for them);
3. a greedy set cover (the start first, then the viewpoint seeing the most
   cells not yet seen) until ``TARGET`` of the cells are seen;
4. the shortest open tour from the start through those viewpoints by path
   distance (:mod:`homing.mapping.frontier_tour`), and its time at
   ``NAV_MAX_V``, with no turning, stopping or scan-matching time.

Greedy cover and tour are heuristics, so the route is a little longer than
the best one, but the robot that drives it knows everything the explorer has
to find out: read its time as what the building itself costs, the floor
under a strategy's time to 95 per cent.
"""

from __future__ import annotations

import argparse
import heapq
import math
from dataclasses import asdict, dataclass

import numpy as np
from homing.robot.turtlebot import NAV_MAX_V

from homing.map_server import FREE, MapData

LIDAR_RANGE = 6.0  # [m] RPLIDAR A1 as the thesis used it
RAYS = 360  # lidar rays (1° steps)
SPACING = 0.5  # [m] lattice of candidate viewpoints
TARGET = 0.95  # share of the reachable free area to see
CHUNK = 64  # viewpoints ray-cast at once (memory)


@dataclass(frozen=True)
class Bound:
    """A covering route: the navigable area [m²], viewpoints on it, its length [m] and time [s]; the free area
    [m²] behind passages narrower than the robot and the widest of those passages [m] (0: none)."""

    world: str
    area: float
    viewpoints: int
    length: float
    time: float
    blocked_area: float = 0.0
    blocked_width: float = 0.0


def visible_cells(free: np.ndarray, resolution: float, cells: np.ndarray) -> list[np.ndarray]:
    """For each of ``cells`` (N, 2) int (row, col), the flat indices into ``free`` (H, W) bool of the free cells a
    lidar there sees: rays sampled every half cell out to ``LIDAR_RANGE`` [m], stopping at the first cell that
    is not free — ``RAYS`` of them, or as many as keep neighbouring rays within a cell of each other at that
    range (754 on a 5 cm map, where 360 left a viewpoint of FHW's museum blind to half the cells 6 m away and
    the bound 15 % longer than the robot's own time to 95 %). Each cell once, in no particular order."""
    h, w = free.shape
    n_s = int(LIDAR_RANGE / (0.5 * resolution))
    r = (np.arange(n_s) + 0.5) * 0.5  # [cells]
    rays = max(RAYS, int(math.ceil(2 * math.pi * LIDAR_RANGE / resolution)))
    a = np.arange(rays) * (2 * np.pi / rays)
    # A ray's samples as whole-cell steps from the viewpoint's cell (floor(c + 0.5 + d) = c + floor(0.5 + d) for a
    # whole c), each cell once: a sample in the cell before it reads the same, and the first wall stops both.
    steps_r = np.floor(0.5 + np.sin(a)[:, None] * r[None, :]).astype(np.int64)
    steps_c = np.floor(0.5 + np.cos(a)[:, None] * r[None, :]).astype(np.int64)
    pad = n_s // 2 + 2
    padded = np.pad(free, pad, constant_values=False).ravel()
    pw = w + 2 * pad
    steps = steps_r * pw + steps_c  # (rays, samples) flat offsets in the padded grid
    new = np.ones_like(steps, dtype=bool)
    new[:, 1:] = steps[:, 1:] != steps[:, :-1]
    ray_of = np.repeat(np.arange(rays), new.sum(axis=1))
    steps = steps[new]
    first = np.flatnonzero(np.r_[True, ray_of[1:] != ray_of[:-1]])[ray_of]  # each step's ray's first step
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    base = (cells[:, 0] + pad) * pw + cells[:, 1] + pad
    # Each seen cell once, in no particular order: the last sample to write a cell's slot keeps it (no sort).
    slot = np.empty(padded.size, dtype=np.int64)
    out = []
    for i in range(0, len(cells), CHUNK):
        flat = base[i : i + CHUNK, None] + steps[None, :]
        # A step is seen when it and every step before it on its ray are free: no wall counted since the ray began.
        blocked = ~padded[flat]
        walls = np.cumsum(blocked, axis=1, dtype=np.int32)
        open_ray = walls == walls[:, first] - blocked[:, first]
        for k in range(len(flat)):
            seen = flat[k][open_ray[k]]
            at = np.arange(len(seen))
            slot[seen] = at
            seen = seen[slot[seen] == at]
            out.append((seen // pw - pad) * w + seen % pw - pad)
    return out


def greedy_cover(sets: list[np.ndarray], need: int, first: int) -> list[int]:
    """Indices of ``sets`` (flat cell indices each, none twice) whose union has at least ``need`` cells: ``first``, then
    greedily the set adding the most (lazy evaluation: a set's gain only shrinks)."""
    seen = np.zeros(max((int(s.max()) + 1 for s in sets if len(s)), default=0), dtype=bool)
    seen[sets[first]] = True
    n_seen = int(seen.sum())
    chosen = [first]
    heap = [(-len(s), i) for i, s in enumerate(sets) if i != first]
    heapq.heapify(heap)
    while n_seen < need and heap:
        _, i = heapq.heappop(heap)
        gain = len(sets[i]) - int(np.count_nonzero(seen[sets[i]]))
        if heap and gain < -heap[0][0]:
            heapq.heappush(heap, (-gain, i))  # stale: look again later
            continue
        if gain == 0:
            break
        chosen.append(i)
        seen[sets[i]] = True
        n_seen += gain
    return chosen


def covering_route(world_spec: str, target: float = TARGET) -> Bound:
    """The route of the module doc for the world ``world_spec`` (a bundled name, YAML path or ``KIND:SEED``),
    from its start pose."""
    from homing.sim import load_world

    world = load_world(world_spec)
    area, viewpoints, length = route(world.map, (world.start.x, world.start.y), target)
    from homing.mapping.evaluate import navigable_truth

    blocked = navigable_truth(world.map, (world.start.x, world.start.y)).blocked
    return Bound(world_spec, area, viewpoints, length, length / NAV_MAX_V, sum(b.area for b in blocked),
                 max((b.width for b in blocked), default=0.0))


def route(truth: MapData, start: tuple[float, float], target: float = TARGET) -> tuple[float, int, float]:
    """The navigable area [m²] of ``truth`` from ``start`` (x, y) [m], the number of viewpoints of the covering
    route (module doc) and its length [m]."""
    from homing.mapping.evaluate import navigable_truth
    from homing.mapping.frontier_tour import open_tour, path_distances, tour_length

    res = truth.resolution
    nav = navigable_truth(truth, start)
    reach, fits = nav.mask, nav.region.copy()
    free = truth.grid == FREE
    # The start, moved onto the nearest cell where the footprint fits; viewpoints where it fits.
    fr, fc = np.nonzero(fits)
    s_r, s_c = (start[1] - truth.origin[1]) / res, (start[0] - truth.origin[0]) / res
    j = int(np.argmin((fr - s_r) ** 2 + (fc - s_c) ** 2))
    s_cell = (int(fr[j]), int(fc[j]))
    step = max(1, int(round(SPACING / res)))
    lattice = np.zeros_like(fits)
    lattice[::step, ::step] = True
    cand = np.vstack([np.array([s_cell]), np.argwhere(fits & lattice)])
    sets = [s[reach.ravel()[s]] for s in visible_cells(free, res, cand)]
    chosen = greedy_cover(sets, int(math.ceil(target * int(reach.sum()))), 0)
    d = path_distances(fits, res, cand[chosen])
    d = np.where(np.isfinite(d), d, 1e6)
    order = open_tour(d[0, 1:], d[1:, 1:])
    return float(reach.sum()) * res * res, len(chosen), tour_length(order, d[0, 1:], d[1:, 1:])


# -- CLI ---------------------------------------------------------------------------------------------------
def add_arguments(parser: argparse.ArgumentParser) -> None:
    from homing.missions.commands._args import count

    parser.add_argument("--worlds", nargs="+", metavar="WORLD",
                        help="bundled names or YAML paths (default: as bench explore)")
    parser.add_argument("--generated", type=count, default=3,
                        help="also the first N generated plans of each kind (as bench explore)")


def run(args: argparse.Namespace) -> int:
    from homing.benchmarks.common import print_table, write_json
    from homing.benchmarks.explore import plan_kind, world_label, world_specs
    from homing.sim.world import check_spec

    worlds = world_specs(args.worlds, args.generated if not args.worlds else 0)
    for w in worlds:
        check_spec(w)
    bounds = [covering_route(w) for w in worlds]
    print_table(
        f"Covering routes: the lidar ({LIDAR_RANGE:g} m) sees {TARGET:.0%} of the navigable area; "
        "time at the navigation speed limit; 'behind' is the free area only passages narrower than the robot "
        "(or than a map may draw them) lead to (the widest of them)",
        ["world", "kind", "area m²", "behind m²", "viewpoints", "route m", "time s"],
        [[world_label(b.world), plan_kind(world_label(b.world)), b.area,
          f"{b.blocked_area:.1f} ({b.blocked_width:.2f} m)" if b.blocked_area else "0", b.viewpoints, b.length,
          b.time] for b in bounds],
    )
    write_json(args.json, {world_label(b.world): asdict(b) for b in bounds})
    return 0
