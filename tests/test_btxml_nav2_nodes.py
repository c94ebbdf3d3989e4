"""Nav2's whole node set: every node of ``nav2_tree_nodes.xml`` maps onto a homing node or is refused with its reason.

The IDs below are those of ``nav2_behavior_tree/nav2_tree_nodes.xml`` in
ros-navigation/navigation2 (rolling, commit 011cd937), its Groot model of
every node Nav2 registers. A tree using the newer nodes (goal updates, path
utilities, the new sequences, BT.CPP 4's ``TryCatch``) imports and passes
``homing check``.
"""

from __future__ import annotations

from pathlib import Path

import py_trees
import pytest
from homing.behaviours import load_nodes
from homing.behaviours.registry import NODES
from homing.btxml.catalog import NO_EQUIVALENT, RULES
from homing.btxml.importer import import_xml
from homing.missions.cli import main
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner

from homing.errors import UserError
from tests.mission_fakes import FakeRobot

NAV2_NODES = """
BackUp DriveOnHeading CancelControl CancelBackUp CancelDriveOnHeading CancelSpin CancelAssistedTeleop CancelWait
CancelComputeAndTrackRoute ClearEntireCostmap ClearCostmapExceptRegion ClearCostmapAroundRobot ClearCostmapAroundPose
ComputePathToPose ComputePathThroughPoses ComputeRoute ComputeAndTrackRoute RemovePassedGoals RemoveInCollisionGoals
SmoothPath FollowPath NavigateToPose NavigateThroughPoses ReinitializeGlobalLocalization TruncatePath TruncatePathLocal
PlannerSelector ControllerSelector SmootherSelector GoalCheckerSelector ProgressCheckerSelector Spin Wait AssistedTeleop
DockRobot UndockRobot GetPoseFromPath GetCurrentPose ConcatenatePaths
GoalReached IsStuck IsStopped TransformAvailable GoalUpdated GlobalUpdatedGoal IsBatteryLow IsBatteryCharging
DistanceTraveled TimeExpired PathExpiringTimer InitialPoseReceived IsPathValid WouldAControllerRecoveryHelp
WouldAPlannerRecoveryHelp WouldASmootherRecoveryHelp WouldARouteRecoveryHelp AreErrorCodesPresent ArePosesNear
PipelineSequence RecoveryNode RoundRobin NonblockingSequence PauseResumeController PersistentSequence
RateController DistanceController SingleTrigger GoalUpdater SpeedController PathLongerOnApproach GoalUpdatedController
""".split()


def test_every_nav2_node_is_mapped_or_refused_with_a_reason() -> None:
    load_nodes()
    assert len(NAV2_NODES) == len(set(NAV2_NODES)) == 71
    for name in NAV2_NODES:
        if name in RULES:
            assert RULES[name].homing in NODES, f"{name} maps to {RULES[name].homing}, which is not registered"
        else:
            reason = NO_EQUIVALENT.get(name, "")
            assert reason and "\n" not in reason, f"{name} is neither mapped nor refused with a reason"
    mapped = [n for n in NAV2_NODES if n in RULES]
    assert len(mapped) == 64, f"{len(mapped)} of 71 mapped (7 refused, each with its reason)"


NEWER = """<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main">
    <TryCatch>
      <PersistentSequence current_child_idx="{step}">
        <GoalUpdater input_goal="{goal}" output_goal="{updated_goal}">
          <AlwaysSuccess/>
        </GoalUpdater>
        <GetCurrentPose current_pose="{here}"/>
        <ArePosesNear ref_pose="{here}" target_pose="{here}" tolerance="0.1"/>
        <NonblockingSequence>
          <AlwaysSuccess/>
          <Script code="done := true"/>
        </NonblockingSequence>
        <GoalUpdatedController goal="{updated_goal}">
          <AlwaysSuccess/>
        </GoalUpdatedController>
        <PauseResumeController pause_service_name="/operator/pause" resume_service_name="/operator/resume">
          <AlwaysSuccess/>
          <Wait wait_duration="1"/>
        </PauseResumeController>
      </PersistentSequence>
      <Script code="caught := true"/>
    </TryCatch>
  </BehaviorTree>
</root>
"""


