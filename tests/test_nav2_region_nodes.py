"""Nav2's region clearing, local path window and in-collision goal culling, against the costmap's cells and path geometry.

Nav2 sources: ``nav2_behavior_tree/plugins/action/clear_costmap_service.cpp``
and ``nav2_costmap_2d/src/clear_costmap_service.cpp`` (a square of side
``reset_distance`` centred on the point; only the sensor layers),
``truncate_path_local_action.cpp`` (closest pose by position and weighted
heading, ``first_after_integrated_distance`` either way),
``remove_in_collision_goals_action.cpp`` (keep a goal whose cost is below
``cost_threshold``, or unknown unless ``consider_unknown_as_obstacle``).
Every leaf is ticked on its own, its inputs changed between ticks, and its
outputs (costmap cells, blackboard entries, status) checked after each tick.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import py_trees
import pytest
from homing.behaviours.costmap_clearing import (
    ClearCostmapAroundPose,
    ClearCostmapAroundRobot,
    ClearCostmapExceptRegion,
)
from homing.behaviours.grid_slam_service import GridSlamService
from homing.behaviours.keys import LOCALIZED_KEY, NAVIGATOR_KEY, POSE_KEY, RELOCALIZE_KEY
from homing.behaviours.localization import ReinitializeGlobalLocalization
from homing.behaviours.path_tools import TruncatePathLocal, path_length
from homing.behaviours.paths import RemoveInCollisionGoals
from homing.behaviours.smoothing import SmoothPath
from homing.btxml.importer import import_xml
from homing.missions.cli import main
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner
from homing.navigation.costmap import FREE, INSCRIBED, LETHAL, NO_INFORMATION, Costmap
from homing.navigation.smoother import smooth_path
from homing.robot import Pose2
from homing.sim import SimRobot, load_world
from py_trees.common import Status

from homing.errors import UserError
from tests.mission_fakes import F, S, board, tick
from tests.test_path_leaves import maze, run_maze  # noqa: F401 - the maze fixture

VIA = [[3.0, 8.5, 0.0], [5.0, 1.0, 0.0], [9.0, 1.0, 0.0]]  # [m, m, rad] poses through the test maze

RES = 0.1  # [m]


def free_costmap(n: int = 40) -> Costmap:
    """An n x n free static map, 0.1 m cells, origin (0, 0): (r, c) has its centre at ((c + ½)/10, (r + ½)/10) m."""
    cm = Costmap()
    cm.set_static(np.zeros((n, n), dtype=np.int8), RES, (0.0, 0.0))
    return cm


def mark(cm: Costmap, *xy: tuple[float, float]) -> None:
    """Obstacle marks at map points [m], as the scan leaves them."""
    cm._mark(np.array(xy, dtype=float))
    cm._inflate()


def marks(cm: Costmap) -> set[tuple[int, int]]:
    return {(int(r), int(c)) for r, c in np.argwhere(cm.obstacles)}


def test_clear_region_clears_the_square_or_all_but_it_and_keeps_static_and_keepout() -> None:
    g = np.zeros((40, 40), dtype=np.int8)
    g[20, 20] = 100  # a wall cell of the static map at (2.05, 2.05) m, in the square
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    cm.set_keepout([[1.75, 2.25, 0.05]])  # a keep-out disc in the square
    mark(cm, (1.55, 1.55), (2.45, 2.45), (2.55, 2.05), (0.35, 3.55))
    assert marks(cm) == {(15, 15), (24, 24), (20, 25), (35, 3)}
    keep_before = cm.cost[22, 17]
    # The 1 m square centred on (2, 2): cell centres from 1.5 to 2.5 m on both axes.
    assert cm.clear_region(2.0, 2.0, 1.0) == 2
    assert marks(cm) == {(20, 25), (35, 3)}, "(1.55, 1.55) and (2.45, 2.45) were inside, 2.55 is not"
    assert cm.cost[20, 20] == LETHAL and cm.cost[22, 17] == keep_before == LETHAL, "static and keep-out stay"
    assert cm.cost[15, 15] != LETHAL and cm.cost[20, 25] == LETHAL
    # Everything but the square: the mark at (2.55, 2.05) goes only when the square excludes it.
    assert cm.clear_region(2.0, 2.0, 1.2, inside=False) == 1
    assert marks(cm) == {(20, 25)} and cm.cost[35, 3] == FREE
    assert cm.clear_region(2.0, 2.0, 0.0, inside=False) == 1 and not cm.obstacles.any()
    assert cm.cost[20, 20] == LETHAL and cm.cost[22, 17] == LETHAL


def test_clear_region_drops_the_bumper_marks_in_the_square_only() -> None:
    cm = free_costmap()
    cm.bumps.add(np.array([[1.0, 1.0], [3.0, 3.0]]), stamp=0.0)
    cm._inflate()
    assert cm.cost_at(np.array([[1.0, 1.0], [3.0, 3.0]])).tolist() == [LETHAL, LETHAL]
    cm.clear_region(1.0, 1.0, 0.5)
    assert cm.bumps.points.tolist() == [[3.0, 3.0]] and cm.cost_at(np.array([[1.0, 1.0]]))[0] == FREE


def test_clear_costmap_around_robot_tick_by_tick() -> None:
    client = board(NAVIGATOR_KEY, POSE_KEY)
    node = ClearCostmapAroundRobot("clear", reset_distance=1.0)
    assert tick(node) == F and node.feedback_message == "no navigation service"
    cm = free_costmap()
    client.set(NAVIGATOR_KEY, SimpleNamespace(costmap=cm))
    assert tick(node) == F and node.feedback_message == "no pose to clear round"
    mark(cm, (1.05, 1.05), (1.45, 0.65), (1.65, 1.05), (3.05, 3.05))
    client.set(POSE_KEY, Pose2(1.0, 1.0, 0.7))
    assert tick(node) == S
    assert marks(cm) == {(10, 16), (30, 30)}, "within 0.5 m on both axes of (1, 1) gone; x = 1.65 stays"
    assert node.feedback_message == "2 obstacle cells cleared within 1 m round (1.00, 1.00)"
    client.set(POSE_KEY, Pose2(3.0, 3.0, 0.0))
    assert tick(node) == S and marks(cm) == {(10, 16)}
    mark(cm, (3.05, 3.05))  # the scan marks it again: the next tick clears it again
    assert tick(node) == S and marks(cm) == {(10, 16)}
    assert tick(node) == S and node.feedback_message.startswith("0 obstacle cells")


def test_clear_costmap_around_pose_tick_by_tick() -> None:
    client = board(NAVIGATOR_KEY, POSE_KEY, "/goal")
    cm = free_costmap()
    client.set(NAVIGATOR_KEY, SimpleNamespace(costmap=cm))
    client.set(POSE_KEY, Pose2(0.5, 0.5, 0.0))
    mark(cm, (0.55, 0.55), (3.05, 2.05), (3.55, 2.05))
    node = ClearCostmapAroundPose("clear", pose_key="/goal", reset_distance=0.6)
    assert tick(node) == F and marks(cm) == {(5, 5), (20, 30), (20, 35)}, "no pose at /goal: nothing cleared"
    client.set("/goal", [3.0, 2.0, 1.0])
    assert tick(node) == S and marks(cm) == {(5, 5), (20, 35)}, "round the goal, not the robot"
    client.set("/goal", Pose2(3.5, 2.0, 0.0))
    assert tick(node) == S and marks(cm) == {(5, 5)}


def test_clear_costmap_except_region_tick_by_tick() -> None:
    client = board(NAVIGATOR_KEY, POSE_KEY)
    cm = free_costmap()
    client.set(NAVIGATOR_KEY, SimpleNamespace(costmap=cm))
    client.set(POSE_KEY, Pose2(2.0, 2.0, 0.0))
    mark(cm, (2.25, 2.05), (2.95, 2.05), (0.55, 0.55))
    node = ClearCostmapExceptRegion("keep", reset_distance=1.0)
    assert tick(node) == S and marks(cm) == {(20, 22)}, "only the mark within the 1 m square round the robot stays"
    assert cm.cost[20, 22] == LETHAL and cm.cost[5, 5] == FREE
    client.set(POSE_KEY, Pose2(0.5, 0.5, 0.0))
    assert tick(node) == S and marks(cm) == set(), "the robot moved away: that mark is outside now"


def straight(n: int, step: float = 0.5) -> np.ndarray:
    """n points along +x from the origin, ``step`` apart; the end heading 0.3 rad."""
    path = np.full((n, 3), math.nan)
    path[:, 0], path[:, 1] = np.arange(n) * step, 0.0
    path[-1, 2] = 0.3
    return path


def test_truncate_path_local_keeps_the_window_round_the_closest_pose_tick_by_tick() -> None:
    client = board(POSE_KEY, "/plan", "/local")
    client.set("/plan", straight(21))  # x = 0 .. 10 m
    node = TruncatePathLocal("local", distance_forward=2.0, distance_backward=1.0, input_key="/plan",
                             output_key="/local")
    assert tick(node) == F, "no robot pose"
    client.set(POSE_KEY, Pose2(3.1, 0.2, 0.0))
    assert tick(node) == S
    out = client.get("/local")
    assert out[:, 0].tolist() == [2.0, 2.5, 3.0, 3.5, 4.0, 4.5, 5.0], "1 m behind and 2 m ahead of x = 3"
    assert np.isnan(out[:-1, 2]).all() and out[-1, 2] == 0.0, "the end heading along the path"
    client.set(POSE_KEY, Pose2(9.6, 0.0, 0.0))
    assert tick(node) == S
    out = client.get("/local")
    assert out[:, 0].tolist() == [8.5, 9.0, 9.5, 10.0] and out[-1, 2] == 0.3, "ties go to the later pose; the end kept"
    client.set(POSE_KEY, Pose2(-2.0, 0.0, 0.0))
    assert tick(node) == S and client.get("/local")[:, 0].tolist() == [0.0, 0.5, 1.0, 1.5, 2.0]
    client.set("/plan", np.zeros((0, 3)))
    assert tick(node) == S and len(client.get("/local")) == 0


def out_and_back() -> np.ndarray:
    """Out along y = 0 to x = 2 m, then back along y = 0.2 m: a hairpin (every 0.5 m)."""
    xs = [0.0, 0.5, 1.0, 1.5, 2.0]
    pts = [(x, 0.0) for x in xs] + [(x, 0.2) for x in reversed(xs)]
    path = np.full((len(pts), 3), math.nan)
    path[:, :2] = pts
    return path


def test_truncate_path_local_weighs_the_heading_to_pick_the_right_leg() -> None:
    client = board(POSE_KEY, "/plan", "/local")
    client.set("/plan", out_and_back())
    client.set(POSE_KEY, Pose2(1.0, 0.15, math.pi))  # nearer the outward leg's y but facing back
    plain = TruncatePathLocal("plain", distance_forward=0.5, distance_backward=0.0, input_key="/plan",
                              output_key="/local")
    assert tick(plain) == S
    assert client.get("/local")[:, :2].tolist() == [[1.0, 0.2], [0.5, 0.2]], "0.05 m from the return leg"
    client.set(POSE_KEY, Pose2(1.0, 0.05, math.pi))  # now nearer the outward leg
    assert tick(plain) == S and client.get("/local")[:, :2].tolist() == [[1.0, 0.0], [1.5, 0.0]]
    weighted = TruncatePathLocal("weighted", distance_forward=0.5, distance_backward=0.0, angular_distance_weight=0.2,
                                 input_key="/plan", output_key="/local")
    assert tick(weighted) == S
    assert client.get("/local")[:, :2].tolist() == [[1.0, 0.2], [0.5, 0.2]], "facing back: the return leg"


def test_truncate_path_local_search_window_follows_the_robot_until_the_path_changes() -> None:
    client = board(POSE_KEY, "/plan", "/local")
    plan = out_and_back()
    client.set("/plan", plan)
    node = TruncatePathLocal("pruned", distance_forward=0.0, distance_backward=0.0, max_robot_pose_search_dist=1.0,
                             input_key="/plan", output_key="/local")
    client.set(POSE_KEY, Pose2(0.4, 0.0, 0.0))
    assert tick(node) == S and client.get("/local")[:, :2].tolist() == [[0.5, 0.0]]
    client.set(POSE_KEY, Pose2(1.9, 0.1, 0.0))
    assert tick(node) == S and client.get("/local")[:, :2].tolist() == [[1.5, 0.0]], "1 m of path past x = 0.5 only"
    assert tick(node) == S and client.get("/local")[:, :2].tolist() == [[2.0, 0.2]], "from x = 1.5 it reaches the turn"
    client.set(POSE_KEY, Pose2(1.0, 0.05, 0.0))
    assert tick(node) == S and client.get("/local")[:, :2].tolist() == [[1.0, 0.2]], "never back to the outward leg"
    client.set("/plan", plan.copy())  # an equal path (a new array): the search stays where it was
    assert tick(node) == S and client.get("/local")[:, :2].tolist() == [[1.0, 0.2]]
    new = plan.copy()
    new[-1, 2] = 1.0  # another path: the search starts over from its first pose
    client.set("/plan", new)
    assert tick(node) == S and client.get("/local")[:, :2].tolist() == [[1.0, 0.0]]


def test_remove_in_collision_goals_tick_by_tick() -> None:
    client = board(NAVIGATOR_KEY, "/goals", "/kept")
    g = np.zeros((40, 40), dtype=np.int8)
    g[20, 20] = 100  # lethal at (2.05, 2.05)
    g[30:, 30:] = -1  # unknown beyond (3, 3)
    cm = Costmap()
    cm.set_static(g, RES, (0.0, 0.0))
    goals = [Pose2(2.05, 2.05, 0.0), Pose2(2.15, 2.05, 0.0), Pose2(2.55, 2.05, 0.0), Pose2(3.55, 3.55, 0.0),
             Pose2(0.55, 0.55, 0.0), Pose2(9.0, 9.0, 0.0)]  # fmt: skip
    costs = cm.cost_at(np.array([[p.x, p.y] for p in goals])).tolist()
    assert costs[:2] == [LETHAL, INSCRIBED] and 0 < costs[2] < INSCRIBED and costs[3:] == [NO_INFORMATION, FREE,
                                                                                            NO_INFORMATION]
    node = RemoveInCollisionGoals("cull", input_key="/goals", output_key="/kept")
    client.set("/goals", goals)
    assert tick(node) == F, "no navigation service"
    client.set(NAVIGATOR_KEY, SimpleNamespace(costmap=cm))
    assert tick(node) == S
    assert client.get("/kept") == goals[2:], "lethal and (footprint-lethal) inscribed dropped; unknown kept"
    assert node.feedback_message == "4 of 6 goals clear"
    point = RemoveInCollisionGoals("point", input_key="/goals", output_key="/kept", use_footprint=False)
    assert tick(point) == S and client.get("/kept") == goals[1:], "the point cost: only the lethal one"
    assert costs[2] == 68, "0.5 m from the wall: 252 exp(-5 (0.5 - 0.226))"
    strict = RemoveInCollisionGoals("strict", input_key="/goals", output_key="/kept", cost_threshold=68.0,
                                    consider_unknown_as_obstacle=True)
    assert tick(strict) == S and client.get("/kept") == [goals[4]]
    mark(cm, (0.55, 0.55))  # the scan now sees something on the last free goal
    assert tick(strict) == S and client.get("/kept") == [] and strict.feedback_message == "every goal is in collision"
    client.set("/goals", [])
    assert tick(strict) == S and client.get("/kept") == []


NAV_TREE = """<root BTCPP_format="4" main_tree_to_execute="NavigateToPose">
  <BehaviorTree ID="NavigateToPose">
    <RecoveryNode number_of_retries="6" name="NavigateRecovery">
      <PipelineSequence name="NavigateWithReplanning">
        <RateController hz="1.0">
          <RecoveryNode number_of_retries="1" name="ComputePathToPose">
            <ComputePathToPose goal="{goal}" path="{path}" planner_id="GridBased"/>
            <ClearCostmapAroundPose name="ClearAroundGoal" pose="{goal}" reset_distance="1.5"
                                    service_name="global_costmap/clear_around_pose_global_costmap"/>
          </RecoveryNode>
        </RateController>
        <TruncatePathLocal input_path="{path}" output_path="{local_path}" distance_forward="3.0"
                           distance_backward="1.0" robot_frame="base_link" angular_distance_weight="0.2"/>
        <FollowPath path="{path}" controller_id="FollowPath"/>
      </PipelineSequence>
      <ReactiveFallback name="RecoveryFallback">
        <GoalUpdated/>
        <RoundRobin name="RecoveryActions">
          <ClearCostmapAroundRobot name="ClearLocalAroundRobot" reset_distance="2.0"
                                   service_name="local_costmap/clear_around_local_costmap"/>
          <ClearCostmapExceptRegion name="ClearGlobalExcept" reset_distance="3.0"
                                    service_name="global_costmap/clear_except_global_costmap"/>
          <Spin spin_dist="1.57"/>
          <BackUp backup_dist="0.30" backup_speed="0.05"/>
        </RoundRobin>
      </ReactiveFallback>
    </RecoveryNode>
  </BehaviorTree>
