"""An ill-posed pose graph never ends a run: a 30 s gap in odometry, an odometer that jumps, a degenerate scan,
and GTSAM's "Indeterminate linear system" met by rebuilding the graph with QR."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from homing.logs import open_log
from homing.logs.offline import run_method, scans_of
from homing.mapping.graph_slam import ODOM_SIGMA_MAX, GraphConfig, GraphSlam
from homing.mapping.relations import relations_from_poses, score
from homing.robot.types import Pose2

from tests.log_helpers import cast, drifting_odometry, flaser_line, loop_trajectory, odom_line

SICK = -math.pi / 2 + np.radians(np.arange(180))
GAP = range(20, 50)  # scans (1 s apart) during which the wheels report nothing: 30 s


def gap_log(tmp_path: Path, seed: int = 4) -> tuple[Path, list[Pose2], list[Pose2], list[float]]:
    """A raw CARMEN log twice round the pillar, 0.4 m a second, with no ODOM line for 30 s while the robot drives on."""
    rng = np.random.default_rng(seed)
    truth = (loop_trajectory(40) * 2)[:70]
    odo = drifting_odometry(truth, rng)
    lines, stamps = [], []
    for k, (t, o) in enumerate(zip(truth, odo, strict=True)):
        stamp = 1.0 + k
        if k not in GAP:
            lines.append(odom_line(o, stamp - 0.05))
        lines.append(flaser_line(cast(t, SICK, 30.0) + rng.normal(0, 0.01, len(SICK)), o, o, stamp))
        stamps.append(stamp)
    path = tmp_path / "gap.log"
    path.write_text("\n".join(lines) + "\n")
    return path, truth, odo, stamps


def test_the_odometry_path_through_a_30_s_gap_in_odometry(tmp_path: Path) -> None:
    path, truth, odo, stamps = gap_log(tmp_path)
    log = open_log(path)
    result = run_method(log, "odometry")
    # Every scan placed, nothing raised; each step with the wheels silent for over 5 s (scans 24–49) and the
    # step that ends the gap (its increment spans 31 s) are counted.
    assert result.stamps == stamps
    assert result.info["factors_skipped"] == {"odometry gap: weak factor": 27}
    got = np.array([(p.x, p.y, p.theta) for p in result.poses])
    assert np.all(np.isfinite(got))
    # Sane: the wheels' own trajectory — standing at their last reading through the gap, then where they resume.
    for k, p in enumerate(result.poses):
        want = odo[GAP.start - 1] if k in GAP else odo[k]
        assert p.distance_to(want) < 1e-5 and abs(math.remainder(p.theta - want.theta, math.tau)) < 1e-5
    # Relations away from the gap score as the drifting wheels do: centimetres per metre, not metres.
    rel = [r for r in relations_from_poses(stamps, truth) if not any(s - 1 in GAP for s in (r.t1, r.t2))]
    away = score([r for r in rel if r.t2 - r.t1 < 5], stamps, result.poses)
    assert away.n > 20 and away.trans_mean < 0.1


def test_the_pose_graph_bridges_the_gap_with_the_lidar(tmp_path: Path) -> None:
    path, truth, _, stamps = gap_log(tmp_path)
    result = run_method(open_log(path), "graph")
    assert result.stamps == stamps
    assert result.info["factors_skipped"]["odometry gap: weak factor"] >= 1
    e = score(relations_from_poses(stamps, truth), result.stamps, result.poses)
    assert e.missing == 0 and e.trans_mean < 0.05 and e.rot_mean < 1.0  # [m], [deg]: the gap is not in the map


def test_an_odometer_that_jumps_10_km_does_not_make_the_graph_indeterminate() -> None:
    """The σ of a 10 km increment (0.02 m + 10 % of the path: 1 km) made iSAM2's Cholesky fail ("Indeterminate
    linear system", from 5 km on); now the σ is capped and the step counted."""
    slam = GraphSlam(GraphConfig(scan_matching=False, closure_radius=0.0, keyframe_distance=0.0, keyframe_angle=0.0))
    odom = Pose2()
    for k in range(30):
        step = Pose2(1e4, 0.0, 3.0) if k == 5 else Pose2(0.5, 0.0, 0.02)  # a corrupt reading, as logged
        odom = odom.compose(step)
        slam.update(0.1 * k, odom, None)
        slam.update(0.1 * k, odom, _scan(0.1 * k))
    slam.finish()
    stamps, poses = slam.trajectory()
    assert len(poses) == 30 and all(math.isfinite(p.x) for p in poses)
    assert poses[-1].x == pytest.approx(odom.x, abs=1e-6)  # the odometry path is the odometry's
    assert slam.stats.skipped == {"odometry gap: weak factor": 1}


def _scan(stamp: float) -> Any:
    from homing.robot.types import Scan

    return Scan(stamp, -math.pi / 2, math.radians(1.0), np.full(180, 3.0, np.float32), 0.0, 30.0, Pose2())


class _FailsOnce:
    """iSAM2 whose ``n``-th update raises as GTSAM does on an indeterminate system; otherwise the real one."""

    def __init__(self, isam: Any, n: int) -> None:
        self.isam, self.n = isam, n

    def update(self, *args: Any) -> Any:
        self.n -= 1
        if self.n == 0:
            raise RuntimeError("\nIndeterminant linear system detected while working near variable\n8646911284551352325")
        return self.isam.update(*args)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.isam, name)


def test_an_indeterminate_update_rebuilds_the_graph_with_qr_and_the_run_goes_on(tmp_path: Path) -> None:
    path, truth, _, stamps = gap_log(tmp_path, seed=5)
    data = [(o.stamp, o.pose, s) for _, o, s in scans_of(open_log(path))]
    runs = {}
    for fail_at in (None, 30):
        slam = GraphSlam()
        for k, (t, pose, scan) in enumerate(data):
            if fail_at is not None and k == 1:
                slam.isam = _FailsOnce(slam.isam, fail_at)
            slam.update(t, pose, scan)
        slam.finish()
        runs[fail_at] = slam
    assert runs[30].stats.qr_rebuilds == 1 and runs[None].stats.qr_rebuilds == 0
    _, clean = runs[None].trajectory()
    st, rebuilt = runs[30].trajectory()
    assert st == stamps
    # The same graph, solved by QR from the failure on (relinearised there, so the later fits move a little):
    # the same map within millimetres, and the same score.
    assert max(a.distance_to(b) for a, b in zip(clean, rebuilt, strict=True)) < 0.01
    rel = relations_from_poses(stamps, truth)
    assert score(rel, st, rebuilt).trans_mean == pytest.approx(score(rel, st, clean).trans_mean, abs=2e-3)
    assert score(rel, st, rebuilt).trans_mean < 0.05
    assert ODOM_SIGMA_MAX[0] < 100.0  # the cap stays below the σ that broke Cholesky (see the odometer test)
