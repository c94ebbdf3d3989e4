"""BT.CPP 4's ``TryCatch`` and Nav2's newer control nodes and goal decorators, pinned tick by tick.

As ``tests/test_control_nodes.py``: scripted children, every node's status
after every tick, tick/start/halt counts, against the reference sources
(BT.CPP ``src/controls/try_catch_node.cpp``; Nav2 ``plugins/control/
nonblocking_sequence.cpp``, ``persistent_sequence.cpp``, ``plugins/
decorator/goal_updater_node.cpp``, ``goal_updated_controller.cpp``).
"""

from __future__ import annotations

import py_trees
import pytest
from homing.behaviours.goal_updates import GoalUpdatedController, GoalUpdater
from homing.behaviours.nav2_sequences import NonblockingSequence, PersistentSequence
from homing.behaviours.pause_resume import PauseResumeController
from homing.behaviours.try_catch import TryCatch
from py_trees.common import Status

from tests.mission_fakes import F, R, S, Scripted, after, board, tick

N = Status.INVALID


def statuses(*nodes: py_trees.behaviour.Behaviour) -> list[Status]:
    return [n.status for n in nodes]


# --------------------------------------------------------------------------- TryCatch


def test_try_catch_succeeds_without_ticking_the_catch() -> None:
    a, b, catch = Scripted("a", after(2)), Scripted("b", [S]), Scripted("catch", [S])
    node = TryCatch("tc", [a, b, catch])
    assert tick(node) == R and statuses(a, b, catch) == [R, N, N]
    assert tick(node) == S and statuses(a, b, catch) == [S, S, N] and catch.ticks == 0
    assert a.ticks == 2 and a.starts == 1, "a RUNNING try child is resumed, not restarted"


def test_try_catch_runs_the_catch_in_the_same_tick_and_fails_whatever_it_returns() -> None:
    a, b, catch = Scripted("a", [S]), Scripted("b", [R, F]), Scripted("catch", [R, S])
    node = TryCatch("tc", [a, b, catch])
    assert tick(node) == R and statuses(a, b, catch) == [S, R, N]
    assert tick(node) == R and statuses(b, catch) == [F, R], "b failed: the catch child ticked at once"
    assert a.ticks == 1, "the try block is not re-run from the start while catching"
    assert tick(node) == F and statuses(node, catch) == [F, S], "the catch succeeded; the node still fails"
    assert (a.ticks, b.ticks, catch.ticks) == (1, 2, 2)
    assert tick(node) == F and statuses(a, b, catch) == [S, F, S], "b's script ends on F: caught again"
    assert a.ticks == 2 and catch.ticks == 3, "a new activation starts the try block over"


def test_try_catch_failing_catch_still_fails_and_needs_two_children() -> None:
    a, catch = Scripted("a", [F]), Scripted("catch", [F])
    node = TryCatch("tc", [a, catch])
    assert tick(node) == F and (a.ticks, catch.ticks) == (1, 1)
    with pytest.raises(ValueError, match="at least 2 children"):
        TryCatch("tc", [Scripted("only", [S])])


@pytest.mark.parametrize("catch_on_halt", [False, True])
def test_try_catch_halt_runs_the_catch_once_only_when_asked(catch_on_halt: bool) -> None:
    a, catch = Scripted("a", [R]), Scripted("catch", [R])
    node = TryCatch("tc", [a, catch], catch_on_halt=catch_on_halt)
    tick(node)
    node.stop(Status.INVALID)
    assert statuses(node, a, catch) == [N, N, N] and a.halts == 1
    assert (catch.ticks, catch.halts) == ((1, 1) if catch_on_halt else (0, 0)), "ticked once, halted while running"


def test_try_catch_halt_while_catching_does_not_run_the_catch_again() -> None:
    a, catch = Scripted("a", [F]), Scripted("catch", [R])
    node = TryCatch("tc", [a, catch], catch_on_halt=True)
    assert tick(node) == R and catch.ticks == 1
    node.stop(Status.INVALID)
    assert catch.ticks == 1 and catch.halts == 1 and statuses(node, catch) == [N, N]


# --------------------------------------------------------------------------- NonblockingSequence


def test_nonblocking_sequence_ticks_past_running_children_and_restarts_finished_ones() -> None:
    a, b, c = Scripted("a", [R, S, S]), Scripted("b", [S, S, S]), Scripted("c", [R, R, S])
    node = NonblockingSequence("nbs", [a, b, c])
    assert tick(node) == R and statuses(a, b, c) == [R, S, R], "a runs, b and c are ticked anyway"
    assert tick(node) == R and statuses(a, b, c) == [S, S, R]
    assert b.starts == 2, "a child that succeeded is started again on the next tick"
    assert tick(node) == S and statuses(a, b, c) == [S, S, S]
    assert (a.ticks, b.ticks, c.ticks) == (3, 3, 3) and a.starts == 2


def test_nonblocking_sequence_first_failure_halts_the_running_and_fails() -> None:
    a, b, c = Scripted("a", [R]), Scripted("b", [R, F]), Scripted("c", [R])
    node = NonblockingSequence("nbs", [a, b, c])
    assert tick(node) == R and statuses(a, b, c) == [R, R, R]
    assert tick(node) == F and statuses(a, b, c) == [N, F, N]
    assert (a.halts, c.halts, c.ticks) == (1, 1, 1), "c is not ticked after b fails; a and c are halted"


# --------------------------------------------------------------------------- PersistentSequence


