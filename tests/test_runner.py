"""The runner's tick (ARCHITECTURE.md) against a scripted adapter: order, commands, stopping, logging."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from homing.behaviours.registry import Param, register_service
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner, RunResult, StatusChange, parse_duration
from homing.robot import Observation
from py_trees.common import Status

from homing.signals import received, stop_on_signals, stop_requested
from tests.conftest import REPO
from tests.mission_fakes import FakeRobot

CALLS: list[tuple[str, float]] = []


@register_service("_test_odometer", params=(Param("scale", float, 1.0),), writes=("/test/distance",))
class Odometer:
    """Test service: integrates |v| from odometry into /test/distance."""

    name = "_test_odometer"
    writes = ("/test/distance",)

    def __init__(self, scale: float = 1.0):
        self.scale = scale
        self.total = 0.0
        self.last: float | None = None

    def setup(self, robot: object, blackboard: object) -> None:
        self.bb = blackboard
        self.bb.set("/test/distance", 0.0, overwrite=True)  # type: ignore[attr-defined]

    def update(self, obs: Observation) -> None:
        CALLS.append(("service", obs.stamp))
        if self.last is not None:
            self.total += abs(obs.odom.twist.v) * (obs.stamp - self.last) * self.scale
        self.last = obs.stamp
        self.bb.set("/test/distance", self.total, overwrite=True)  # type: ignore[attr-defined]

    def shutdown(self) -> None:
        CALLS.append(("shutdown", -1.0))


def mission(tmp: Path, tree: str, services: str = "[]", extra: str = "") -> Path:
    path = tmp / "m.yaml"
    path.write_text(f"services: {services}\nrate: 10\n{extra}tree:\n{tree}")
    return path


def run(path: Path, robot: FakeRobot, **kw: object) -> tuple[RunResult, list[StatusChange]]:
    log: list[StatusChange] = []
    runner = Runner(compile_mission(path), robot, on_change=log.append, **kw)  # type: ignore[arg-type]
    return runner.run(), log


def test_drive_then_finish_stops_the_robot(tmp_path: Path) -> None:
    path = mission(tmp_path, "  sequence:\n    - Drive: {v: 0.2, seconds: 1}\n    - Wait: 0.5 s\n")
    robot = FakeRobot()
    result, log = run(path, robot)
    assert result.reason == "success"
    # 10 ticks drive at 0.2 m/s (t = 0.0 … 0.9), then zero while waiting, zero at the end
    driving = [c for c in robot.commands if c[1] > 0]
    assert len(driving) == 10 and driving[0][0] == 0.0 and driving[-1][0] == pytest.approx(0.9)
    assert robot.pose.x == pytest.approx(0.2, abs=1e-9), "1 s at 0.2 m/s on the adapter clock"
    assert robot.commands[-1][1:] == (0.0, 0.0) and result.final_command.v == 0.0
    assert result.time == pytest.approx(1.5)
    wait_done = [c for c in log if c.node == "Wait" and c.new == Status.SUCCESS]
    assert len(wait_done) == 1 and wait_done[0].time == pytest.approx(1.5)


def test_services_update_before_the_tree_and_shut_down(tmp_path: Path) -> None:
    CALLS.clear()
    path = mission(
        tmp_path,
        "  sequence:\n    - Drive: {v: 0.5, seconds: 2}\n    - CheckBlackboard: {key: /test/distance, op: '>=', value: 0.99}\n",
        services="[{_test_odometer: {scale: 1.0}}]",
    )
    result, _ = run(path, FakeRobot())
    assert result.reason == "success", "the service's distance reached the check on the tree's tick"
    assert CALLS[0] == ("service", 0.0) and CALLS[-1][0] == "shutdown"


def test_time_limit_halts_running_leaf_and_stops(tmp_path: Path) -> None:
    path = mission(tmp_path, "  Drive: {v: 0.3, seconds: 100}\n")
    robot = FakeRobot()
    result, log = run(path, robot, until=2.0)
    assert result.reason == "time_limit" and result.time == pytest.approx(2.0)
    assert result.ticks == 20
    assert robot.commands[-1][1:] == (0.0, 0.0)
    assert log[-1].node == "Drive" and log[-1].new == Status.INVALID and log[-1].time == pytest.approx(2.0)


def test_ctrl_c_stops_robot_and_halts_tree(tmp_path: Path) -> None:
    path = mission(tmp_path, "  Drive: {v: 0.3, seconds: 100}\n")
    robot = FakeRobot()

    def interrupt(runner: Runner) -> None:
        if runner.ticks == 7 and runner.mission.root.status == Status.RUNNING:
            raise KeyboardInterrupt

    log: list[StatusChange] = []
    runner = Runner(compile_mission(path), robot, on_change=log.append, on_tick=interrupt)
    result = runner.run()
    assert result.reason == "interrupted" and result.ticks == 7
    assert robot.commands[-1][1:] == (0.0, 0.0)
    assert runner.mission.root.status == Status.INVALID


def test_a_signal_whose_exception_is_swallowed_still_stops_the_run(tmp_path: Path) -> None:
    # A stop signal's exception can land in code that swallows it (a library's clean-up, a callback from C):
    # the runner polls for the signal as well, so the stop is never lost.
    path = mission(tmp_path, "  Drive: {v: 0.3, seconds: 100}\n")
    robot = FakeRobot()

    def swallowed(runner: Runner) -> None:
        if runner.ticks == 7:
            try:
                os.kill(os.getpid(), signal.SIGTERM)
            except KeyboardInterrupt:
                pass

    with stop_on_signals():
        result = Runner(compile_mission(path), robot, on_tick=swallowed).run()
        assert received() == signal.SIGTERM
    assert result.reason == "interrupted" and result.ticks == 7
    assert robot.commands[-1][1:] == (0.0, 0.0)
    assert not stop_requested()  # outside the block a stale signal stops nothing


def test_battery_guard_preempts_and_rate_override(tmp_path: Path) -> None:
    tree = (
        "  reactive_fallback:\n"
        "    - sequence: [{BatteryBelow: {percent: 50}}, {MissionState: {state: MapHome}}]\n"
        "    - Drive: {v: 0.1, seconds: 1000}\n"
    )
    robot = FakeRobot(battery=60.0, drain=1.0)  # crosses 50 % at t = 10 s
    result, log = run(mission(tmp_path, tree), robot, rate=5.0)
    assert result.reason == "success"
    halted = [c for c in log if c.node == "Drive" and c.new == Status.INVALID]
    assert len(halted) == 1 and halted[0].time == pytest.approx(10.2), "first 5 Hz tick with 60 - t < 50"
    assert result.ticks == 52


def test_same_seed_same_log(tmp_path: Path) -> None:
    path = mission(tmp_path, "  sequence: [{Drive: {v: 0.1, seconds: 1}}, {Wait: 1}]\n")
    logs = [[c.line() for c in run(path, FakeRobot(seed=3), seed=3)[1]] for _ in range(2)]
    assert logs[0] == logs[1] and len(logs[0]) >= 6


def test_parse_duration() -> None:
    assert parse_duration("2h") == 7200 and parse_duration("90 min") == 5400 and parse_duration("30") == 30
    with pytest.raises(ValueError):
        parse_duration("5 m")


def test_cli_run_no_view_prints_timestamped_changes(tmp_path: Path) -> None:
    path = mission(tmp_path, "  sequence: [{Drive: {v: 0.1, seconds: 1}}, Stop]\n")
    out = subprocess.run(
        [sys.executable, "-m", "homing.missions.cli", "run", str(path), "--adapter", "tests.mission_fakes:make_robot",
         "--seed", "1", "--no-view"],
        capture_output=True, text=True, timeout=60, cwd=REPO,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert "[      0.00 s] Drive: INVALID -> RUNNING" in lines
    assert "[      1.00 s] Drive: RUNNING -> SUCCESS" in lines
    assert lines[-2].startswith("stopped: success at t=1.00 s after 11 ticks")
    assert lines[-1].startswith("final command v=0.000 m/s ω=0.000 rad/s (robot stopped); root ")


def test_cli_run_bad_until_is_a_user_error(tmp_path: Path) -> None:
    path = mission(tmp_path, "  Stop\n")
    out = subprocess.run(
        [sys.executable, "-m", "homing.missions.cli", "run", str(path), "--adapter", "tests.mission_fakes:make_robot", "--until", "3 m"],
        capture_output=True, text=True, timeout=60, cwd=REPO,
    )  # fmt: skip
    assert out.returncode == 2 and "Traceback" not in out.stderr and "wrong unit 'm'" in out.stderr


def test_a_counter_reads_zero_before_its_first_count(tmp_path: Path) -> None:
    # The persistent mission's dock cycles are shown from the start ("cycles 0"), not only after the first dock.
    path = mission(tmp_path, "  sequence: [{Wait: 1 s}, {Increment: {key: /mission/cycles}}]\n")
    runner = Runner(compile_mission(path), FakeRobot())
    runner.setup()
    assert runner.read("/mission/cycles") == 0
    result = runner.run()
    assert result.reason == "success" and runner.read("/mission/cycles") == 1


def test_free_memory_is_handed_back_once_at_the_start_of_each_idle_stretch(tmp_path: Path, monkeypatch) -> None:
    import homing.missions.runner as runner_module
    from homing.behaviours.keys import IDLE_KEY

    released: list[float] = []
    monkeypatch.setattr(runner_module, "_release_memory", lambda: released.append(runner.now))
    runner = Runner(compile_mission(mission(tmp_path, "  Wait: 100 s\n")), FakeRobot())
    runner.setup()
    steps = []
    for t, idle in [(0.0, None), (0.1, 30.0), (30.0, 60.0), (60.0, None), (60.1, 90.0)]:
        runner.now = t
        runner.bb.set(IDLE_KEY, idle, overwrite=True)
        steps.append(runner.next_step())
    assert steps == pytest.approx([0.1, 29.9, 30.0, 0.1, 29.9])
    assert released == [0.1, 60.1]  # the first idle step of each stretch, not every one
    runner.shutdown()
    # The real call finds glibc's malloc_trim here (Linux), or settles on doing nothing.
    monkeypatch.undo()
    runner_module._LIBC = None
    runner_module._release_memory()
    assert runner_module._LIBC is False or hasattr(runner_module._LIBC, "malloc_trim")


HEAP_PROBE = """
import ctypes, sys
import numpy as np
import homing.missions.runner as runner_module
libc = ctypes.CDLL("libc.so.6")
class MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in ("arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks",
                                                 "fsmblks", "uordblks", "fordblks", "keepcost")]
