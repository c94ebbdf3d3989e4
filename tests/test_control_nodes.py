"""The control nodes BT.CPP, Nav2 and py_trees users expect, pinned tick by tick (STYLE.md rule 10).

Each test scripts its children's statuses and states every node's status
after every tick, with the tick and halt counts, against the reference
implementation's semantics (BT.CPP v4 ``src/controls`` and
``src/decorators``, Nav2 ``nav2_behavior_tree/plugins``, py_trees
``decorators``) as the node's docstring spells them out.
"""

from __future__ import annotations

import py_trees
import pytest
from homing.behaviours import branching as br
from homing.behaviours import decorators as d
from homing.behaviours import outcomes as oc
from homing.behaviours import sequences as sq
from homing.behaviours import throttles as th
from homing.behaviours.keys import OBSERVATION_KEY, POSE_KEY
from homing.behaviours.testing import StatusQueue
from homing.robot import Pose2
from py_trees.common import Access, Status

from tests.mission_fakes import F, FakeRobot, R, S, Scripted, after, tick

N = Status.INVALID


def statuses(*nodes: object) -> list[Status]:
    return [n.status for n in nodes]  # type: ignore[attr-defined]


def setup(root: object, robot: FakeRobot) -> None:
    for node in root.iterate():  # type: ignore[attr-defined]
        node.setup(robot=robot)


def writer(*keys: str) -> py_trees.blackboard.Client:
    client = py_trees.blackboard.Client(name="test-writer")
    for key in keys:
        client.register_key(key=key, access=Access.WRITE)
    return client


# --------------------------------------------------------------------------- branching


def test_if_then_else_runs_the_chosen_branch_to_its_end_without_rechecking() -> None:
    cond, then, other = Scripted("cond", [R, S, F]), Scripted("then", after(3)), Scripted("else", [S])
    node = br.IfThenElse("ite", **{"if": cond, "then": then, "else": other})
    assert tick(node) == R and statuses(cond, then, other) == [R, N, N]  # condition undecided
    assert tick(node) == R and statuses(cond, then, other) == [S, R, N]
    assert tick(node) == R and cond.ticks == 2, "not reactive: the condition is not ticked while 'then' runs"
    assert tick(node) == S and statuses(then, other) == [S, N]
    assert tick(node) == S and statuses(cond, then, other) == [F, N, S], "a new activation decides again"


def test_if_then_else_without_else_fails_on_a_false_condition() -> None:
    cond, then = Scripted("cond", [F]), Scripted("then", [S])
    node = br.IfThenElse("ite", **{"if": cond, "then": then})
    assert tick(node) == F and then.ticks == 0


def test_if_then_else_halt_resets_the_choice() -> None:
    cond, then = Scripted("cond", [S]), Scripted("then", [R])
    node = br.IfThenElse("ite", **{"if": cond, "then": then})
    tick(node)
    node.stop(Status.INVALID)
    assert statuses(node, cond, then) == [N, N, N] and then.halts == 1
    tick(node)
    assert cond.ticks == 2, "after a halt the condition is ticked again"


def test_while_do_else_switches_branches_as_the_condition_changes() -> None:
    cond, do, other = Scripted("cond", [S, S, F, F, S]), Scripted("do", [R]), Scripted("else", [R, S])
    node = br.WhileDoElse("wde", **{"while": cond, "do": do, "else": other})
    assert [tick(node) for _ in range(2)] == [R, R] and do.ticks == 2
    assert tick(node) == R and statuses(do, other) == [N, R] and do.halts == 1, "false: 'do' halted, 'else' ticked"
    assert tick(node) == S and statuses(node, other) == [S, S]
    assert tick(node) == R and statuses(do, other) == [R, N]


def test_while_do_else_without_else_halts_do_and_fails() -> None:
    cond, do = Scripted("cond", [S, F]), Scripted("do", [R])
    node = br.WhileDoElse("wde", **{"while": cond, "do": do})
    assert tick(node) == R
    assert tick(node) == F and do.status == N and do.halts == 1


