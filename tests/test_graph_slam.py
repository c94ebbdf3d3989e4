"""The pose graph's parts against worked examples: scan-to-submap fits, relative covariances, closure windows and
confirmation, and every scan (not only keyframes) placed by the lidar when the wheels lose degrees."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from homing.mapping import graph_slam, submap
from homing.mapping.graph_slam import (
    CLOSURE_SIGMAS,
    CLOSURE_WINDOW_MAX,
    CLOSURE_WINDOW_MIN,
    closure_window,
)
from homing.mapping.relations import relations_from_poses, score
from homing.mapping.scan_match import CorrelativeMatcher
from homing.robot.types import Pose2

from tests.log_helpers import cast, flaser_line, loop_trajectory, odom_line

SICK = -math.pi / 2 + np.radians(np.arange(180))  # a SICK's 180 beams at 1°, the laser looking forward


def _points(pose: Pose2, rng: np.random.Generator) -> np.ndarray:
    """End points (M, 2) [m, base_link] of a 180° scan from ``pose`` in the room, 1 cm range noise."""
    r = cast(pose, SICK, 30.0) + rng.normal(0.0, 0.01, len(SICK))
    ok = np.isfinite(r)
    return np.column_stack([r[ok] * np.cos(SICK[ok]), r[ok] * np.sin(SICK[ok])])


def test_a_scan_is_fitted_to_a_submap_from_a_prior_tens_of_centimetres_and_degrees_off() -> None:
    rng = np.random.default_rng(0)
    keyframes = [Pose2(2.0, 2.0, 0.2), Pose2(3.0, 2.2, 0.5), Pose2(3.8, 2.9, 0.9)]
    refs = [submap.scan_reference(_points(p, rng)) for p in keyframes]
    built = submap.build(refs, keyframes)
    assert built is not None
    truth = Pose2(4.3, 3.4, 1.2)
    matcher = CorrelativeMatcher(window_xy=0.5, window_theta=math.radians(12.0), min_score=0.0)
    for off in (Pose2(0.3, -0.2, math.radians(6.0)), Pose2(-0.25, 0.3, math.radians(-9.0))):
        found = submap.fit(built, _points(truth, rng), truth.compose(off), matcher, min_score=0.6)
        assert found is not None
        assert found.pose.distance_to(truth) < 0.02
        assert abs(math.remainder(found.pose.theta - truth.theta, 2 * math.pi)) < math.radians(0.3)
        assert np.sqrt(np.linalg.eigvalsh(found.covariance[:2, :2])).max() < 0.05  # a room pins every direction
    # A scan of a place the submap never saw scores too low to be trusted.
    far = submap.build([refs[0]], [Pose2(40.0, 40.0, 0.0)])
    assert far is not None
    assert submap.fit(far, _points(truth, rng), Pose2(40.0, 40.0, 0.0), matcher, min_score=0.6) is None


def test_closure_window_is_its_sigmas_clipped() -> None:
    w = closure_window(np.diag([0.2**2, 0.25**2, math.radians(4.0) ** 2]))
    assert w == pytest.approx((CLOSURE_SIGMAS * 0.25, CLOSURE_SIGMAS * math.radians(4.0)))
    assert closure_window(np.diag([1e-6, 1e-6, 1e-8])) == pytest.approx(CLOSURE_WINDOW_MIN)
    assert closure_window(np.diag([100.0, 100.0, 10.0])) == pytest.approx(CLOSURE_WINDOW_MAX)
    # The position's σ is the covariance's largest axis, whichever way it points.
    rot = np.array([[math.cos(0.7), -math.sin(0.7)], [math.sin(0.7), math.cos(0.7)]])
    c = np.eye(3) * 1e-8
    c[:2, :2] = rot @ np.diag([0.3**2, 0.01**2]) @ rot.T
    assert closure_window(c)[0] == pytest.approx(CLOSURE_SIGMAS * 0.3)


def test_wide_closures_count_only_when_two_move_the_map_alike() -> None:
    fit = submap.Fit
    cov = np.eye(3) * 1e-4
    # The map has drifted: the truth is the estimate moved by 1.5 m and 10° about the origin.
    drift = Pose2(1.5, -0.5, math.radians(10.0))
    est_a, est_b = Pose2(20.0, 5.0, 0.3), Pose2(21.0, 5.3, 0.35)
    a = graph_slam._Closure(0, 10, Pose2(), fit(drift.compose(est_a), cov, 0.8), est_a)
    b = graph_slam._Closure(1, 11, Pose2(), fit(drift.compose(est_b), cov, 0.8), est_b)
    assert graph_slam._agree(a, b)
    # A false match 0.5 m along a corridor from the true one does not agree, nor one 5° off.
    b_false = graph_slam._Closure(1, 11, Pose2(), fit(drift.compose(est_b).compose(Pose2(0.5, 0.0, 0.0)), cov, 0.8),
                                  est_b)
    b_turned = graph_slam._Closure(1, 11, Pose2(), fit(drift.compose(est_b).compose(Pose2(0, 0, 0.09)), cov, 0.8),
                                   est_b)
    assert not graph_slam._agree(a, b_false) and not graph_slam._agree(a, b_turned)


def test_scans_between_keyframes_are_placed_by_the_lidar_not_the_wheels(tmp_path: Path) -> None:
    """Dense scans (10 cm apart) with wheels that lose 2° per step: every scan's heading comes from its fit."""
    from homing.logs import open_log
    from homing.logs.offline import run_method

    rng = np.random.default_rng(5)
    truth = loop_trajectory(160)  # 16 m round the pillar, 10 cm steps
    odo = [truth[0]]
    for a, b in zip(truth, truth[1:], strict=False):
        d = a.between(b)
        odo.append(odo[-1].compose(Pose2(d.x, d.y, d.theta + rng.normal(0.0, math.radians(2.0)))))
    lines = []
    for k, (t, o) in enumerate(zip(truth, odo, strict=True)):
        lines.append(odom_line(o, 1.0 + 0.2 * k))
        lines.append(flaser_line(cast(t, SICK, 30.0) + rng.normal(0, 0.01, 180), o, o, 1.0 + 0.2 * k))
    path = tmp_path / "dense.log"
    path.write_text("\n".join(lines) + "\n")
    log = open_log(path)
    rel = relations_from_poses([1.0 + 0.2 * k for k in range(len(truth))], truth)
    errs = {m: score(rel, *(lambda r: (r.stamps, r.poses))(run_method(log, m))) for m in ("odometry", "scan_matching")}
    result = run_method(log, "scan_matching")
    assert result.info["keyframes"] < 0.7 * len(truth)  # most scans are not keyframes…
    assert errs["odometry"].rot_mean > 3.0  # [deg] the wheels alone: degrees off within a metre
    assert errs["scan_matching"].rot_mean < 0.3  # …yet each is within a few tenths of a degree
    assert errs["scan_matching"].trans_mean < 0.02
