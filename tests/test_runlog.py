"""Run logs: exact round trip, offline SLAM replay equal to online, and killed runs."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from homing.logs.runlog import MAGIC, Recorder, RunLog
from homing.mapping.landmark_slam import LandmarkSlam
from homing.mapping.landmark_synthetic import synthetic_loop
from homing.robot.types import (
    IR,
    BatteryState,
    Bumpers,
    ChargingSource,
    ChargingState,
    DockIR,
    Observation,
    Odometry,
    Pose2,
    Scan,
    Twist2,
)

from homing.errors import UserError


def _scan(t: float, rng: np.random.Generator) -> Scan:
    r = rng.uniform(0.2, 5.0, 360).astype(np.float32)
    r[rng.integers(0, 360, 20)] = np.inf
    return Scan(t, -math.pi, math.radians(1.0), r, 0.15, 6.0, Pose2(0.02, 0.0, 0.0))


def _record_online(path: Path, seed: int = 0, laps: int = 1) -> tuple[LandmarkSlam, list, list]:
    """Drive a synthetic loop, run SLAM online as the tag_slam service does, and log it all."""
    run = synthetic_loop(seed=seed, laps=laps)
    rng = np.random.default_rng(seed)
    slam = LandmarkSlam()
    states = []
    scan = None
    with Recorder(path, {"world": "synthetic", "seed": seed}, fsync=False) as rec:
        for i, (t, truth, odom, seen) in enumerate(run.ticks):
            if i % 2 == 0:
                scan = _scan(t - 0.01, rng)
            obs = Observation(
                t, Odometry(t, odom, Twist2(0.3, 0.0)), scan, None, Bumpers(left=i % 7 == 0),
                DockIR(right=IR.FAR_LEFT, centre=IR.NONE, left=IR.NEAR_CENTER | IR.FAR_CENTER),
                BatteryState(15.9 - 1e-4 * i, 80.0, ChargingSource.NONE, ChargingState.DISCHARGING),
            )
            rec.record_observation(obs)
            slam.update(obs.stamp, obs.odom.pose, obs.scan, seen)
            rec.record_tags(obs.stamp, seen)
            rec.record_command(t, Twist2(0.3, 0.1))
            rec.record_truth(truth, t)
            if i % 50 == 0:
                rec.record_status("Explore", "RUNNING", t)
            states.append((t, slam.map_to_odom, slam.landmarks()))
    return slam, states, run.ticks


def _replay(log: RunLog, until: float | None = None) -> LandmarkSlam:
    slam = LandmarkSlam()
    for tick in log.ticks(until):
        slam.update(tick.obs.stamp, tick.obs.odom.pose, tick.obs.scan, tick.tags)
    return slam


def test_observations_round_trip_exactly(tmp_path):
    rng = np.random.default_rng(1)
    scan = _scan(0.95, rng)
    obs = Observation(
        1.0, Odometry(0.99, Pose2(0.1 / 3, -2.0, 1.0 / 7), Twist2(0.25, -0.5)), scan, None,
        Bumpers(False, True, False), DockIR(IR.NEAR_LEFT, IR.FAR_CENTER | IR.NEAR_CENTER, IR.NONE),
        BatteryState(15.123456789, 61.5, ChargingSource.DOCK, ChargingState.DOCKING_CHARGING),
        BatteryState(12.0, 40.0),
    )
    with Recorder(tmp_path / "run.hlog", {"seed": 7}) as rec:
        rec.record_observation(obs)
    log = RunLog(tmp_path / "run.hlog")
    assert log.meta == {"seed": 7} and not log.truncated
    assert set(log.schema) >= {"obs", "scan", "tags", "cmd", "status", "truth"}
    (tick,) = list(log.ticks())
    back = tick.obs
    assert back.odom == obs.odom and back.bumpers == obs.bumpers and back.dock_ir == obs.dock_ir
    assert back.battery == obs.battery and back.computer_battery == obs.computer_battery
    assert back.scan is not None and back.scan.stamp == scan.stamp and back.scan.laser_pose == scan.laser_pose
    np.testing.assert_array_equal(back.scan.ranges, scan.ranges)  # inf included
    assert back.scan.ranges.dtype == np.float32


def test_offline_replay_equals_the_online_slam(tmp_path):
    online, _, ticks = _record_online(tmp_path / "run.hlog")
    log = RunLog(tmp_path / "run.hlog")
    assert sum(len(t.tags) for t in log.ticks()) == sum(len(s) for *_, s in ticks) > 0
    offline = _replay(log)
    assert offline.landmarks() == online.landmarks()  # bit for bit
    assert offline.map_to_odom == online.map_to_odom
    assert offline.keyframe_poses() == online.keyframe_poses()


def test_truth_and_the_rest_are_kept_apart(tmp_path):
    _, _, ticks = _record_online(tmp_path / "run.hlog")
    log = RunLog(tmp_path / "run.hlog")
    truth = log.truth()
    assert [p for _, p in truth] == [tr for _, tr, _, _ in ticks]
    assert all("truth" not in r for r in log.records if r["k"] == "obs")
    assert len(log.commands()) == len(ticks) and log.commands()[0][1] == Twist2(0.3, 0.1)
    assert log.statuses()[0][1:] == ("Explore", "RUNNING")


@pytest.mark.parametrize("cut_back", [1, 7, 200])
def test_a_log_cut_mid_write_replays_up_to_the_cut(tmp_path, cut_back):
    path = tmp_path / "run.hlog"
    _, states, _ = _record_online(path)
    raw = path.read_bytes()
    cut = tmp_path / "cut.hlog"
    cut.write_bytes(raw[: len(raw) - cut_back])  # the run was killed while writing its last frame
    log = RunLog(cut)
    assert log.truncated
    end = log.end
    assert 0 < end < states[-1][0]
    assert states[-1][0] - end < 2.5  # lost at most the last frame (≤ 1 s) plus the torn one
    replayed = _replay(log)
    last = list(log.ticks())[-1].obs.stamp
    assert end - 0.1 < last <= end
    t, m2o, marks = max((s for s in states if s[0] <= end), key=lambda s: s[0])
    assert t == last
    assert replayed.map_to_odom == m2o and replayed.landmarks() == marks


def test_replay_stops_at_a_chosen_time(tmp_path):
    _, states, _ = _record_online(tmp_path / "run.hlog")
    t, m2o, marks = states[len(states) // 2]
    replayed = _replay(RunLog(tmp_path / "run.hlog"), until=t)
    assert replayed.map_to_odom == m2o and replayed.landmarks() == marks


def test_a_killed_recorder_loses_at_most_its_last_second(tmp_path):
    path = tmp_path / "run.hlog"
    rec = Recorder(path, {}, flush_period=1.0, fsync=False)
    for i in range(101):  # 10 s of commands at 10 Hz, never closed (the process is killed)
        rec.record_command(0.1 * i, Twist2(0.1, 0.0))
    log = RunLog(path)
    stamps = [t for t, _ in log.commands()]
    assert stamps == pytest.approx([0.1 * i for i in range(len(stamps))])
    assert stamps[-1] >= 10.0 - 1.0 - 1e-9
    rec.close()
    assert len(RunLog(path).commands()) == 101


def test_a_file_that_is_not_a_log_is_a_user_error(tmp_path):
    bad = tmp_path / "notes.txt"
    bad.write_text("hello\n")
    with pytest.raises(UserError, match="not a homing run log"):
        RunLog(bad)
    with pytest.raises(UserError, match="cannot read"):
        RunLog(tmp_path / "missing.hlog")
    (tmp_path / "empty.hlog").write_bytes(MAGIC)
    with pytest.raises(UserError, match="no header"):
        RunLog(tmp_path / "empty.hlog")


def test_replay_command_reproduces_the_online_map_and_draws_it(tmp_path, capsys):
    import json

    from homing.missions.cli import main

    online, _, _ = _record_online(tmp_path / "run.hlog")
    online.flush()
    rc = main(["replay", str(tmp_path / "run.hlog"), "--slam", "--json", str(tmp_path / "m.json"),
               "--out", str(tmp_path / "fig.png")])
    assert rc == 0
    got = json.loads((tmp_path / "m.json").read_text())
    assert {int(k): v for k, v in got["landmarks"].items()} == {
        k: [p.x, p.y, p.theta] for k, p in online.landmarks().items()}
    assert got["map_to_odom"] == online.map_to_odom.as_array().tolist()
    assert (tmp_path / "fig.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "tag" in capsys.readouterr().out
    assert main(["replay", str(tmp_path / "nope.hlog"), "--slam"]) == 2


def _frame_starts(raw: bytes) -> list[int]:
    """Byte offsets of every frame in a log (the file's own layout: 8-byte header, then the payload)."""
    import struct

    pos, out = len(MAGIC), []
    while pos < len(raw):
        out.append(pos)
        pos += 8 + struct.unpack_from("<I", raw, pos)[0]
    return out


@pytest.mark.parametrize("where", ["payload", "length"])
def test_a_damaged_byte_is_corruption_at_its_offset_not_a_killed_run(tmp_path, where, capsys):
    from homing.missions.cli import main

    path = tmp_path / "run.hlog"
    _record_online(path)
    raw = bytearray(path.read_bytes())
    starts = _frame_starts(bytes(raw))
    assert len(starts) > 4
    frame = starts[3]
    if where == "payload":
        raw[frame + 20] ^= 0x40  # one bit flipped inside the third record frame
    else:
        raw[frame + 3] = 0xFF  # its length now claims gigabytes
    bad = tmp_path / "bad.hlog"
    bad.write_bytes(bytes(raw))
    with pytest.raises(UserError) as info:
        RunLog(bad)
    message = str(info.value)
    assert message.startswith(f"{bad}: corrupted run log at byte {frame}: ")
    assert ("fails its CRC check" if where == "payload" else "header is damaged") in message
    assert "3 intact frames before it" in message and "killed" not in message
    salvaged = RunLog(bad, salvage=True)
    assert not salvaged.truncated and salvaged.damage is not None and salvaged.damage.startswith(f"byte {frame}")
    intact = RunLog(path)
    assert salvaged.records == [r for r in intact.records if r["t"] <= salvaged.end][: len(salvaged.records)]
    assert 0 < salvaged.end < intact.end
    assert main(["replay", str(bad), "--slam"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"corrupted run log at byte {frame}" in err
    assert main(["replay", str(bad), "--slam", "--salvage"]) == 0
    assert f"damaged at byte {frame}" in capsys.readouterr().err


def test_a_log_of_a_newer_format_says_so(tmp_path):
    path = tmp_path / "run.hlog"
    _record_online(path)
    newer = tmp_path / "newer.hlog"
    newer.write_bytes(b"HOMINGLOG 2\n" + path.read_bytes()[len(MAGIC):])
    with pytest.raises(UserError, match=r"newer.hlog:1:1: run log format version 2 is newer than this homing reads"):
        RunLog(newer)
    from tests.conftest import homing_cli

    code, _, err = homing_cli("replay", str(newer), "--slam")
    assert code == 2 and "run log format version 2 is newer than this homing reads" in err
