"""Frontier goal strategies chosen by name: the thesis's four (Mata 2017, §2.4.2, table 5.1), explore_lite's cost (Hörner 2016), a tour over explore_lite's frontiers (the default), and information gain per travel time.

Every strategy sees the same :class:`GoalContext`: the map_server grid, the
robot's cell and heading, the travel-distance field from the robot on the
costmap (``distance`` (H, W) [m], ``inf`` where the planner cannot reach —
navigation's ``distance_map``), cells excluded as goals (blacklisted, or
within the reach radius of the robot), the current goal and a seeded
generator. A strategy returns a :class:`GoalChoice` (a reachable cell) or
``None`` when no frontier is left. Blacklisting, progress timeouts and when to
choose again live in :mod:`homing.mapping.explorer`, shared by all.

- ``nearest`` — Yamauchi (1997): the segment whose closest reachable cell is
  nearest by travel distance; goal = that cell.
- ``largest_closest`` — the largest segment; goal = its nearest cell.
- ``largest_random`` — the largest segment; goal = a uniformly random
  reachable cell of it (the thesis's best).
- ``largest_random_raw`` — the same on the raw, unsmoothed frontier.
- ``explore_lite`` — explore_lite's frontier search and cost:
  ``potential_scale·min_distance·resolution − gain_scale·size·resolution``
  (its defaults 3.0 / 1.0; ``min_distance`` the straight-line distance in
  metres to the nearest frontier cell, multiplied by the resolution as its
  source does), frontiers of unknown cells 4-adjacent to free, 8-connected,
  ``min_frontier_size`` 0.75 m, goal = centroid. move_base's global planner
  then plans to the centroid; here the centroid is snapped to the nearest
  reachable cell within ``CENTROID_TOLERANCE`` (else the frontier is skipped,
  as move_base would abort it and explore_lite blacklist it).
- ``frontier_travel`` (default) — explore_lite's frontiers and centroid
  goals, visited in the order of the shortest open tour through all of them
  by path distance, a door passed costing a toll
  (:mod:`homing.mapping.frontier_tour`), re-planned every 3 s as
  explore_lite replans, keeping its current goal unless another order is
  clearly shorter (hysteresis), and leaving a goal at once when no
  frontier is left near it (lookahead: the lidar saw what the robot was
  going to look at); the way to the first goal counts its
  frontier's length less, so in a hall the long frontier goes first. A
  one-step rule — explore_lite's cost, whose distance term is 0.15 per metre
  at 5 cm cells and hardly counts, or the nearest frontier — sends the robot
  back for the door it passed or across the building for the largest
  frontier; the tour passes each room on the way and finishes a room before
  leaving it. The tour takes the frontiers in three tiers, the next only
  when the one before is empty: first those at least ``LONG_FRONTIER`` long
  and the shorter ones of the room the robot stands in (:func:`robot_room`:
  what it reaches without passing a door); then every one of explore_lite's
  minimum size, and the ones down to ``CRUMB_SIZE`` nearer than the nearest
  of those (a short frontier close by is looked at now, not after a trip
  across the building and back: a door seen at a grazing angle is one, with
  a room behind it); then ones down to ``CRUMB_SIZE``, so the run does not end
  short of the whole map (explore_lite's "ends early"). From a hospital's
  corridor the robot looks into each room through its door and sees a short
  frontier behind a bed: the first tier sweeps the corridor and the open
  wards and comes back for those rooms last, as explore_lite's gain term
  does, and a room the robot has entered is finished before it leaves.
  (Touring the crumbs from the start was tried: slower in halls, where the
  long frontiers reveal them anyway. Deferring every short frontier, the
  robot's own room's too, was tried: faster in hospitals, slower in offices,
  where it left rooms half-seen behind desks and came back for them.)
- ``gain_rate`` — information gain per travel time (the default before
  ``frontier_travel``: better in worlds of many small rooms, slower in
  halls, where it leaves a hall half-seen for a bigger gain elsewhere and
  comes back). Candidate goals are the reachable cells of every smoothed
  segment plus viewpoints standing back from them in known free space (a
  ``SETBACK_STRIDE`` lattice within ``SETBACK``: the lidar sees a
  frontier's unknown from there without driving to its edge, and the robot
  stays in the open where the controller runs at full speed). Score = unknown area the lidar would
  see from the goal within ``VIEW_RADIUS`` (ray cast, :func:`visible_unknown`,
  so unknown space behind a mapped wall does not draw the robot to it)
  divided by the travel time there: the planner's travel distance / speed
  + turning time + a fixed overhead + the time lost crawling near walls.
  Goals revealing less than ``MIN_GAIN`` are ignored while better ones exist,
  then ones revealing ``CRUMB_GAIN`` are still visited, so the run does not
  end short of the whole map. Lookahead: a goal is given up (and the next
  chosen while the robot is still moving) as soon as it would reveal less
  than ``MIN_GAIN`` (:meth:`GainRate.goal_spent`). Hysteresis: keeps its
  current goal unless another scores ``HYSTERESIS`` times better, so it does
  not oscillate between two goals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np
from homing.mapping import frontier_tour
from homing.mapping.distance import distance_cells
from homing.mapping.frontier import (
    OCCUPIED_AT,
    FrontierSegment,
    keep_reachable,
    raw_frontiers,
    smoothed_frontiers,
)
from homing.robot.turtlebot import FOOTPRINT_RADIUS, NAV_MAX_V

from homing.map_server import FREE, UNKNOWN

POTENTIAL_SCALE = 3.0  # explore_lite launch default
GAIN_SCALE = 1.0  # explore_lite launch default
MIN_FRONTIER_SIZE = 0.75  # [m] explore_lite launch default
CENTROID_TOLERANCE = 1.0  # [m] how far a centroid goal may be moved to a reachable cell
SAME_FRONTIER = 1.5  # [m] frontier_travel: a frontier passing this near the current goal is the one driven to
CRUMB_SIZE = 0.3  # [m] frontier_travel visits frontiers this small once none of MIN_FRONTIER_SIZE is left
LONG_FRONTIER = 1.5  # [m] frontier_travel tours frontiers this long first, the shorter ones once none is left
GAIN_RADIUS = 3.0  # [m] unknown area counted around a goal: half the lidar's 6 m range
GAIN_POOL = 4  # cells pooled per side when counting unknown area (speed)
TRAVEL_SPEED = 0.8 * NAV_MAX_V  # [m/s] average speed assumed along a path
TURN_RATE = 1.0  # [rad/s] in-place turning speed assumed
FIXED_OVERHEAD = 3.0  # [s] per goal: planning, accelerating, the stop
HYSTERESIS = 1.3  # a new goal must score this much better than the current one
SLOW_GAP = 0.30  # [m] a controller slows down when its footprint is closer than this to a wall (Nav2 RPP)
SLOW_SPEED = 0.15  # [m/s] the slowest it goes there
SLOW_STRETCH = 1.5  # [m] of the path's end that runs as close to the walls as its goal cell
MAX_CANDIDATES = 60  # cells evaluated per segment by gain_rate (evenly spaced)
GAIN_RAYS = 48  # rays cast from each candidate to count the unknown area it would see
MIN_GAIN = 0.75  # [m²] a goal that would reveal less is not worth the trip (the thesis's "drop small frontiers")
CRUMB_GAIN = 0.2  # [m²] with no goal worth MIN_GAIN left, gain_rate still visits ones revealing this much
VIEW_RADIUS = 5.0  # [m] gain_rate counts what the lidar (6 m) would see from a goal, less a margin for sparse far rays
SETBACK = 1.5  # [m] gain_rate also tries viewpoints in known free space this far back from a frontier
SETBACK_STRIDE = 0.3  # [m] lattice spacing of those viewpoints
VIEW_CANDIDATES = 320  # gain_rate evaluates at most this many goals (each ray cast VIEW_RAYS × VIEW_RADIUS; ~50 ms)
VIEW_RAYS = 32  # rays per goal: 1 m apart at VIEW_RADIUS, enough for room-sized unknown


@dataclass
class GoalContext:
    """What a strategy may look at. Cells are (row, col); ``distance`` (H, W) [m] from the robot."""

    grid: np.ndarray
    resolution: float
    robot_cell: tuple[float, float]
    robot_heading: float
    distance: np.ndarray
    excluded: np.ndarray
    rng: np.random.Generator
    current_goal: tuple[int, int] | None = None
    robot_radius: float = FOOTPRINT_RADIUS


@dataclass
class GoalChoice:
    """A goal cell, the segment it came from, and every segment considered (for pictures)."""

    cell: tuple[int, int]
    segment: FrontierSegment | None
    segments: list[FrontierSegment] = field(default_factory=list)
    score: float = float("nan")


class GoalStrategy(Protocol):
    """Chooses the next exploration goal. ``replan_period`` [s]: choose again this often while driving (None: only
    when the goal is reached or given up); ``drop_explored``: give up a goal whose frontier has been seen."""

    name: str
    replan_period: float | None
    drop_explored: bool

    def choose(self, ctx: GoalContext) -> GoalChoice | None: ...


def _allowed(segments: list[FrontierSegment], ctx: GoalContext) -> list[FrontierSegment]:
    """Segments restricted to reachable, non-excluded cells; empty ones dropped."""
    out = []
    for seg in keep_reachable(segments, ctx.distance):
        keep = ~ctx.excluded[seg.cells[:, 0], seg.cells[:, 1]]
        if keep.any():
            out.append(seg.subset(keep))
    return out


def _nearest_cell(seg: FrontierSegment, ctx: GoalContext) -> tuple[tuple[int, int], float]:
    d = ctx.distance[seg.cells[:, 0], seg.cells[:, 1]]
    i = int(np.argmin(d))
    return (int(seg.cells[i, 0]), int(seg.cells[i, 1])), float(d[i])


class Nearest:
    """Yamauchi (1997): nearest frontier, its closest point."""

    name = "nearest"
    replan_period: float | None = None
    drop_explored = False

    def choose(self, ctx: GoalContext) -> GoalChoice | None:
        segs = _allowed(smoothed_frontiers(ctx.grid, ctx.resolution, ctx.robot_radius), ctx)
        if not segs:
            return None
        best = min(segs, key=lambda s: _nearest_cell(s, ctx)[1])
        cell, d = _nearest_cell(best, ctx)
        return GoalChoice(cell, best, segs, -d)


class LargestClosest:
    """Largest frontier, its closest point."""

    name = "largest_closest"
    replan_period: float | None = None
    drop_explored = False

    def choose(self, ctx: GoalContext) -> GoalChoice | None:
        segs = _allowed(smoothed_frontiers(ctx.grid, ctx.resolution, ctx.robot_radius), ctx)
        if not segs:
            return None
        best = max(segs, key=lambda s: s.size)
        return GoalChoice(_nearest_cell(best, ctx)[0], best, segs, float(best.size))


class LargestRandom:
    """Largest frontier, a random reachable point of it (the thesis's best)."""

    name = "largest_random"
    replan_period: float | None = None
    drop_explored = False
    smooth = True

    def choose(self, ctx: GoalContext) -> GoalChoice | None:
        if self.smooth:
            raw = smoothed_frontiers(ctx.grid, ctx.resolution, ctx.robot_radius)
        else:
            raw = raw_frontiers(ctx.grid, ctx.resolution)
        segs = _allowed(raw, ctx)
        if not segs:
            return None
        best = max(segs, key=lambda s: s.size)
        r, c = best.cells[int(ctx.rng.integers(len(best.cells)))]
        return GoalChoice((int(r), int(c)), best, segs, float(best.size))


class LargestRandomRaw(LargestRandom):
    """Largest frontier, a random point, without smoothing (the thesis's pre-smoothing variant)."""

    name = "largest_random_raw"
    smooth = False


class ExploreLite:
    """explore_lite's frontier search and cost (see module doc)."""

    name = "explore_lite"
    replan_period: float | None = 1.0 / 0.33  # [s] its launch file's planner_frequency 0.33 Hz
    drop_explored = False
    ends_without_goal = True  # its published behaviour: no frontier of its own kind left ends it ("ends early")

    def __init__(
        self,
        potential_scale: float = POTENTIAL_SCALE,
        gain_scale: float = GAIN_SCALE,
        min_frontier_size: float = MIN_FRONTIER_SIZE,
    ) -> None:
        self.potential_scale = potential_scale
        self.gain_scale = gain_scale
        self.min_frontier_size = min_frontier_size

    def frontiers(self, ctx: GoalContext, min_size: float | None = None) -> list[FrontierSegment]:
        """Unknown cells 4-adjacent to a free cell the robot can reach, grouped 8-connected, ≥ ``min_size`` [m]
        (default ``min_frontier_size``)."""
        min_size = self.min_frontier_size if min_size is None else min_size
        cand = _bordering(ctx.grid, (ctx.grid == FREE) & np.isfinite(ctx.distance))
        n, labels = cv2.connectedComponents(cand.astype(np.uint8), connectivity=8)
        # The labelled cells are the candidates: np.nonzero's row-major (row, col), from the flat indices (a 2-D
        # nonzero over a floor costs ten times the 1-D one).
        rows, cols = np.divmod(np.flatnonzero(cand), cand.shape[1])
        lab = labels[rows, cols]
        order = np.argsort(lab, kind="stable")
        rows, cols, lab = rows[order], cols[order], lab[order]
        splits = np.flatnonzero(np.diff(lab)) + 1
        out: list[FrontierSegment] = []
        for r, c in zip(np.split(rows, splits), np.split(cols, splits), strict=False):
            if len(r) and len(r) * ctx.resolution >= min_size:
                out.append(FrontierSegment(np.column_stack([r, c]).astype(np.int64), len(out)))
        return out

    def costs(self, ctx: GoalContext, segs: list[FrontierSegment]) -> list[float]:
        """explore_lite's frontierCost for each segment (lower is better)."""
        rr, rc = ctx.robot_cell
        res = ctx.resolution
        costs = []
        for s in segs:
            min_distance = float(np.min(np.hypot(s.cells[:, 0] - rr, s.cells[:, 1] - rc))) * res  # [m]
            costs.append(self.potential_scale * min_distance * res - self.gain_scale * s.size * res)
        return costs

    def choose(self, ctx: GoalContext) -> GoalChoice | None:
        return self._choose(ctx, self.min_frontier_size)

    def _choose(self, ctx: GoalContext, min_size: float) -> GoalChoice | None:
        segs = self.frontiers(ctx, min_size)
        if not segs:
            return None
        costs = self.costs(ctx, segs)
        free = _goal_cells(ctx)
        for i in np.argsort(costs, kind="stable"):
            if not math.isfinite(costs[int(i)]):
                break  # the rest cannot be reached either
            cell = _centroid_goal(segs[int(i)], ctx, free)
            if cell is not None:
                return GoalChoice(cell, segs[int(i)], segs, -float(costs[int(i)]))
        return None


def _bordering(grid: np.ndarray, free: np.ndarray) -> np.ndarray:
    """(H, W) bool: explore_lite's frontier cells, the unknown cells of ``grid`` 4-adjacent to a ``free`` cell."""
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)
    return (grid == UNKNOWN) & cv2.dilate(free.astype(np.uint8), cross).astype(bool)


