"""Control-node semantics pinned tick by tick with scripted leaves (STYLE.md rule 10).

Each test states the expected status of every node after every tick, for
the cases DESIGN.md warns about: memory vs reactive, retry counts, timeout
units, recovery retries, round-robin order, a guard halting a running child.
"""

from __future__ import annotations

import pytest
from homing.behaviours import decorators as d
from py_trees.common import Status

from tests.mission_fakes import F, FakeRobot, R, S, Scripted, after, tick

N = Status.INVALID  # not ticked or halted


def statuses(*nodes: object) -> list[Status]:
    return [n.status for n in nodes]  # type: ignore[attr-defined]


def setup(root: object, robot: FakeRobot | None = None) -> None:
    for node in root.iterate():  # type: ignore[attr-defined]
        node.setup(robot=robot)


def test_sequence_with_memory_resumes_at_running_child() -> None:
    a, b = Scripted("a", [S, F]), Scripted("b", after(3))
    seq = d.Sequence("seq", [a, b], memory=True)
    expected = [(R, S, R), (R, S, R), (S, S, S)]
    for want in expected:
        tick(seq)
        assert statuses(seq, a, b) == list(want)
    assert a.ticks == 1, "memory: the succeeded child is not re-ticked while b runs"
    assert b.ticks == 3


def test_reactive_sequence_reticks_and_halts_running_child() -> None:
    a, b = Scripted("a", [S, S, F]), Scripted("b", [R])
    seq = d.ReactiveSequence("seq", [a, b])
    tick(seq)
    assert statuses(seq, a, b) == [R, S, R]
    tick(seq)
    assert statuses(seq, a, b) == [R, S, R]
    tick(seq)
    assert statuses(seq, a, b) == [F, F, N]
    assert a.ticks == 3 and b.ticks == 2 and b.halts == 1


def test_sequence_memory_restarts_from_first_after_failure() -> None:
    a, b = Scripted("a", [S]), Scripted("b", [F])
    seq = d.Sequence("seq", [a, b])
    tick(seq)
    assert statuses(seq, a, b) == [F, S, F]
    tick(seq)
    assert a.ticks == 2, "after FAILURE the memory sequence starts at the first child (BT.CPP Sequence)"


def test_fallback_memory_vs_reactive_preemption() -> None:
    # High priority fails at first, then succeeds: only the reactive fallback notices.
    for reactive, want_low_halts in ((False, 0), (True, 1)):
        high, low = Scripted("high", [F, S]), Scripted("low", [R])
        fb = d.ReactiveFallback("fb", [high, low]) if reactive else d.Fallback("fb", [high, low])
        tick(fb)
        assert statuses(fb, high, low) == [R, F, R]
        tick(fb)
        if reactive:
            assert statuses(fb, high, low) == [S, S, N]
        else:
            # py_trees resets skipped higher priorities to INVALID for display; they are not ticked
            assert statuses(fb, high, low) == [R, N, R]
            assert high.ticks == 1
        assert low.halts == want_low_halts


def test_retry_counts_attempts_in_all() -> None:
    child = Scripted("c", [F])
    retry = d.Retry("retry", child, attempts=3)
    got = [tick(retry) for _ in range(3)]
    assert got == [R, R, F]
    assert child.starts == 3, "attempts: 3 → the child runs three times in all"
    child2 = Scripted("c2", [F, S])
    retry2 = d.Retry("retry2", child2, attempts=3)
    assert tick(retry2) == R
    assert tick(retry2) == S
    assert child2.starts == 2


def test_timeout_is_seconds_on_the_adapter_clock() -> None:
    robot = FakeRobot()
    child = Scripted("c", [R])
    to = d.Timeout("to", child, seconds=1.0)
    setup(to, robot)
    got = []
    for _ in range(11):
        got.append((robot.clock.t, tick(to, robot, dt=0.1)))
    # ticks at t = 0.0 … 0.9 run the child; at t = 1.0 it fails without ticking it
    assert [s for _, s in got[:10]] == [R] * 10
    assert got[10] == (1.0, F)
    assert child.ticks == 10 and child.halts == 1 and child.status == N
    assert "timed out after 1 s" in to.feedback_message


