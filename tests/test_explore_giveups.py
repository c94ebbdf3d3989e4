"""The explorer's give-ups: a detour is no lack of progress, a place given up for a transient reason is tried
again within the round once the strategy finds nothing else, and a place where the robot itself failed (the
navigator's verdict ended the leaf) only at the round's end (:mod:`homing.mapping.giveups`)."""

from __future__ import annotations

import numpy as np
from homing.mapping.explorer import Explorer
from homing.mapping.giveups import reachable_again, robot_failed
from homing.mapping.strategies import make_strategy
from homing.navigation.costmap import Costmap
from homing.navigation.navigator import NoProgress
from homing.navigation.planner import distance_map
from homing.robot import Pose2
from py_trees.common import Status

from tests.test_explore import _failing_leaf, _tick, _two_openings


def _explorer_and_field() -> tuple[Explorer, object, Pose2, np.ndarray]:
    grid = _two_openings()
    cm = Costmap()
    cm.update_static(grid)
    robot = Pose2(1.0, 0.5, 0.0)
    return Explorer(make_strategy("nearest"), progress_timeout=30.0), grid, robot, distance_map(cm, robot)


def test_a_path_grown_into_a_long_detour_is_driven_not_given_up_as_no_progress() -> None:
    # office:1 seed 0: the short way to a room closed on the costmap, the path grew from 12.6 m to 31.7 m, and the
    # robot drove the detour at 0.5 m/s: given up after 30 s as no_progress while it was 13 m nearer.
    ex, grid, robot, field = _explorer_and_field()
    first = ex.update(grid, robot, field, 0.0)
    assert first.goal is not None
    travel, t = 12.6, 0.0
    for t in range(1, 6):  # driving the short way
        travel -= 0.5
        assert ex.update(grid, robot, field, float(t), travel=travel).goal == first.goal
    best = travel
    travel = 31.7  # the short way closed: a 19 m detour
    for t in range(6, 60):
        step = ex.update(grid, robot, field, float(t), travel=travel)
        assert step.goal == first.goal and not ex.blacklist, f"given up at {t} s, {travel - best:.1f} m to go"
        travel -= 0.5
        if travel < best - 1.0:
            break
    assert travel < best  # it drove the whole detour on the same goal


def test_a_path_that_flips_between_two_ways_still_times_out() -> None:
    # A robot dithering between two ways (the path's length jumping up and down) makes no progress: the detour's
    # allowance is given once for the longest way, not on every jump.
    ex, grid, robot, field = _explorer_and_field()
    first = ex.update(grid, robot, field, 0.0)
    for t in range(1, 200):
        step = ex.update(grid, robot, field, float(t), travel=8.0 if t % 2 else 15.0)
        if step.goal != first.goal:
            break
    assert ex.blacklist_reasons[:1] == ["no_progress"]
    assert t <= 1 + 30 + (15.0 - 8.0) / 0.35 + 1


def _give_up_side(ex: Explorer, grid: object, robot: Pose2, field: np.ndarray, west: bool, reason: str,
                  t: float) -> object:
    """Give up every goal on the west (east) opening for ``reason``; returns the next step."""
    step = ex.update(grid, robot, field, t)
    while step.goal is not None and (step.goal.x < 2.0) == west:
        ex.report_failure(reason)
        t += 1.0
        step = ex.update(grid, robot, field, t)
    return step


def test_a_place_given_up_for_a_transient_reason_is_tried_again_when_nothing_else_is_left() -> None:
    # The robot gives the west opening up (no progress), goes to the east one, and once that one is given up after
    # looking (the strategy has nothing left) the west is tried again in the same round, not only at its end.
    ex, grid, robot, field = _explorer_and_field()
    assert ex.update(grid, robot, field, 0.0).goal.x < 2.0  # the west opening is the nearer
    step = _give_up_side(ex, grid, robot, field, True, "no_progress", 0.0)
    assert step.goal is not None and step.goal.x > 2.0  # then the east
    step = _give_up_side(ex, grid, robot, field, False, "not_cleared", 10.0)
    assert not step.done and step.goal is not None and step.goal.x < 2.0, "the west not tried again in the round"
    assert set(ex.blacklist_reasons) == {"not_cleared"} and ex.round == 0
    for t in range(20, 60):  # given up again: once a round, so the round ends (incomplete) in a few steps
        if step.done:
            break
        ex.report_failure("no_progress" if step.goal is not None and step.goal.x < 2.0 else "not_cleared")
        step = ex.update(grid, robot, field, float(t))
    assert step.done and step.gave_up > 0  # to be tried again next round
    ex.new_round(grid, robot, incomplete=True)
    assert ex.retried == [] and set(ex.blacklist_reasons) == {"not_cleared"}