def test_a_tree_of_the_newer_nodes_imports_checks_and_runs(tmp_path: Path) -> None:
    xml = tmp_path / "newer.xml"
    xml.write_text(NEWER)
    out = tmp_path / "newer.yaml"
    assert main(["import", str(xml), "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0
    mission = compile_mission(out, {"goal": [1.0, 0.0, 0.0]})
    kinds = {i.spec for i in mission.info.values()}
    assert {"try_catch", "persistent_sequence", "GoalUpdater", "GetCurrentPose", "ArePosesNear",
            "nonblocking_sequence", "GoalUpdatedController", "pause_resume_controller"} <= kinds
    pause = next(i for i in mission.info.values() if i.spec == "pause_resume_controller")
    assert pause.params == {"pause_key": "/operator/pause", "resume_key": "/operator/resume"}
    runner = Runner(mission, FakeRobot(), until=1.0)
    assert runner.run().reason == "success"


def test_nav2_nodes_with_ports_are_converted(tmp_path: Path) -> None:
    xml = tmp_path / "paths.xml"
    xml.write_text("""<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>
      <PathLongerOnApproach path="{path}" prox_len="3.0" length_factor="2.0"><Wait wait_duration="5"/></PathLongerOnApproach>
      <TruncatePath distance="1.0" input_path="{path}" output_path="{truncated}"/>
      <GetPoseFromPath path="{truncated}" index="-1" pose="{end}"/>
      <PathExpiringTimer seconds="15" path="{path}"/>
    </Sequence></BehaviorTree></root>""")
    out = tmp_path / "paths.yaml"
    out.write_text(import_xml(xml).text)
    assert main(["check", str(out)]) == 0, "the path the tree reads becomes a mission input"
    mission = compile_mission(out, {"path": [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]})
    by_kind = {i.spec: i.params for i in mission.info.values()}
    assert by_kind["path_longer_on_approach"] == {"path_key": "/path", "prox_len": 3.0, "length_factor": 2.0}
    assert by_kind["TruncatePath"] == {"distance": 1.0, "input_key": "/path", "output_key": "/truncated"}
    assert by_kind["GetPoseFromPath"]["pose_key"] == "/end" and by_kind["GetPoseFromPath"]["index"] == -1


@pytest.mark.parametrize("name", ["AssistedTeleop", "InitialPoseReceived", "ComputeRoute", "Finally", "LatchedSequence"])
def test_unmapped_nodes_are_refused_with_their_reason(tmp_path: Path, name: str) -> None:
    xml = tmp_path / "t.xml"
    body = f"<{name}><AlwaysSuccess/><AlwaysSuccess/></{name}>" if name in ("Finally", "LatchedSequence") else f"<{name}/>"
    xml.write_text(f'<root BTCPP_format="4">\n<BehaviorTree ID="T">\n  {body}\n</BehaviorTree></root>')
    with pytest.raises(UserError) as info:
        import_xml(xml)
    assert str(info.value) == f"{xml}:3:3: <{name}> has no homing equivalent: {NO_EQUIVALENT[name]}"


NAV2 = Path(__file__).parent / "data" / "nav2"


def test_odometry_calibration_drives_a_square_back_to_its_start(tmp_path: Path) -> None:
    out = tmp_path / "square.yaml"
    assert main(["import", str(NAV2 / "odometry_calibration.xml"), "-o", str(out)]) == 0
    robot = FakeRobot()
    result = Runner(compile_mission(out), robot, until=200.0).run()
    assert result.reason == "success"
    legs = [p for p in robot.commands if p[1] > 0.0]
    assert legs and max(p[1] for p in legs) == pytest.approx(0.02), "DriveOnHeading at Nav2's speed 0.02 m/s"
    assert robot.pose.x == pytest.approx(0.0, abs=0.03) and robot.pose.y == pytest.approx(0.0, abs=0.03)
    assert 40.0 < result.time < 60.0, "4 x 0.2 m at 0.02 m/s plus four quarter turns"


def test_drive_on_heading_refuses_a_speed_against_the_distance(tmp_path: Path) -> None:
    xml = tmp_path / "bad.xml"
    xml.write_text('<root><BehaviorTree ID="T"><DriveOnHeading dist_to_travel="0.2" speed="-0.1"/></BehaviorTree></root>')
    out = tmp_path / "bad.yaml"
    out.write_text(import_xml(xml).text)
    robot = FakeRobot()
    runner = Runner(compile_mission(out), robot, until=5.0)
    assert runner.run().reason == "failure" and robot.pose.x == 0.0
    assert py_trees.blackboard.Blackboard.storage["/nav/failure"] == "bad_request"


def test_follow_point_follows_goal_updates(tmp_path: Path) -> None:
    out = tmp_path / "follow.yaml"
    assert main(["import", str(NAV2 / "follow_point.xml"), "-o", str(out)]) == 0
    mission = compile_mission(out, {"goal": [1.0, 0.0, 0.0]})
    by_kind = {i.spec: i.params for i in mission.info.values()}
    assert by_kind["GoalUpdater"]["output_goal"] == "/updated_goal"
    assert by_kind["ComputePathToPose"]["goal_key"] == "/updated_goal"
    assert by_kind["TruncatePath"] == {"distance": 1.0, "input_key": "/path", "output_key": "/truncated_path"}
    assert by_kind["FollowPath"]["path_key"] == "/truncated_path"