def test_timeout_passes_through_a_child_that_finishes_in_time() -> None:
    robot = FakeRobot()
    child = Scripted("c", after(5))
    to = d.Timeout("to", child, seconds=1.0)
    setup(to, robot)
    got = [tick(to, robot) for _ in range(5)]
    assert got == [R, R, R, R, S]


def test_repeat_counts_successes_and_stops_on_failure() -> None:
    child = Scripted("c", [S])
    rep = d.Repeat("rep", child, times=3)
    assert [tick(rep) for _ in range(3)] == [R, R, S]
    assert child.starts == 3
    child_f = Scripted("f", [F])
    assert tick(d.Repeat("rep2", child_f, times=-1)) == F


@pytest.mark.parametrize(
    ("cls", "child", "want"),
    [
        (d.Inverter, S, F), (d.Inverter, F, S), (d.Inverter, R, R),
        (d.ForceSuccess, F, S), (d.ForceSuccess, S, S), (d.ForceSuccess, R, R),
        (d.ForceFailure, S, F), (d.ForceFailure, F, F), (d.ForceFailure, R, R),
    ],
)  # fmt: skip
def test_status_mapping_decorators(cls: type, child: Status, want: Status) -> None:
    assert tick(cls("x", Scripted("c", [child]))) == want


def test_one_shot_runs_once_then_replays_its_status() -> None:
    child = Scripted("c", [F])
    once = d.OneShot("once", child)
    assert [tick(once) for _ in range(3)] == [F, F, F]
    assert child.ticks == 1
    child2 = Scripted("c2", [F, S])
    until_ok = d.OneShot("until_ok", child2, policy="on_success")
    tick(until_ok)
    tick(until_ok)
    tick(until_ok)
    assert child2.ticks == 2 and until_ok.status == S


def test_rate_limit_starts_child_at_most_hz_and_replays_status() -> None:
    robot = FakeRobot()
    child = Scripted("plan", [S])
    rl = d.RateLimit("rl", child, hz=2.0)
    setup(rl, robot)
    got = [tick(rl, robot, dt=0.1) for _ in range(12)]
    assert got == [S] * 12
    assert child.ticks == 3, "2 Hz over 1.2 s of adapter time: started at t = 0.0, 0.5, 1.0"


def test_guard_halts_running_child_when_condition_turns_false() -> None:
    cond, child = Scripted("battery_ok", [S, S, F]), Scripted("explore", [R])
    guard = d.Guard("guard", cond, child)
    assert [tick(guard) for _ in range(2)] == [R, R]
    assert child.ticks == 2
    tick(guard)
    assert statuses(guard, cond, child) == [F, F, N]
    assert child.halts == 1 and child.ticks == 2, "the child is halted, not ticked, once the guard is false"


def test_recovery_node_retries_as_nav2_number_of_retries() -> None:
    child, recovery = Scripted("nav", [F]), Scripted("clear", [S])
    node = d.RecoveryNode("rec", child, recovery, retries=6)
    tick(node)
    # All inside one tick, as Nav2: 1 attempt + 6 recoveries/retries, then FAILURE.
    assert node.status == F
    assert child.starts == 7 and recovery.starts == 6


def test_recovery_node_running_recovery_then_success() -> None:
    child, recovery = Scripted("nav", [F]), Scripted("spin", after(2))
    node = d.RecoveryNode("rec", child, recovery, retries=1)
    tick(node)
    assert statuses(node, child, recovery) == [R, F, R]
    child.script = [S]
    tick(node)
    assert statuses(node, child, recovery) == [S, S, S]
    assert child.starts == 2 and recovery.starts == 1


def test_recovery_node_fails_when_recovery_fails() -> None:
    child, recovery = Scripted("nav", [F]), Scripted("clear", [F])
    node = d.RecoveryNode("rec", child, recovery, retries=3)
    tick(node)
    assert node.status == F and child.starts == 1 and recovery.starts == 1


def test_round_robin_order_across_activations() -> None:
    a, b, c = Scripted("a", [S]), Scripted("b", [S]), Scripted("c", [S])
    rr = d.RoundRobin("rr", [a, b, c])
    order: list[str] = []
    for _ in range(4):
        before = {n.name: n.ticks for n in (a, b, c)}
        assert tick(rr) == S
        order.extend(n.name for n in (a, b, c) if n.ticks > before[n.name])
    assert order == ["a", "b", "c", "a"], "each activation starts after the child that last finished"


