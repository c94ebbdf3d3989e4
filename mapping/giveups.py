"""Places exploration gave up, and when they count again (:mod:`homing.mapping.explorer`'s bookkeeping).

A place is given up for a reason. Some reasons are the robot's own verdict after it stood there and looked
(``not_cleared``), or the verdict of every retry round (``…, 3 rounds``): those are *settled* and no longer keep
exploration incomplete. Others are *transient* — the navigator made no progress, the costmap did not reach the
goal, a costmap cut the frontiers off, the planner found no path — and say nothing about the place itself: an
obstacle moved, the robot turned a corner, a recovery cleared the costmap. Such a place is tried again within the
round (once per round) as soon as the strategy finds nothing else worth the trip, if the costmap reaches it then
(:func:`reachable_again`), rather than only at the round's end. Measured on ``office:1`` seed 0 (bench explore,
frontier_travel): a south-east room given up at 273 s (no_progress) and 401 s was entered only after the round's
end at 705 s, the robot visiting crumbs and places seen through a gap in the outer wall meanwhile; t95 740 s.

A place where the *robot itself* failed — the navigator's own verdict (it moved too little, was blocked, stood in
an obstacle, its path went invalid) ended the exploration leaf for the mission's recoveries — is given up with
that reason marked as the navigator's (:func:`robot_failed`: ``no_progress (navigator)``). It is tried again at
the round's end like any other (:meth:`Explorer.forgive`), never within the round: the recovery that follows
restarts the leaf, and sent straight back to the same goal the robot fails again. Measured on ``office:1``
(bench persist, seed 1, 5fb012a): unable to leave its dock for 8 minutes, the robot was sent 24 times to the same
place 10 m away, each time failing the navigator's progress check in 10 s and going through the Error state
(248 s of Error in the day); the explorer's own progress check (``no_progress``: the travel distance did not
shrink for ``progress_timeout``) still lets its place be tried again within the round.
"""

from __future__ import annotations

import math

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.mapping.navigable import disc

from homing.map_server import UNKNOWN

LOOKED_AT = "not_cleared"  # the one reason a place is given up after the robot stood at it and looked
TRANSIENT = ("no_progress", "unreachable", "cut_off", "no_path")  # reasons that say nothing of the place itself
NAVIGATOR = "(navigator)"  # the mark of a reason that was the navigator's verdict on the robot itself


def robot_failed(reason: str) -> str:
    """The reason a place is given up for when the robot itself failed on the way to it (the navigator's
    ``reason`` ended the exploration leaf): ``no_progress (navigator)``, never :data:`TRANSIENT` within the round."""
    return f"{reason} {NAVIGATOR}"


def settled(reason: str) -> bool:
    """Whether a place given up for ``reason`` no longer keeps exploration incomplete: the robot looked at it from
    where it is, or it was given up again on every retry round (:meth:`Explorer.forgive`: for good, or deferred to
    a later round)."""
    return reason == LOOKED_AT or " rounds" in reason


def reachable_again(points: list[tuple[float, float]], reasons: list[str], retried: list[tuple[float, float]],
                    distance: np.ndarray, grid: OccupancyGrid, radius: float,
                    nearer_than: float = math.inf) -> set[int]:
    """The indices of ``points`` ((x, y) [m] in ``map``) given up for a transient reason (:data:`TRANSIENT`), not
    within ``radius`` [m] of a place already ``retried`` this round, whose cells within ``radius`` the travel
    ``distance`` field (inf: unreachable) now reaches, nearer than ``nearer_than`` [m]: the places worth trying
    again now."""
    h, w = distance.shape
    k = int(math.ceil(radius / grid.resolution))
    out = set()
    for i, ((x, y), why) in enumerate(zip(points, reasons, strict=True)):
        if why not in TRANSIENT or any(math.hypot(x - px, y - py) <= radius for px, py in retried):
            continue
        r, c = (int(v) for v in grid.world_to_cell(x, y))
        window = distance[max(r - k, 0) : min(r + k + 1, h), max(c - k, 0) : min(c + k + 1, w)]
        if window.size and window.min() < nearer_than:
            out.add(i)
    return out


def mapped(points: list[tuple[float, float]], grid: OccupancyGrid, radius: float) -> set[int]:
    """The indices of ``points`` ((x, y) [m] in ``map``) with no unknown cell of ``grid`` within ``radius`` [m]:
    places the map now holds whole, with no frontier left to give up."""
    data, res = grid.data, grid.resolution
    h, w = data.shape
    near_disc = disc(radius / res).astype(bool)
    n = near_disc.shape[0] // 2
    out = set()
    for i, (x, y) in enumerate(points):
        r, c = (int(v) for v in grid.world_to_cell(x, y))
        if not (0 <= r < h and 0 <= c < w):
            continue
        r0, c0 = max(r - n, 0), max(c - n, 0)
        patch = data[r0 : r + n + 1, c0 : c + n + 1]
        near = near_disc[r0 - (r - n) : r0 - (r - n) + patch.shape[0], c0 - (c - n) : c0 - (c - n) + patch.shape[1]]
        if not (patch[near] == UNKNOWN).any():
            out.add(i)
    return out
