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
  ``blacklist_radius``;
- cells within ``reach_radius`` of the robot are never chosen (they would
  count as reached at once).

Blacklisted points are kept in the ``map`` frame, so a grid that grows (and
moves its origin) keeps them in place. Time comes from the caller (the
adapter's clock).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.mapping.strategies import GoalChoice, GoalContext, GoalStrategy
from homing.robot import Pose2
from homing.robot.turtlebot import BASE_RADIUS, FOOTPRINT_RADIUS

from homing.map_server import UNKNOWN

REACH_RADIUS = 2 * BASE_RADIUS  # [m] about one robot diameter (thesis)
PROGRESS_TIMEOUT = 30.0  # [s] explore_lite's progress_timeout
PROGRESS_STEP = 0.10  # [m] the travel distance must shrink this much to count as progress
BLACKLIST_RADIUS = 0.5  # [m]
EXPLORED_RADIUS = 0.35  # [m] a goal with no unknown cell this close has been seen


@dataclass(frozen=True)
class ExploreStep:
    """What the explorer decided this update: the goal (``map``) or None, and whether exploration is over."""

    goal: Pose2 | None
    changed: bool
    done: bool
    choice: GoalChoice | None


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
    ) -> None:
        self.strategy = strategy
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.reach_radius = reach_radius
        self.progress_timeout = progress_timeout
        self.blacklist_radius = blacklist_radius
        self.robot_radius = robot_radius
        self.goal: Pose2 | None = None
        self.choice: GoalChoice | None = None
        self.blacklist: list[tuple[float, float]] = []
        self.goals_chosen = 0
        self._best_distance = math.inf
        self._last_progress = 0.0
        self._last_choice = -math.inf

    def report_failure(self) -> None:
        """Navigation failed to reach the goal: blacklist it and choose another on the next update."""
        if self.goal is not None:
            self.blacklist.append((self.goal.x, self.goal.y))
        self.goal = None

    def update(self, grid: OccupancyGrid, pose: Pose2, distance: np.ndarray, now: float) -> ExploreStep:
        """One decision. ``pose`` base_link in ``map``; ``distance`` (H, W) [m] travel distance from the robot
        on ``grid``'s cells (inf = unreachable); ``now`` [s] adapter time."""
        if distance.shape != grid.shape:
            raise ValueError(f"distance field {distance.shape} does not match the grid {grid.shape}")
        changed = False
        if self.goal is not None and self._give_up(grid, pose, distance, now):
            self.goal = None
        replan = (
            self.goal is not None
            and self.strategy.replan_period is not None
            and now - self._last_choice >= self.strategy.replan_period
        )
        if self.goal is None or replan:
            choice = self.strategy.choose(self._context(grid, pose, distance))
            self._last_choice = now
            if choice is None:
                done = self.goal is None or not replan
                if replan and self.goal is not None:
                    return ExploreStep(self.goal, False, False, self.choice)
                self.goal, self.choice = None, None
                return ExploreStep(None, True, done, None)
            gx, gy = grid.cell_to_world(*choice.cell)
            new_goal = Pose2(float(gx), float(gy), math.atan2(float(gy) - pose.y, float(gx) - pose.x))
            if self.goal is None or self.goal.distance_to(new_goal) > 0.5 * grid.resolution:
                changed = True
                self.goal = new_goal
                self.goals_chosen += 1
                self._best_distance = float(distance[choice.cell])
                self._last_progress = now
            self.choice = choice
        return ExploreStep(self.goal, changed, False, self.choice)

    # ---------------------------------------------------------------- rules
    def _give_up(self, grid: OccupancyGrid, pose: Pose2, distance: np.ndarray, now: float) -> bool:
        assert self.goal is not None
        if pose.distance_to(self.goal) <= self.reach_radius:
            return True  # reached: choose the next one (thesis)
        cell = grid.world_to_cell(self.goal.x, self.goal.y)
        r, c = int(cell[0]), int(cell[1])
        if not grid.in_bounds(np.int64(r), np.int64(c)) or not np.isfinite(distance[r, c]):
            self.blacklist.append((self.goal.x, self.goal.y))
            return True
        d = float(distance[r, c])
        if d < self._best_distance - PROGRESS_STEP:
            self._best_distance = d
            self._last_progress = now
        elif now - self._last_progress > self.progress_timeout:
            self.blacklist.append((self.goal.x, self.goal.y))
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
        h, w = grid.shape
        res = grid.resolution
        rr = (pose.y - grid.origin[1]) / res - 0.5
        rc = (pose.x - grid.origin[0]) / res - 0.5
        rows = np.arange(h)[:, None]
        cols = np.arange(w)[None, :]
        excluded = (rows - rr) ** 2 + (cols - rc) ** 2 <= (self.reach_radius / res) ** 2
        for bx, by in self.blacklist:
            br, bc = (by - grid.origin[1]) / res - 0.5, (bx - grid.origin[0]) / res - 0.5
            excluded |= (rows - br) ** 2 + (cols - bc) ** 2 <= (self.blacklist_radius / res) ** 2
        current = None
        if self.goal is not None:
            gr, gc = grid.world_to_cell(self.goal.x, self.goal.y)
            current = (int(gr), int(gc))
        return GoalContext(
            grid=grid.data, resolution=res, robot_cell=(rr, rc), robot_heading=pose.theta,
            distance=distance, excluded=excluded, rng=self.rng, current_goal=current,
            robot_radius=self.robot_radius,
        )