def _goal_cells(ctx: GoalContext) -> np.ndarray:
    """(H, W) bool: the cells a goal may be moved to, reachable and not excluded."""
    return np.isfinite(ctx.distance) & ~ctx.excluded


def robot_room(ctx: GoalContext, doors: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: the reachable cells the robot reaches without passing a door (``doors`` (H, W) bool, by
    default :func:`frontier_tour.door_cells` of the grid); a robot standing in a door is in the rooms on both
    sides."""
    reach = np.isfinite(ctx.distance)
    if doors is None:
        doors = frontier_tour.door_cells(ctx.grid, ctx.resolution)
    doors = doors & reach
    r, c = int(round(ctx.robot_cell[0])), int(round(ctx.robot_cell[1]))
    h, w = reach.shape
    r, c = min(max(r, 0), h - 1), min(max(c, 0), w - 1)
    _, labels = cv2.connectedComponents((reach & ~doors).astype(np.uint8), connectivity=8)
    if not doors[r, c]:
        keep = {int(labels[r, c])} - {0}
    else:
        _, dl = cv2.connectedComponents(doors.astype(np.uint8), connectivity=8)
        blob = cv2.dilate((dl == dl[r, c]).astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        keep = set(np.unique(labels[blob]).tolist()) - {0}
    if not keep:
        return np.zeros_like(reach)
    chosen = np.zeros(int(labels.max()) + 1, bool)  # a lookup by label: no sort of the whole floor's labels
    chosen[list(keep)] = True
    return chosen[labels]


def _centroid_goal(seg: FrontierSegment, ctx: GoalContext, free: np.ndarray) -> tuple[int, int] | None:
    """explore_lite's goal for a segment: its centroid, moved to the nearest of the ``free`` (H, W) cells within
    ``CENTROID_TOLERANCE`` (the first in row-major order of those as near); None when the centroid is excluded
    or no such cell is near (move_base would abort it and explore_lite blacklist it). Only the cells within the
    tolerance's square round the centroid are looked at, not the whole floor."""
    cr, cc = seg.centroid()
    if ctx.excluded[int(round(cr)), int(round(cc))]:
        return None
    t = CENTROID_TOLERANCE / ctx.resolution
    h, w = free.shape
    r0, r1 = max(int(math.floor(cr - t)), 0), min(int(math.ceil(cr + t)) + 1, h)
    c0, c1 = max(int(math.floor(cc - t)), 0), min(int(math.ceil(cc + t)) + 1, w)
    near = np.argwhere(free[r0:r1, c0:c1])
    if not len(near):
        return None
    d2 = (near[:, 0] + r0 - cr) ** 2 + (near[:, 1] + c0 - cc) ** 2
    j = int(np.argmin(d2))
    if math.sqrt(float(d2[j])) * ctx.resolution > CENTROID_TOLERANCE:
        return None
    return int(near[j, 0]) + r0, int(near[j, 1]) + c0


def _frontier_goal(seg: FrontierSegment, ctx: GoalContext, free: np.ndarray) -> tuple[int, int] | None:
    """frontier_travel's goal for a segment: explore_lite's (:func:`_centroid_goal`) when it has one; else, when
    the centroid is off the frontier and no reachable cell is near it — a frontier curved round a patch of
    unknown in the middle of a hall, seen from every side, has its centroid in the patch, metres from any free
    cell, and explore_lite never sends the robot to it — the segment's own cell nearest its centroid, moved to
    the nearest of the ``free`` cells in the same way. None when that too has none (or the centroid is
    excluded: the robot stands at it)."""
    cell = _centroid_goal(seg, ctx, free)
    if cell is not None:
        return cell
    cr, cc = seg.centroid()
    if ctx.excluded[int(round(cr)), int(round(cc))]:
        return None
    j = int(np.argmin((seg.cells[:, 0] - cr) ** 2 + (seg.cells[:, 1] - cc) ** 2))
    return _centroid_goal(FrontierSegment(seg.cells[j : j + 1], seg.label), ctx, free)


class FrontierTravel(ExploreLite):
    """explore_lite's frontiers and centroid goals, visited in the order of the shortest tour (see module doc)."""

    name = "frontier_travel"
    ends_without_goal = False  # homing's rule: the map decides when it is done (homing.mapping.explorer)
    drop_explored = True  # a goal whose frontier the lidar has seen is left at once, not at the next replan

    def __init__(self, min_frontier_size: float = MIN_FRONTIER_SIZE, crumb_size: float = CRUMB_SIZE,
                 long_frontier: float = LONG_FRONTIER) -> None:
        super().__init__(min_frontier_size=min_frontier_size)
        self.crumb_size = crumb_size
        self.long_frontier = long_frontier
        self.tour: list[tuple[int, int]] = []  # the goals in the order of the last tour planned (for pictures)
        self.doors = frontier_tour.Doors()  # the map's doors, kept up to date round what changed

    def goals(self, ctx: GoalContext, doors: np.ndarray | None = None) -> list[tuple[FrontierSegment, tuple[int, int]]]:
        """The frontiers to tour with their goals: those at least ``long_frontier`` long and the shorter ones in the
        robot's room (``doors`` (H, W) bool: the grid's doors, else found here); when none is left, every one of
        explore_lite's minimum size, with the ones down to ``crumb_size`` the robot reaches before the nearest of
        them (:meth:`_crumbs_before`); then those down to ``crumb_size`` (rather than stop short of the whole map:
        explore_lite's "ends early"); then, when none of those has a goal by explore_lite's rule, the ones down to
        ``crumb_size`` with their goals by :func:`_frontier_goal`."""
        free = _goal_cells(ctx)
        for size in (self.min_frontier_size, self.crumb_size):
            out = []
            for seg in self.frontiers(ctx, size):
                cell = _centroid_goal(seg, ctx, free)
                if cell is not None:
                    out.append((seg, cell))
            if out and size == self.min_frontier_size:
                room: np.ndarray | None = None
                first = []
                for seg, cell in out:
                    if seg.size * ctx.resolution < self.long_frontier:
                        if room is None:
                            room = robot_room(ctx, doors)
                        if not room[cell]:
                            continue
                    first.append((seg, cell))
                if first:
                    return first
                return out + self._crumbs_before(ctx, out, free)
            if out:
                return out
        # No frontier has a goal by explore_lite's rule: those whose centroids lie deep in unknown get one on
        # themselves (:func:`_frontier_goal`), rather than leave the map's check to say done round them.
        out = []
        for seg in self.frontiers(ctx, self.crumb_size):
            cell = _frontier_goal(seg, ctx, free)
            if cell is not None:
                out.append((seg, cell))
        return out

    def _crumbs_before(self, ctx: GoalContext, goals: list[tuple[FrontierSegment, tuple[int, int]]],
                       free: np.ndarray) -> list[tuple[FrontierSegment, tuple[int, int]]]:
        """The frontiers shorter than explore_lite's minimum (down to ``crumb_size``) whose goals are nearer the
        robot (by path) than the nearest of ``goals``: every one is visited before "done" anyway, and one passed
        now costs less than a trip across the building and back for it later (a door seen at a grazing angle
        shows a short frontier, and the room behind it may be large)."""
        near = min(float(ctx.distance[cell]) for _, cell in goals)
        out = []
        for seg in self.frontiers(ctx, self.crumb_size):
            if seg.size * ctx.resolution >= self.min_frontier_size:
                continue
            cell = _centroid_goal(seg, ctx, free)
            if cell is not None and float(ctx.distance[cell]) < near:
                out.append((seg, cell))
        return out

    def choose(self, ctx: GoalContext) -> GoalChoice | None:
        doors = self.doors(ctx.grid, ctx.resolution)
        goals = self.goals(ctx, doors)
        if not goals:
            self.tour = []
            return None
        cells = np.array([c for _, c in goals], np.int64)
        start = ctx.distance[cells[:, 0], cells[:, 1]]
        current = None
        if ctx.current_goal is not None:
            # The frontier driven to is the one passing nearest the current goal (its centroid, and so its goal,
            # shifts as the lidar sees more of it; the frontier itself stays where it was, or recedes).
            g = ctx.current_goal
            near = [float(np.min(np.hypot(seg.cells[:, 0] - g[0], seg.cells[:, 1] - g[1]))) for seg, _ in goals]
            if min(near) * ctx.resolution <= SAME_FRONTIER:
                current = int(np.argmin(near))
        robot = (int(round(ctx.robot_cell[0])), int(round(ctx.robot_cell[1])))
        lengths = np.array([seg.size * ctx.resolution for seg, _ in goals])
        order = frontier_tour.plan(robot, ctx.grid, ctx.resolution, np.isfinite(ctx.distance), cells, start, current,
                                   lengths, doors)
        self.tour = [goals[i][1] for i in order]
        seg, cell = goals[order[0]]
        return GoalChoice(cell, seg, [s for s, _ in goals], -float(start[order[0]]))

    def goal_spent(self, grid: np.ndarray, resolution: float, cell: tuple[int, int]) -> bool:
        """True when no frontier cell (unknown, 4-adjacent to free) is left within ``SAME_FRONTIER`` of the goal
        ``cell``: the lidar has seen what the robot was going to look at, so the next goal is chosen now rather
        than at the next replan (the robot would drive on towards a spent goal for up to ``replan_period``)."""
        k = int(math.ceil(SAME_FRONTIER / resolution))
        r, c = cell
        r0, c0 = max(r - k, 0), max(c - k, 0)
        patch = grid[r0 : r + k + 1, c0 : c + k + 1]
        rows, cols = np.nonzero(_bordering(patch, patch == FREE))
        return not bool(((rows + r0 - r) ** 2 + (cols + c0 - c) ** 2 <= k * k).any())


def unknown_gain(grid: np.ndarray, resolution: float, radius: float = GAIN_RADIUS) -> np.ndarray:
    """(H, W) float32 unknown area [m²] within ``radius`` [m] of every cell (pooled by GAIN_POOL for speed)."""
    h, w = grid.shape
    unknown = (grid == UNKNOWN).astype(np.float32)
    small = cv2.resize(unknown, (max(1, w // GAIN_POOL), max(1, h // GAIN_POOL)), interpolation=cv2.INTER_AREA)
    r = radius / (resolution * GAIN_POOL)
    k = int(math.ceil(r))
    yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
    disc = (xx * xx + yy * yy <= r * r).astype(np.float32)
    area = cv2.filter2D(small, -1, disc, borderType=cv2.BORDER_CONSTANT) * (resolution * GAIN_POOL) ** 2
    return cv2.resize(area, (w, h), interpolation=cv2.INTER_LINEAR)


def visible_unknown(grid: np.ndarray, resolution: float, cells: np.ndarray, radius: float = GAIN_RADIUS,
                    rays: int = GAIN_RAYS) -> np.ndarray:
    """(N,) unknown area [m²] a sensor at each of ``cells`` (N, 2) (row, col) would see within ``radius`` [m].

    ``rays`` rays per cell, sampled every cell; a ray stops at the first wall
    (unknown cells are taken as transparent, the optimistic guess). Each
    sample stands for the annulus sector it sits in (r·dθ·dr), so the sum is an
    area. Unlike :func:`unknown_gain`, unknown space behind a mapped wall (the
    outside of a building) counts for nothing.
    """
    n_s = max(1, int(radius / resolution))
    r = (np.arange(n_s) + 0.5) * resolution  # (S,) [m]
    a = np.arange(rays) * (2 * np.pi / rays)
    dr = np.cos(a)[:, None] * r[None, :] / resolution  # (A, S) [cells]
    dc = np.sin(a)[:, None] * r[None, :] / resolution
    # Off the grid reads as wall: pad by the reach, then gather through flat indices (no bounds checks).
    pad = n_s + 1
    padded = np.pad(grid, pad, constant_values=OCCUPIED_AT)
    # floor(x + 0.5), not rint: rint rounds halves to even, so an axis-aligned ray (samples at k + 0.5 cells)
    # would skip every odd cell and see through a one-cell wall.
    rows = np.floor(cells[:, 0, None, None] + dr[None] + 0.5).astype(np.int64) + pad  # (N, A, S)
    cols = np.floor(cells[:, 1, None, None] + dc[None] + 0.5).astype(np.int64) + pad
    v = padded.ravel()[rows * padded.shape[1] + cols]
    open_ray = np.logical_and.accumulate(v < OCCUPIED_AT, axis=2)
    seen = open_ray & (v == UNKNOWN)
    return (seen * (r * (2 * np.pi / rays) * resolution)[None, None, :]).sum(axis=(1, 2))


def viewpoints(ctx: GoalContext, frontier: np.ndarray) -> np.ndarray:
    """(K, 2) reachable, non-excluded free cells on a ``SETBACK_STRIDE`` lattice within ``SETBACK`` [m] of the
    ``frontier`` cells (N, 2): goals from which the lidar sees a frontier's unknown without driving to its edge."""
    h, w = ctx.grid.shape
    mark = np.full((h, w), 255, np.uint8)
    mark[frontier[:, 0], frontier[:, 1]] = 0
    near = cv2.distanceTransform(mark, cv2.DIST_L2, 3) * ctx.resolution <= SETBACK
    stride = max(1, int(round(SETBACK_STRIDE / ctx.resolution)))
    lattice = np.zeros((h, w), bool)
    lattice[::stride, ::stride] = True
    ok = near & lattice & np.isfinite(ctx.distance) & ~ctx.excluded & (ctx.grid == FREE)
    return np.argwhere(ok).astype(np.int64)


def _wall_gap(grid: np.ndarray, resolution: float, robot_radius: float) -> np.ndarray:
    """(H, W) float32 [m]: distance from each cell to the nearest wall cell, less the robot's radius."""
    occ = (grid >= OCCUPIED_AT).astype(np.uint8)
    if not occ.any():
        return np.full(grid.shape, np.inf, np.float32)
    d = distance_cells(1 - occ) * resolution
    return d - robot_radius


class GainRate:
    """Information gain per travel time (see module doc)."""

    name = "gain_rate"
    replan_period: float | None = 2.0  # [s]
    drop_explored = True

    def __init__(self) -> None:
        self._spent_below = MIN_GAIN  # [m²] the current goal is given up when it would reveal less

    def choose(self, ctx: GoalContext) -> GoalChoice | None:
        segs = _allowed(smoothed_frontiers(ctx.grid, ctx.resolution, ctx.robot_radius), ctx)
        if not segs:
            return None
        self._gap = _wall_gap(ctx.grid, ctx.resolution, ctx.robot_radius)
        cells, owners = [], []
        for k, s in enumerate(segs):
            step = max(1, len(s.cells) // MAX_CANDIDATES)
            cells.append(s.cells[::step])
            owners.append(np.full(len(cells[-1]), k))
        cand = np.concatenate(cells)
        owner = np.concatenate(owners)
        back = viewpoints(ctx, cand)
        if len(back):
            # Each set-back viewpoint belongs to the segment of its nearest frontier cell (for pictures).
            near = np.argmin((back[:, None, 0] - cand[None, :, 0]) ** 2 + (back[:, None, 1] - cand[None, :, 1]) ** 2,
                             axis=1)
            cand, owner = np.concatenate([cand, back]), np.concatenate([owner, owner[near]])
        if len(cand) > VIEW_CANDIDATES:
            keep = np.linspace(0, len(cand) - 1, VIEW_CANDIDATES).astype(np.int64)
            cand, owner = cand[keep], owner[keep]
        gain = visible_unknown(ctx.grid, ctx.resolution, cand, VIEW_RADIUS, VIEW_RAYS)
        score = np.where(gain >= MIN_GAIN, self._score(ctx, cand, gain), -np.inf)
        if not np.isfinite(score).any():
            # Only crumbs left: still visit those the lidar would clear (quitting short of the whole map is
            # explore_lite's "ends early"), but never ones it cannot see into.
            score = np.where(gain >= CRUMB_GAIN, self._score(ctx, cand, gain), -np.inf)
        i = int(np.argmax(score))
        if not np.isfinite(score[i]):
            return None  # nothing the lidar could still reveal: exploration is over
        best, best_score = (int(cand[i, 0]), int(cand[i, 1])), float(score[i])
        if ctx.current_goal is not None:
            cur = np.array([ctx.current_goal])
            cur_gain = visible_unknown(ctx.grid, ctx.resolution, cur, VIEW_RADIUS, VIEW_RAYS)
            cur_score = float(self._score(ctx, cur, cur_gain)[0])
            if cur_gain[0] >= self._spent_below and np.isfinite(cur_score) and best_score < HYSTERESIS * cur_score:
                d2 = (cand[:, 0] - cur[0, 0]) ** 2 + (cand[:, 1] - cur[0, 1]) ** 2
                return GoalChoice(ctx.current_goal, segs[int(owner[int(np.argmin(d2))])], segs, cur_score)
        self._spent_below = min(MIN_GAIN, 0.5 * float(gain[i]))
        return GoalChoice(best, segs[int(owner[i])], segs, best_score)

    def goal_spent(self, grid: np.ndarray, resolution: float, cell: tuple[int, int]) -> bool:
        """True when the lidar would see less than ``MIN_GAIN`` of unknown from ``cell`` (half the gain it was chosen
        for, if that was a crumb): give the goal up and go on to the next before arriving (lookahead)."""
        gain = visible_unknown(grid, resolution, np.array([cell]), VIEW_RADIUS, VIEW_RAYS)[0]
        return bool(gain < self._spent_below)

    def _score(self, ctx: GoalContext, cells: np.ndarray, gain: np.ndarray) -> np.ndarray:
        """gain (N,) [m²] of ``cells`` (N, 2) over the estimated time to get there [s]."""
        d = ctx.distance[cells[:, 0], cells[:, 1]]
        bearing = np.arctan2(cells[:, 0] - ctx.robot_cell[0], cells[:, 1] - ctx.robot_cell[1])
        turn = np.abs(np.arctan2(np.sin(bearing - ctx.robot_heading), np.cos(bearing - ctx.robot_heading)))
        gap = self._gap[cells[:, 0], cells[:, 1]]
        v_end = np.clip(NAV_MAX_V * gap / SLOW_GAP, SLOW_SPEED, TRAVEL_SPEED)
        crawl = np.minimum(d, SLOW_STRETCH) * (1.0 / v_end - 1.0 / TRAVEL_SPEED)
        time = d / TRAVEL_SPEED + turn / TURN_RATE + FIXED_OVERHEAD + crawl
        return np.where(np.isfinite(d), gain / time, -np.inf)


STRATEGIES: dict[str, type] = {
    cls.name: cls
    for cls in (Nearest, LargestClosest, LargestRandom, LargestRandomRaw, ExploreLite, FrontierTravel, GainRate)
}
DEFAULT_STRATEGY = "frontier_travel"


def make_strategy(name: str, **params: object) -> GoalStrategy:
    """The strategy registered under ``name`` (KeyError lists the names)."""
    if name not in STRATEGIES:
        raise KeyError(f"unknown strategy '{name}' (known: {', '.join(sorted(STRATEGIES))})")
    return STRATEGIES[name](**params)  # type: ignore[no-any-return]
