"""Exploration leaves: ``Explore`` (frontier goals one at a time, Mata 2017 §2.4) and the ``NoFrontierLeft`` condition.

Thin by design (DESIGN.md, rules of the house): the frontier search, the goal
strategies, blacklisting and progress checks live in
:class:`homing.mapping.explorer.Explorer`; the travel-distance field comes
from :func:`homing.navigation.planner.distance_map` on the navigation
service's costmap; driving is the navigator's (``/nav/navigator``). The leaf
only decides *when* to ask for a decision, hands the goal to the navigator
and returns its status.

Cost per tick: decisions come every ``decide_period`` [s] of adapter time,
at once when the navigator reaches or fails its goal, and never otherwise;
the other ticks cost one navigator step. A decision that keeps the goal
(the navigator has a path to it, the strategy does not replan yet) measures
progress on the navigator's path length and costs next to nothing; the
distance field (fast marching over the whole grid, tens of ms on a 25 m
map) is computed only for decisions that choose.

Failures: a goal the navigator cannot plan to (``no_path``,
``goal_occupied``) or that pressed the bumpers too often on the way
(``bumped``, the navigator's TooManyBumps) is blacklisted and exploration
goes on with the next one, as explore_lite does. A failure of the robot itself (``blocked``,
``no_progress``, ``start_occupied``, ``invalid_path``) blacklists the goal too,
then ends the leaf with FAILURE and that reason, so a mission's recovery node
(clear costmap, spin, back up, wait) can act before it starts again; the
explorer and its blacklist survive the restart. Such a goal is given up as
the navigator's verdict (``no_progress (navigator)``): not tried again
within the round, where the restart would send the robot straight back to
fail again (:mod:`homing.mapping.giveups`), but at its end.

"Done" means done (:mod:`homing.mapping.explorer`, :mod:`homing.mapping.reachable`):
SUCCESS only when the map has no frontier the robot's footprint could reach
from where it is (frontiers behind gaps narrower than the robot are reported
in the feedback message, with the robot's coverage estimate, as are places
it stood at and looked into without clearing them). When the only ones
left are places it gave up before it looked (no progress, unreachable, cut
off), exploration is **incomplete**: FAILURE ``incomplete`` with the same
report, ``/explore/explored`` stays False, and the next start of the leaf
(a recovery round, or the persistent mission's next round) tries them
again, up to ``RETRY_ROUNDS`` times each (:meth:`Explorer.forgive`); then, measured on
the map, a place behind a way narrower than the robot is given up for good, and one the robot fits the way
to is deferred to a later round (:meth:`Explorer.new_round`); every start measures the ways in to places given
up as too narrow again on the map as it is, and tries those the robot now fits (:meth:`Explorer.remeasure`: a
door opened since). Frontiers it could reach but the costmap cuts off end the leaf
with FAILURE ``frontier_cut_off`` for the recoveries; after a round of
them those frontiers are given up (a frontier the costmap reaches only at
places already given up is given up with them at once: no recovery brings
those back).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from homing.behaviours.base import (
    TIMEOUT_PARAM,
    HomingBehaviour,
)
from homing.behaviours.keys import (
    CMD_VEL_KEY,
    EXPLORE_GOAL_KEY,
    EXPLORED_KEY,
    GRID_KEY,
    MAP_TO_ODOM_KEY,
    NAVIGATOR_KEY,
    OBSERVATION_KEY,
    POSE_KEY,
)
from homing.behaviours.motion import FAILURE_KEY, FAILURE_PARAM, _ReportsFailure, failure_reason
from homing.behaviours.registry import Param, register
from homing.mapping.explorer import REACH_RADIUS, Explorer, ExploreStep
from homing.mapping.reachable import frontier_report
from homing.mapping.strategies import DEFAULT_STRATEGY, STRATEGIES, make_strategy
from homing.navigation.navigator import NavStatus
from homing.navigation.planner import FIELD_BLOCK, distance_map
from homing.robot import Pose2
from py_trees.common import Status

GOAL_KEY = EXPLORE_GOAL_KEY
DECIDE_PERIOD = 1.0  # [s] adapter time between decisions while driving (strategies replan no faster)
GOAL_REASONS = ("no_path", "goal_occupied", "bumped")  # the goal's fault (bumped: TooManyBumps near it): blacklist it and go on
START_PATIENCE = 3.0  # [s] the robot's cell may be blocked on the costmap this long before the leaf fails
NO_FRONTIER_PERIOD = 2.0  # [s] NoFrontierLeft recomputes at most this often on a changing grid


def distance_field(navigator: Any, grid: Any, pose: Pose2) -> np.ndarray | None:
    """Travel distance [m] (H, W) from ``pose`` on the navigator's costmap, or None if it does not match ``grid`` yet.

    Reachable cells exactly, distances marched on ``FIELD_BLOCK`` blocks (:func:`distance_map`'s ``coarse``):
    strategies rank frontiers metres apart, and a march over every 5 cm cell of a large floor is the
    costliest part of a decision."""
    if navigator.costmap.shape != grid.shape:
        return None
    return distance_map(navigator.costmap, pose, allow_unknown=False, coarse=FIELD_BLOCK)


def trail_on(navigator: Any, grid: Any) -> np.ndarray | None:
    """(H, W) bool: the robot's trail (:mod:`homing.navigation.trail`, kept by the navigator's costmap) on
    ``grid``'s cells, or None without one: where its centre has been, the map check asks the footprint alone to
    fit (:func:`homing.mapping.reachable.fits_on_trail`)."""
    trail = getattr(getattr(navigator, "costmap", None), "trail", None)
    if trail is None or not trail.version:
        return None
    return trail.mask(grid.origin, grid.resolution, grid.shape)


class _StartBlocked(Exception):
    """The robot's own cell is blocked on the costmap: the distance field is empty."""


