"""Exploration end to end: the bundled mission, the runner and the pybullet TurtleBot in a small three-room world."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from homing.robot import Pose2

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData, save_map

RES = 0.05  # [m]


def three_rooms(folder: Path, second_door: tuple[float, float] = (0.0, 1.2)) -> Path:
    """An 8 m × 4 m floor split into three rooms by walls at x = 2.7 m (door at the north end) and x = 5.3 m
    (a door from y = ``second_door[0]`` to ``[1]`` [m], at the south end), so no room sees into the next but one; map_server YAML
    (the sim places the dock)."""
    margin, wall = 0.5, 0.10  # [m]
    w, h = 8.0, 4.0
    g = np.full((round((h + 2 * margin) / RES), round((w + 2 * margin) / RES)), UNKNOWN, dtype=np.int8)
    i0, i1 = round((margin - wall) / RES), round(margin / RES)
    g[i0:-i0, i0:-i0] = OCCUPIED
    g[i1:-i1, i1:-i1] = FREE
    for x, (y0, y1) in ((2.7, (2.8, 4.0)), (5.3, second_door)):
        c = round((margin + x) / RES)
        g[i1:-i1, c - 1 : c + 1] = OCCUPIED
        g[round((margin + y0) / RES) : round((margin + y1) / RES), c - 1 : c + 1] = FREE  # the door
    return save_map(folder / "three_rooms.yaml", MapData(g, RES, (-margin, -margin, 0.0)))


@pytest.mark.slow
@pytest.mark.parametrize("strategy", ["frontier_travel", "gain_rate"])
def test_explores_three_rooms_without_touching_anything(tmp_path: Path, strategy: str) -> None:
    from homing.benchmarks.explore import run_one
    from homing.mapping.map_io import load_grid

    world = three_rooms(tmp_path)
    saved = tmp_path / "final.yaml"
    r = run_one(str(world), strategy, seed=4, minutes=6.0, save_map=str(saved))
    assert r.done, "no frontier left before the time limit"
    assert r.coverage >= 0.95, r  # of the free area reachable from the dock, from the sim's truth
    assert r.bumps == 0
    assert r.agreement >= 0.95  # the grid agrees with the true floor plan (the matcher drifts ~2° here: see report)
    assert r.goals >= 3 and r.farthest > 2.0  # it drove through the doors, not just looked
    grid = load_grid(saved)
    assert abs((grid.data == FREE).sum() * grid.resolution**2 - r.area) < 0.01


@pytest.mark.slow
def test_a_log_without_the_view_ends_with_the_explorers_end_report(tmp_path: Path) -> None:
    """``homing run --no-view`` ends, as the live view does, with how exploration ended: explored, the coverage
    estimate and the gap given up as narrower than the robot."""
    import subprocess
    import sys

    plan = three_rooms(tmp_path, second_door=(0.3, 0.55))
    out = subprocess.run([sys.executable, "-m", "homing.missions.cli", "run", "explore", "--world", str(plan),
                          "--seed", "3", "--until", "8 min", "--no-view"], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    last = out.stdout.splitlines()[-1]
    assert last.startswith("Explore: explored: coverage estimate "), last
    assert "0 reachable frontier(s) left" in last and "narrower_than_robot" in last, last


@pytest.mark.slow
def test_a_gap_narrower_than_the_robot_ends_exploration_with_the_gap_reported_and_the_rest_covered(
        tmp_path: Path) -> None:
    """The third room is behind a 0.25 m gap (the robot is 0.35 m wide): exploration ends on its own, says
    which gap it gave up, and has covered the two rooms the robot can get into."""
    import cv2
    from homing.benchmarks.explore import run_one
    from homing.mapping.map_io import load_grid
    from homing.mapping.reachable import frontier_report
    from homing.robot.turtlebot import FOOTPRINT_RADIUS
    from homing.sim import load_world

    plan = three_rooms(tmp_path, second_door=(0.3, 0.55))
    saved = tmp_path / "final.yaml"
    r = run_one(str(plan), "frontier_travel", seed=3, minutes=8.0, save_map=str(saved))
    assert r.done and r.frontiers_left == 0 and r.given_up >= 1, r
    world = load_world(plan)
    world_from_map = world.start  # the map frame is the odometry's, which starts at zero on the dock
    grid = load_grid(saved)
    # The gap given up: a narrow frontier just beyond the wall at x = 5.3 m, near the gap (y 0.3..0.55 m).
    report = frontier_report(grid, (0.0, 0.0))
    assert report.reachable == ()
    near_gap = []
    for site in report.narrow:
        p = world_from_map.compose(Pose2(site.x, site.y, 0.0))
        near_gap.append(5.0 <= p.x <= 6.3 and -0.2 <= p.y <= 1.2)
    assert any(near_gap), report.summary()
    # Everything the footprint can reach (the first two rooms), and the walls around it, has been seen.
    truth = world.map
    fits = cv2.distanceTransform((truth.grid == FREE).astype(np.uint8), cv2.DIST_L2, 5) * truth.resolution
    reach = (fits > FOOTPRINT_RADIUS) & (np.arange(truth.grid.shape[1])[None, :] * truth.resolution
                                         + truth.origin[0] < 5.2)
    rows, cols = np.nonzero(reach)
    xy = np.column_stack([truth.origin[0] + (cols + 0.5) * truth.resolution,
                          truth.origin[1] + (rows + 0.5) * truth.resolution])
    pts = world_from_map.inverse().transform_points(xy)
    gr, gc = grid.world_to_cell(pts[:, 0], pts[:, 1])
    ok = grid.in_bounds(gr, gc)
    seen = np.zeros(len(rows), bool)
    seen[ok] = grid.data[gr[ok], gc[ok]] != UNKNOWN
    assert seen.mean() >= 0.95


@pytest.mark.slow
def test_a_run_until_the_target_ends_at_its_95_percent_with_the_full_runs_figures(tmp_path: Path) -> None:
    """``bench explore --until-target``: the session ends at the first sample at 95 % coverage, and its t95, area
    then and efficiency (what the ratios compare) are those of the same run let go on to its end."""
    from homing.benchmarks.explore import COVERAGE_PERIOD, run_one

    world = str(three_rooms(tmp_path))
    # A seed whose run goes on exploring past its 95 % sample (seed 4's ended on it once the controller no longer
    # slowed beside walls, seed 1's once the costmap placed scans between ticks; seeds 0 and 4 now go on 3-4 s),
    # so that the cut run has something to leave out.
    full = run_one(world, "frontier_travel", seed=4, minutes=6.0)
    cut = run_one(world, "frontier_travel", seed=4, minutes=6.0, until_target=True)
    assert full.done and not full.stopped_at_target and full.explore_time > full.t95 + 1.0
    assert cut.stopped_at_target and not cut.done
    assert (cut.t95, cut.area95, cut.efficiency) == (full.t95, full.area95, full.efficiency)
    assert cut.t95 <= cut.explore_time <= cut.t95 + 0.5  # it ended there (within a tick or two)
    assert full.t95 % COVERAGE_PERIOD < 0.5  # on the sampling grid, as the full sweep's