libc.mallinfo2.restype = MallInfo2
if sys.argv[1] == "steady":
    runner_module._steady_heap()
big = np.ones(8 << 20, np.uint8)  # mapped (above any threshold); freeing it raises glibc's adaptive threshold
del big
before = libc.mallinfo2().hblkhd
block = np.ones(2 << 20, np.uint8)
print(libc.mallinfo2().hblkhd - before)
"""


def test_the_runners_steady_heap_maps_megabyte_blocks_so_freeing_them_shrinks_the_process() -> None:
    """After an 8 MB array is freed, glibc's adaptive threshold serves a 2 MB one from the heap, whose holes then
    keep the resident size up (bench persist's creeping RSS); with the runner's steady heap it is mapped."""
    import ctypes

    try:
        ctypes.CDLL("libc.so.6").mallinfo2  # noqa: B018 - glibc ≥ 2.33
    except (OSError, AttributeError):
        pytest.skip("needs glibc ≥ 2.33 (mallinfo2) to see where a block came from")
    mapped = {}
    for mode in ("default", "steady"):
        out = subprocess.run([sys.executable, "-c", HEAP_PROBE, mode], capture_output=True, text=True, check=True)
        mapped[mode] = int(out.stdout.split()[-1])
    assert mapped["default"] < 1 << 20, mapped  # from the heap
    assert mapped["steady"] >= 2 << 20, mapped  # a mapping of its own
