"""`homing run` end to end against the pybullet simulator (homing.sim): the robot moves as commanded, then stops."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import homing.sim as sim  # noqa: E402 - part of the package: a broken simulator must fail, not skip
import pytest
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner, StatusChange

from tests.conftest import REPO

MISSION = "services: []\ntree:\n  sequence: [{Drive: {v: -0.2, seconds: 3}}, {Drive: {omega: 90 deg/s, seconds: 1}}, Stop]\n"


def _run(path: Path, seed: int) -> tuple[object, object, list[str]]:
    robot = sim.SimRobot(sim.load_world("lab"), seed=seed)
    start = robot.truth_pose()
    log: list[StatusChange] = []
    result = Runner(compile_mission(path), robot, seed=seed, on_change=log.append).run()
    end = robot.truth_pose()  # ground truth: this is evaluation code
    odom = robot.observe().odom.pose
    robot.close()
    assert result.reason == "success" and result.final_command.v == 0.0 and result.final_command.omega == 0.0
    return (start, end), odom, [c.line() for c in log]


def test_back_out_and_turn_in_the_lab(tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION)
    (start, end), odom, log = _run(path, seed=1)
    # 3 s at -0.2 m/s backwards along the heading, then a quarter turn counter-clockwise
    back = -0.6
    expect_x = start.x + back * math.cos(start.theta)
    expect_y = start.y + back * math.sin(start.theta)
    assert math.hypot(end.x - expect_x, end.y - expect_y) < 0.05
    turned = math.atan2(math.sin(end.theta - start.theta), math.cos(end.theta - start.theta))
    assert turned == pytest.approx(math.pi / 2, abs=0.08)
    (_, end2), odom2, log2 = _run(path, seed=1)
    assert log2 == log and (odom2.x, odom2.y, odom2.theta) == (odom.x, odom.y, odom.theta), "same seed, same run"


def test_cli_run_world_until(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "homing.missions.cli", "run", str(REPO / "missions/examples/wander.yaml"),
         "--world", "lab", "--seed", "2", "--until", "3 s", "--no-view"],
        capture_output=True, text=True, timeout=120, cwd=REPO,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[-2].startswith("stopped: time_limit at t=3.00 s after 30 ticks")
    assert lines[-1].startswith("final command v=0.000 m/s ω=0.000 rad/s (robot stopped); root ")