def test_while_do_else_running_condition_ticks_no_branch() -> None:
    cond, do = Scripted("cond", [S, R, S]), Scripted("do", [R])
    node = br.WhileDoElse("wde", **{"while": cond, "do": do})
    tick(node)
    assert tick(node) == R and do.ticks == 1 and do.status == R, "BT.CPP leaves the branch as it is"
    tick(node)
    assert do.ticks == 2 and do.starts == 1


def test_switch_picks_the_case_and_halts_the_previous_one() -> None:
    bb = writer("/mode")
    a, b, default = Scripted("a", [R]), Scripted("b", [R]), Scripted("default", [S])
    node = br.Switch("sw", key="/mode", cases=["explore", 2], children=[a, b, default])
    assert tick(node) == S and default.ticks == 1, "unset key: the default"
    bb.set("/mode", "explore")
    assert tick(node) == R and a.status == R
    bb.set("/mode", "2")
    assert tick(node) == R and statuses(a, b) == [N, R] and a.halts == 1, "'2' matches 2 as BT.CPP compares"
    bb.set("/mode", 2.0)
    assert tick(node) == R and b.ticks == 2 and b.starts == 1
    bb.set("/mode", "other")
    assert tick(node) == S and b.halts == 1 and default.ticks == 2


def test_switch_needs_one_child_per_case_plus_default() -> None:
    with pytest.raises(ValueError, match="3 children, not 2"):
        br.Switch("sw", key="/k", cases=[1, 2], children=[Scripted("a", [S]), Scripted("b", [S])])


# --------------------------------------------------------------------------- sequences


def test_pipeline_sequence_reticks_reached_children_as_nav2() -> None:
    # Nav2's doc: tick the first till it succeeds, then the first and second, and so on.
    plan, follow, last = Scripted("plan", [R, S]), Scripted("follow", [R, R, R, S]), Scripted("last", [R, S])
    node = sq.PipelineSequence("pipe", [plan, follow, last])
    assert tick(node) == R and statuses(plan, follow, last) == [R, N, N]
    assert tick(node) == R and statuses(plan, follow, last) == [S, R, N]
    assert tick(node) == R and plan.ticks == 3 and plan.starts == 2, "the succeeded planner is started again"
    plan.script, plan.i = [R], 0
    assert tick(node) == R and statuses(plan, follow, last) == [R, R, N], "a planner running behind does not stop the walk"
    assert tick(node) == R and statuses(plan, follow, last) == [R, S, R]
    assert tick(node) == S and plan.status == N and plan.halts == 1, "done: the planner still running is halted"
    assert (follow.starts, last.ticks) == (2, 2)


def test_pipeline_sequence_failure_halts_everything() -> None:
    a, b = Scripted("a", [S, S, F]), Scripted("b", [R])
    node = sq.PipelineSequence("pipe", [a, b])
    assert [tick(node) for _ in range(2)] == [R, R]
    assert tick(node) == F and b.status == N and b.halts == 1
    assert node.furthest == 0


def test_pipeline_sequence_succeeds_when_the_last_succeeds_and_halts_runners() -> None:
    a, b = Scripted("a", [S, R]), Scripted("b", [R, S])
    node = sq.PipelineSequence("pipe", [a, b])
    assert tick(node) == R
    assert tick(node) == S and a.status == N and a.halts == 1, "a, still running behind, is halted"


def test_sequence_with_memory_resumes_at_the_failed_child() -> None:
    a, b, c = Scripted("a", [S]), Scripted("b", [F, S]), Scripted("c", [R, S])
    node = sq.SequenceWithMemory("swm", [a, b, c])
    assert tick(node) == F and (a.ticks, b.ticks) == (1, 1)
    assert tick(node) == R and (a.ticks, b.ticks, c.ticks) == (1, 2, 1), "a is not run again"
    node.stop(Status.INVALID)  # a halt keeps the place too
    assert c.halts == 1
    assert tick(node) == S and (a.ticks, b.ticks, c.ticks) == (1, 2, 2)
    assert tick(node) == S and a.ticks == 2, "after SUCCESS it starts over"


