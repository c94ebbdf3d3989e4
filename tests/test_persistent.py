"""The persistent mission (missions/persistent.yaml): the lifecycle of thesis chapter 3, cycle after cycle."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.lifecycle_helpers import live

pytestmark = pytest.mark.slow


def test_a_cycle_undocks_explores_goes_home_docks_and_charges() -> None:
    log, robot, runner = live("lab", until=600.0, overrides={"session": "150 s"}, stop_after_cycles=1)
    try:
        seq = log.sequence()
        assert seq[:2] == ["Undocking", "Exploring"]  # "Docked" lasted one tick: the battery was full
        home = seq.index("MapHome")
        assert "AutoDocking" in seq[home:] and seq[-1] == "AutoDocking"
        assert log.cycles == 1 and robot.charging  # docked by the charger's word and the truth
        # It left at the end of its session, not because the batteries ran low.
        assert log.entered("MapHome")[0] == pytest.approx(log.entered("Undocking")[0] + 150.0, abs=20.0)
        assert log.lowest["computer"] > 90.0
        dock = runner.read("/nav/dock")
        assert dock is not None
    finally:
        robot.close()


def test_the_energy_guard_preempts_exploration_and_the_robot_charges_back(tmp_path: Path) -> None:
    # A small computer battery (0.3 Ah at 1.3 A: 0.12 %/s) at 45 %: the go-home level comes within minutes.
    world = tmp_path / "lab_small_battery.yaml"
    from homing.sim.world import WORLDS_DIR

    text = (WORLDS_DIR / "lab.yaml").read_text().replace("map: lab_map.yaml", f"map: {WORLDS_DIR / 'lab_map.yaml'}")
    text = text.replace("computer: {percent: 100.0}", "computer: {percent: 45.0, capacity_ah: 0.3}")
    world.write_text(text)
    log, robot, runner = live(world, until=1500.0, overrides={"session": "30 min"}, stop_after_cycles=1)
    try:
        assert log.cycles == 1 and robot.charging
        left = log.entered("MapHome")[0]
        assert left < 30 * 60 - 200  # long before the session's end
        t, policy = log.policy_at["MapHome"]
        computer = policy["computer"]
        assert computer["percent"] <= computer["home"] + computer["reserve"] + 0.5  # the guard's reason
        assert computer["reserve"] > 0.5  # the way home counted
        assert log.lowest["computer"] > computer["home"] - 1.0  # never run down below the threshold
    finally:
        robot.close()


def test_once_the_building_is_mapped_a_round_ends_the_trip_and_the_robot_rests_on_its_dock() -> None:
    rest = 600.0
    log, robot, runner = live("lab", until=3000.0, overrides={"session": "30 min", "rest": f"{rest:g} s"})
    try:
        seq = log.sequence()
        assert seq[:3] == ["Undocking", "Exploring", "Patrolling"]
        # The patrol round ended the trip, long before the session's 30 minutes.
        assert log.entered("MapHome")[0] < log.entered("Undocking")[0] + 30 * 60 - 120
        # Home, on the charger (judged by the dock's contacts), it rests for `rest`, then goes out again.
        resting = log.entered("Resting")
        assert resting and log.docked_at and resting[0] >= log.docked_at[0]
        again = [t for t in log.entered("Undocking") if t > resting[0]]
        assert again and again[0] - resting[0] == pytest.approx(rest, abs=15.0)
        k = seq.index("Resting")
        # the next trip: a frontier given up last trip may be tried again, then a round
        assert seq[k + 1] == "Undocking" and "Patrolling" in seq[k + 2:]
    finally:
        robot.close()