def test_only_transient_reasons_the_costmap_reaches_are_tried_again() -> None:
    _, grid, robot, field = _explorer_and_field()
    places = [(2.0, 1.0), (2.0, 1.0), (2.0, 1.0), (50.0, 50.0), (2.0, 1.0)]
    reasons = ["no_progress", "not_cleared", "no_progress, 3 rounds", "unreachable", "cut_off"]
    assert reachable_again(places, reasons, [], field, grid, 0.5) == {0, 4}
    assert reachable_again(places, reasons, [(2.1, 1.0)], field, grid, 0.5) == set()
    near = float(field[grid.world_to_cell(2.0, 1.0)])
    assert reachable_again(places, reasons, [], field, grid, 0.5, nearer_than=near - 1.0) == set()  # a nearer site
    unreachable = np.full_like(field, np.inf)
    assert reachable_again(places, reasons, [], unreachable, grid, 0.5) == set()


def test_a_place_the_robot_itself_failed_at_is_not_tried_again_within_the_round() -> None:
    # The navigator's own no_progress (the robot moved too little) ends the leaf for the recoveries: the restart
    # must not send the robot straight back. The explorer's own no_progress (the previous tests) still is.
    ex, grid, robot, field = _explorer_and_field()
    step, failed = ex.update(grid, robot, field, 0.0), []
    for t in range(1, 60):
        if step.done:
            break
        assert step.goal is not None
        if step.goal.x < 2.0:  # the west opening: the robot fails on the way, a recovery restarts the leaf
            assert all(np.hypot(step.goal.x - x, step.goal.y - y) > ex.blacklist_radius for x, y in failed), \
                "a place the robot failed at was tried again within the round"
            failed.append((step.goal.x, step.goal.y))
            ex.report_failure("no_progress", robot=True)
            ex.new_round(grid, robot)
        else:  # the east: looked at
            ex.report_failure("not_cleared")
        step = ex.update(grid, robot, field, float(t))
    assert step.done and step.gave_up > 0 and failed
    assert robot_failed("no_progress") in ex.blacklist_reasons
    ex.new_round(grid, robot, incomplete=True)  # the round's end: tried again then
    assert ex.update(grid, robot, field, 60.0).goal.x < 2.0
    places = [(2.0, 1.0), (2.0, 1.0)]
    assert reachable_again(places, [robot_failed("no_progress"), "no_progress"], [], field, grid, 0.5) == {1}


def test_a_robot_that_cannot_move_fails_each_place_once_a_round_not_for_ever() -> None:
    # office:1 seed 1 (bench persist, 5fb012a): unable to leave its dock, the robot was sent 24 times in 8 minutes
    # to the same place, failing the navigator's progress check each time (an Error state and recoveries each).
    # Every start of the leaf after a failure is a recovery's: each place fails once, then the round ends incomplete.
    leaf, bot, nav, _ = _failing_leaf(NoProgress("moved less than 0.25 m in 10 s"))
    ends = []
    for _ in range(200):
        status = _tick(leaf, bot)
        if status == Status.FAILURE:
            ends.append(leaf.failure_reason)
            if leaf.failure_reason == "incomplete":
                break
    assert ends[-1:] == ["incomplete"], f"{len(ends)} failures: {ends[:3]}…"
    failed = [(g.x, g.y) for g in nav.goals]
    assert all(min(np.hypot(x - px, y - py) for px, py in failed[:i]) > leaf.explorer.blacklist_radius
               for i, (x, y) in enumerate(failed) if i), "the robot was sent back to a place it failed at"
