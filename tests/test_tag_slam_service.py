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


def test_at_image_rate_a_standing_robot_looks_once_and_a_moving_one_again() -> None:
    # A charging robot faces its dock's tag for hours: once it has looked from where it stands, another look
    # adds nothing (and costs a render and a detection). Moving, it looks at image_rate again.
    import py_trees
    from homing.behaviours.keys import TAGS_KEY
    from homing.behaviours.tag_slam_service import TagSlamService
    from py_trees.common import Access

    py_trees.blackboard.Blackboard.clear()
    world = sim.load_world("lab")
    robot = sim.SimRobot(world, seed=3)
    try:
        robot.set_truth_pose(world.staging_pose(1.0))  # 1 m in front of the dock, facing its tag
        robot.step(0.4)  # the camera's next frame is taken there
        service = TagSlamService(grid=False, image_rate=1.0)
        client = py_trees.blackboard.Client(name="service:tag_slam")
        for key in TagSlamService.writes:
            client.register_key(key=key, access=Access.WRITE)
        service.setup(robot, client)
        looks: list[int] = []
        detect = service.detector.detect
        service.detector.detect = lambda frame: looks.append(1) or detect(frame)  # type: ignore[method-assign]

        def run(seconds: float, v: float) -> list[int]:
            seen: list[int] = []
            robot.command(v, 0.0)
            for _ in range(int(round(seconds / 0.2))):
                robot.step(0.2)
                service.update(robot.observe())
                seen.append(len(service.bb.get(TAGS_KEY) or []))
            return seen

        standing = run(10.0, 0.0)
        assert len(looks) == 1 and max(standing) >= 1  # one look, and it saw the dock's tag
        run(4.0, -0.05)  # backing away, 0.2 m: looks at 1 Hz again
        assert 3 <= len(looks) - 1 <= 5
    finally:
        robot.close()