@register("Explore")
class Explore(_ReportsFailure):
    """Drive to frontier goals one at a time with a named strategy until no frontier is left (SUCCESS); RUNNING while driving.

    Each goal goes to the navigation service's navigator; the next one is
    chosen when the robot is within ``reach_radius`` of it (about one robot
    diameter, as the thesis), when the strategy replans, or when the goal is
    given up (no progress for ``progress_timeout``, unreachable, navigation
    failed: blacklisted). Writes the goal to ``/explore/goal``.
    """

    PARAMS = (
        Param("strategy", str, DEFAULT_STRATEGY, "", "frontier goal strategy", choices=tuple(sorted(STRATEGIES))),
        Param("decide_period", float, DECIDE_PERIOD, "s", "time between decisions while driving", above=0.0),
        Param("reach_radius", float, REACH_RADIUS, "m", "a goal this close counts as reached", above=0.0),
        Param("progress_timeout", float, 30.0, "s", "blacklist a goal the robot gets no closer to for this long",
              above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, NAVIGATOR_KEY, GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY)
    WRITES = (CMD_VEL_KEY, GOAL_KEY, EXPLORED_KEY, "$failure_key")

    def __init__(self, name: str, strategy: str = DEFAULT_STRATEGY, decide_period: float = DECIDE_PERIOD,
                 reach_radius: float = REACH_RADIUS, progress_timeout: float = 30.0, timeout: float = 0.0,
                 failure_key: str = FAILURE_KEY, **kwargs: Any) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout, **kwargs)
        if strategy not in STRATEGIES:
            raise ValueError(f"unknown strategy '{strategy}' (known: {', '.join(sorted(STRATEGIES))})")
        self.strategy_name = strategy
        self.decide_period = float(decide_period)
        self.reach_radius = float(reach_radius)
        self.progress_timeout = float(progress_timeout)
        self.explorer: Explorer | None = None
        self.navigator: Any = None
        self.last_step: ExploreStep | None = None
        self.failures: list[tuple[float, str, Pose2 | None]] = []  # (time, reason, goal) navigation failures
        self._next_decision = -math.inf
        self._nav_goal: Pose2 | None = None
        self._blocked_since: float | None = None
        self.incomplete = False  # the last run ended with reachable places given up: try them again next start

    def setup(self, **kwargs: Any) -> None:
        super().setup(**kwargs)
        self.explorer = None  # a new run: a new explorer, seeded from the run's seed

    def _explorer(self) -> Explorer:
        if self.explorer is None:
            self.explorer = Explorer(make_strategy(self.strategy_name), self.rng(), reach_radius=self.reach_radius,
                                     progress_timeout=self.progress_timeout,
                                     trail=lambda grid: trail_on(self.navigator, grid))
        return self.explorer

    # -- LongAction hooks ---------------------------------------------------------------
    def on_start(self) -> Status | None:
        self.navigator = self.read(NAVIGATOR_KEY)
        if self.navigator is None:
            return self.fail("no_navigator", "no navigation service (add 'navigation' to services)")
        if self.explorer is not None:
            # A later round (after a recovery, the persistent mission's next): after an incomplete end every place
            # given up is tried again, places deferred to this round are, whatever the end, and so are places
            # given up as too narrow whose way in the map now shows open.
            self.explorer.new_round(self.read(GRID_KEY), self.read(POSE_KEY), self.incomplete)
        self.incomplete = False
        self._explorer()
        self._next_decision = -math.inf
        self._nav_goal = None
        self._blocked_since = None
        return None

    def on_running(self) -> Status:
        obs, grid, pose = self.observation(), self.read(GRID_KEY), self.read(POSE_KEY)
        if obs is None or grid is None or pose is None:
            self.feedback_message = "waiting for the map"
            return Status.RUNNING
        now = self.now()
        nav = self.navigator
        explorer = self._explorer()
        # The navigator's verdict on the current goal comes first: it may force a decision now.
        if self._nav_goal is not None and nav.status is NavStatus.SUCCEEDED:
            self._next_decision = -math.inf
        elif self._nav_goal is not None and nav.status is NavStatus.FAILED:
            reason = failure_reason(nav.feedback.error)
            self.failures.append((now, reason, self._nav_goal))
            explorer.report_failure(reason, robot=reason not in GOAL_REASONS)
            self._nav_goal = None
            self._next_decision = -math.inf
            if reason not in GOAL_REASONS:
                self.write(GOAL_KEY, None)
                return self.fail(reason, f"navigation failed ({reason}): {nav.feedback.message}")
        if now >= self._next_decision:
            status = self._decide(grid, pose, now)
            if status is not None:
                return status
        if self._nav_goal is None:
            self.feedback_message = "choosing a frontier"
            return Status.RUNNING
        nav_status, cmd, fb = nav.step(obs, grid, pose, self.read(MAP_TO_ODOM_KEY))
        self.drive(cmd.v, cmd.omega)
        if nav_status in (NavStatus.SUCCEEDED, NavStatus.FAILED):
            self._next_decision = -math.inf  # decide on the next tick (the tick's command is already zero)
        self.feedback_message = f"goal ({self._nav_goal.x:.1f}, {self._nav_goal.y:.1f}): {fb.message}"
        return Status.RUNNING

    def _decide(self, grid: Any, pose: Pose2, now: float) -> Status | None:
        if self.navigator.costmap.shape != grid.shape:
            return None  # the costmap has not caught up with a grown grid: next tick
        self._next_decision = now + self.decide_period
        nav = self.navigator
        travel = None
        if (self._nav_goal is not None and nav.status is NavStatus.RUNNING and nav.goal is self._nav_goal
                and nav.feedback.error is None and nav.feedback.path is not None):
            travel = float(nav.feedback.distance_remaining)

        def field() -> np.ndarray:
            distance = distance_field(nav, grid, pose)
            assert distance is not None
            if not np.isfinite(distance).any():
                raise _StartBlocked
            return distance

        try:
            # Without the navigator's path, the field is asked for at once (is the robot's own cell free?).
            step = self._explorer().update(grid, pose, field if travel is not None else field(), now, travel)
        except _StartBlocked:
            # The robot's own cell is blocked on the costmap: nothing is reachable, which is not "explored".
            if self._blocked_since is None:
                self._blocked_since = now
            if now - self._blocked_since >= START_PATIENCE:
                self._blocked_since = None
                return self.fail("start_occupied", "the robot stands in an obstacle on the costmap")
            return None
        self._blocked_since = None
        self.last_step = step
        if step.done:
            self.navigator.cancel()
            self._nav_goal = None
            self.write(GOAL_KEY, None)
            if step.gave_up and not getattr(self._explorer().strategy, "ends_without_goal", False):
                self.incomplete = True
                self.write(EXPLORED_KEY, False)
                return self.fail("incomplete", f"incomplete: {self._explorer().end_message()}")
            self.feedback_message = f"explored: {self._explorer().end_message()}"
            self.write(EXPLORED_KEY, True)
            return Status.SUCCESS
        if step.stuck is not None:
            # Frontiers the robot could reach on the map are cut off on the costmap: not "explored" — a failure
            # the mission's recoveries (clear the costmap, spin, back up) act on.
            self.navigator.cancel()
            self._nav_goal = None
            self.write(GOAL_KEY, None)
            assert step.report is not None
            return self.fail(step.stuck, f"{step.stuck.replace('_', ' ')}: {step.report.summary()}")
        if step.goal is None:
            self._nav_goal = None
            self.write(GOAL_KEY, None)
            return None
        if step.changed or self._nav_goal is None or self.navigator.status is not NavStatus.RUNNING:
            # Reaching the frontier within reach_radius is the thesis's rule; the final heading does not matter.
            self.navigator.set_goal(step.goal, xy_tolerance=self.reach_radius, yaw_tolerance=math.inf)
            self._nav_goal = step.goal
            self.write(GOAL_KEY, step.goal)
            self.write(EXPLORED_KEY, False)
        return None

    def on_success(self) -> Status:
        return Status.SUCCESS

    def on_cancel(self) -> None:
        if self.navigator is not None:
            self.navigator.cancel()
        self._nav_goal = None

    def end_report(self) -> str | None:
        """How exploration stands, for the end of a run's log: explored, incomplete (what was given up and why,
        the coverage estimate), or what the map said when last asked; None before any verdict."""
        if self.explorer is None or self.explorer.report is None:
            return None
        if self.status == Status.SUCCESS:
            state = "explored"
        elif self.incomplete:
            state = "incomplete"
        else:
            state = f"not finished ({self.status.value.lower()})"
        retried = f" (places given up tried again {self.explorer.retries}×)" if self.explorer.retries else ""
        return f"{state}{retried}: {self.explorer.end_message()}"