def test_sequence_passes_over_a_skipped_child() -> None:
    once = oc.RunOnce("once", Scripted("undock", [S]))
    b = Scripted("b", [S])
    seq = d.Sequence("seq", [once, b])
    assert tick(seq) == S and statuses(once, b) == [S, S]
    assert tick(seq) == S and statuses(once, b) == [N, S] and b.ticks == 2, "skipped: the sequence goes on"
    only = d.Sequence("only", [oc.RunOnce("o2", Scripted("x", [S]))])
    tick(only)
    assert tick(only) == N, "a sequence whose children were all skipped is skipped"


def test_fallback_passes_over_a_skipped_child() -> None:
    once = oc.RunOnce("once", Scripted("try", [F]))
    b = Scripted("b", [S])
    fb = d.Fallback("fb", [once, b])
    assert tick(fb) == S and b.ticks == 1
    assert tick(fb) == S and once.status == N and b.ticks == 2


# --------------------------------------------------------------------------- throttles


def test_rate_controller_is_running_between_ticks_of_its_child() -> None:
    robot = FakeRobot()
    child = Scripted("plan", [S])
    node = th.RateController("rc", child, hz=2.0)
    setup(node, robot)
    got = [tick(node, robot, dt=0.1) for _ in range(12)]
    assert got == [S, R, R, R, R, S, R, R, R, R, S, R]
    assert child.ticks == 3, "ticked at t = 0.0, 0.5, 1.0 (each period after the last success)"


def test_rate_controller_ticks_a_running_child_every_tick_and_restarts_after_halt() -> None:
    robot = FakeRobot()
    child = Scripted("plan", [R, R, S, S])
    node = th.RateController("rc", child, hz=1.0)
    setup(node, robot)
    assert [tick(node, robot) for _ in range(4)] == [R, R, S, R]
    assert child.ticks == 3
    node.stop(Status.INVALID)
    assert tick(node, robot) == S and child.ticks == 4, "after a halt the child is ticked at once"


def test_distance_controller_ticks_again_after_the_robot_moved() -> None:
    robot = FakeRobot()
    bb = writer(POSE_KEY)
    child = Scripted("plan", [S])
    node = th.DistanceController("dc", child, distance=1.0)
    setup(node, robot)
    got = []
    for x in (0.0, 0.4, 0.9, 1.0, 1.5, 2.1):
        bb.set(POSE_KEY, Pose2(x, 0.0, 0.0))
        got.append(tick(node, robot))
    assert got == [S, R, R, S, R, S]


def test_distance_controller_fails_without_a_pose() -> None:
    robot = FakeRobot()
    writer(POSE_KEY).unset(POSE_KEY)
    node = th.DistanceController("dc", Scripted("plan", [S]), distance=1.0)
    setup(node, robot)
    assert tick(node, robot) == F


def test_speed_controller_rate_follows_the_odometry_speed() -> None:
    node = th.SpeedController("sc", Scripted("c", [S]), min_rate=0.1, max_rate=1.0, min_speed=0.0, max_speed=0.5)
    assert node.rate(0.0) == pytest.approx(0.1)
    assert node.rate(0.25) == pytest.approx(0.55)
    assert node.rate(0.9) == pytest.approx(1.0)


