"""The relations metric as Kümmerle et al. 2009 score it: stamps on, near, between and beyond a trajectory's poses,
squared errors, and relations files on another clock than their log (aligned, or refused with the offset)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from homing.mapping.relations import Relation, pose_at, score, shifted, time_offset
from homing.missions.cli import main
from homing.robot.types import Pose2

from homing.errors import UserError
from tests.test_slam_logs import synthetic_log

EPOCH_START = 1071078718.46  # [s] freiburg-079's PARAM lines: 10 Dec 2003, 18:51:58 UTC


def _arc(stamps: list[float]) -> list[Pose2]:
    """Poses on a circle of radius 4 m at 0.5 m/s, heading along it: turning 0.125 rad/s."""
    return [Pose2(4 * math.sin(0.125 * t), 4 * (1 - math.cos(0.125 * t)), 0.125 * t) for t in stamps]


def test_stamps_on_near_between_and_beyond_the_poses() -> None:
    stamps = [0.5 * k for k in range(11)]  # scans every 0.5 s, 0 … 5 s
    poses = _arc(stamps)
    # 5 ms off a scan (a stamp printed with two decimals): that scan's pose, as it is.
    assert pose_at(stamps, poses, 2.005) == (poses[4], "nearest")
    # 60 ms off: between the scans at 2.0 and 2.5 s, 12 % of the way — interpolated, checked by hand.
    p, how = pose_at(stamps, poses, 2.06)
    assert how == "interpolated" and p is not None
    a, b = poses[4], poses[5]
    assert (p.x, p.y, p.theta) == pytest.approx((a.x + 0.12 * (b.x - a.x), a.y + 0.12 * (b.y - a.y),
                                                 a.theta + 0.12 * (b.theta - a.theta)), abs=1e-12)
    # 4·sin 0.25 + 0.12·4·(sin 0.3125 − sin 0.25), 4·(1 − cos 0.25) + 0.12·4·(cos 0.25 − cos 0.3125), 0.25 + 0.12·0.0625
    assert (p.x, p.y, p.theta) == pytest.approx((1.01843, 0.13267, 0.2575), abs=1e-5)
    # 0.2 s after the last scan: outside the trajectory, nothing to interpolate from.
    p, why = pose_at(stamps, poses, 5.2)
    assert p is None and why == "5.200 s is 0.200 s after the trajectory's last pose (5.000 s)"
    # Within 0.1 s beyond an end: the end pose (the evaluator's nearest-pose tolerance).
    assert pose_at(stamps, poses, -0.08) == (poses[0], "nearest")


def test_every_relation_is_scored_or_listed_with_its_reason_and_errors_are_squared_too() -> None:
    stamps = [0.5 * k for k in range(11)]
    poses = _arc(stamps)
    truth = dict(zip(stamps, poses, strict=True))
    on_arc = _arc([2.06])[0]  # where the robot truly was 60 ms after the scan at 2.0 s
    rel = [
        Relation(1.005, 3.0, truth[1.0].between(truth[3.0]).compose(Pose2(0.1, 0.0, 0.0))),  # 0.1 m off
        Relation(2.06, 4.0, on_arc.between(truth[4.0]).compose(Pose2(0.0, 0.0, math.radians(2.0)))),  # 2° off
        Relation(1.0, 5.2, Pose2(2.0, 0.0, 0.0)),  # 0.2 s past the trajectory: listed, not scored
    ]
    e = score(rel, stamps, poses)
    assert (e.n, e.interpolated, e.missing) == (2, 1, 1)
    assert e.unmatched[0].relation == rel[2]
    assert e.unmatched[0].reason == "t2 5.200 s is 0.200 s after the trajectory's last pose (5.000 s)"
    # Relation 1: 0.1 m, 0°. Relation 2: 2°, and the chord between the scans against the arc, 12 % along it:
    # 0.12·0.88·4·sagitta, sagitta = 0.25²/(8·4) m, i.e. 0.8 mm.
    assert e.trans_max == pytest.approx(0.1, abs=1e-9)
    assert e.trans_mean == pytest.approx((0.1 + 0.12 * 0.88 * 4 * 0.25**2 / 32) / 2, abs=5e-5)
    assert e.rot_mean == pytest.approx(1.0, abs=1e-3) and e.rot_max == pytest.approx(2.0, abs=1e-3)
    assert e.trans_sq_mean == pytest.approx((0.1**2 + 0.0) / 2, abs=1e-5)
    assert e.trans_sq_max == pytest.approx(0.01, abs=1e-8)
    assert e.rot_sq_mean == pytest.approx((0.0 + 4.0) / 2, abs=1e-2)
    assert e.rot_sq_std == pytest.approx(math.sqrt(2 * 2.0**2), abs=1e-2)  # sample std of (0, 4) deg²
    # Taking the scan at 2.0 s for the stamp 2.06 s (the nearest within 0.1 s) would charge 3 cm of motion.
    nearest = score([rel[1]], stamps, poses, tolerance=0.1)
    assert nearest.trans_max < 1e-3
    assert score([Relation(2.0, 4.0, rel[1].delta)], stamps, poses).trans_max > 0.025


def _irregular_stamps(n: int = 300, seed: int = 7) -> list[float]:
    """Scan stamps as a real laser gives them: 0.2–0.8 s apart, from 0.23 s."""
    rng = np.random.default_rng(seed)
    return list(0.23 + np.cumsum(rng.uniform(0.2, 0.8, n)))


def test_relations_in_epoch_time_are_put_on_a_relative_log_when_one_offset_does_it() -> None:
    stamps = _irregular_stamps()
    poses = _arc(stamps)
    rel = [Relation(stamps[i] + EPOCH_START, stamps[i + 4] + EPOCH_START, poses[i].between(poses[i + 4]))
           for i in range(0, 290, 3)]
    offset = time_offset(rel, stamps)
    assert offset == pytest.approx(EPOCH_START, abs=1e-6)
    e = score(shifted(rel, offset), stamps, poses)
    assert (e.n, e.missing, e.interpolated) == (len(rel), 0, 0) and e.trans_max < 1e-6
    # Scored as they come, not one stamp would fall inside the log: each would be listed, none scored.
    assert score(rel, stamps, poses).n == 0
    # The other way round (a log on the epoch clock, relations from 0 s): the opposite offset.
    assert time_offset(shifted(rel, EPOCH_START), [t + EPOCH_START for t in stamps]) == \
        pytest.approx(-EPOCH_START, abs=1e-6)
    # Relations on the log's own clock need nothing.
    assert time_offset(shifted(rel, EPOCH_START), stamps) == 0.0
    # Relative relations counted from another start (37.4 s earlier) mostly fall inside the log too, but on
    # no scan: the offset that puts them on the scans is taken, not 0 (which would interpolate every one).
    late = shifted(rel, EPOCH_START - 37.4)
    assert time_offset(late, stamps) == pytest.approx(37.4, abs=1e-6)
    as_given = score(late, stamps, poses)
    assert as_given.n > len(rel) / 2 and as_given.interpolated == as_given.n  # scored, each one between scans


def test_an_ambiguous_offset_is_refused_naming_the_offset_needed() -> None:
    stamps = [0.5 * k for k in range(600)]  # a laser at exactly 2 Hz: every 0.5 s shift fits as well
    rel = [Relation(t + EPOCH_START, t + 2.0 + EPOCH_START, Pose2(1.0, 0.0, 0.0)) for t in stamps[40:500:5]]
    with pytest.raises(UserError) as err:
        time_offset(rel, stamps, "fr079.relations")
    msg = str(err.value)
    assert msg.startswith("fr079.relations: the relations' stamps (absolute (epoch), 1071078738.46–")
    assert "log's scans (relative, 0.00–299.50 s)" in msg
    assert msg.endswith(f"give --relations-offset {EPOCH_START + 20.0:.3f} if that is the offset")
    assert "\n" not in msg
    # On the log's own clock but 20.25 s late: inside the log, yet between every two scans, while shifts of
    # 20.25 s ± k·0.5 s put all on scans — refused too, not scored by interpolation.
    late = [Relation(r.t1 - EPOCH_START + 20.25, r.t2 - EPOCH_START + 20.25, r.delta) for r in rel]
    with pytest.raises(UserError, match=r"give --relations-offset 40.250 if that is the offset$"):
        time_offset(late, stamps)


def test_bench_slam_logs_aligns_or_refuses_a_relations_file_on_another_clock(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log, truth = synthetic_log(tmp_path, laps=0.5, seed=1)  # scans at 1, 2, … 20 s
    stamps = [1.0 + k for k in range(len(truth))]
    rel = tmp_path / "abs.relations"
    rel.write_text("".join(f"{stamps[i] + EPOCH_START:.6f} {stamps[i + 2] + EPOCH_START:.6f} "
                           f"{d.x:.6f} {d.y:.6f} 0 0 0 {d.theta:.6f}\n"
                           for i in range(0, 17, 2) for d in [truth[i].between(truth[i + 2])]))
    js = tmp_path / "out.json"
    # Scans 1 s apart exactly: every whole-second offset fits, so the offset cannot be found…
    assert main(["bench", "slam-logs", str(log), "--relations", str(rel), "--methods", "odometry",
                 "--json", str(js)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"{rel}: the relations' stamps (absolute (epoch)") and "\n" not in err
    assert "Traceback" not in err and f"--relations-offset {EPOCH_START:.3f}" in err
    # …and given, the relations are scored on the log's clock.
    assert main(["bench", "slam-logs", str(log), "--relations", str(rel), "--relations-offset", str(EPOCH_START),
                 "--methods", "odometry", "graph", "--json", str(js)]) == 0
    data = json.loads(js.read_text())
    for method in ("odometry", "graph"):
        r = data["raw"][method]
        assert (r["relations"], r["relations_missing"], r["relations_unmatched"]) == (9, 0, [])
        assert r["relations_offset_s"] == pytest.approx(EPOCH_START)
        assert r["trans_sq_err_mean_m2"] == pytest.approx(
            r["trans_err_mean_m"] ** 2 + r["trans_err_std_m"] ** 2 * 8 / 9, rel=1e-9)
    assert data["raw"]["graph"]["trans_err_mean_m"] < 0.03 < data["raw"]["odometry"]["trans_err_mean_m"]
    assert data["failed"] == [] and data["method_failures"] == []


def test_bad_relations_input_is_one_line_and_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log, _ = synthetic_log(tmp_path, laps=0.3, seed=2)
    bad = tmp_path / "bad.relations"
    bad.write_text("1 3 0.5 0 0 0 0 0.1\n2 5 0.9 0.1 0 0 0\n")
    assert main(["bench", "slam-logs", str(log), "--relations", str(bad), "--methods", "odometry"]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"{bad}:2:1: a relation has 8 numbers (t1 t2 x y z roll pitch yaw), this line 7"
    with pytest.raises(SystemExit) as stop:
        main(["bench", "slam-logs", str(log), "--relations-offset", "soon"])
    assert stop.value.code == 2
    assert "Traceback" not in capsys.readouterr().err
    good = tmp_path / "good.relations"
    good.write_text("1 3 0.5 0 0 0 0 0.1\n")
    assert main(["bench", "slam-logs", str(log), "--relations", str(good), "--relations-offset", "1",
                 "--relations-offset", "2", "--methods", "odometry"]) == 2
    assert capsys.readouterr().err.strip() == "2 --relations-offset values for 1 relations files"
