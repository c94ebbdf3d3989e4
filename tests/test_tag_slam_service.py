"""The tag_slam service through the mission runner on the simulator; run logs recorded and replayed via the CLI."""

from __future__ import annotations

import json
import math
from pathlib import Path

import homing.sim as sim  # noqa: E402 - part of the package: a broken simulator must fail, not skip
import pytest
from homing.logs.runlog import Recorder, RunLog
from homing.missions.cli import main
from homing.missions.commands.replay import replay_slam
from homing.missions.compiler import compile_mission
from homing.missions.runner import Runner

TOUR = Path(__file__).resolve().parents[1] / "missions" / "examples" / "tag_tour.yaml"


def _tour(seed: int, log: Path):
    """Run the tag tour with a recorder as ``homing run --record`` does; the service, truth and map frame."""
    world = sim.load_world("lab")
    robot = sim.SimRobot(world, seed=seed)
    try:
        start_truth, start_odom = robot.truth_pose(), robot.observe().odom.pose
        with Recorder(log, {"world": "lab", "seed": seed, "mission": str(TOUR)}) as rec:
            runner = Runner(compile_mission(TOUR), robot, seed=seed, recorder=rec, truth=robot.truth_pose)
            result = runner.run()
        assert result.reason == "success"
        return runner.services[0], robot.truth_pose(), robot.observe().odom.pose, start_truth.compose(start_odom.inverse())
    finally:
        robot.close()


@pytest.fixture(scope="module")
def tours(tmp_path_factory: pytest.TempPathFactory):
    folder = tmp_path_factory.mktemp("tour")
    return {seed: (*_tour(seed, folder / f"tour{seed}.log"), folder / f"tour{seed}.log") for seed in (0, 1)}


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_map_to_odom_correction_reduces_the_pose_error_on_a_driven_loop(tours, seed):
    service, truth, odom, world_from_map = tours[seed][:4]
    odom_err = world_from_map.compose(odom).distance_to(truth)
    slam_err = world_from_map.compose(service.slam.pose(odom)).distance_to(truth)
    assert odom_err > 0.03  # the gyro's scale error over three turns really drifted
    assert slam_err < 0.6 * odom_err and slam_err < 0.025
    # and every tag it mapped is where the world has it
    tags = {t.id: t for t in sim.load_world("lab").tags}
    marks = service.slam.landmarks()
    assert {0, 1, 2, 3} <= set(marks)
    for tag_id, p in marks.items():
        q = world_from_map.compose(p)
        assert math.hypot(q.x - tags[tag_id].x, q.y - tags[tag_id].y) < 0.05


@pytest.mark.slow
def test_replay_of_the_recorded_run_equals_the_online_slam(tours):
    service, *_, log = tours[0]
    offline = replay_slam(RunLog(log))
    assert offline.landmarks() == service.slam.landmarks()  # bit for bit
    assert offline.map_to_odom == service.slam.map_to_odom
    assert len(offline.keyframes) == len(service.slam.keyframes)
    statuses = RunLog(log).statuses()
    assert ("TagTour", "SUCCESS") in {(n, s) for _, n, s in statuses}
    assert len(RunLog(log).truth()) == len(list(RunLog(log).ticks()))


@pytest.mark.slow
def test_cli_record_then_a_log_cut_mid_write_replays_up_to_the_cut(tmp_path, capsys):
    log, out = tmp_path / "run.log", tmp_path / "slam.json"
    assert main([
        "run", str(TOUR), "--world", "lab", "--seed", "2", "--until", "30s", "--no-view", "--record", str(log),
    ]) == 0  # fmt: skip
    full = RunLog(log)
    assert not full.truncated and full.meta["world"] == "lab" and full.meta["seed"] == 2
    raw = log.read_bytes()
    log.write_bytes(raw[: int(len(raw) * 0.6)])  # killed mid-frame
    cut = RunLog(log)
    assert cut.truncated and 5.0 < cut.end < full.end
    assert main(["replay", str(log), "--slam", "--json", str(out)]) == 0
    assert "ends mid-frame" in capsys.readouterr().out
    got = json.loads(out.read_text())
    assert got["truncated"] and got["end_s"] == cut.end
    # what the cut log replays is exactly what the full log gives up to the cut
    expect = replay_slam(full, until=cut.end)
    assert got["landmarks"] == {str(k): [v.x, v.y, v.theta] for k, v in expect.landmarks().items()}
    assert got["keyframes"] == len(expect.keyframes)