def test_speed_controller_ticks_slowly_when_stopped_and_fast_when_driving() -> None:
    robot = FakeRobot()
    bb = writer(OBSERVATION_KEY)
    child = Scripted("plan", [S])
    node = th.SpeedController("sc", child, min_rate=0.5, max_rate=2.0, min_speed=0.0, max_speed=0.5,
                              filter_duration=0.3)  # fmt: skip
    setup(node, robot)
    ticks = []
    for _ in range(40):  # 4 s standing still: period 2 s (0.5 Hz) once the first 0.5 s period runs out
        bb.set(OBSERVATION_KEY, robot.observe())
        ticks.append(tick(node, robot))
    stopped = child.ticks
    robot.command(0.5, 0.0)
    for _ in range(40):  # 4 s at 0.5 m/s: 2 Hz
        bb.set(OBSERVATION_KEY, robot.observe())
        robot.step(0.0)
        ticks.append(tick(node, robot))
    assert stopped == 3, "t = 0 (first tick), 0.5 (first period, 1/max_rate), 2.5 (then every 2 s)"
    assert child.ticks - stopped >= 7, "about every 0.5 s while driving at max_speed"


def test_delay_runs_the_child_after_the_delay() -> None:
    robot = FakeRobot()
    child = Scripted("c", after(2))
    node = th.Delay("delay", child, seconds=0.3)
    setup(node, robot)
    got = [tick(node, robot, dt=0.1) for _ in range(6)]
    assert got == [R, R, R, R, S, R]
    assert child.ticks == 2, "ticked at t = 0.3 and 0.4; the delay restarts after it finishes"


# --------------------------------------------------------------------------- outcomes


def test_keep_running_until_failure() -> None:
    child = Scripted("c", [S, S, F])
    node = oc.KeepRunningUntilFailure("krf", child)
    assert [tick(node) for _ in range(3)] == [R, R, F]
    assert child.starts == 3


def test_run_once_replays_when_not_skipping() -> None:
    child = Scripted("c", [R, F, S])
    node = oc.RunOnce("once", child, then_skip=False)
    assert [tick(node) for _ in range(4)] == [R, F, F, F] and child.ticks == 2
    node.stop(Status.INVALID)
    assert tick(node) == F and child.ticks == 2, "a halt does not reset it"


def test_single_trigger_runs_once_per_activation() -> None:
    child = Scripted("c", [S])
    node = oc.SingleTrigger("st", child)
    assert [tick(node) for _ in range(3)] == [S, F, F] and child.ticks == 1
    node.stop(Status.INVALID)  # reset by its parent
    assert tick(node) == S and child.ticks == 2


@pytest.mark.parametrize(
    ("cls", "child", "want"),
    [
        (oc.RunningIsSuccess, R, S), (oc.RunningIsSuccess, F, F), (oc.RunningIsSuccess, S, S),
        (oc.RunningIsFailure, R, F), (oc.RunningIsFailure, S, S), (oc.RunningIsFailure, F, F),
        (oc.SuccessIsRunning, S, R), (oc.SuccessIsRunning, F, F), (oc.SuccessIsRunning, R, R),
        (oc.FailureIsRunning, F, R), (oc.FailureIsRunning, S, S), (oc.FailureIsRunning, R, R),
    ],
)  # fmt: skip
def test_py_trees_status_mappings(cls: type, child: Status, want: Status) -> None:
    kid = Scripted("c", [child])
    node = cls("m", kid)
    assert tick(node) == want
    if child == R and want != R:
        assert kid.halts == 1, "the decorator finished: its running child is halted"


def test_status_to_blackboard_writes_the_status() -> None:
    bb = py_trees.blackboard.Client(name="reader")
    bb.register_key(key="/last", access=Access.READ)
    node = oc.StatusToBlackboard("s2b", Scripted("c", [R, F]), key="/last")
    assert tick(node) == R and bb.get("/last") == "RUNNING"
    assert tick(node) == F and bb.get("/last") == "FAILURE"


def test_status_queue_plays_its_statuses_then_eventually() -> None:
    leaf = StatusQueue("q", ["running", "FAILURE", "success"], eventually="failure")
    assert [tick(leaf) for _ in range(5)] == [R, F, S, F, F]
    cycle = StatusQueue("c", ["success", "failure"])
    assert [tick(cycle) for _ in range(4)] == [S, F, S, F]
    with pytest.raises(ValueError, match="one of success"):
        StatusQueue("bad", ["succeed"])
