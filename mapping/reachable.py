"""Which frontiers the robot could reach on the map itself, and the report exploration ends with ("done" means done).

A strategy sees frontiers through the navigator's costmap: inflation around
the robot in a doorway, a transient obstacle or a momentary localisation
error can cut the robot off in a pocket, and a strategy that then finds no
goal would call the building explored (explore_lite's best-known failure,
m-explore #26, #68). This module asks the map alone:

1. where the robot's centre fits: known-free cells farther than the
   inscribed radius from every wall cell (:mod:`homing.mapping.navigable`,
   the costmap's own rule; unknown space does not block: the robot may
   stand beside it), and, on the robot's trail (the cells its centre has
   occupied), farther than the footprint's radius (:func:`fits_on_trail`:
   the way back through a door the map redrew a cell narrower);
2. the part of it the robot is in: the 8-connected components of (1) within
   ``SEED_RADIUS`` of the robot (so a robot standing in inflation, or
   slightly mislocalised, still counts as in the room it is in), else the
   component nearest to it;
3. **reachable frontiers**: cells of (2) 8-adjacent to unknown space of at
   least ``MIN_UNKNOWN`` (a map's pinholes are not frontiers), grouped
   8-connected, ``MIN_SITE`` long or more, from which the lidar would see at
   least ``MIN_VIEW`` of unknown space (rays stopped by mapped walls:
   :func:`homing.mapping.strategies.visible_unknown`) — so the unknown inside
   a desk whose corner the lidar never outlined, walled in on every other
   side, is not a frontier: places the robot can stand next to the unknown
   and see into it;
4. **narrow frontiers**: known-free cells 8-adjacent to such unknown space
   that no cell of (2) comes within the footprint's radius (plus a cell) of,
   grouped the same way: unknown seen only through a gap narrower than the
   robot (explore_lite #40, #52), given up at once and reported, never
   retried — but only when walls make the gap narrow. A door the lidar saw
   only at a grazing angle from the corridor is a sliver of known free
   cells along one jamb with unknown beside it: the footprint does not fit
   in what is known of it, yet it would if the unknown were free. Such a
   frontier — near where the robot would fit, reckoning unknown cells free
   and walls alone as walls — is a **peek** site, reachable: the robot goes
   to stand in front of it (within ``PEEK`` of it) and looks. Measured on
   ``office:6`` seed 1 (bench explore, frontier_travel): a 0.9 m door seen
   only from the corridor's far end was reported narrower than the robot,
   and the room behind it, 19 m², was never entered (coverage 0.947).
   A peek site the robot's centre reaches from (2) only across more than
   ``THROUGH`` of unknown space (known free cells cost nothing on the way,
   walls are impassable: :func:`unknown_way`, then on to where its edge
   touches the site, not through a wall or a crack between wall cells:
   :func:`within_reach`) is **seen through a wall**,
   given up at once and reported with that length, never visited: free cells
   the lidar saw through a crack in an outer wall (a ray slipping between
   wall cells), which the map joins to the robot's room only round the
   outside of the building. A door seen from the side is a few cells of
   unknown away. Measured on ``office:1`` seed 0 (bench explore,
   frontier_travel): 11 of the 17 places given up as ``not_cleared``, and
   about 140 s of the run, lay outside the building. Unless the map holds
   a way in to it through known free cells farther than ``CRACK`` from every
   wall cell (:func:`gapped`), a gap the lidar saw it through, narrower than
   the robot (else the site would be reachable): it is then a narrow
   frontier, its way in measured where the lidar saw it — a reason a person
   can check. The lab's room behind a door left ajar 0.28 m (persistent
   mission, seed 1) was said to be seen through a wall (more than 3 m of
   unknown to it), its gap in the map; a crack a ray slipped through leaves
   free cells with a wall cell beside each, and its free cells beyond stay
   seen through a wall;
5. the robot's own coverage estimate: known free area over known free area
   plus what is still unseen behind every frontier left (reachable, given up,
   narrow or seen through a wall): the unknown area the lidar would see from it within ``VIEW``,
   but no more than the frontier's length times ``VIEW`` (unknown space
   behind an unmapped wall face is not all building). It reads 100 % on a
   closed map.

Grids are map_server views ((H, W) int8, FREE 0 / OCCUPIED 100 / UNKNOWN −1,
row 0 at the lowest y); positions are metres in the ``map`` frame.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import cv2
import numpy as np
from homing.mapping.distance import distance_cells
from homing.mapping.frontier import OCCUPIED_AT
from homing.mapping.grid import OccupancyGrid
from homing.mapping.navigable import cells_by_label, centre_fits, disc, inscribed_radius
from homing.mapping.strategies import VIEW_RAYS, visible_unknown
from homing.robot.turtlebot import FOOTPRINT_RADIUS

from homing.map_server import FREE, UNKNOWN

SEED_RADIUS = 0.6  # [m] fitting cells this close to the robot are where it is (inflation, localisation error)
MIN_UNKNOWN = 0.05  # [m²] unknown pockets smaller than this (pinholes between rays) are not frontiers
MIN_SITE = 0.25  # [m] frontier sites shorter than this are noise
VIEW = 3.0  # [m] unknown this close to an open frontier counts as still to be seen (half the lidar's range)
MIN_VIEW = 0.5  # [m²] unknown area the lidar must be able to see from a site for it to be a frontier
VIEW_SAMPLES = 12  # cells of a site the view is cast from (evenly spaced)
VIEW_BATCH = 256  # cells whose views are cast at once (32 rays × 60 samples each: 0.5 M samples a batch)
PEEK = 0.75  # [m] how far from a peek site the robot may stand to look at it (a door's frame is a wall thick)
THROUGH = 1.0  # [m] unknown space a route to a peek site may cross (a door seen from the side); more: seen through a wall
THROUGH_MEASURED = 3.0  # [m] unknown measured along a route to a peek site at most (the reason says "more than" beyond)
CRACK = 1.0  # [cells] clearance of the free cells a ray slipping between wall cells leaves (a wall cell beside each)


@dataclass(frozen=True)
class FrontierSite:
    """A frontier segment: its centroid (x, y) [m] in ``map``, its length [m], and its cells (N, 2) (row, col)."""

    x: float
    y: float
    length: float
    cells: np.ndarray = field(repr=False, compare=False)
    view: float = 0.0  # [m²] unknown area the lidar would see from its best cell within VIEW
    peek: bool = False  # half seen: the robot looks from up to PEEK away rather than standing on it (module doc)
    unknown: float = 0.0  # [m] a peek site: the unknown space the route to it crosses (inf: more than measured)

    def through_wall(self) -> str:
        """The reason a peek site is given up as seen through a wall: how much unknown space the way to it crosses."""
        if math.isfinite(self.unknown):
            return f"seen through a wall ({self.unknown:.1f} m of unknown to it)"
        return f"seen through a wall (more than {THROUGH_MEASURED:.1f} m of unknown to it)"


@dataclass(frozen=True)
class GivenUp:
    """A frontier exploration will not go to, and why: ``narrower_than_robot``, or the explorer's reason for
    blacklisting the place (``no_progress``, ``no_path``, ``cut_off``, …)."""

    x: float
    y: float
    length: float
    reason: str


@dataclass(frozen=True)
class FrontierReport:
    """What the map says is left: frontiers the robot can reach, ones behind gaps narrower than it, and its own
    coverage estimate (fraction, 1.0 when nothing is left to see)."""

    reachable: tuple[FrontierSite, ...]
    narrow: tuple[FrontierSite, ...]
    coverage_estimate: float
    free_area: float  # [m²]
    left: int = -1  # reachable frontiers not given up (-1: not counted yet, all of ``reachable``)
    walled: tuple[FrontierSite, ...] = ()  # peek sites seen through a wall: more than THROUGH of unknown on the way
    unseen_reach: float = 0.0  # [m²] the unseen area the estimate counts behind reachable sites ...
    unseen_beyond: float = 0.0  # [m²] ... and behind narrow and walled ones

    @property
    def open(self) -> int:
        """Reachable frontiers still to go to (those the explorer has not given up)."""
        return len(self.reachable) if self.left < 0 else self.left

    def given_up(self, left: int) -> FrontierReport:
        """The same report, knowing that only ``left`` of the reachable frontiers are still open."""
        return dataclasses.replace(self, left=left)

    def summary(self, given_up: tuple[GivenUp, ...] = ()) -> str:
        """One line for a log or a feedback message."""
        gone = [*(GivenUp(s.x, s.y, s.length, "narrower_than_robot") for s in self.narrow),
                *(GivenUp(s.x, s.y, s.length, s.through_wall()) for s in self.walled), *given_up]
        text = f"coverage estimate {self.coverage_estimate:.0%} of {self.free_area:.0f} m² free"
        beyond = len(self.narrow) + len(self.walled)
        if beyond and self.unseen_beyond > 0.0 and self.free_area > 0.0:
            # A map with many cracks (a real building's, rays slipped through its walls) reads low on the whole;
            # what the robot can reach is the figure a person checks first.
            near = self.free_area / (self.free_area + self.unseen_reach)
            text += (f" ({near:.0%} of what the robot can reach; {self.unseen_beyond:.0f} m² unseen behind "
                     f"{beyond} gap(s) narrower than it or walls)")
        text += f"; {self.open} reachable frontier(s) left"
        if gone:
            text += "; given up: " + ", ".join(f"({g.x:.1f}, {g.y:.1f}) {g.length:.1f} m {g.reason}" for g in gone)
        return text


def clear_of_walls(grid: np.ndarray, resolution: float, robot_radius: float = FOOTPRINT_RADIUS,
                   trail: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: cells where the robot's centre fits between the walls (any state) of ``grid``: the rule the
    costmap and the benchmarks use (:func:`homing.mapping.navigable.centre_fits`); unknown cells do not block.
    ``trail`` (H, W) bool: cells the robot's centre has occupied, where the footprint alone must fit
    (:func:`fits_on_trail`)."""
    fits = centre_fits(grid >= OCCUPIED_AT, resolution, robot_radius)
    if trail is None or not trail.any():
        return fits
    return fits | fits_on_trail(distance_cells(grid < OCCUPIED_AT), resolution, trail, robot_radius)


