"""The terminal view: fits 80 × 24, shows statuses and the running path; live in a real terminal via tmux."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner
from homing.missions.view import LiveView, fold, static_tree, tree_lines
from rich.console import Console

from tests.conftest import REPO
from tests.mission_fakes import FakeRobot

WANDER = REPO / "missions" / "examples" / "wander.yaml"


def test_render_fits_80x24_with_header_statuses_and_feedback() -> None:
    mission = compile_mission(WANDER)
    robot = FakeRobot(battery=77.0)
    runner = Runner(mission, robot, seed=0, until=4.5)
    runner.setup()
    for _ in range(45):  # 4.5 s: inside the first side's Drive
        runner.tick()
        robot.step(runner.period)
    console = Console(width=80, height=24, record=True, force_terminal=True, color_system="truecolor")
    view = LiveView(mission, console)
    console.print(view.render(runner))
    text = console.export_text()
    lines = text.rstrip("\n").splitlines()
    assert len(lines) <= 24 and max(len(line) for line in lines) <= 80
    assert lines[0].startswith("wander t 0:00:04.4")
    assert lines[1] == "state Exploring" and lines[2].startswith("base      77% ▕"), "facts under the header"
    assert any("● ⁇ Lifecycle" in line for line in lines)
    assert any("✘ → GoHome" in line or "✘ BatteryBelow" in line for line in lines)
    assert any("● Drive#2" in line for line in lines), "the running leaf (the turn after 4 s of driving)"
    assert any(line.startswith("▶ Drive#2: v=0.00 m/s ω=1.57 rad/s") for line in lines)
    assert any(line.startswith("/mission/state = 'Exploring'") for line in lines)
    # the running path is bold: Lifecycle, Wander, repeat, Lap, Side, Drive#2
    bold = [t.plain for t in tree_lines(mission, 20) if any("bold" in str(span.style) for span in t.spans)]
    assert len(bold) == 6 and all("●" in b for b in bold)
    assert [b.split()[-1] if "⧉" not in b else "Side" for b in bold][-1] == "Drive#2"


def test_fold_keeps_the_running_path_within_budget() -> None:
    mission = compile_mission(WANDER)
    robot = FakeRobot()
    runner = Runner(mission, robot)
    runner.setup()
    for _ in range(3):
        runner.tick()
        robot.step(runner.period)
    for budget in (4, 8, 12, 40):
        lines = tree_lines(mission, budget)
        assert len(lines) <= budget
        opened = fold(mission.root, budget)
        assert mission.root.id in opened
    plain = [line.plain for line in tree_lines(mission, 8)]
    assert any("Lap" in p for p in plain) or any("▸(+" in p for p in plain)
    full = [line.plain for line in tree_lines(mission, 100)]
    assert len(full) == len(mission.info), "with room, every node is drawn"


def test_static_tree_shows_kinds_and_parameters() -> None:
    console = Console(width=100, record=True)
    console.print(static_tree(compile_mission(WANDER)))
    text = console.export_text()
    assert "⁇ Lifecycle  reactive_fallback" in text
    assert "BatteryBelow  percent=20" in text
    assert "Drive#2  omega=1.5708 seconds=1 v=0" in text


def _pane(session: str) -> str:
    return subprocess.run(["tmux", "capture-pane", "-p", "-t", session], capture_output=True, text=True).stdout


def _wait_for(predicate, timeout: float = 30.0) -> bool:  # type: ignore[no-untyped-def]
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.1)
    return False


@pytest.mark.tmux
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed (.ci/run installs it)")
def test_live_view_in_a_real_terminal_and_ctrl_c(tmp_path: Path) -> None:
    session = f"homing-{uuid.uuid4().hex[:8]}"
    robot_log, exit_file = tmp_path / "robot.json", tmp_path / "exit"
    command = (
        f"cd {REPO} && HOMING_FAKE_ROBOT_LOG={robot_log} {sys.executable} -m homing.missions.cli run "
        f"{WANDER} --adapter tests.mission_fakes:make_robot --seed 1 --speed 2; echo $? > {exit_file}; sleep 60"
    )
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", "80", "-y", "24", command], check=True)
    try:
        assert _wait_for(lambda: "● Drive" in _pane(session) and "Lifecycle" in _pane(session)), _pane(session)
        screen = _pane(session)
        assert "wander t 0:00:" in screen and "state Exploring" in screen
        assert "✘" in screen and "●" in screen, "failed and running nodes both on screen"
        assert "▶ Drive" in screen
        subprocess.run(["tmux", "send-keys", "-t", session, "C-c"], check=True)
        assert _wait_for(exit_file.exists), _pane(session)
        assert _wait_for(lambda: exit_file.read_text().strip() != "")
        screen = _pane(session)
        assert exit_file.read_text().strip() == "130", screen
        assert "Traceback" not in screen
        assert "stopped: interrupted" in screen and "final command v=0.000 m/s ω=0.000 rad/s" in screen
        record = json.loads(robot_log.read_text())
        assert record["closed"] is True
        assert record["commands"][-1][1:] == [0.0, 0.0], "the last command the robot got was a stop"
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)


@pytest.mark.tmux
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed (.ci/run installs it)")
@pytest.mark.parametrize(("width", "height"), [(80, 24), (120, 40)])
def test_live_view_shows_the_map_and_facts_and_keeps_what_ran_in_its_final_frame(tmp_path: Path, width: int,
                                                                                  height: int) -> None:
    session = f"homing-{uuid.uuid4().hex[:8]}"
    exit_file = tmp_path / "exit"
    command = (f"cd {REPO} && {sys.executable} -m homing.missions.cli run explore --world lab --seed 1 --speed 20; "
               f"echo $? > {exit_file}; sleep 60")
    subprocess.run(["tmux", "new-session", "-d", "-s", session, "-x", str(width), "-y", str(height), command],
                   check=True)
    try:
        assert _wait_for(lambda: "▶ Explore: goal" in _pane(session) and "mapped" in _pane(session), 180), _pane(session)
        screen = _pane(session)
        lines = screen.splitlines()
        assert len(lines) <= height and max(map(len, lines)) <= width
        assert "state Exploring" in screen and "base " in screen and "computer " in screen
        assert "pose (" in screen and " m " in screen and "°" in screen, "poses in metres and degrees"
        assert re.search(r"mapped \d+\.\d m²", screen) and "frontiers " in screen
        braille_chars = sum(1 for ch in screen if 0x2801 <= ord(ch) <= 0x28FF)
        assert braille_chars > 40, "the map is drawn in braille"
        assert any(arrow in screen for arrow in "→↗↑↖←↙↓↘"), "the robot"
        subprocess.run(["tmux", "send-keys", "-t", session, "C-c"], check=True)
        assert _wait_for(lambda: exit_file.exists() and exit_file.read_text().strip() != ""), _pane(session)
        final = _pane(session)
        assert exit_file.read_text().strip() == "130", final
        assert "■ halted: Explore was running" in final, "the final frame shows what was running"
        assert "● ⇉ UntilDoneOrTimeLimit" in final and "explore t 0:" in final, "its statuses and header stay on screen"
        assert "stopped: interrupted by Ctrl-C" in final and "Traceback" not in final
    finally:
        subprocess.run(["tmux", "kill-session", "-t", session], capture_output=True)


def test_without_the_view_the_same_facts_are_plain_lines(tmp_path: Path) -> None:
    out = subprocess.run(
        [sys.executable, "-m", "homing.missions.cli", "run", str(WANDER), "--adapter", "tests.mission_fakes:make_robot",
         "--seed", "1", "--no-view", "--until", "65 s"],
        capture_output=True, text=True, timeout=120, cwd=REPO, env={**os.environ, "HOMING_FAKE_BATTERY": "77"},
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    facts = [line for line in out.stdout.splitlines() if "· base" in line or line.endswith("base 77%")]
    stamps = [float(line[1:].split(" s]")[0]) for line in facts]
    assert stamps[:3] == [0.0, 30.0, 60.0] and stamps[-1] == 65.0, stamps  # every 30 s and at the end
    assert all("state " in line and "base 77%" in line for line in facts[1:]), facts


def test_blackboard_numbers_show_to_the_centimetre_whatever_their_float_type() -> None:
    import numpy as np
    from homing.missions.view import _short

    assert _short(np.float32(7.123456), live=True) == "7.12"  # /energy/distance_home came as 7.1234565
    assert _short(12.0, live=True) == "12" and _short(-0.001, live=True) == "0" and _short(0.5, live=True) == "0.5"
    assert _short(3, live=True) == "3" and _short(True, live=True) == "True" and _short("Docked", live=True) == "'Docked'"
    assert _short(1.5707963) == "1.5708"  # a parameter shows as written (6 digits)
