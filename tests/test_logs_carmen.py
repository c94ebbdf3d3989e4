"""CARMEN logs: the documented line formats, corrected logs' odometry, malformed and damaged files."""

from __future__ import annotations

import gzip
import math
from pathlib import Path

import numpy as np
import pytest
from homing.logs import open_log
from homing.logs.carmen import read_carmen
from homing.robot.types import Pose2

from homing.errors import UserError
from tests.log_helpers import SHARED_CARMEN, cast, flaser_line, odom_line

FLASER_ANGLES = -math.pi / 2 + np.arange(180) * math.radians(1.0)  # 180 beams over 180°


def corrected_log(tmp_path: Path, gz: bool = False) -> tuple[Path, list[Pose2], list[Pose2]]:
    """A corrected-style log: FLASER at the corrected pose, ODOM re-anchored after each scan, then the wheels.

    Returns the path, the corrected poses and the wheel increments' end poses (in each anchor's frame).
    """
    corrected = [Pose2(2.0 + 1.0 * k, 2.0 + 0.1 * k, 0.05 * k) for k in range(4)]
    wheel = [Pose2(0.9, 0.05, 0.06), Pose2(1.1, 0.12, 0.02), Pose2(0.95, 0.11, 0.07)]  # what the wheels measured
    lines = ["# message formats defined: PARAM SYNC ODOM FLASER", "PARAM robot_frontlaser_offset 0.0 nohost 0"]
    for k, pose in enumerate(corrected):
        ranges = cast(pose, FLASER_ANGLES, 81.0)
        lines.append(flaser_line(ranges, pose, pose, 10.0 + k))
        lines.append(odom_line(pose, 0.0))  # the re-anchoring line (stamp 0, as the corrected logs write it)
        lines.append(f"NEFF {30 - k}")
        if k < len(wheel):
            half = Pose2(wheel[k].x / 2, wheel[k].y / 2, wheel[k].theta / 2)
            lines.append(odom_line(pose.compose(half), 10.0 + k + 0.5))
            lines.append(odom_line(pose.compose(wheel[k]), 10.0 + k + 0.9))
    text = "\n".join(lines) + "\n"
    path = tmp_path / ("c.log.gz" if gz else "c.log")
    if gz:
        path.write_bytes(gzip.compress(text.encode()))
    else:
        path.write_text(text)
    return path, corrected, wheel


@pytest.mark.parametrize("gz", [False, True])
def test_corrected_log_gives_scans_wheel_odometry_and_reference(tmp_path: Path, gz: bool) -> None:
    path, corrected, wheel = corrected_log(tmp_path, gz)
    log = open_log(path)
    assert log.meta["format"] == "carmen" and log.meta["corrected"] is True
    scans = [t.obs for t in log.ticks() if t.obs.scan is not None]
    assert len(scans) == 4
    s = scans[0].scan
    assert s is not None
    assert len(s.ranges) == 180 and s.angle_min == pytest.approx(-math.pi / 2)
    assert s.angle_increment == pytest.approx(math.radians(1.0))
    # End points land on the room's walls: the beam geometry is the documented one.
    truth = cast(corrected[0], FLASER_ANGLES, 81.0)
    np.testing.assert_allclose(s.ranges[np.isfinite(truth)], truth[np.isfinite(truth)], atol=1e-3)
    # The odometry between scans is what the wheels measured, not the corrected motion.
    for k in range(3):
        d = scans[k].odom.pose.between(scans[k + 1].odom.pose)
        assert (d.x, d.y, d.theta) == pytest.approx((wheel[k].x, wheel[k].y, wheel[k].theta), abs=1e-5)
    # Each scan's tick carries the wheels' reading it holds, stamped when the wheels gave it (not the stamp-0
    # re-anchoring line): the first scan's own, then the last ODOM before each scan (so a gap in them shows).
    assert [o.odom.stamp for o in scans] == pytest.approx([10.0, 10.9, 11.9, 12.9])
    ref = log.reference()
    assert [p for _, p in ref] == [pytest.approx(c) for c in corrected] or all(
        p.distance_to(c) < 1e-6 for (_, p), c in zip(ref, corrected, strict=True))


def test_no_return_is_inf_and_range_max_below_it(tmp_path: Path) -> None:
    path, corrected, _ = corrected_log(tmp_path)
    text = path.read_text().splitlines()
    i = next(n for n, line in enumerate(text) if line.startswith("FLASER"))
    words = text[i].split()
    words[2:14] = ["81.91"] * 12  # the first twelve beams see nothing: the laser's saturation value
    text[i] = " ".join(words)
    path.write_text("\n".join(text) + "\n")
    scan = next(t.obs.scan for t in open_log(path).ticks() if t.obs.scan is not None)
    assert np.isinf(scan.ranges[:12]).all() and np.isfinite(scan.ranges[12:20]).all()
    assert scan.range_max < 81.91