def fits_on_trail(clearance: np.ndarray, resolution: float, trail: np.ndarray,
                  robot_radius: float = FOOTPRINT_RADIUS) -> np.ndarray:
    """(H, W) bool: the cells of ``trail`` ((H, W) bool, the cells the robot's centre has occupied,
    :mod:`homing.navigation.trail`) whose centre lies farther than the footprint's radius from every wall cell's
    (``clearance`` [cells] to the nearest one). Where the robot has been it fits, so the half cell of padding the
    inscribed radius adds for the walls' rasterisation is not needed there (a 0.5 m door the map drew 8 cells
    wide once the robot was through it: its middle cells clear the jambs' centres by 0.20 m, the footprint
    0.19 m, the inscribed radius 0.215 m); the footprint itself is, so a wall or an obstacle mapped on the trail
    since keeps the robot off it as anywhere else. The costmap's rule on the same cells
    (:class:`homing.navigation.costmap.Costmap`)."""
    return trail & (clearance * resolution > robot_radius)


def robot_region(fits: np.ndarray, robot_cell: tuple[float, float], resolution: float) -> np.ndarray:
    """(H, W) bool: the components of ``fits`` within SEED_RADIUS of ``robot_cell`` (row, col) (fractional), or the
    one nearest to it; all False when nothing fits anywhere."""
    n, labels = cv2.connectedComponents(fits.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros_like(fits)
    h, w = fits.shape
    r, c = robot_cell
    k = int(math.ceil(SEED_RADIUS / resolution))
    r0, r1 = max(int(r) - k, 0), min(int(r) + k + 1, h)
    c0, c1 = max(int(c) - k, 0), min(int(c) + k + 1, w)
    yy, xx = np.mgrid[r0:r1, c0:c1]
    near = (yy - r) ** 2 + (xx - c) ** 2 <= k * k
    seeds = np.unique(labels[r0:r1, c0:c1][near])
    seeds = seeds[seeds > 0]
    if not len(seeds):
        rows, cols = np.nonzero(fits)
        i = int(np.argmin((rows - r) ** 2 + (cols - c) ** 2))
        seeds = np.array([labels[rows[i], cols[i]]])
    return np.isin(labels, seeds)


def _open_unknown(grid: np.ndarray, resolution: float) -> np.ndarray:
    """(H, W) bool: unknown cells in 8-connected unknown regions of at least MIN_UNKNOWN."""
    unknown = (grid == UNKNOWN).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(unknown, connectivity=8)
    big = stats[:, cv2.CC_STAT_AREA] * resolution**2 >= MIN_UNKNOWN
    big[0] = False
    return big[labels]


def _sites(mask: np.ndarray, grid: OccupancyGrid, peek: bool = False) -> list[FrontierSite]:
    """The 8-connected components of ``mask`` at least ``MIN_SITE`` long from which the lidar would see at least
    ``MIN_VIEW`` of unknown (:func:`visible_unknown` from up to 2 × ``VIEW_SAMPLES`` of their cells), as sites.

    Work in the number of cells, not components × grid: a real building's map has hundreds of sites (every crack
    a ray slipped through makes one; ACES' corrected log at 5 cm), and a pass over the grid for each one cost
    2.9 s a call there. The cells are grouped by component in one sort (stable, so each component's cells are in
    the grid's row-major order, as a scan of the grid gives them), and the views of all the sites' samples are
    cast in batches of ``VIEW_BATCH`` cells."""
    n, labels = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return []
    w = labels.shape[1]
    parts = [(idx // w, idx % w) for idx in cells_by_label(labels, list(range(1, n)))
             if len(idx) * grid.resolution >= MIN_SITE]
    samples = []
    for r, c in parts:
        step = max(1, len(r) // VIEW_SAMPLES)
        samples.append(np.column_stack([r[::step], c[::step]]).astype(np.int64))
    if not samples:
        return []
    cells = np.concatenate(samples)
    views = np.concatenate([visible_unknown(grid.data, grid.resolution, cells[i:i + VIEW_BATCH], VIEW, VIEW_RAYS)
                            for i in range(0, len(cells), VIEW_BATCH)])
    out = []
    start = 0
    for (r, c), sample in zip(parts, samples, strict=True):
        view = float(views[start:start + len(sample)].max())
        start += len(sample)
        if view < MIN_VIEW:
            continue  # walled in: nothing the lidar could see from here
        x, y = grid.cell_to_world(float(r.mean()), float(c.mean()))
        out.append(FrontierSite(float(x), float(y), len(r) * grid.resolution,
                                np.column_stack([r, c]).astype(np.int64), view, peek))
    return out


def frontier_report(grid: OccupancyGrid, robot_xy: tuple[float, float],
                    robot_radius: float = FOOTPRINT_RADIUS, trail: np.ndarray | None = None) -> FrontierReport:
    """The map's frontiers split into reachable and narrow (module doc), and the coverage estimate.
    ``robot_xy`` [m] in ``map``; ``trail`` (H, W) bool on ``grid``'s cells: where the robot's centre has been,
    places it fits with the footprint alone (:func:`fits_on_trail`)."""
    g, res = grid.data, grid.resolution
    r = (robot_xy[1] - grid.origin[1]) / res - 0.5
    c = (robot_xy[0] - grid.origin[0]) / res - 0.5
    clearance = distance_cells(g < OCCUPIED_AT)  # [cells] to the nearest wall cell
    clear = clearance * res > inscribed_radius(res, robot_radius)  # clear_of_walls, from the same transform
    if trail is not None:
        clear |= fits_on_trail(clearance, res, trail, robot_radius)
    region = robot_region((g == FREE) & clear, (r, c), res)
    reach_disc = disc(robot_radius / res + 1.0)
    unknown = _open_unknown(g, res)
    beside_unknown = cv2.dilate(unknown.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    reach_front = region & beside_unknown
    near_region = cv2.dilate(region.astype(np.uint8), reach_disc).astype(bool)
    out_of_reach = (g == FREE) & beside_unknown & ~near_region
    # Narrow only if walls make it so: where the footprint would fit with the unknown taken as free, it is a door
    # half seen (a peek site), not a gap narrower than the robot.
    hopeful = robot_region(((g == FREE) | (g == UNKNOWN)) & clear, (r, c), res) & (g == UNKNOWN)
    near_hopeful = cv2.dilate(hopeful.astype(np.uint8), reach_disc).astype(bool)
    peek = out_of_reach & near_hopeful
    peeks = _sites(peek, grid, peek=True)
    if peeks:
        way = unknown_way(g, res, region, ~(clear & ((g == FREE) | (g == UNKNOWN))), THROUGH_MEASURED)
        near_way = within_reach(way, g, res, robot_radius / res + 1.0)
        peeks = [dataclasses.replace(s, unknown=float(near_way[s.cells[:, 0], s.cells[:, 1]].min())) for s in peeks]
    walled = [s for s in peeks if not s.unknown <= THROUGH]
    reachable = _sites(reach_front, grid) + [s for s in peeks if s.unknown <= THROUGH]
    narrow = _sites(out_of_reach & ~near_hopeful, grid)
    if walled:
        # Walled, but joined to the robot's room through a gap the map drew (a way in through known free cells
        # clearer of walls than a crack): narrow, its way in measured where the lidar saw it.
        gap = gapped(g, clearance, region)
        narrow += [dataclasses.replace(s, peek=False) for s in walled if gap[s.cells[:, 0], s.cells[:, 1]].any()]
        walled = [s for s in walled if not gap[s.cells[:, 0], s.cells[:, 1]].any()]
    free_area = float((g == FREE).sum()) * res**2
    reach = sum(min(s.view, s.length * VIEW) for s in reachable)  # [m²]
    beyond = sum(min(s.view, s.length * VIEW) for s in (*narrow, *walled))
    estimate = free_area / (free_area + reach + beyond) if free_area > 0 else 0.0
    return FrontierReport(tuple(reachable), tuple(narrow), estimate, free_area, walled=tuple(walled),
                          unseen_reach=reach, unseen_beyond=beyond)


def gapped(grid: np.ndarray, clearance: np.ndarray, region: np.ndarray) -> np.ndarray:
    """(H, W) bool: the known free cells joined to ``region`` (8-connected) through known free cells farther than
    ``CRACK`` from every wall cell (``clearance`` [cells] to the nearest one): the places a way in the map drew
    leads to, however narrow, and not one a lidar ray slipping through a crack between wall cells made (its free
    cells touch a wall cell each side). The narrowest of such a way is what :func:`homing.mapping.navigable.ways_in`
    measures (``known``: the map's free cells). Cost: one labelling of the grid."""
    known = (grid == FREE) & (clearance > CRACK)
    _, labels = cv2.connectedComponents(known.astype(np.uint8), connectivity=8)
    joined = np.zeros(int(labels.max()) + 1, bool)
    joined[labels[region]] = True
    joined[0] = False
    return joined[labels]


def unknown_way(grid: np.ndarray, resolution: float, region: np.ndarray, blocked: np.ndarray,
                limit: float) -> np.ndarray:
    """(H, W) float32: the least unknown space [m] a route of the robot's centre from ``region`` to each cell
    crosses, up to ``limit`` (inf beyond, or never reached). The centre goes where ``blocked`` is False (walls and
    the cells too near them); a known free cell costs nothing, an unknown one its length (a cell, 8-connected).
    Known free space joined to the route only through unknown is entered at the unknown's cost, then costs nothing
    again.

    A breadth-first search a cell of unknown a step, from the cells each step added (the older ones' neighbours
    are all reached already, or walls): its work is the cells it reaches, not the grid once a step — on a large
    map (Edmonton's log, 1847 × 1687 cells) 60 whole-grid dilations took 1.4 s a call."""
    h, w = grid.shape
    # Flat indices into the grid with a blocked border a cell wide: a neighbour is an offset, never out of bounds.
    passable = np.pad(~blocked, 1, constant_values=False).ravel()
    g = np.pad(grid, 1, constant_values=UNKNOWN).ravel()
    free = passable & (g == FREE)
    unknown = passable & (g == UNKNOWN)
    _, labels = cv2.connectedComponents(free.reshape(h + 2, w + 2).astype(np.uint8), connectivity=8)
    labels = labels.ravel()
    way = np.full(g.shape, np.inf, np.float32)
    reached = np.pad(region, 1, constant_values=False).ravel() & passable
    way[reached] = 0.0
    offsets = np.array([dr * (w + 2) + dc for dr in (-1, 0, 1) for dc in (-1, 0, 1) if dr or dc])
    # The cells whose neighbours are still to be looked at: to begin with, those of the region on its edge.
    inner = cv2.erode(reached.reshape(h + 2, w + 2).astype(np.uint8), np.ones((3, 3), np.uint8),
                      borderValue=1).astype(bool).ravel()
    new = np.flatnonzero(reached & ~inner)
    joined = np.zeros(int(labels.max()) + 1, bool)

    def beyond(cells: np.ndarray) -> np.ndarray:
        """The neighbours of ``cells`` not reached yet, each once."""
        nb = cells[:, None] + offsets[None, :]
        nb = nb[~reached[nb]]
        return np.unique(nb)

    for k in range(1, int(math.floor(limit / resolution + 1e-9)) + 1):
        grow = beyond(new)
        # Known free space next to the last unknown step: entered at that step's cost, all of it.
        fresh = np.unique(labels[grow[free[grow]]])
        fresh = fresh[(fresh > 0) & ~joined[fresh]]
        entered = np.zeros(0, np.int64)
        if fresh.size:
            joined[fresh] = True
            entered = np.flatnonzero(np.isin(labels, fresh) & ~reached)
            way[entered] = (k - 1) * resolution
            reached[entered] = True
        ring = beyond(np.concatenate([new, entered]))
        front = ring[unknown[ring]]
        if not front.size:
            break
        way[front] = k * resolution
        reached[front] = True
        new = np.concatenate([front, entered])
    return way.reshape(h + 2, w + 2)[1:-1, 1:-1].copy()


def within_reach(way: np.ndarray, grid: np.ndarray, resolution: float, reach: float) -> np.ndarray:
    """(H, W) float32: ``way`` (:func:`unknown_way`) carried on up to ``reach`` cells further, 4-connected, through
    cells that are not walls (the footprint's edge reaching past where its centre fits): the unknown space on the
    way to a cell the robot can touch. Not through a wall, nor between two wall cells that touch at a corner (the
    crack a lidar ray slipped through), however near it is."""
    open_ = grid < OCCUPIED_AT
    unknown = grid == UNKNOWN
    out = way.copy()
    cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
    for _ in range(int(math.ceil(reach))):
        step = cv2.erode(out, cross, borderValue=np.inf) + np.where(unknown, resolution, 0.0).astype(np.float32)
        out = np.where(open_, np.minimum(out, step), out)
    return out


def site_blacklisted(site: FrontierSite, grid: OccupancyGrid, points: list[tuple[float, float]],
                     radius: float) -> bool:
    """Whether every cell of ``site`` lies within ``radius`` [m] of one of ``points`` ((x, y) [m] in ``map``)."""
    if not points:
        return False
    x, y = grid.cell_to_world(site.cells[:, 0].astype(float), site.cells[:, 1].astype(float))
    pts = np.asarray(points, float)
    d2 = (np.asarray(x)[:, None] - pts[None, :, 0]) ** 2 + (np.asarray(y)[:, None] - pts[None, :, 1]) ** 2
    return bool((d2.min(axis=1) <= radius * radius).all())
