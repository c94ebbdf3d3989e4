"""bench dock's figures (thesis table 5.2) from its runs: the rates' definitions and the JSON keys the issue names."""

from __future__ import annotations

import math

import pytest
from homing.benchmarks.dock import FAULT_KINDS, summary


def run(fault: str, arrived: bool, docked: bool, time: float, attempts: int) -> dict:
    return {"variant": "recovery", "seed": 0, "fault": fault, "distance": 5.0, "arrived": arrived,
            "docked": docked, "time": time if docked else math.nan, "attempts": attempts, "wall": 1.0}


def test_autodock_rate_is_over_the_runs_that_arrived_and_times_over_those_that_docked() -> None:
    rows = [run("lidar_dropout", True, True, 30.0, 1), run("camera_off", True, True, 50.0, 2),
            run("kidnap", True, False, 0.0, 3), run("bumper_hit", False, False, 0.0, 0)]
    f = summary(rows)
    assert f["runs"] == 4
    assert f["arrival_rate"] == pytest.approx(3 / 4)  # reached the dock's IR field (AutoDock began)
    assert f["autodock_rate"] == pytest.approx(2 / 3)  # of those, charging at the end
    assert f["docked_rate"] == pytest.approx(2 / 4)
    assert f["dock_time_median_s"] == pytest.approx(40.0)  # failed runs have no time
    assert f["attempts_mean"] == pytest.approx(2.0)  # over the arrived runs
    assert f["by_fault"]["kidnap"] == 0.0 and f["by_fault"]["lidar_dropout"] == 1.0
    assert set(f["by_fault"]) <= set(FAULT_KINDS)


def test_no_run_arrived_gives_nan_not_an_error() -> None:
    f = summary([run("kidnap", False, False, 0.0, 0)])
    assert f["arrival_rate"] == 0.0 and math.isnan(f["autodock_rate"]) and math.isnan(f["dock_time_median_s"])
