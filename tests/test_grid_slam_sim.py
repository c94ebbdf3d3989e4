"""Grid SLAM in the simulator: scan-to-map tracking must not be worse than the Kobuki's gyro odometry it starts from."""

from __future__ import annotations

import math

import numpy as np
import pytest


def _first_minute_errors(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(N, 2) SLAM and odometry errors [m, deg] against the sim's truth over the first minute of exploring the lab."""
    from homing.behaviours.keys import OBSERVATION_KEY, POSE_KEY
    from homing.benchmarks.explore import MISSION
    from homing.missions.compiler import compile_mission
    from homing.missions.runner import Runner
    from homing.sim import SimRobot, load_world
    from py_trees.common import Access

    robot = SimRobot(load_world("lab"), seed=seed, camera=False)
    try:
        mission = compile_mission(MISSION, {"time_limit": "60 s"})
        start = robot.truth_pose()
        world_from_odom = start.compose(robot.observe().odom.pose.inverse())  # map = odom at start
        slam_err: list[tuple[float, float]] = []
        odom_err: list[tuple[float, float]] = []

        def on_tick(r: Runner) -> None:
            pose = r.read(POSE_KEY)
            if pose is None:
                return
            truth = robot.truth_pose()
            for est, out in ((world_from_odom.compose(pose), slam_err),
                             (world_from_odom.compose(r.read(OBSERVATION_KEY).odom.pose), odom_err)):
                out.append((math.hypot(est.x - truth.x, est.y - truth.y),
                            abs(math.degrees(math.remainder(est.theta - truth.theta, 2 * math.pi)))))

        runner = Runner(mission, robot, seed=seed, until=61.0, on_tick=on_tick)
        for key in (POSE_KEY, OBSERVATION_KEY):
            if key not in runner.bb.remappings:
                runner.bb.register_key(key=key, access=Access.READ)
        runner.run()
    finally:
        robot.close()
    return np.array(slam_err), np.array(odom_err)


@pytest.mark.slow
def test_grid_slam_keeps_the_gyro_heading_and_odometry_accuracy_while_exploring_the_lab() -> None:
    """The first minute of the bundled exploration mission in the lab, seeds 1-4, errors against the sim's truth.

    With the odometry prior on heading as loose as a one-shot match's (3°), the correlative search's 0.5° steps
    turned the map by ~0.9° in the first seconds (the gyro was off by 0.08°) and the pose error grew to twice
    odometry's: every later scan was matched to the turned map. One seed is a noisy measure of this (seed 2:
    SLAM 0.32° against the gyro's 0.15°, seed 4: 0.77° against 0.93°), so the means over four are compared.
    Tracking must also beat odometry's position by a margin: while Gauss-Newton was held at the correlative
    search's 5 cm steps (no polish, grid_slam.POLISH_XY), it was odometry's within a centimetre (4.1 cm mean
    against 5.2 cm); polished, 2.8 cm against 6.2 cm.
    """
    runs = [_first_minute_errors(seed) for seed in (1, 2, 3, 4)]
    for slam, _ in runs:
        assert len(slam) > 400  # ten ticks a second for most of the minute
    slam_deg, odom_deg = (float(np.mean([r[i][:, 1].mean() for r in runs])) for i in (0, 1))
    slam_m, odom_m = (float(np.mean([r[i][:, 0].mean() for r in runs])) for i in (0, 1))
    assert slam_deg < odom_deg + 0.1, (slam_deg, odom_deg)  # [deg]
    assert slam_m < 0.6 * odom_m, (slam_m, odom_m)  # [m]