def test_persistent_sequence_keeps_its_place_on_the_blackboard_across_halts() -> None:
    client = board("/idx")
    a, b, c = Scripted("a", [S]), Scripted("b", [R, R, S]), Scripted("c", [F, S])
    node = PersistentSequence("ps", [a, b, c], index_key="/idx")
    assert tick(node) == R and statuses(a, b, c) == [S, R, N] and client.get("/idx") == 1
    node.stop(Status.INVALID)
    assert statuses(a, b) == [N, N] and b.halts == 1 and client.get("/idx") == 1, "a halt keeps the place"
    assert tick(node) == R and a.ticks == 1, "resumes at b, not a"
    assert tick(node) == F and statuses(b, c) == [S, F] and client.get("/idx") == 0, "a failure writes 0"
    assert tick(node) == S and (a.ticks, b.ticks, c.ticks) == (2, 4, 2) and client.get("/idx") == 0
    client.set("/idx", 2)
    assert tick(node) == S and (a.ticks, b.ticks, c.ticks) == (2, 4, 3), "another writer jumps to child 2"


# --------------------------------------------------------------------------- goal decorators


def test_goal_updater_passes_the_update_when_there_is_one() -> None:
    client = board("/goal", "/nav/goal_update", "/updated")
    client.set("/goal", [1.0, 0.0, 0.0])
    child = Scripted("child", [R, R, S])
    node = GoalUpdater("gu", child, input_goal="/goal", output_goal="/updated")
    assert tick(node) == R and client.get("/updated") == [1.0, 0.0, 0.0], "no update: the input goal passes"
    client.set("/nav/goal_update", [4.0, 2.0, 0.0])
    assert tick(node) == R and client.get("/updated") == [4.0, 2.0, 0.0] and client.get("/goal") == [1.0, 0.0, 0.0]
    assert tick(node) == S and child.ticks == 3, "the child's status every tick"


def test_goal_updated_controller_reticks_the_child_only_for_a_new_goal() -> None:
    client = board("/goal")
    client.set("/goal", [1.0, 0.0, 0.0])
    child = Scripted("child", [R, S, S, S])
    node = GoalUpdatedController("guc", child, goal_key="/goal")
    assert tick(node) == R and child.ticks == 1, "ticked first"
    client.set("/goal", [2.0, 0.0, 0.0])  # changes while the child runs: absorbed, as Nav2 clears its flag
    assert tick(node) == S and child.ticks == 2
    assert tick(node) == R and child.ticks == 2, "finished and the goal is the same: RUNNING, child not ticked"
    client.set("/goal", [3.0, 0.0, 0.0])
    assert tick(node) == S and child.ticks == 3, "a new goal ticks the child again"
    node.stop(Status.INVALID)
    assert tick(node) == S and child.ticks == 4, "a new activation ticks the child first"


# --------------------------------------------------------------------------- PauseResumeController


def test_pause_resume_controller_pauses_runs_the_event_children_and_resumes() -> None:
    client = board("/pause", "/resume")
    work, paused, on_pause, on_resume = (Scripted("work", [R]), Scripted("paused", [R]), Scripted("on_pause", [R, S]),
                                         Scripted("on_resume", [S]))  # fmt: skip
    node = PauseResumeController("prc", [work, paused, on_pause, on_resume])
    assert tick(node) == R and statuses(work, paused, on_pause) == [R, N, N] and node.state == "RESUMED"
    client.set("/resume", True)
    assert tick(node) == R and work.ticks == 2 and client.get("/resume") is False, "resume while resumed: refused"
    client.set("/pause", True)
    assert tick(node) == R and statuses(work, on_pause) == [N, R] and work.halts == 1 and node.state == "ON_PAUSE"
    assert client.get("/pause") is False, "the request is taken"
    assert tick(node) == R and statuses(on_pause) == [S] and node.state == "PAUSED", "ON_PAUSE done: paused"
    assert tick(node) == R and statuses(paused) == [R] and work.ticks == 2
    client.set("/resume", True)
    assert tick(node) == R and statuses(paused, on_resume) == [N, S] and paused.halts == 1
    assert node.state == "RESUMED"
    assert tick(node) == R and work.ticks == 3 and work.starts == 2, "the work child starts afresh"


def test_pause_resume_controller_without_optional_children_and_its_outcomes() -> None:
    client = board("/pause", "/resume")
    work = Scripted("work", [R, R, S])
    node = PauseResumeController("prc", [work])
    assert tick(node) == R
    client.set("/pause", True)
    assert tick(node) == R and node.state == "PAUSED" and work.halts == 1, "no ON_PAUSE child: paused at once"
    assert tick(node) == R and work.ticks == 1, "no PAUSED child: RUNNING, nothing ticked"
    client.set("/resume", True)
    assert tick(node) == R and node.state == "RESUMED" and work.ticks == 1, "no ON_RESUME child: resumed next tick"
    assert tick(node) == R and tick(node) == S, "SUCCESS only from the RESUMED child"
    failing = PauseResumeController("prc2", [Scripted("w", [R]), Scripted("p", [F])])
    assert tick(failing) == R
    client.set("/pause", True)
    assert tick(failing) == R and failing.state == "PAUSED"
    assert tick(failing) == F, "a failing child fails the node"
    with pytest.raises(ValueError, match="1 to 4 children"):
        PauseResumeController("prc3", [Scripted(str(i), [S]) for i in range(5)])
