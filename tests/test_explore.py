"""Exploration leaves and the grid_slam service: blacklisting through the leaf, the no-frontier condition, the
service's grid against the simulator's truth, and the benchmark's run-by-run ratios."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import py_trees
import pytest
from homing.behaviours.explore import GOAL_KEY, Explore, NoFrontierLeft
from homing.benchmarks.common import write_json
from homing.benchmarks.explore import RunResult, load_runs, ratios, session_efficiency, summarise
from homing.mapping.grid import OccupancyGrid
from homing.mapping.reachable import frontier_report
from homing.mapping.strategies import SETBACK
from homing.navigation.costmap import Costmap
from homing.navigation.navigator import NavFeedback, NavStatus, NoProgress, TooManyBumps
from homing.navigation.planner import NoPathFound
from homing.robot import Pose2, Twist2
from py_trees.common import Access, Status

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData

RES = 0.05  # [m]


def _two_openings() -> OccupancyGrid:
    """A 4 m × 3 m room (origin at its lower-left corner) with a 1.5 m opening onto unknown in the east and the
    west wall (explore_lite's frontiers must be ≥ 0.75 m of cells the robot fits next to)."""
    g = np.full((100, 120), UNKNOWN, dtype=np.int8)
    g[20:80, 20:100] = FREE
    g[20, 20:100] = g[79, 20:100] = OCCUPIED
    g[20:80, 20] = g[20:80, 99] = OCCUPIED
    g[35:65, 99] = FREE  # east opening
    g[35:65, 20] = FREE  # west opening
    return OccupancyGrid.from_map_data(MapData(g, RES, (-1.0, -1.0, 0.0)))


class _FailingNavigator:
    """Stands in for the Navigator above which the leaf sits: a real costmap, and every goal fails as told."""

    def __init__(self, grid: OccupancyGrid, error: Exception) -> None:
        self.costmap = Costmap()
        self.costmap.update_static(grid)
        self.error = error
        self.status = NavStatus.IDLE
        self.feedback = NavFeedback()
        self.goals: list[Pose2] = []

    def set_goal(self, goal: Pose2, xy_tolerance: float | None = None, yaw_tolerance: float | None = None) -> None:
        self.goals.append(goal)
        self.status = NavStatus.RUNNING
        self.feedback = NavFeedback(goal=goal)

    def step(self, obs: Any, grid: Any, pose: Pose2, map_to_odom: Any = None) -> tuple[NavStatus, Twist2, NavFeedback]:
        self.status = NavStatus.FAILED  # fails on its first step
        self.feedback.error = self.error
        self.feedback.message = str(self.error)
        return self.status, Twist2(), self.feedback

    def cancel(self) -> None:
        self.status = NavStatus.CANCELLED


class _Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def now(self) -> float:
        return self.t


class _Robot:
    def __init__(self) -> None:
        self.clock = _Clock()


def _board(grid: OccupancyGrid, nav: Any, pose: Pose2) -> py_trees.blackboard.Client:
    py_trees.blackboard.Blackboard.clear()
    bb = py_trees.blackboard.Client(name="test")
    for key in ("/robot/observation", "/nav/navigator", "/map/grid", "/map/pose", "/map/map_to_odom", GOAL_KEY,
                "/explore/explored"):
        bb.register_key(key=key, access=Access.WRITE)
    bb.set("/robot/observation", object())  # the fake navigator never looks at it
    bb.set("/nav/navigator", nav)
    bb.set("/map/grid", grid)
    bb.set("/map/pose", pose)
    bb.set("/map/map_to_odom", Pose2())
    return bb


def _failing_leaf(error: Exception, strategy: str = "nearest",
                  seed: int = 0) -> tuple[Explore, _Robot, Any, py_trees.blackboard.Client]:
    """An Explore leaf at (1.0, 1.5) in :func:`_two_openings` whose navigator fails every goal with ``error``:
    (leaf, robot, navigator, blackboard)."""
    grid = _two_openings()
    nav = _FailingNavigator(grid, error)
    bb = _board(grid, nav, Pose2(1.0, 1.5, 0.0))
    robot = _Robot()
    leaf = Explore("Explore", strategy=strategy)
    leaf.setup(robot=robot, seed=seed)
    return leaf, robot, nav, bb


def _tick(leaf: Explore, robot: _Robot, dt: float = 0.1) -> Status:
    leaf.tick_once()
    robot.clock.t += dt
    return leaf.status


@pytest.mark.parametrize("strategy", ["nearest", "gain_rate", "explore_lite"])
def test_explore_blacklists_a_goal_the_navigator_fails_and_moves_on(strategy: str) -> None:
    grid = _two_openings()
    pose = Pose2(1.0, 1.5, 0.0)
    nav = _FailingNavigator(grid, NoPathFound("no free path"))
    _board(grid, nav, pose)
    robot = _Robot()
    leaf = Explore("Explore", strategy=strategy)
    leaf.setup(robot=robot, seed=3)
    statuses = [_tick(leaf, robot) for _ in range(2)]
    # A goal the planner cannot reach is the goal's fault: blacklisted, and the leaf goes on RUNNING.
    assert statuses == [Status.RUNNING, Status.RUNNING], leaf.feedback_message
    assert len(nav.goals) == 2
    first, second = nav.goals[0], nav.goals[1]
    assert first.distance_to(second) > leaf.explorer.blacklist_radius  # not the same frontier again
    assert (first.x, first.y) in leaf.explorer.blacklist
    assert [f[1] for f in leaf.failures] == ["no_path"]
    # Goals lie at the two openings (x ≈ 0 or x ≈ 4 m, 0.75 ≤ y ≤ 2.25 m); gain_rate's may stand back from them
    # (a viewpoint in known free space within SETBACK), the others' sit on the frontier.
    slack = SETBACK if strategy == "gain_rate" else 0.0  # [m]
    assert all(min(abs(g.x), abs(g.x - 4.0)) < 0.4 + slack and 0.75 - slack <= g.y <= 2.25 + slack
               for g in nav.goals)


def test_explore_blacklists_a_goal_the_navigator_bumped_on_and_goes_on() -> None:
    leaf, robot, nav, _ = _failing_leaf(TooManyBumps("a bumper fired 3 times on the way"))
    statuses = [_tick(leaf, robot) for _ in range(2)]
    # TooManyBumps is the goal's fault (something low near it the lidar misses): blacklist it, keep exploring.
    assert statuses == [Status.RUNNING, Status.RUNNING], leaf.feedback_message
    assert [f[1] for f in leaf.failures] == ["bumped"]
    assert (nav.goals[0].x, nav.goals[0].y) in leaf.explorer.blacklist
    assert len(nav.goals) == 2 and nav.goals[0].distance_to(nav.goals[1]) > 3.0


def test_explore_fails_with_the_reason_when_the_robot_cannot_progress() -> None:
    leaf, robot, nav, bb = _failing_leaf(NoProgress("stuck"))
    statuses = [_tick(leaf, robot) for _ in range(2)]
    assert statuses == [Status.RUNNING, Status.FAILURE] and leaf.failure_reason == "no_progress"
    assert len(leaf.explorer.blacklist) == 1 and bb.get(GOAL_KEY) is None
    # Started again (as a recovery node does), it keeps its blacklist and picks the other opening.
    _tick(leaf, robot)
    assert len(nav.goals) == 2 and nav.goals[0].distance_to(nav.goals[1]) > 3.0


def test_explore_that_gave_up_reachable_frontiers_ends_incomplete_and_tries_them_again_next_start() -> None:
    leaf, robot, nav, bb = _failing_leaf(NoPathFound("no free path"))
    reasons = []
    for _ in range(200):  # started again after each failure, as a recovery node does
        if _tick(leaf, robot) == Status.FAILURE:
            reasons.append(leaf.failure_reason)
            if leaf.failure_reason == "incomplete":
                break
    # Every goal fails as the planner's fault; the places the strategy no longer offers are cut off on the
    # costmap for a round of recoveries, then given up too. The map still says the robot could reach them:
    # that is not "explored" but FAILURE incomplete, with what was given up and why.
    assert reasons and reasons[-1] == "incomplete" and "incomplete" not in reasons[:-1], reasons
    assert bb.get("/explore/explored") is False
    assert "no_path" in leaf.feedback_message and "2 reachable frontier" not in leaf.feedback_message
    report = leaf.end_report()
    assert report is not None and report.startswith("incomplete") and "given up" in report
    tried = len(nav.goals)
    assert tried >= 2
    # Started again (a recovery round, the persistent mission's next round): every place is tried again.
    assert _tick(leaf, robot) == Status.RUNNING
    assert len(nav.goals) == tried + 1 and leaf.explorer.retries == 1
    assert "tried again 1×" in (leaf.end_report() or "")
    # Given up again on every retry round, the places no longer keep exploration incomplete: the robot fits the
    # way to them on the map, so they are deferred to a later round, saying so, and that is the end of this one.
    from homing.mapping.explorer import RETRY_ROUNDS

    incompletes, status = 1, Status.RUNNING
    for _ in range(2000):
        status = _tick(leaf, robot)
        if status == Status.SUCCESS:
            break
        incompletes += status == Status.FAILURE and leaf.failure_reason == "incomplete"
    assert status == Status.SUCCESS and incompletes >= RETRY_ROUNDS + 1, (incompletes, leaf.feedback_message)
    assert f"no_path, {RETRY_ROUNDS + 1} rounds; the robot fits the way in: tried again in round" in \
        leaf.feedback_message and bb.get("/explore/explored") is True
    # Later rounds (each a new start of the leaf): nothing is tried before the first deferred place's round,
    # and it is tried then.
    ex = leaf.explorer
    due = min(ex.deferred.values())
    tried = len(nav.goals)
    while ex.round < due - 1:
        assert _tick(leaf, robot) == Status.SUCCESS  # started again: at once explored, nothing tried
    assert len(nav.goals) == tried
    _tick(leaf, robot)
    assert ex.round == due and len(nav.goals) == tried + 1


def test_explore_succeeds_when_no_frontier_is_left_and_the_condition_agrees() -> None:
    g = np.full((100, 120), UNKNOWN, dtype=np.int8)
    g[20:80, 20:100] = FREE
    g[20, 20:100] = g[79, 20:100] = OCCUPIED
    g[20:80, 20] = g[20:80, 99] = OCCUPIED
    closed = OccupancyGrid.from_map_data(MapData(g, RES, (-1.0, -1.0, 0.0)))
    # an empty map has no frontier, but nothing is explored either (the persistent mission rests on "done")
    empty = OccupancyGrid.from_map_data(MapData(np.full((100, 120), UNKNOWN, dtype=np.int8), RES, (-1.0, -1.0, 0.0)))
    for grid, done in ((closed, True), (_two_openings(), False), (empty, False)):
        nav = _FailingNavigator(grid, NoPathFound("x"))
        bb = _board(grid, nav, Pose2(1.0, 1.5, 0.0))
        robot = _Robot()
        cond = NoFrontierLeft("NoFrontierLeft")
        cond.setup(robot=robot, seed=0)
        cond.tick_once()
        assert cond.status == (Status.SUCCESS if done else Status.FAILURE)
        if done:
            leaf = Explore("Explore")
            leaf.setup(robot=robot, seed=0)
            assert _tick(leaf, robot) == Status.SUCCESS and not nav.goals
            assert bb.get("/explore/explored") is True  # what the persistent mission rests on


def test_grid_slam_service_grid_agrees_with_the_truth(tmp_path: Path) -> None:
    """The service in the mission runner, on the simulator: back out of the lab's dock and turn a full circle."""
    import homing.sim as sim
    from homing.mapping.evaluate import cell_agreement
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner

    mission = tmp_path / "m.yaml"
    mission.write_text(
        "services: [{grid_slam: {publish_period: 0.5}}]\n"
        "view: {blackboard: [/map/grid, /map/pose]}\n"
        "tree:\n  sequence: [{Drive: {v: -0.1, seconds: 4}}, {Drive: {omega: 0.8, seconds: 8}}]\n"
    )
    robot = sim.SimRobot(sim.load_world("lab"), seed=2, camera=False)
    try:
        world_from_map = robot.truth_pose().compose(robot.observe().odom.pose.inverse())
        runner = Runner(compile_mission(mission), robot, seed=2)
        result = runner.run()
        truth_end = robot.truth_pose()
        grid, pose = runner.read("/map/grid"), runner.read("/map/pose")
        assert result.reason == "success"
        assert (grid.data != UNKNOWN).sum() * RES**2 > 20.0  # a full turn sees a good part of the room
        assert cell_agreement(grid, robot.world.map, world_from_map) >= 0.97
        est = world_from_map.compose(pose)
        assert math.hypot(est.x - truth_end.x, est.y - truth_end.y) < 0.10
        assert abs(math.remainder(est.theta - truth_end.theta, 2 * math.pi)) < math.radians(3.0)
    finally:
        robot.close()


def _run(world: str, strategy: str, seed: int, eff: float) -> RunResult:
    nan = float("nan")
    return RunResult(world, strategy, seed, eff, 10.0, 0.9, 1.0, 1.0, 100.0, nan, nan, True, 0, 0, 1, 1.0, 1.0, 1.0)


def test_benchmark_ratios_are_taken_run_by_run_on_the_same_world_and_seed() -> None:
    runs = [
        _run("a", "nearest", 0, 0.01), _run("a", "gain_rate", 0, 0.02),
        _run("a", "nearest", 1, 0.04), _run("a", "gain_rate", 1, 0.05),
        _run("a", "nearest", 2, 0.10), _run("a", "gain_rate", 2, 0.30),
        _run("b", "nearest", 0, 1.00), _run("b", "gain_rate", 0, 0.50),
    ]  # fmt: skip
    r = ratios(runs, "nearest")
    # per seed: 2.0, 1.25, 3.0 → median 2.0 (a ratio of medians would say 0.05 / 0.04 = 1.25)
    assert r[("a", "gain_rate")] == pytest.approx(2.0)
    assert r[("b", "gain_rate")] == pytest.approx(0.5)
    s = summarise(runs)
    assert s["a"]["gain_rate"]["ratio_vs_nearest"] == pytest.approx(2.0)
    assert math.isnan(s["a"]["gain_rate"]["ratio_vs_explore_lite"])  # no explore_lite runs
    assert s["all"]["gain_rate"]["ratio_vs_nearest"] == pytest.approx(1.625)  # median of 2.0, 1.25, 3.0, 0.5
    assert set(s["a"]["nearest"]) >= {"efficiency", "area", "coverage", "path_length", "ratio_vs_nearest",
                                      "ratio_vs_explore_lite"}


def test_session_efficiency_is_taken_at_95_percent_or_over_the_whole_session() -> None:
    # Reached 95 % at 200 s with 40 m² mapped: 0.2 m²/s, whatever happened after.
    assert session_efficiency(40.0, 200.0, 42.0, 1800.0) == pytest.approx(0.2)
    # Quit early at 150 s with 38 m² (< 95 %): the session clock runs on to 30 min.
    quitter = session_efficiency(float("nan"), float("nan"), 38.0, 1800.0)
    assert quitter == pytest.approx(38.0 / 1800.0)
    assert quitter < session_efficiency(40.0, 400.0, 42.0, 1800.0)  # slower but complete wins


def test_saved_runs_load_back_filtered_by_strategy_and_world(tmp_path: Path) -> None:
    from dataclasses import asdict

    from homing.errors import UserError

    runs = [_run("a", "nearest", 0, 0.01), _run("a", "gain_rate", 0, 0.02), _run("b", "gain_rate", 1, 0.5)]
    write_json(tmp_path / "runs.json", {"runs": [asdict(r) for r in runs]})
    back = load_runs([str(tmp_path / "runs.json")], ["gain_rate"], ["a"])
    assert [(r.world, r.strategy, r.efficiency) for r in back] == [("a", "gain_rate", 0.02)]
    assert math.isnan(back[0].t95)  # NaN survives the round trip
    (tmp_path / "bad.json").write_text("{}")
    with pytest.raises(UserError):
        load_runs([str(tmp_path / "bad.json")], ["gain_rate"], None)


def test_gain_rate_counts_only_the_unknown_area_a_sensor_could_see() -> None:
    from homing.mapping.strategies import GAIN_RADIUS, visible_unknown

    g = np.full((200, 200), FREE, dtype=np.int8)
    centre = np.array([[100, 100]])
    g[:, 121:] = UNKNOWN  # unknown beyond x = 1 m east of the cell (cell edges at 0.05 m)
    seen = float(visible_unknown(g, RES, centre)[0])
    a, r = 1.05, GAIN_RADIUS  # the circular segment beyond the chord
    segment = r * r * math.acos(a / r) - a * math.sqrt(r * r - a * a)
    assert seen == pytest.approx(segment, rel=0.08)
    g[:, 118:121] = OCCUPIED  # a mapped wall in front of the unknown: nothing to see
    assert float(visible_unknown(g, RES, centre)[0]) == 0.0


def test_a_decision_that_keeps_its_goal_measures_progress_on_the_navigators_path_and_needs_no_field() -> None:
    # The distance field (fast marching over the whole map) is asked for only by decisions that choose; while
    # the navigator has a path to the goal its length is the progress, and a path that stops shrinking for the
    # progress timeout gives the goal up, as the field's distance did.
    from homing.mapping.explorer import Explorer
    from homing.mapping.strategies import make_strategy
    from homing.navigation.planner import distance_map

    grid = _two_openings()
    cm = Costmap()
    cm.update_static(grid)
    robot = Pose2(1.0, 0.5, 0.0)
    asked: list[float] = []

    def field() -> np.ndarray:
        asked.append(1.0)
        return distance_map(cm, robot)

    ex = Explorer(make_strategy("nearest"), progress_timeout=30.0)
    first = ex.update(grid, robot, field, 0.0)
    assert first.goal is not None and len(asked) == 1  # choosing needs the field
    travel = 3.0
    for t in range(1, 25):  # driving: the path shrinks by 0.12 m a second
        travel -= 0.12
        step = ex.update(grid, robot, field, float(t), travel=travel)
        assert step.goal == first.goal and not step.done
    assert len(asked) == 1 and ex.fields == 1  # no field while the goal is kept
    for t in range(25, 56):  # stuck: the path no longer shrinks
        step = ex.update(grid, robot, field, float(t), travel=travel)
        if step.goal != first.goal:
            break
    assert t == 24 + 30 + 1, f"given up {t - 24} s after the last progress, not after the 30 s timeout"
    assert step.goal != first.goal and ex.blacklist_reasons == ["no_progress"]
    assert len(asked) == 2  # the new choice needed the field again


def test_a_sweep_resumed_keeps_the_runs_its_file_holds_and_runs_only_the_others(tmp_path: Path,
                                                                                capsys: pytest.CaptureFixture[str]) -> None:
    import json

    from homing.missions.cli import main

    runs = tmp_path / "runs.json"
    args = ["bench", "explore", "--worlds", "lab", "--strategies", "nearest", "--minutes", "0.2", "--runs-json",
            str(runs), "--resume"]
    assert main([*args, "--seeds", "1"]) == 0
    saved = json.loads(runs.read_text())
    saved["runs"][0]["area"] = 12345.0  # marked: a run made again would not carry it
    runs.write_text(json.dumps(saved))
    assert main([*args, "--seeds", "2"]) == 0
    after = {r["seed"]: r for r in json.loads(runs.read_text())["runs"]}
    assert sorted(after) == [0, 1] and after[0]["area"] == 12345.0 and after[1]["area"] < 1000.0
    assert "1 run(s) kept" in capsys.readouterr().out
    # A narrower sweep resumed from the same file (one seed of the two) runs nothing and loses no run of it.
    assert main([*args, "--seeds", "1"]) == 0
    again = {r["seed"]: r for r in json.loads(runs.read_text())["runs"]}
    assert again == after
    assert main(["bench", "explore", "--worlds", "lab", "--resume"]) == 2  # nothing to resume from


def _wall_with_gap(gap: float, seen: bool = False) -> OccupancyGrid:
    """An 8 m × 4 m room (origin at its corner) cut in two by a wall at x = 4 m with a ``gap`` [m] in it at y = 2 m;
    the far half's middle (x 5–7.5 m, y 0.5–3.5 m) unseen, unless ``seen``."""
    g = np.full((80, 160), FREE, dtype=np.int8)
    g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = OCCUPIED
    g[:, 80] = OCCUPIED  # a wall across, with a gap
    half = int(round(gap / RES / 2))
    g[40 - half:40 + half, 80] = FREE
    if not seen:
        g[10:70, 100:150] = UNKNOWN
    return OccupancyGrid.from_map_data(MapData(g, RES, (0.0, 0.0, 0.0)))


def test_a_place_given_up_leaves_the_list_once_the_map_holds_it_whole() -> None:
    # Places given up before the robot looked and after (not_cleared), while the room behind them is unseen, stay
    # given up at a new round; once the map holds the room (mapped through another way), they leave the list and
    # the end report: there is no frontier there to give up. A place still next to unknown cells stays.
    from homing.mapping.explorer import Explorer
    from homing.mapping.strategies import make_strategy

    pose = Pose2(1.0, 2.0, 0.0)
    unseen = _wall_with_gap(0.30)
    ex = Explorer(make_strategy("nearest"))
    ex.blacklist = [(6.0, 2.0), (5.2, 3.0), (7.9, 0.2)]  # in the room; near its west edge; in a mapped corner
    ex.blacklist_reasons = ["not_cleared", "no_path, 3 rounds; way in 0.30 m, narrower than the robot", "no_path"]
    ex.new_round(unseen, pose)
    # Unknown cells within the radius round the first two: kept; the corner's nearest is 0.54 m off: mapped round.
    assert ex.blacklist == [(6.0, 2.0), (5.2, 3.0)]
    assert ex.blacklist_reasons[0] == "not_cleared"
    seen = _wall_with_gap(0.30, seen=True)
    seen_part = _wall_with_gap(0.30)
    seen_part.data[10:70, 100:125] = FREE  # the room's west half seen: (5.2, 3.0) mapped round, (6.0, 2.0) not
    ex.new_round(seen_part, pose)
    assert ex.blacklist == [(6.0, 2.0)]
    ex.new_round(seen, pose)
    assert ex.blacklist == [] and "(6.0, 2.0)" not in ex.end_message()


@pytest.mark.parametrize(("gap", "fits"), [(0.30, False), (0.80, True)])
def test_a_place_given_up_on_every_retry_round_is_measured_on_the_map(gap: float, fits: bool) -> None:
    # A place given up again on every retry round: measured on the map from the robot, a way in narrower than the
    # robot gives it up for good, saying how wide; one the robot fits defers it to a later round.
    from homing.mapping.explorer import RETRY_ROUNDS, Explorer, settled
    from homing.mapping.strategies import make_strategy

    grid = _wall_with_gap(gap)
    ex = Explorer(make_strategy("nearest"))
    place = (6.0, 2.0)  # beyond the wall
    ex.blacklist, ex.blacklist_reasons = [place], ["no_path"]
    ex.rounds = [(place[0], place[1], RETRY_ROUNDS)]
    ex.forgive(grid, Pose2(1.0, 2.0, 0.0))
    (why,) = ex.blacklist_reasons
    assert settled(why) and why.startswith(f"no_path, {RETRY_ROUNDS + 1} rounds")
    if fits:
        assert "the robot fits the way in: tried again in round" in why and ex.deferred
    else:
        width = float(why.split("way in ")[1].split(" m")[0])
        assert "narrower than the robot" in why and not ex.deferred
        assert width == pytest.approx(gap, abs=2 * RES)


def test_a_place_given_up_as_too_narrow_is_measured_again_each_round_and_tried_once_the_way_is_open() -> None:
    # Given up for good behind a 0.30 m gap (a door left ajar, a parcel in the doorway): while the map still shows
    # the gap, new rounds keep it given up; once the map shows the doorway open (0.80 m), the next round takes it
    # off the blacklist, the reason's history kept for the end report, and its retry rounds start afresh.
    from homing.mapping.explorer import RETRY_ROUNDS, Explorer, settled
    from homing.mapping.strategies import make_strategy

    pose, place = Pose2(1.0, 2.0, 0.0), (6.0, 2.0)
    narrow = _wall_with_gap(0.30)
    ex = Explorer(make_strategy("nearest"))
    ex.blacklist, ex.blacklist_reasons = [place], ["no_path"]
    ex.rounds = [(place[0], place[1], RETRY_ROUNDS)]
    ex.forgive(narrow, pose)
    (why,) = ex.blacklist_reasons
    assert settled(why) and why.endswith("narrower than the robot")
    for _ in range(3):  # the world has not changed: measured again, still too narrow
        assert ex.new_round(narrow, pose) == 0 and ex.new_round(narrow, pose, incomplete=True) == 0
        assert ex.blacklist == [place] and ex.blacklist_reasons == [why] and not ex.reopened
    assert ex.new_round() == 0 and ex.blacklist == [place]  # no map to measure on: kept
    opened = _wall_with_gap(0.80)
    assert ex.new_round(opened, pose) == 1
    assert ex.blacklist == [] and ex.rounds == []  # tried again, with its retry rounds counted afresh
    (again,) = ex.reopened
    assert (again.x, again.y) == place and again.reason.startswith(why + "; way in now ≥ ")
    assert again.reason.endswith("m, the robot fits")
    # The end report keeps the history.
    ex.report = frontier_report(opened, (pose.x, pose.y))
    assert f"tried again: (6.0, 2.0) {again.reason}" in ex.end_message()
    assert ex.new_round(opened, pose) == 0 and len(ex.reopened) == 1  # nothing left to measure


def test_the_leaf_tries_a_place_given_up_as_too_narrow_once_the_map_shows_its_way_open() -> None:
    # The Explore leaf on its next start (the persistent mission's next round): a room behind a doorway once
    # measured 0.30 m wide, its frontier given up for good; the map now shows the doorway 0.80 m wide (a door
    # opened, seen on the patrol). Without measuring again it would say "explored" at once.
    from homing.mapping.explorer import NARROW, REOPENED_KEPT

    def room_behind(gap: float) -> OccupancyGrid:
        grid = _wall_with_gap(gap)
        grid.data[10:70, 100:150] = UNKNOWN  # the room beyond the wall, unseen
        return grid

    narrow, opened = room_behind(0.30), room_behind(0.80)
    pose = Pose2(1.0, 2.0, 0.0)
    nav = _FailingNavigator(narrow, NoPathFound("no free path"))
    bb = _board(narrow, nav, pose)
    robot = _Robot()
    leaf = Explore("Explore", strategy="nearest")
    leaf.setup(robot=robot, seed=0)
    assert _tick(leaf, robot) == Status.SUCCESS and not nav.goals  # behind a 0.30 m gap: nothing to go to
    ex = leaf.explorer
    (site,) = frontier_report(opened, (pose.x, pose.y)).reachable
    ex._blacklist_site(site, opened, f"no_path, 3 rounds; way in 0.30 m, {NARROW}")  # given up for good then
    points = len(ex.blacklist)
    bb.set("/map/grid", opened)
    nav.costmap.update_static(opened)
    assert _tick(leaf, robot) == Status.RUNNING and len(nav.goals) == 1  # started again: goes for the room
    assert nav.goals[0].x > 4.0 and not ex.blacklist
    assert len(ex.reopened) == min(points, REOPENED_KEPT)  # the latest, with their reasons' history
    assert all(g.reason.endswith("way in 0.30 m, narrower than the robot; way in now ≥ 0.40 m, the robot fits")
               for g in ex.reopened)