def test_round_robin_skips_failures_in_one_tick_and_fails_after_all() -> None:
    a, b, c = Scripted("a", [F]), Scripted("b", [F]), Scripted("c", [S])
    rr = d.RoundRobin("rr", [a, b, c])
    assert tick(rr) == S and (a.ticks, b.ticks, c.ticks) == (1, 1, 1)
    c.script = [F]
    assert tick(rr) == F
    assert (a.ticks, b.ticks, c.ticks) == (2, 2, 2)


def test_recovery_with_round_robin_uses_next_recovery_each_retry() -> None:
    nav = Scripted("nav", [F])
    clear, spin, back = Scripted("clear", [S]), Scripted("spin", [S]), Scripted("back", [S])
    node = d.RecoveryNode("rec", nav, d.RoundRobin("recoveries", [clear, spin, back]), retries=4)
    tick(node)
    assert node.status == F and nav.starts == 5
    assert (clear.starts, spin.starts, back.starts) == (2, 1, 1)


@pytest.mark.parametrize(("success", "scripts", "want"), [
    ("all", ([S], after(2)), [R, S]),
    ("all", ([F], [R]), [F]),
    ("one", ([F], after(2)), [R, S]),
    ("one", ([F], [F]), [F]),
    (2, ([S], [F], after(3)), [R, R, S]),
    (2, ([F], [F], [R]), [F]),
])  # fmt: skip
def test_parallel_policies(success: object, scripts: tuple[list[Status], ...], want: list[Status]) -> None:
    kids = [Scripted(f"k{i}", s) for i, s in enumerate(scripts)]
    par = d.Parallel("par", kids, success=success)  # type: ignore[arg-type]
    got = [tick(par) for _ in want]
    assert got == want
    assert all(k.status != R for k in kids) or got[-1] == R, "a finished parallel leaves nothing running"


def test_parallel_rejects_impossible_policy() -> None:
    with pytest.raises(ValueError, match="1..2"):
        d.Parallel("p", [Scripted("a", [S]), Scripted("b", [S])], success=3)


def test_guard_halts_a_condition_still_running_when_it_finishes() -> None:
    # The condition subtree has not decided (RUNNING): the guard fails, and must not leave it running.
    cond, child = Scripted("deciding", [R, S]), Scripted("explore", [R])
    guard = d.Guard("guard", cond, child)
    tick(guard)
    assert statuses(guard, cond, child) == [F, N, N], "nothing below a finished guard stays RUNNING"
    assert cond.halts == 1 and child.ticks == 0
    tick(guard)  # the next activation starts the condition afresh
    assert cond.starts == 2 and statuses(guard, cond, child) == [R, S, R]


def test_round_robin_starts_at_first_child_after_a_whole_round_failed() -> None:
    # Nav2 RoundRobin: all children failed → halt() → current_child_idx_ = 0.
    a, b, c = Scripted("a", [S]), Scripted("b", [F]), Scripted("c", [F])
    rr = d.RoundRobin("rr", [a, b, c])
    assert tick(rr) == S  # a succeeds; the turn moves to b
    a.script = [F]
    assert tick(rr) == F  # b, c, a fail in turn: a whole round
    assert (a.ticks, b.ticks, c.ticks) == (2, 1, 1)
    a.script = [S]
    assert tick(rr) == S
    assert (a.ticks, b.ticks, c.ticks) == (3, 1, 1), "the next activation starts at the first child, not at b"


def test_parallel_failure_threshold_as_bt_cpp_failure_count() -> None:
    # py_trees' SuccessOnOne: the first failure fails it; BT.CPP failure_count = 1.
    kids = [Scripted("a", [F]), Scripted("b", [R]), Scripted("c", after(3))]
    par = d.Parallel("par", kids, success="one", failure=1)
    assert tick(par) == F and kids[1].halts == 1
    kids = [Scripted("a", [F]), Scripted("b", after(2)), Scripted("c", [R])]
    auto = d.Parallel("p2", kids, success="one")  # 'auto': one failure does not decide it
    assert [tick(auto), tick(auto)] == [R, S]
    with pytest.raises(ValueError, match="failure must be 'all', 'auto'"):
        d.Parallel("p3", [Scripted("x", [S])], failure=0)