@register("NoFrontierLeft", kind="condition")
class NoFrontierLeft(HomingBehaviour):
    """SUCCESS when the map has no frontier the robot's footprint can reach from where it is
    (:func:`homing.mapping.reachable.frontier_report`: the map itself, not the costmap), else FAILURE
    (also while nothing is mapped: an empty map has no frontier, and nothing is explored either).

    Recomputed when the grid changes, at most every ``period`` [s]; between
    times it answers from the last result, so it is cheap in a guard ticked
    every tick.
    """

    PARAMS = (Param("period", float, NO_FRONTIER_PERIOD, "s", "recompute at most this often", minimum=0.0),)
    READS = (NAVIGATOR_KEY, GRID_KEY, POSE_KEY)

    def __init__(self, name: str, period: float = NO_FRONTIER_PERIOD, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.period = float(period)
        self._key: tuple[int, int] | None = None
        self._next = -math.inf
        self._answer = False
        self.segments = 0

    def update(self) -> Status:
        nav, grid, pose = self.read(NAVIGATOR_KEY), self.read(GRID_KEY), self.read(POSE_KEY)
        if nav is None or grid is None or pose is None:
            self.feedback_message = "no map yet"
            return Status.FAILURE
        key = (id(grid), int(grid.version))
        now = self.now()
        if key != self._key and now >= self._next:
            self._key, self._next = key, now + self.period
            if not (grid.data == 0).any():  # nothing mapped yet is not a mapped building
                self.segments, self._answer = -1, False
            else:
                self.segments = len(frontier_report(grid, (pose.x, pose.y), trail=trail_on(nav, grid)).reachable)
                self._answer = not self.segments
        self.feedback_message = ("no frontier left" if self._answer else "nothing mapped yet" if self.segments < 0
                                 else f"{self.segments} reachable frontier(s)")
        return Status.SUCCESS if self._answer else Status.FAILURE
