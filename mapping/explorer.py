"""The exploration loop around a goal strategy: when to choose a goal, progress timeouts and the blacklist (Mata 2017, §2.4.2; explore_lite's progress_timeout).

Shared by every strategy, so that they differ only in their rule:

- a new goal is chosen when the robot is within ``reach_radius`` (about one
  robot diameter, as the thesis) of the current one, when navigation
  reports failure, when the goal becomes unreachable, and — for strategies
  that ask — every ``replan_period`` or once the goal's frontier is seen
  (the strategy's ``goal_spent(grid, resolution, cell)`` when it has one,
  else no unknown cell within ``EXPLORED_RADIUS`` of the goal);
- a goal whose travel distance has not shrunk by ``PROGRESS_STEP`` for
  ``progress_timeout`` [s] is blacklisted (explore_lite: 30 s), as is one
  navigation failed on; blacklisted points exclude goals within
  ``blacklist_radius``. The travel distance is the navigator's path length
  when the caller passes it (``travel``), else the distance field's value:
  the field (fast marching over the whole map, the costly part of a
  decision) is then computed only for decisions that choose a goal;
- cells within ``reach_radius`` of the robot are never chosen (they would
  count as reached at once).

- a goal reached ``MAX_ARRIVALS`` times whose frontier is still there is
  blacklisted (``not_cleared``): the lidar cannot clear it from there, so it
  is not visited for ever.

"Done" means done (:mod:`homing.mapping.reachable`): when the strategy finds
no goal, the map itself is asked which frontiers the robot could reach with
its footprint from where it is, whatever the costmap says (on the robot's
trail, when the caller gives one, with the footprint alone: the way back
through a door the map redrew narrower once the robot was through). None left but
those behind gaps narrower than the robot: done, with the robot's coverage
estimate and the gaps, each with the width of its way in measured between
walls through the known free space the lidar saw it through
(``narrower_than_robot (way in 0.28 m)``); the same when the others were given up after the
robot stood at them and looked (``not_cleared``: the lidar cannot see in).
Frontiers given up before it looked (no progress, unreachable, cut off…):
done *incomplete* (``ExploreStep.gave_up`` > 0) — the caller reports it as
such, not as explored, and may :meth:`Explorer.forgive` them to try again;
a place given up again on ``RETRY_ROUNDS`` retry rounds no longer keeps
exploration incomplete: measured on the map, a way to it narrower than the
robot gives it up for good (the reason gives the width), one the robot
fits defers it to a later round (after 2, 4, 8… more rounds). "For good"
holds while the map says so: every new round measures those ways in again
on the current map (a door opened, a parcel taken away, once the lidar has
seen it), and a place the robot now fits leaves the blacklist, its reason's
history kept for the end report (``…; way in now ≥ 0.40 m, the robot fits``).

A site the costmap still reaches but the strategy declined (too small for its rule) is
visited anyway: the robot stands against it, or for a door seen only at a
grazing angle (a peek site) within ``PEEK`` of it, to look through — next
to the robot too: it has then arrived, and a site whose frontier is still
there once it looked from where it stands is given up as ``not_cleared``.
Places to stand are cells the costmap reaches that no place given up
covers; a site the costmap reaches only at places given up (goals near it
that were unreachable, no progress…) goes with them — no recovery brings
those back — as ``stands given up (unreachable)``, tried again when they
are (a later round), or as ``not_cleared`` when all were looked from; and
so does a peek site that no cell of the map the robot fits in comes within
``PEEK`` of (reached on the map only through unknown space; across more
than ``THROUGH`` of it, the map gives it up itself: seen through a wall): ``no place to look from within 0.75 m``, tried again on a
later round, when the map may have one. A
site the costmap cuts off (inflation in a doorway, a transient obstacle, a
localisation error) is a failure with a typed reason, ``frontier_cut_off``,
for the mission's recoveries to act on; after
``CUT_OFF_TRIES`` such failures in a row those sites are given up as
``cut_off``. A strategy whose early end is its published behaviour
(``ends_without_goal``: explore_lite) still ends when it finds no goal, and
its report says what it left.

Blacklisted points are kept in the ``map`` frame, so a grid that grows (and
moves its origin) keeps them in place. Time comes from the caller (the
adapter's clock).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from homing.mapping.frontier import OCCUPIED_AT
from homing.mapping.giveups import LOOKED_AT, mapped, reachable_again, robot_failed, settled
from homing.mapping.grid import OccupancyGrid
from homing.mapping.navigable import disc, ways_in
from homing.mapping.reachable import (
    PEEK,
    FrontierReport,
    FrontierSite,
    GivenUp,
    clear_of_walls,
    frontier_report,
    robot_region,
    site_blacklisted,
)
from homing.mapping.strategies import GoalChoice, GoalContext, GoalStrategy
from homing.robot import Pose2
from homing.robot.turtlebot import BASE_RADIUS, FOOTPRINT_RADIUS

from homing.map_server import FREE, UNKNOWN

REACH_RADIUS = 2 * BASE_RADIUS  # [m] about one robot diameter (thesis)
PROGRESS_TIMEOUT = 30.0  # [s] explore_lite's progress_timeout
PROGRESS_STEP = 0.10  # [m] the travel distance must shrink this much to count as progress
DETOUR_SPEED = 0.35  # [m/s] a path grown longer than ever gives the goal the time to drive the extra at this speed
BLACKLIST_RADIUS = 0.5  # [m]
EXPLORED_RADIUS = 0.35  # [m] a goal with no unknown cell this close has been seen
MAX_ARRIVALS = 2  # a place reached this often with its frontier still there is blacklisted (not_cleared)
RETRY_ROUNDS = 2  # rounds a place given up before the robot looked at it is tried again, before it is given up for good
CUT_OFF_TRIES = 4  # failures in a row on frontiers the costmap cuts off before they are given up (one recovery round)
STANDS_GIVEN_UP = "stands given up"  # a site whose every place to look from was given up (and why those were)
NO_PLACE = "no place to look from"  # a peek site no cell of the map the robot fits in comes near
NARROW = "narrower than the robot"  # the mark of a place given up for good by its width (measured again each round)
REOPENED_KEPT = 20  # places whose way in was measured open again, kept with their reasons for the end report


@dataclass(frozen=True)
class ExploreStep:
    """What the explorer decided this update: the goal (``map``) or None, and whether exploration is over."""

    goal: Pose2 | None
    changed: bool
    done: bool
    choice: GoalChoice | None
    stuck: str | None = None  # frontiers the robot could reach are cut off: a typed reason for the recoveries
    report: FrontierReport | None = None  # what the map said was left, when it was asked
    gave_up: int = 0  # done, but incomplete: reachable frontiers given up before the robot looked at them


class Explorer:
    """Frontier exploration with one strategy: call :meth:`update` every tick, drive to ``goal``."""

    def __init__(
        self,
        strategy: GoalStrategy,
        rng: np.random.Generator | None = None,
        reach_radius: float = REACH_RADIUS,
        progress_timeout: float = PROGRESS_TIMEOUT,
        blacklist_radius: float = BLACKLIST_RADIUS,
        robot_radius: float = FOOTPRINT_RADIUS,
        trail: Callable[[OccupancyGrid], np.ndarray | None] | None = None,
    ) -> None:
        self.strategy = strategy
        # The robot's trail on a grid's cells ((H, W) bool, or None): where its centre has been, the map check
        # asks the footprint alone to fit (homing.mapping.reachable.fits_on_trail).
        self.trail = trail
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.reach_radius = reach_radius
        self.progress_timeout = progress_timeout
        self.blacklist_radius = blacklist_radius
        self.robot_radius = robot_radius
        self.goal: Pose2 | None = None
        self.choice: GoalChoice | None = None
        self.blacklist: list[tuple[float, float]] = []
        self.blacklist_reasons: list[str] = []  # why each blacklist point was given up
        self.arrivals: list[tuple[float, float]] = []  # goals reached, (x, y) [m] in map
        self.report: FrontierReport | None = None  # the map's verdict at the last "no goal"
        self.narrow_widths: tuple[float, ...] = ()  # [m] the way in to each of its narrow frontiers, at the end
        self.cut_offs = 0  # "no goal" verdicts in a row with frontiers the costmap cuts off
        self._declined: FrontierSite | None = None  # the site the current goal visits though the strategy declined it
        self.goals_chosen = 0
        self.retries = 0  # times the places given up were tried again (forgive)
        self.rounds: list[tuple[float, float, int]] = []  # (x, y) [m] of places forgiven and how many times
        self.round = 0  # starts of exploration after the first (new_round)
        self.deferred: dict[tuple[float, float], int] = {}  # places given up on every retry round the robot fits
        # the way to, and the round they are tried again in
        self.reopened: list[GivenUp] = []  # places given up as narrower than the robot, measured open since
        # (the latest REOPENED_KEPT), their reasons' history ("…; way in now ≥ 0.40 m, the robot fits")
        self.retried: list[tuple[float, float]] = []  # places tried again within this round (once a round each)
        self._best_distance = math.inf
        self._best_travel = math.inf  # the navigator's path length to the goal, the least so far [m]
        self._longest_travel = 0.0  # [m] and the longest (a detour found since gives time to drive it)
        self._last_progress = 0.0
        self._last_choice = -math.inf
        self.fields = 0  # distance fields asked for (the costly part of a decision)

    def report_failure(self, reason: str = "nav_failed", robot: bool = False) -> None:
        """Navigation failed to reach the goal (``reason``): blacklist it and choose another on the next update.
        ``robot``: the robot itself failed (the navigator's verdict ends the exploration leaf for the recoveries):
        the place is given up as such (:func:`homing.mapping.giveups.robot_failed`), to be tried again at the
        round's end, not within it."""
        if self.goal is not None:
            self._blacklist(self.goal.x, self.goal.y, robot_failed(reason) if robot else reason)
        self.goal = None

    def _blacklist(self, x: float, y: float, reason: str) -> None:
        self.blacklist.append((x, y))
        self.blacklist_reasons.append(reason)

    def _blacklist_site(self, site: FrontierSite, grid: OccupancyGrid, reason: str) -> None:
        """Blacklist points covering every cell of ``site`` (greedy: a cell farther than the radius from every
        point so far becomes a point)."""
        x, y = grid.cell_to_world(site.cells[:, 0].astype(float), site.cells[:, 1].astype(float))
        xy = np.column_stack([np.atleast_1d(x), np.atleast_1d(y)])
        todo = np.ones(len(xy), bool)
        while todo.any():
            p = xy[int(np.argmax(todo))]
            self._blacklist(float(p[0]), float(p[1]), reason)
            todo &= np.hypot(xy[:, 0] - p[0], xy[:, 1] - p[1]) > 0.9 * self.blacklist_radius

    def forgive(self, grid: OccupancyGrid | None = None, pose: Pose2 | None = None) -> int:
        """Try again every place given up before the robot looked at it (a later round, after the costmap was
        cleared): they leave the blacklist; returns how many. Places looked at from where they are
        (``not_cleared``) stay given up. A place given up again on each of ``RETRY_ROUNDS`` rounds is measured on
        ``grid`` (walls alone block): if the widest way to it from ``pose`` is narrower than the robot, it is given
        up for good, the reason saying so and how wide (``no_path, 3 rounds; way in 0.34 m, narrower than the
        robot``); if the robot fits, it is deferred — tried again after 2, 4, 8… more rounds
        (:meth:`new_round`), its reason saying when — and no longer keeps exploration incomplete meanwhile.
        Without a grid, it is given up for good after ``RETRY_ROUNDS``."""
        keep, forgiven = [], 0
        for (x, y), why in zip(self.blacklist, self.blacklist_reasons, strict=True):
            if settled(why):
                keep.append(((x, y), why))
                continue
            past = next((i for i, (px, py, _) in enumerate(self.rounds)
                         if math.hypot(px - x, py - y) <= self.blacklist_radius), None)
            n = 1 if past is None else self.rounds[past][2] + 1
            if past is None:
                self.rounds.append((x, y, n))
            else:
                self.rounds[past] = (x, y, n)
            if n > RETRY_ROUNDS:
                keep.append(((x, y), self._for_good(x, y, why, n, grid, pose)))
            else:
                forgiven += 1
        self.blacklist = [p for p, _ in keep]
        self.blacklist_reasons = [why for _, why in keep]
        self.cut_offs, self.goal, self.choice, self._declined = 0, None, None, None
        self.retries += 1
        return forgiven

    def _for_good(self, x: float, y: float, why: str, n: int, grid: OccupancyGrid | None,
                  pose: Pose2 | None) -> str:
        """The reason a place given up on every retry round keeps (see :meth:`forgive`); records a deferral."""
        reason = f"{why}, {n} rounds"
        if grid is None or pose is None:
            return reason
        ((width, fits),) = self._ways_in(grid, pose, [(x, y)])
        if not fits:
            return f"{reason}; way in {width:.2f} m, {NARROW}"
        due = self.round + 2 ** (n - RETRY_ROUNDS)
        self.deferred[(x, y)] = due
        return f"{reason}; the robot fits the way in: tried again in round {due}"

    def _ways_in(self, grid: OccupancyGrid, pose: Pose2, places: list[tuple[float, float]],
                 narrow_widths: bool = True) -> list[tuple[float, bool]]:
        """The way in to each place (x, y) [m] (the cells within ``blacklist_radius``) from ``pose`` on ``grid``,
        walls alone blocking: its width [m] and whether the robot fits (:func:`homing.mapping.navigable.ways_in`;
        on the robot's trail the footprint alone must fit, as in the map check: a way back through a door the map
        redrew a cell narrower once the robot was through is no way narrower than the robot)."""
        res = grid.resolution
        rows, cols = np.ogrid[:grid.shape[0], :grid.shape[1]]
        masks = []
        for x, y in places:
            pr, pc = grid.world_to_cell(x, y)
            masks.append((rows - int(pr)) ** 2 + (cols - int(pc)) ** 2 <= (self.blacklist_radius / res) ** 2)
        start = _cell_of(grid, pose)
        out = ways_in(grid.data < OCCUPIED_AT, res, start, masks, self.robot_radius, narrow_widths)
        trail = self._trail(grid)
        if trail is None or all(fits for _, fits in out):
            return out
        g = grid.data
        region = robot_region((g < OCCUPIED_AT) & clear_of_walls(g, res, self.robot_radius, trail), start, res)
        return [(width, fits or bool(region[mask].any())) for (width, fits), mask in zip(out, masks, strict=True)]

    def _measure_narrow(self, grid: OccupancyGrid, pose: Pose2, report: FrontierReport) -> None:
        """The width [m] of the way in to each of ``report``'s narrow frontiers through known free space (where
        the lidar saw the gap), between walls: the reason a person can check (:attr:`narrow_widths`)."""
        masks = []
        for site in report.narrow:
            mask = np.zeros(grid.shape, bool)
            mask[site.cells[:, 0], site.cells[:, 1]] = True
            masks.append(mask)
        measured = ways_in(grid.data < OCCUPIED_AT, grid.resolution, _cell_of(grid, pose), masks, self.robot_radius,
                           known=grid.data == FREE)
        self.narrow_widths = tuple(width for width, _ in measured)

    def remeasure(self, grid: OccupancyGrid, pose: Pose2) -> int:
        """Measure again, on ``grid`` from ``pose``, the way in to every place given up for good as narrower than
        the robot (a door opened since, a parcel taken away, once the lidar has seen it): one the robot now fits
        leaves the blacklist, its reason's history kept in :attr:`reopened` (``…; way in now ≥ 0.40 m, the
        robot fits``) and its retry rounds counted afresh. Returns how many left. Cost: two distance transforms
        and one labelling of the grid for all of them (floor:1 at 5 cm, 0.9 M cells: 60 ms, 140 ms for 20)."""
        narrow = [i for i, why in enumerate(self.blacklist_reasons) if why.endswith(NARROW)]
        if not narrow:
            return 0
        opened = set()
        for i, (width, fits) in zip(narrow, self._ways_in(grid, pose, [self.blacklist[i] for i in narrow], False),
                                    strict=True):
            if fits:
                x, y = self.blacklist[i]
                why = f"{self.blacklist_reasons[i]}; way in now ≥ {width:.2f} m, the robot fits"
                self.reopened.append(GivenUp(x, y, 0.0, why))
                self.rounds = [r for r in self.rounds if math.hypot(r[0] - x, r[1] - y) > self.blacklist_radius]
                opened.add(i)
        del self.reopened[:-REOPENED_KEPT]
        self._drop(opened)
        return len(opened)

    def _drop(self, indices: set[int]) -> None:
        """Take the blacklist's points at ``indices`` off it, to be tried again: the current goal is chosen anew."""
        if not indices:
            return
        keep = [i for i in range(len(self.blacklist)) if i not in indices]
        self.blacklist = [self.blacklist[i] for i in keep]
        self.blacklist_reasons = [self.blacklist_reasons[i] for i in keep]
        self.cut_offs, self.goal, self.choice, self._declined = 0, None, None, None

    def new_round(self, grid: OccupancyGrid | None = None, pose: Pose2 | None = None,
                  incomplete: bool = False) -> int:
        """A new start of exploration (a recovery round, the persistent mission's next round): places given up
        as narrower than the robot are measured again (:meth:`remeasure`), after an incomplete end every place
        given up is tried again (:meth:`forgive`), and places deferred to this round are, whatever the end;
        returns how many were forgiven."""
        self.round += 1
        self.retried = []
        if grid is not None:
            # A place the map now holds whole (a room mapped since through another way, a doorway since seen
            # open) has no frontier left to give up: it leaves the list, and the end report, for good.
            mapped_now = mapped(self.blacklist, grid, self.blacklist_radius)
            self.deferred = {p: r for p, r in self.deferred.items()
                             if p not in {self.blacklist[i] for i in mapped_now}}
            self._drop(mapped_now)
        forgiven = self.remeasure(grid, pose) if grid is not None and pose is not None else 0
        forgiven += self.forgive(grid, pose) if incomplete else 0
        due = {i for i, p in enumerate(self.blacklist) if self.deferred.get(p, math.inf) <= self.round}
        self.deferred = {p: r for p, r in self.deferred.items() if r > self.round}
        self._drop(due)
        return forgiven + len(due)

    def given_up(self) -> tuple[GivenUp, ...]:
        """The places given up so far (blacklisted), with why; narrow gaps are in :attr:`report`."""
        return tuple(GivenUp(x, y, 0.0, why) for (x, y), why in zip(self.blacklist, self.blacklist_reasons,
                                                                    strict=True))

    def end_message(self) -> str:
        """How exploration ended: the robot's coverage estimate and the frontiers given up, and why; and the
        places given up as too narrow whose way in was measured open later."""
        if self.report is None:
            return "no frontier left"
        narrow: tuple[GivenUp, ...] = ()
        if len(self.narrow_widths) == len(self.report.narrow):  # measured at the end (else said as they are)
            narrow = tuple(GivenUp(s.x, s.y, s.length, f"narrower_than_robot (way in {w:.2f} m)")
                           for s, w in zip(self.report.narrow, self.narrow_widths, strict=True))
        text = dataclasses.replace(self.report, narrow=() if narrow else self.report.narrow).summary(
            (*narrow, *self.given_up()))
        if self.reopened:
            text += "; tried again: " + ", ".join(f"({g.x:.1f}, {g.y:.1f}) {g.reason}" for g in self.reopened)
        return text

    def update(self, grid: OccupancyGrid, pose: Pose2, distance: np.ndarray | Callable[[], np.ndarray], now: float,
               travel: float | None = None) -> ExploreStep:
        """One decision. ``pose`` base_link in ``map``; ``distance`` (H, W) [m] travel distance from the robot
        on ``grid``'s cells (inf = unreachable), or a function that computes it, called only when this decision
        needs it; ``now`` [s] adapter time; ``travel`` [m] the navigator's path length to the current goal when it
        has one (progress is then measured on it, and a decision that keeps the goal needs no field)."""
        cache: list[np.ndarray] = [distance] if isinstance(distance, np.ndarray) else []

        def field() -> np.ndarray:
            if not cache:
                assert callable(distance)
                cache.append(distance())
                self.fields += 1
            if cache[0].shape != grid.shape:
                raise ValueError(f"distance field {cache[0].shape} does not match the grid {grid.shape}")
            return cache[0]

        if cache:
            field()
        changed = False
        if self.goal is not None and self._give_up(grid, pose, field, now, travel):
            self.goal = None
        replan = (
            self.goal is not None
            and self.strategy.replan_period is not None
            and now - self._last_choice >= self.strategy.replan_period
        )
        if self.goal is None or replan:
            distance = field()
            choice = self.strategy.choose(self._context(grid, pose, distance))
            self._last_choice = now
            if choice is None:
                if replan and self.goal is not None:
                    return ExploreStep(self.goal, False, False, self.choice)
                self.goal, self.choice = None, None
                step = self._no_goal(grid, pose, distance)
                # Places given up for a transient reason are tried again when nothing nearer is worth the trip (a
                # site the map asks for, nearer, comes first).
                near = math.inf if step is not None or self.choice is None else float(distance[self.choice.cell])
                if self._retry_now(grid, distance, near):
                    choice = self.strategy.choose(self._context(grid, pose, distance))
                    step = self._no_goal(grid, pose, distance) if choice is None else None
                if step is not None:
                    return step
                choice = choice if choice is not None else self.choice
                assert choice is not None
            if choice is not self.choice:  # the strategy's choice
                self.cut_offs = 0
                self._declined = None
            gx, gy = grid.cell_to_world(*choice.cell)
            new_goal = Pose2(float(gx), float(gy), math.atan2(float(gy) - pose.y, float(gx) - pose.x))
            if self.goal is None or self.goal.distance_to(new_goal) > 0.5 * grid.resolution:
                changed = True
                self.goal = new_goal
                self.goals_chosen += 1
                self._best_distance = float(distance[choice.cell])
                self._best_travel, self._longest_travel = math.inf, 0.0
                self._last_progress = now
            self.choice = choice
        return ExploreStep(self.goal, changed, False, self.choice)

    def _retry_now(self, grid: OccupancyGrid, distance: np.ndarray, nearer_than: float) -> bool:
        """The strategy found nothing worth the trip: places given up for a transient reason that the costmap
        reaches now, nearer than ``nearer_than`` [m], leave the blacklist, once a round each
        (:func:`homing.mapping.giveups.reachable_again`)."""
        again = reachable_again(self.blacklist, self.blacklist_reasons, self.retried, distance, grid,
                                self.blacklist_radius, nearer_than)
        self.retried += [self.blacklist[i] for i in sorted(again)]
        self._drop(again)
        return bool(again)

    # ---------------------------------------------------------------- "done" means done
    def _no_goal(self, grid: OccupancyGrid, pose: Pose2, distance: np.ndarray) -> ExploreStep | None:
        """The strategy found no goal: ask the map (module doc). Returns the step to give, or None after setting
        ``self.choice`` to a frontier the strategy declined but the costmap reaches."""
        report = frontier_report(grid, (pose.x, pose.y), self.robot_radius, self._trail(grid))
        open_sites = [s for s in report.reachable
                      if not site_blacklisted(s, grid, self.blacklist, self.blacklist_radius)]
        report = report.given_up(len(open_sites))
        self.report, self.narrow_widths = report, ()
        if not open_sites or getattr(self.strategy, "ends_without_goal", False):
            looked = [p for p, why in zip(self.blacklist, self.blacklist_reasons, strict=True) if settled(why)]
            unlooked = sum(site_blacklisted(s, grid, self.blacklist, self.blacklist_radius)
                           and not site_blacklisted(s, grid, looked, self.blacklist_radius) for s in report.reachable)
            self._measure_narrow(grid, pose, report)
            return ExploreStep(None, True, True, None, report=report, gave_up=int(unlooked))
        # Stand where the footprint touches the site (a peek site: within PEEK of it, to look), on a cell the costmap
        # reaches and no given-up place covers; next to the robot too (it then counts as arrived at once, and the site,
        # looked at from there, is given up as not_cleared if its frontier is still there).
        given = self._given_up_mask(grid)
        allowed = np.where(given, np.inf, distance)
        radius = {False: self.robot_radius, True: max(self.robot_radius, PEEK - grid.resolution)}
        kinds = {site.peek for site in open_sites}
        beside = {peek: _beside(allowed, radius[peek], grid.resolution) for peek in kinds}
        near = {peek: _beside(distance, radius[peek], grid.resolution) for peek in kinds}
        best: tuple[float, FrontierSite, tuple[int, int]] | None = None
        looked_over: list[FrontierSite] = []  # the costmap reaches them, but every place to look from was given up
        for site in open_sites:
            d = beside[site.peek][site.cells[:, 0], site.cells[:, 1]]
            i = int(np.argmin(d))  # the site's cell nearest to a place to stand
            if not np.isfinite(d[i]):
                if np.isfinite(near[site.peek][site.cells[:, 0], site.cells[:, 1]]).any():
                    looked_over.append(site)
                continue
            cell = _stand_cell(allowed, given, tuple(site.cells[i]), radius[site.peek], grid.resolution)
            if cell is not None and (best is None or d[i] < best[0]):
                best = (float(d[i]), site, cell)
        if best is not None:
            self.cut_offs = 0
            self.choice = GoalChoice(best[2], None, [], -best[0])
            self._declined = best[1]  # visited once: given up on arrival if still there
            return None
        if looked_over:
            # No recovery brings back a place given up: the site goes with them, and says why (module doc).
            for site in looked_over:
                self._blacklist_site(site, grid, self._stands_reason(site, grid, radius[site.peek]))
            return self._no_goal(grid, pose, distance)
        unseeable = self._no_place_to_look(grid, pose, open_sites, radius[True])
        if unseeable:
            # Nor does a recovery of the costmap make a place the map itself does not have.
            for site in unseeable:
                self._blacklist_site(site, grid, f"{NO_PLACE} within {PEEK:.2f} m")
            return self._no_goal(grid, pose, distance)
        self.cut_offs += 1
        if self.cut_offs >= CUT_OFF_TRIES:
            self.cut_offs = 0
            for site in open_sites:
                self._blacklist_site(site, grid, "cut_off")
            return self._no_goal(grid, pose, distance)
        return ExploreStep(None, True, False, None, stuck="frontier_cut_off", report=report)

    def _no_place_to_look(self, grid: OccupancyGrid, pose: Pose2, sites: list[FrontierSite],
                          radius: float) -> list[FrontierSite]:
        """The peek sites of ``sites`` that no cell of the map the robot fits in (walls alone, the costmap aside)
        comes within ``radius`` (plus a cell) of: free cells seen through a wall or past a corner, reached on the map
        only through unknown space. Cost: one distance transform and one labelling of the grid (rare: only when no
        site has a place to stand)."""
        peeks = [s for s in sites if s.peek]
        if not peeks:
            return []
        g, res = grid.data, grid.resolution
        cell = ((pose.y - grid.origin[1]) / res - 0.5, (pose.x - grid.origin[0]) / res - 0.5)
        region = robot_region((g == FREE) & clear_of_walls(g, res, self.robot_radius, self._trail(grid)), cell, res)
        near = cv2.dilate(region.astype(np.uint8), disc(radius / res + 1.0)).astype(bool)
        return [s for s in peeks if not near[s.cells[:, 0], s.cells[:, 1]].any()]

    def _trail(self, grid: OccupancyGrid) -> np.ndarray | None:
        """The robot's trail on ``grid``'s cells, when the caller keeps one (the navigator's costmap does)."""
        trail = self.trail(grid) if self.trail is not None else None
        return trail if trail is not None and trail.shape == grid.shape else None

    def _given_up_mask(self, grid: OccupancyGrid) -> np.ndarray:
        """(H, W) bool: cells within ``blacklist_radius`` of a place given up."""
        mask = np.zeros(grid.shape, bool)
        for bx, by in self.blacklist:
            _disc(mask, (by - grid.origin[1]) / grid.resolution - 0.5, (bx - grid.origin[0]) / grid.resolution - 0.5,
                  self.blacklist_radius / grid.resolution)
        return mask

    def _stands_reason(self, site: FrontierSite, grid: OccupancyGrid, radius: float) -> str:
        """Why a site is given up whose every place to look from was: ``not_cleared`` when those places were all
        looked from (settled), else ``stands given up (<their reasons>)``, tried again as they are."""
        x, y = grid.cell_to_world(site.cells[:, 0].astype(float), site.cells[:, 1].astype(float))
        reach = radius + 2 * grid.resolution + self.blacklist_radius
        whys = {why for (bx, by), why in zip(self.blacklist, self.blacklist_reasons, strict=True)
                if float(np.min(np.hypot(np.atleast_1d(x) - bx, np.atleast_1d(y) - by))) <= reach}
        if whys and all(settled(why) for why in whys):
            return LOOKED_AT
        names = sorted({why.split(",")[0].split(" (")[0] for why in whys if not settled(why)})
        return f"{STANDS_GIVEN_UP} ({', '.join(names)})"

    # ---------------------------------------------------------------- rules
    def _give_up(self, grid: OccupancyGrid, pose: Pose2, field: Callable[[], np.ndarray], now: float,
                 travel: float | None) -> bool:
        assert self.goal is not None
        if pose.distance_to(self.goal) <= self.reach_radius:
            # Reached: choose the next one (thesis). A place reached again and again without its frontier
            # clearing is given up.
            g = (self.goal.x, self.goal.y)
            visits = sum(math.dist(g, a) <= self.blacklist_radius for a in self.arrivals)
            self.arrivals.append(g)
            if self._declined is not None:
                # A site only the map's check wanted (too small for the strategy): one visit is its chance.
                self._blacklist_site(self._declined, grid, "not_cleared")
            elif visits + 1 >= MAX_ARRIVALS:
                self._blacklist(*g, "not_cleared")
            return True
        cell = grid.world_to_cell(self.goal.x, self.goal.y)
        r, c = int(cell[0]), int(cell[1])
        if travel is not None and math.isfinite(travel):
            # The navigator has a path to the goal: it is reachable, and the path's length is the progress.
            if travel < self._best_travel - PROGRESS_STEP:
                self._best_travel = travel
                self._last_progress = now
            elif travel > self._longest_travel:
                # A longer way than any so far (the short one closed on the costmap): the time to drive the extra
                # length is no lack of progress (office:1 seed 0: a 19 m detour driven at 0.5 m/s timed out).
                self._last_progress += (travel - max(self._longest_travel, self._best_travel)) / DETOUR_SPEED
            self._longest_travel = max(self._longest_travel, travel)
        elif not grid.in_bounds(np.int64(r), np.int64(c)) or not np.isfinite(field()[r, c]):
            self._blacklist(self.goal.x, self.goal.y, "unreachable")
            return True
        elif (d := float(field()[r, c])) < self._best_distance - PROGRESS_STEP:
            self._best_distance = d
            self._last_progress = now
        if now - self._last_progress > self.progress_timeout:
            self._blacklist(self.goal.x, self.goal.y, "no_progress")
            return True
        spent = getattr(self.strategy, "goal_spent", None)
        if self.strategy.drop_explored and spent is not None:
            if spent(grid.data, grid.resolution, (r, c)):
                return True
        elif self.strategy.drop_explored:
            k = int(math.ceil(EXPLORED_RADIUS / grid.resolution))
            patch = grid.data[max(r - k, 0) : r + k + 1, max(c - k, 0) : c + k + 1]
            if not (patch == UNKNOWN).any():
                return True
        return False

    def _context(self, grid: OccupancyGrid, pose: Pose2, distance: np.ndarray) -> GoalContext:
        res = grid.resolution
        rr = (pose.y - grid.origin[1]) / res - 0.5
        rc = (pose.x - grid.origin[0]) / res - 0.5
        excluded = self._given_up_mask(grid)
        _disc(excluded, rr, rc, self.reach_radius / res)
        current = None
        if self.goal is not None:
            gr, gc = grid.world_to_cell(self.goal.x, self.goal.y)
            current = (int(gr), int(gc))
        return GoalContext(
            grid=grid.data, resolution=res, robot_cell=(rr, rc), robot_heading=pose.theta,
            distance=distance, excluded=excluded, rng=self.rng, current_goal=current,
            robot_radius=self.robot_radius,
        )


def _disc(mask: np.ndarray, row: float, col: float, radius: float) -> None:
    """Set the cells of ``mask`` whose (row, col) lie within ``radius`` [cells] of (row, col): in the disc's own
    square, not over the whole floor."""
    h, w = mask.shape
    r0, r1 = max(math.floor(row - radius), 0), min(math.ceil(row + radius) + 1, h)
    c0, c1 = max(math.floor(col - radius), 0), min(math.ceil(col + radius) + 1, w)
    if r1 <= r0 or c1 <= c0:
        return
    rows = np.arange(r0, r1)[:, None]
    cols = np.arange(c0, c1)[None, :]
    mask[r0:r1, c0:c1] |= (rows - row) ** 2 + (cols - col) ** 2 <= radius**2


def _cell_of(grid: OccupancyGrid, pose: Pose2) -> tuple[int, int]:
    """The grid cell (row, col) the robot stands in (clipped to the grid)."""
    h, w = grid.shape
    sr, sc = grid.world_to_cell(pose.x, pose.y)
    return int(np.clip(sr, 0, h - 1)), int(np.clip(sc, 0, w - 1))


def _beside(distance: np.ndarray, robot_radius: float, resolution: float) -> np.ndarray:
    """(H, W) [m]: the least travel distance within the footprint's radius (plus a cell) of each cell, inf where
    none is finite: how far the robot must drive to stand against that cell."""
    field = np.where(np.isfinite(distance), distance, 1e9).astype(np.float32)
    out = cv2.erode(field, disc((robot_radius + resolution) / resolution), borderType=cv2.BORDER_CONSTANT, borderValue=1e9).astype(np.float64)
    out[out >= 1e8] = np.inf
    return out


def _stand_cell(distance: np.ndarray, excluded: np.ndarray, cell: tuple[int, int], robot_radius: float,
                resolution: float) -> tuple[int, int] | None:
    """The reachable, non-excluded cell nearest to ``cell`` within the footprint's radius (plus a cell), or None."""
    k = int(math.ceil((robot_radius + resolution) / resolution))
    h, w = distance.shape
    r0, r1 = max(cell[0] - k, 0), min(cell[0] + k + 1, h)
    c0, c1 = max(cell[1] - k, 0), min(cell[1] + k + 1, w)
    ok = np.isfinite(distance[r0:r1, c0:c1]) & ~excluded[r0:r1, c0:c1]
    rows, cols = np.nonzero(ok)
    if not len(rows):
        return None
    d2 = (rows + r0 - cell[0]) ** 2 + (cols + c0 - cell[1]) ** 2
    i = int(np.argmin(d2))
    if d2[i] > k * k:
        return None
    return int(rows[i] + r0), int(cols[i] + c0)
