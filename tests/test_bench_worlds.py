"""Benchmarks find the public floor plans from any working directory, and say where they looked when they find none."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from homing.benchmarks.common import find_plans, plan_folders


def test_homing_worlds_is_searched_first(floor_plans: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("HOMING_WORLDS", str(floor_plans))
    assert plan_folders()[0] == floor_plans.resolve()
    found = find_plans()
    assert found == {n: floor_plans.resolve() / f"{n}.yaml" for n in ("corridor", "loop", "room", "room_with_corner")}


def test_shared_worlds_beside_the_working_directory(floor_plans: Path, tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("HOMING_WORLDS", raising=False)
    (tmp_path / "shared" / "worlds").mkdir(parents=True)
    for f in ("loop.yaml", "loop.pgm"):
        (tmp_path / "shared" / "worlds" / f).write_bytes((floor_plans / f).read_bytes())
    project = tmp_path / "project"
    project.mkdir()
    for cwd in (tmp_path, project):  # from above the project root and from the project root
        monkeypatch.chdir(cwd)
        assert find_plans(("loop",)) == {"loop": tmp_path.resolve() / "shared" / "worlds" / "loop.yaml"}


def test_none_found_names_every_folder_searched(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    empty = [tmp_path / "a", tmp_path / "b"]
    assert find_plans(("loop",), why="running in lab only", folders=empty) == {}
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert str(tmp_path / "a") in err and str(tmp_path / "b") in err and "HOMING_WORLDS" in err
    assert "running in lab only" in err


def test_bench_plan_uses_the_plans_from_another_directory(floor_plans: Path, tmp_path: Path) -> None:
    env = {**os.environ, "HOMING_WORLDS": str(floor_plans)}
    out = subprocess.run([sys.executable, "-m", "homing.missions.cli", "bench", "plan", "--pairs", "1",
                          "--planners", "astar"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "4 maps × 1 pairs" in out.stdout


def test_an_explore_run_stopped_by_a_signal_is_no_finished_run(monkeypatch: pytest.MonkeyPatch) -> None:
    """SIGTERM and Ctrl-C reach the runner as a stop request: the run ends 'interrupted', and bench explore must
    stop there rather than score (and keep in --runs-json) a run cut short."""
    import homing.missions.runner as runner_module
    from homing.benchmarks.explore import run_one

    monkeypatch.setattr(runner_module, "stop_requested", lambda: True)
    with pytest.raises(KeyboardInterrupt):
        run_one("lab", "nearest", 0, 1.0)


def test_bench_persist_stops_on_a_signal_instead_of_counting_an_intervention(monkeypatch: pytest.MonkeyPatch) -> None:
    """bench persist restarts the robot when its mission ends (an intervention): a signal must not be one."""
    import homing.missions.runner as runner_module
    from homing.benchmarks.persist import live

    monkeypatch.setattr(runner_module, "stop_requested", lambda: True)
    out = live("lab", 1, 3600.0, 0.0, False, lambda t: None)
    assert out["interrupted"] and not out["interventions"]
    assert out["time"] < 1.0  # it stopped at once, not after a restart


def test_bench_persist_interrupted_writes_the_figures_of_the_time_it_simulated(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A week's run stopped on day 5 keeps its figures: the tables and the JSON cover the time simulated, say that
    it was interrupted, and the exit status is the signal's."""
    import argparse
    import json

    import homing.missions.runner as runner_module
    from homing.benchmarks import persist

    ticks = iter(range(10**9))
    monkeypatch.setattr(runner_module, "stop_requested", lambda: next(ticks) >= 400)  # ~40 s at 10 Hz
    path = tmp_path / "persist.json"
    args = argparse.Namespace(world="lab", seed=1, days=1.0, fault_every="0", no_changes=True, json=str(path),
                              plot=None, loop_closure=None)
    assert persist.run(args) == 130
    data = json.loads(path.read_text())
    assert data["interrupted"] is True
    assert 20.0 / persist.DAY < data["simulated_days"] < 120.0 / persist.DAY
    assert data["interventions"] == 0 and data["days"] == 1.0
    # The process's CPU time: spent (the simulator runs in it), and per simulated day in proportion to the time run.
    assert data["cpu_s"] > 0.0
    assert data["cpu_per_day_min"] * 60.0 * data["simulated_days"] == pytest.approx(data["cpu_s"], rel=1e-9)


def test_bench_persist_counts_a_robot_that_stays_away_from_its_dock_as_an_intervention(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """The bench stops a run whose robot has not docked for STUCK hours (as it stops one on a signal), and that
    stop is an intervention the bench counts and recovers from, not a Ctrl-C: bench persist seed 2 ended at 30.3
    simulated hours with "interrupted by Ctrl-C" that nobody pressed."""
    import homing.benchmarks.persist as persist

    monkeypatch.setattr(persist, "STUCK", 30.0 / 3600.0)  # 30 s off the dock: the first trip out is "stuck"
    out = persist.live("lab", 1, 240.0, 0.0, False, lambda t: None)
    assert out["interventions"], "the robot left its dock for more than 30 s and no intervention was counted"
    assert all(why == "no dock for 0.00833333 h" for _, why in out["interventions"]), out["interventions"]
    assert out["time"] >= 240.0 - 1e-6  # and the bench carried on to its horizon after each


def test_bench_persist_names_the_failure_that_sent_the_robot_to_error() -> None:
    # The Error subtree runs as a recovery branch beside the leaf that failed: the bench counts Error time per
    # Error node and that leaf's typed failure (its key on the board is already reset by the Error's own leaves).
    from types import SimpleNamespace

    import py_trees
    from homing.benchmarks.persist import error_cause
    from py_trees.common import Status

    class Failed(py_trees.behaviour.Behaviour):
        failure_reason = "no_path"

        def update(self) -> Status:
            return Status.FAILURE

    class Running(py_trees.behaviour.Behaviour):
        def update(self) -> Status:
            return Status.RUNNING

    navigate = py_trees.composites.Sequence("GoHome", memory=True, children=[Failed("NavigateToStaging")])
    error = py_trees.composites.Sequence("MapHomeError", memory=True, children=[Running("Spin")])
    root = py_trees.composites.Selector("MapHome", memory=True, children=[navigate, error])
    root.tick_once()
    assert error_cause(SimpleNamespace(mission=SimpleNamespace(root=root))) == "MapHomeError: NavigateToStaging no_path"
    idle = py_trees.composites.Sequence("Idle", memory=True, children=[Running("Wait")])
    idle.tick_once()
    assert error_cause(SimpleNamespace(mission=SimpleNamespace(root=idle))) == "Error: no Error node running"