def test_malformed_lines_are_counted_and_named(tmp_path: Path) -> None:
    path, _, _ = corrected_log(tmp_path)
    lines = path.read_text().splitlines()
    lines.insert(5, "FLASER 180 1.0 2.0 3.0")  # cut short
    lines.insert(8, "ODOM 1.0 abc 0.0 0 0 0 1.0 host 1.0")  # a word where a number belongs
    lines.insert(9, "TRUEPOS 1 2 3 4 5 6 1.0 host 1.0")  # another message type: skipped silently
    path.write_text("\n".join(lines) + "\n")
    log = read_carmen(path)
    assert log.meta["malformed_lines"] == 2
    assert [w.split(": ")[0] for w in log.warnings] == [f"{path}:6", f"{path}:9"]
    assert "FLASER" in log.warnings[0] and "ODOM" in log.warnings[1]
    assert log.meta["scans"] == 4


def test_robotlaser1_hokuyo_240_degrees(tmp_path: Path) -> None:
    """ROBOTLASER1 states its own field of view and resolution: a Hokuyo's 240° over 683 beams."""
    n, fov = 683, math.radians(240.0)
    res, start = fov / (n - 1), -fov / 2
    angles = start + res * np.arange(n)
    robot, laser_on_robot = Pose2(3.0, 4.0, 0.3), Pose2(0.1, 0.0, 0.0)
    laser = robot.compose(laser_on_robot)
    ranges = cast(laser, angles, 5.6)
    r = " ".join(f"{v:.4f}" if math.isfinite(v) else "5.6" for v in ranges)
    line = (f"ROBOTLASER1 0 {start} {fov} {res} 5.6 0.01 0 {n} {r} 0 {laser.x} {laser.y} {laser.theta} "
            f"{robot.x} {robot.y} {robot.theta} 0 0 0.5 0.3 0 12.5 host 12.5")
    path = tmp_path / "hokuyo.log"
    path.write_text(line + "\n")
    scan = next(t.obs.scan for t in open_log(path).ticks() if t.obs.scan is not None)
    assert len(scan.ranges) == n and scan.angle_min == pytest.approx(start)
    assert scan.laser_pose.x == pytest.approx(0.1)
    assert np.isinf(scan.ranges[~np.isfinite(ranges)]).all()
    pts = scan.points(robot)  # every end point on a wall of the room
    assert len(pts) > 100
    d = np.min([np.abs(pts[:, 1] - 8.0), np.abs(pts[:, 0] - 12.0), np.abs(pts[:, 0]), np.abs(pts[:, 1]),
                np.abs(np.maximum(np.abs(pts[:, 0] - 5.5), np.abs(pts[:, 1] - 3.5)) - 0.5),
                np.abs(pts[:, 0] - 9.0)], axis=0)
    assert np.max(d) < 0.02


def test_damaged_files_are_one_line_errors(tmp_path: Path) -> None:
    path, _, _ = corrected_log(tmp_path, gz=True)
    data = path.read_bytes()
    cut = tmp_path / "cut.log.gz"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(UserError, match="truncated gzip") as err:
        read_carmen(cut)
    assert "\n" not in str(err.value) and str(cut) in str(err.value)
    junk = tmp_path / "junk.log"
    junk.write_bytes(bytes(range(256)) * 4)
    with pytest.raises(UserError, match="no laser scans") as err:
        open_log(junk)
    assert str(err.value).startswith(f"{junk}:1:1: ")


@pytest.mark.skipif(not SHARED_CARMEN.is_dir(), reason="the Radish logs are in ../shared/datasets/carmen (dev checkout)")
def test_shared_aces_log_reads_with_its_documented_facts() -> None:
    log = open_log(SHARED_CARMEN / "aces-corrected.log.gz")
    assert log.meta["corrected"] and log.meta["scans"] == 440 and log.meta["no_return"] == pytest.approx(50.0)
    scans = [t.obs for t in log.ticks() if t.obs.scan is not None]
    ref = [p for _, p in log.reference()]
    errs = [ref[k].between(ref[k + 1]).inverse().compose(scans[k].odom.pose.between(scans[k + 1].odom.pose))
            for k in range(len(scans) - 1)]
    e = np.hypot([p.x for p in errs], [p.y for p in errs])
    assert 0.03 < float(np.median(e)) < 0.08 and float(e.max()) < 0.5  # README: median ~5 cm, up to ~0.4 m


def test_a_scan_with_no_wheel_reading_since_the_last_keeps_that_readings_stamp(tmp_path: Path) -> None:
    """Two scans with only the stamp-0 re-anchoring line between them: the second holds the first's reading."""
    pose = Pose2(2.0, 2.0, 0.0)
    ranges = cast(pose, FLASER_ANGLES, 81.0)
    path = tmp_path / "still.log"
    path.write_text("\n".join([flaser_line(ranges, pose, pose, 10.0), odom_line(pose, 0.0),
                               flaser_line(ranges, pose, pose, 11.0), odom_line(pose, 0.0)]) + "\n")
    scans = [t.obs for t in open_log(path).ticks() if t.obs.scan is not None]
    assert [o.odom.stamp for o in scans] == [10.0, 10.0]
