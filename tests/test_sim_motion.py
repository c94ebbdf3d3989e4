"""Commanded motion moves the true pose by v·t; odometry's errors follow the documented model (encoder slip, gyro heading)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from homing.robot.types import Pose2
from homing.sim import Patch, SimRobot, load_world
from homing.sim import odometry as om

from tests.sim_helpers import box_room

W, H = 9.0, 4.0  # [m]
RUNS = 60


@pytest.fixture(scope="module")
def room(tmp_path_factory: pytest.TempPathFactory):
    return load_world(box_room(tmp_path_factory.mktemp("motion"), W, H))


def _drive(world, seed: int, start: Pose2, v: float, w: float, seconds: float, dt: float = 0.1):
    robot = SimRobot(world, seed=seed, camera=False, start=start)
    robot.command(v, w)
    for _ in range(round(seconds / dt)):
        robot.step(dt)
    out = robot.truth_pose(), robot.observe().odom.pose
    robot.close()
    return out


def test_straight_turn_and_arc_follow_v_times_t(room) -> None:
    truth, _ = _drive(room, 1, Pose2(2.0, 2.0, 0.0), 0.3, 0.0, 5.0)
    assert (truth.x, truth.y, truth.theta) == pytest.approx((3.5, 2.0, 0.0), abs=1e-9)
    truth, _ = _drive(room, 1, Pose2(4.0, 2.0, 0.0), 0.0, 0.5, 2.0)
    assert (truth.x, truth.y, truth.theta) == pytest.approx((4.0, 2.0, 1.0), abs=1e-9)
    v, w, t, th0 = 0.2, 0.4, 3.0, 0.3
    truth, _ = _drive(room, 1, Pose2(3.0, 1.5, th0), v, w, t, dt=0.075)
    x = 3.0 + v / w * (math.sin(th0 + w * t) - math.sin(th0))
    y = 1.5 - v / w * (math.cos(th0 + w * t) - math.cos(th0))
    assert (truth.x, truth.y, truth.theta) == pytest.approx((x, y, th0 + w * t), abs=1e-9)


def test_commands_are_clipped_to_kobuki_limits(room) -> None:
    robot = SimRobot(room, seed=1, camera=False, start=Pose2(1.0, 2.0, 0.0))
    cmd = robot.command(2.0, -10.0)
    assert (cmd.v, cmd.omega) == (0.7, -math.pi)
    robot.command(2.0, 0.0)
    robot.step(1.0)
    assert robot.truth_pose().x == pytest.approx(1.7, abs=1e-9)
    robot.close()


def _straight_errors(world, v: float, seconds: float):
    along, lateral, heading = [], [], []
    for seed in range(RUNS):
        truth, odom = _drive(world, seed, Pose2(1.0, 2.0, 0.0), v, 0.0, seconds)
        assert truth.x == pytest.approx(1.0 + v * seconds, abs=1e-9)
        along.append(odom.x - v * seconds)
        lateral.append(odom.y)
        heading.append(odom.theta)
    return np.array(along), np.array(lateral), np.array(heading)


def _ratio_ok(samples: np.ndarray, var: float) -> bool:
    # sample variance over its expectation: 99.9 % of chi²(RUNS)/RUNS lies in [0.5, 1.6]
    return 0.5 < float(np.mean(samples**2)) / var < 1.6


def _heading_var(t: float, phi: float = 0.0) -> float:
    """Variance over power-ups of the gyro heading after ``t`` [s] turning through ``phi`` [rad]."""
    return om.GYRO_NOISE**2 * t + (om.GYRO_BIAS_SIGMA * t) ** 2 + (om.GYRO_SCALE_SIGMA * phi) ** 2


@pytest.mark.slow
def test_straight_odometry_errors_match_the_model(room) -> None:
    v, s = 0.4, 4.0
    t = s / v
    along, lateral, heading = _straight_errors(room, v, t)
    assert _ratio_ok(along, (om.K_S0 + om.K_SV * v) * s)
    assert _ratio_ok(heading, _heading_var(t))
    # the heading error integrated along the path: white noise (t³/3) and bias (t²/2)² terms
    assert _ratio_ok(lateral, v**2 * (om.GYRO_NOISE**2 * t**3 / 3 + (om.GYRO_BIAS_SIGMA * t**2 / 2) ** 2))
    assert abs(along.mean()) < 4 * math.sqrt((om.K_S0 + om.K_SV * v) * s / RUNS)


@pytest.mark.slow
def test_turning_heading_errors_match_the_gyro_model(room) -> None:
    w, phi = 2 * math.pi / 6.0, 2 * math.pi  # one full turn in 6 s
    errs = []
    for seed in range(RUNS):
        truth, odom = _drive(room, seed, Pose2(4.0, 2.0, 0.0), 0.0, w, phi / w)
        assert truth.theta == pytest.approx(0.0, abs=1e-9)
        errs.append(math.remainder(odom.theta - phi, 2 * math.pi))
    assert _ratio_ok(np.array(errs), _heading_var(phi / w, phi))


@pytest.mark.slow
def test_low_friction_patch_multiplies_encoder_slip_not_gyro_heading(room) -> None:
    slippery = replace(room, patches=(Patch(0.0, 0.0, W, H, slip=4.0),))
    v, s = 0.4, 4.0
    along, _, heading = _straight_errors(slippery, v, s / v)
    assert _ratio_ok(along, 4.0 * (om.K_S0 + om.K_SV * v) * s)
    assert _ratio_ok(heading, _heading_var(s / v))  # the gyro does not feel the floor


def test_faster_motion_slips_more_and_the_gyro_drifts_with_time() -> None:
    model = om.SlipModel()
    slow = model.variances(0.1, 0.0, 1.0)[0] / 0.1
    fast = model.variances(0.5, 0.0, 1.0)[0] / 0.5
    assert fast > slow  # per metre travelled
    # the same turn done slowly takes longer, so the gyro's white noise adds more
    assert model.variances(0.0, 1.0, 2.0)[1] > model.variances(0.0, 1.0, 0.5)[1]


def test_gyro_bias_and_scale_are_drawn_per_power_up_and_repeat_with_the_seed() -> None:
    a = om.WheelOdometry(np.random.default_rng(7))
    b = om.WheelOdometry(np.random.default_rng(7))
    c = om.WheelOdometry(np.random.default_rng(8))
    assert (a.gyro_bias, a.gyro_scale) == (b.gyro_bias, b.gyro_scale) != (c.gyro_bias, c.gyro_scale)
    # standing still, the heading drifts by the bias alone (plus white noise)
    for _ in range(600):
        a.update(0.0, 0.0, 0.1)
    assert a.pose.x == 0.0 and a.pose.y == 0.0
    assert abs(a.pose.theta - 60.0 * a.gyro_bias) < 5 * om.GYRO_NOISE * math.sqrt(60.0)