</root>
"""


def test_a_nav2_tree_with_the_region_nodes_imports_and_checks(tmp_path: Path) -> None:
    xml = tmp_path / "nav.xml"
    xml.write_text(NAV_TREE)
    out = tmp_path / "nav.yaml"
    assert main(["import", str(xml), "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out, {"goal": [1.0, 0.0, 0.0]})
    by_name = {b.name: (mission.info[b.id].spec, mission.info[b.id].params) for b in mission.root.iterate()}
    assert by_name["ClearAroundGoal"] == ("ClearCostmapAroundPose", {"pose_key": "/goal", "reset_distance": 1.5})
    assert by_name["ClearLocalAroundRobot"] == ("ClearCostmapAroundRobot", {"reset_distance": 2.0})
    assert by_name["ClearGlobalExcept"] == ("ClearCostmapExceptRegion", {"reset_distance": 3.0})
    local = next(p for s, p in by_name.values() if s == "TruncatePathLocal")
    assert local.pop("pose_key") == POSE_KEY and math.isnan(local.pop("max_robot_pose_search_dist"))
    assert local == {"input_key": "/path", "output_key": "/local_path", "distance_forward": 3.0,
                     "distance_backward": 1.0, "angular_distance_weight": 0.2}


def test_remove_in_collision_goals_imports_with_its_ports(tmp_path: Path) -> None:
    xml = tmp_path / "through.xml"
    xml.write_text("""<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>
      <RemoveInCollisionGoals input_goals="{goals}" output_goals="{goals}" cost_threshold="253"
                              use_footprint="false" consider_unknown_as_obstacle="true"
                              service_name="/global_costmap/get_cost_global_costmap"/>
      <ComputePathThroughPoses goals="{goals}" path="{path}"/>
    </Sequence></BehaviorTree></root>""")
    result = import_xml(xml)
    out = tmp_path / "through.yaml"
    out.write_text(result.text)
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out, {"goals": [[1.0, 0.0, 0.0]]})
    params = next(i.params for i in mission.info.values() if i.spec == "RemoveInCollisionGoals")
    assert params == {"input_key": "/goals", "output_key": "/goals", "cost_threshold": 253.0, "use_footprint": False,
                      "consider_unknown_as_obstacle": True}


def imported(tmp_path: Path, xml: str, note: str) -> Path:
    """The mission ``homing import`` writes for ``xml``, having checked that one of its notes says ``note``."""
    source = tmp_path / "tree.xml"
    source.write_text(xml)
    result = import_xml(source)
    assert any(note in n for n in result.notes), result.notes
    out = tmp_path / "tree.yaml"
    out.write_text(result.text)
    return out


def test_are_error_codes_present_checks_homing_reasons_for_nav2_codes_tick_by_tick(tmp_path: Path) -> None:
    out = imported(tmp_path, """<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>
      <AreErrorCodesPresent error_code="{compute_path_error_code}" error_codes_to_check="208;205;202;105"/>
    </Sequence></BehaviorTree></root>""", note="homing never reports 202 (TF_ERROR: no TF)")
    mission = compile_mission(out)
    leaf = next(b for b in mission.root.iterate() if mission.info[b.id].spec == "FailureIs")
    assert mission.info[leaf.id].params == {"key": "/compute_path_error_code",
                                           "reasons": ["no_path", "start_occupied", "no_progress"]}
    client = board("/compute_path_error_code")
    assert tick(leaf) == F, "unset: nothing failed"
    for reason, status in [("no_path", S), (None, F), ("goal_occupied", F), ("start_occupied", S), ("no_progress", S),
                           ("blocked", F)]:  # fmt: skip
        client.set("/compute_path_error_code", reason)
        assert tick(leaf) == status, reason


def test_an_unknown_nav2_error_code_is_an_error_at_its_attribute(tmp_path: Path) -> None:
    xml = tmp_path / "codes.xml"
    xml.write_text('<root BTCPP_format="4"><BehaviorTree ID="T">\n'
                   '<AreErrorCodesPresent error_code="{e}" error_codes_to_check="208;701"/></BehaviorTree></root>')
    with pytest.raises(UserError) as info:
        import_xml(xml)
    assert "701 is none of Nav2's controller (1xx), planner (2xx, 3xx) or smoother (5xx) error codes" in str(info.value)
    assert f"{xml}:2:" in str(info.value)


@pytest.mark.usefixtures("maze")
def test_navigate_through_poses_passes_each_pose_then_reaches_the_last(tmp_path: Path) -> None:
    xml = tmp_path / "through.xml"
    xml.write_text("""<root BTCPP_format="4"><BehaviorTree ID="T">
      <NavigateThroughPoses goals="{goals}" behavior_tree="" error_code_id="{nav_error}"/>
    </BehaviorTree></root>""")
    body = import_xml(xml).text.split("tree:\n", 1)[1]
    assert body.strip() == "NavigateThroughPoses: {goals_key: goals, failure_key: nav_error}"
    tree = f"  sequence:\n    - SetBlackboard: {{key: goals, value: {VIA}}}\n    - {body.strip()}\n"
    runner, log, trail = run_maze(tmp_path, tree, until=200.0)
    assert runner.result.reason == "success", "\n".join(c.line() for c in log[-20:])  # type: ignore[attr-defined]
    xy = np.array([(p.x, p.y) for p in trail])
    near = [int(np.argmin(np.hypot(*(xy - g[:2]).T))) for g in VIA]
    assert near == sorted(near), "the poses are passed in order"
    assert min(np.hypot(*(xy - VIA[0][:2]).T)) <= 0.5 + 0.05 and min(np.hypot(*(xy - VIA[1][:2]).T)) <= 0.55
    assert math.hypot(xy[-1, 0] - VIA[2][0], xy[-1, 1] - VIA[2][1]) <= 0.15 + 1e-6
    passed = [c for c in log if c.node == "NavigateThroughPoses" and c.new == Status.SUCCESS]
    assert len(passed) == 1, "one activation: it never stops between the poses"


@pytest.mark.usefixtures("maze")
def test_navigate_through_poses_fails_on_an_empty_list(tmp_path: Path) -> None:
    tree = "  sequence: [SetBlackboard: {key: goals, value: []}, NavigateThroughPoses: {goals_key: goals}]\n"
    runner, _, _ = run_maze(tmp_path, tree, until=2.0)
    assert runner.result.reason == "failure"  # type: ignore[attr-defined]
    assert py_trees.blackboard.Blackboard.storage.get("/nav/failure") == "no_goal"


def corner(n: int = 20, step: float = 0.1) -> np.ndarray:
    """An L: n points up x from (1, 1) m, then n along y: a right-angle corner at (1 + n·step, 1)."""
    leg = np.arange(n) * step
    a = np.column_stack([1.0 + leg, np.full(n, 1.0)])
    b = np.column_stack([np.full(n, 1.0 + n * step), 1.0 + leg])
    return np.vstack([a, b])


def test_smoothing_converges_to_nav2s_fixed_point_and_keeps_the_ends() -> None:
    path = corner()
    out, done = smooth_path(path, refinements=0)
    assert done and out[0].tolist() == path[0].tolist() and out[-1].tolist() == path[-1].tolist()
    # Converged: every inner point satisfies w_data (x - y) + w_smooth (y+ + y- - 2 y) = 0 (Nav2's update is zero).
    residual = 0.2 * (path[1:-1] - out[1:-1]) + 0.3 * (out[2:] + out[:-2] - 2.0 * out[1:-1])
    assert np.abs(residual).max() < 1e-9
    corner_gap = np.hypot(*(out[len(path) // 2] - (3.0, 1.0)))
    assert 0.05 < corner_gap < 0.3, "the corner is cut, but not far"
    refined, done = smooth_path(path)
    turn = np.abs(np.diff(np.arctan2(*np.diff(refined, axis=0).T[::-1]))).max()
    assert done and turn < np.abs(np.diff(np.arctan2(*np.diff(out, axis=0).T[::-1]))).max() < math.pi / 2
    short = corner(5)
    assert smooth_path(short)[0].tolist() == short.tolist(), "10 points or fewer are left alone"


def test_smoothing_stops_before_a_point_would_enter_a_costly_cell() -> None:
    g = np.zeros((60, 60), dtype=np.int8)
    g[13, 27] = 100  # a wall cell inside the corner at (2.75, 1.35): cutting the corner comes close to it
    cm = Costmap()
    cm.set_static(g, 0.1, (0.0, 0.0))
    path = corner()
    assert (cm.cost_at(path) <= 252).all(), "the L itself keeps clear"
    free, _ = smooth_path(path)
    assert (cm.cost_at(free) > 252).any(), "without the costmap the smoothing cuts into the wall's margin"
    out, done = smooth_path(path, cm.cost_at)
    assert not done and (cm.cost_at(out) <= 252).all(), "the last admissible path, and was_completed false"
    assert np.abs(out - path).max() > 0.0, "it smoothed as far as it could"


def test_smooth_path_leaf_tick_by_tick() -> None:
    client = board(NAVIGATOR_KEY, "/plan", "/smooth", "/done", "/err")
    node = SmoothPath("smooth", input_key="/plan", output_key="/smooth", completed_key="/done", failure_key="/err")
    assert tick(node) == F and client.get("/err") == "no_navigator"
    cm = free_costmap(60)
    client.set(NAVIGATOR_KEY, SimpleNamespace(costmap=cm))
    assert tick(node) == F and client.get("/err") == "invalid_path" and not client.exists("/smooth")
    plan = np.full((40, 3), math.nan)
    plan[:, :2], plan[-1, 2] = corner(), 1.2
    client.set("/plan", plan)
    assert tick(node) == S and client.get("/err") is None and client.get("/done") is True
    out = client.get("/smooth")
    assert out.shape == (40, 3) and out[-1, 2] == 1.2 and np.isnan(out[:-1, 2]).all()
    assert np.allclose(out[:, :2], smooth_path(corner())[0])
    mark(cm, (3.05, 2.5))  # an obstacle beside the second leg, within the inscribed radius of it
    checked = SmoothPath("checked", input_key="/plan", output_key="/smooth", check_for_collisions=True,
                         failure_key="/err")
    client.set("/smooth", None)
    assert tick(checked) == F and client.get("/err") == "smoothed_path_in_collision" and client.get("/smooth") is None
    assert tick(node) == S and client.get("/done") is False, "unchecked it succeeds, stopped early at the obstacle"


def test_smooth_path_and_its_recovery_condition_import_and_check(tmp_path: Path) -> None:
    out = imported(tmp_path, """<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>
      <ComputePathToPose goal="{goal}" path="{path}" error_code_id="{plan_error}"/>
      <Fallback>
        <SmoothPath unsmoothed_path="{path}" smoothed_path="{smooth}" smoother_id="simple_smoother"
                    max_smoothing_duration="3.0" check_for_collisions="true" was_completed="{done}"
                    error_code_id="{smooth_error}"/>
        <Sequence>
          <WouldASmootherRecoveryHelp error_code="{smooth_error}"/>
          <ClearEntireCostmap/>
        </Sequence>
      </Fallback>
      <AreErrorCodesPresent error_code="{smooth_error}" error_codes_to_check="503;504"/>
    </Sequence></BehaviorTree></root>""", note="homing never reports 504 (FAILED_TO_SMOOTH_PATH")
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out, {"goal": [1.0, 0.0, 0.0]})
    specs = [(mission.info[b.id].spec, mission.info[b.id].params) for b in mission.root.iterate()]
    assert ("SmoothPath", {"input_key": "/path", "output_key": "/smooth", "check_for_collisions": True,
                           "completed_key": "/done", "failure_key": "/smooth_error"}) in specs
    assert ("FailureIs", {"key": "/smooth_error", "reasons": ["smoothed_path_in_collision", "failed", "timed_out"]}) in specs
    assert ("FailureIs", {"key": "/smooth_error", "reasons": ["smoothed_path_in_collision"]}) in specs


def test_reinitialize_global_localization_has_grid_slam_find_the_robot_in_the_whole_map() -> None:
    py_trees.blackboard.Blackboard.clear()
    robot = SimRobot(load_world("lab"), seed=1)
    try:
        service = GridSlamService()
        client = py_trees.blackboard.Client(name="service:grid_slam")
        for key in GridSlamService.writes:
            client.register_key(key=key, access=py_trees.common.Access.WRITE)
        service.setup(robot, client)
        leaf = ReinitializeGlobalLocalization("reinit")
        for i in range(40):  # 8 s: back 0.6 m off the dock, then stand, mapping
            robot.command(-0.15 if i < 20 else 0.0, 0.0)
            robot.step(0.2)
            service.update(robot.observe())
        assert not robot.observe().battery.on_dock and client.get(LOCALIZED_KEY)
        here = service.slam.pose
        service.slam.set_pose(Pose2(here.x + 1.5, here.y - 0.5, here.theta + 0.4), robot.observe().odom.pose)
        assert tick(leaf) == S and client.get(RELOCALIZE_KEY) is True
        robot.step(0.2)
        service.update(robot.observe())
        assert client.get(RELOCALIZE_KEY) is False and service.reinitialised == 1, "the request is taken once"
        assert service.slam.lost and not client.get(LOCALIZED_KEY), "lost until a scan is found in the map"
        for _ in range(10):  # standing still, a scan is fused each second
            robot.step(0.2)
            service.update(robot.observe())
        assert service.slam.last_relocalisation is not None, "the scan was looked for in the whole map"
        assert client.get(LOCALIZED_KEY) and service.slam.pose.distance_to(here) < 0.1, "found where it stands"
    finally:
        robot.close()


def test_transform_available_succeeds_for_homings_frames_and_names_the_others(tmp_path: Path) -> None:
    xml = tmp_path / "tf.xml"
    xml.write_text('<root BTCPP_format="4"><BehaviorTree ID="T">\n'
                   '<TransformAvailable child="base_link" parent="/map"/></BehaviorTree></root>')
    result = import_xml(xml)
    assert "Succeed" in result.text and any("the transform is available" in n for n in result.notes)
    xml.write_text('<root BTCPP_format="4"><BehaviorTree ID="T">\n'
                   '<TransformAvailable child="base_footprint" parent="map"/></BehaviorTree></root>')
    with pytest.raises(UserError) as info:
        import_xml(xml)
    assert str(info.value).startswith(f"{xml}:2:")
    assert "<TransformAvailable child=\"base_footprint\">: homing's frames are map, odom, base_link, laser, camera" \
        in str(info.value)


def test_round_robin_takes_wrap_around_true_and_refuses_false(tmp_path: Path) -> None:
    xml = tmp_path / "rr.xml"
    tree = ('<root BTCPP_format="4"><BehaviorTree ID="T">\n'
            '<RoundRobin wrap_around="{}"><AlwaysFailure/><AlwaysSuccess/></RoundRobin></BehaviorTree></root>')
    xml.write_text(tree.format("true"))
    assert "round_robin" in import_xml(xml).text
    xml.write_text(tree.format("false"))
    with pytest.raises(UserError) as info:
        import_xml(xml)
    assert f"{xml}:2:" in str(info.value) and "false is not supported" in str(info.value)


@pytest.mark.slow
def test_the_tree_with_the_region_nodes_drives_the_simulated_robot_to_a_goal(tmp_path: Path) -> None:
    xml = tmp_path / "nav.xml"
    xml.write_text(NAV_TREE)
    out = tmp_path / "nav.yaml"
    assert main(["import", str(xml), "-o", str(out)]) == 0
    robot = SimRobot(load_world("lab"), seed=1, camera=False)
    start = robot.truth_pose()  # grid SLAM's map frame starts at the robot's first pose
    goal_world = (8.0, 2.0)  # [m] the lab's east room, behind the partition (as tests/test_btxml.py)
    goal = start.between(Pose2(goal_world[0], goal_world[1], start.theta))
    try:
        result = Runner(compile_mission(out, {"goal": [goal.x, goal.y, goal.theta]}), robot, seed=1, until=150.0).run()
        end = robot.truth_pose()  # evaluation only
    finally:
        robot.close()
    assert result.reason == "success"
    assert math.hypot(end.x - goal_world[0], end.y - goal_world[1]) < 0.15 + 0.1  # tolerance + SLAM's drift
    local = py_trees.blackboard.Blackboard.storage["/local_path"]
    assert 0 < len(local) and path_length(local) <= 4.0 + 0.1, "TruncatePathLocal kept 1 m behind, 3 m ahead"
