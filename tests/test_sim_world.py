"""Worlds load from a name, a world file or a bare floor plan; mistakes are file:line errors, exit 2."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from homing.missions.cli import main
from homing.robot.types import Pose2
from homing.sim import SimRobot, load_world
from homing.sim.dock import DOCK_DEPTH
from homing.sim.walls import WALL_HEIGHT, build_mesh, world_to_cell

from homing.errors import UserError
from homing.map_server import FREE
from tests.sim_helpers import box_room, world_file


def _cell(world, pose: Pose2, ahead: float) -> tuple[int, int]:
    p = pose.compose(Pose2(ahead, 0.0, 0.0))
    r, c = world_to_cell(world.map, np.array([[p.x, p.y]]))
    return int(r[0]), int(c[0])


def _free(world, pose: Pose2, ahead: float) -> bool:
    return bool(world.map.grid[_cell(world, pose, ahead)] == FREE)


def test_lab_is_the_thesis_lab() -> None:
    lab = load_world("lab")
    assert lab.name == "lab"
    assert 8 <= len(lab.tags) <= 12 and len({t.id for t in lab.tags}) == len(lab.tags)
    ys, xs = np.nonzero(lab.map.grid == FREE)
    assert (np.ptp(xs) + 1) * lab.map.resolution == pytest.approx(10.0, abs=0.05)
    assert (np.ptp(ys) + 1) * lab.map.resolution == pytest.approx(10.0, abs=0.05)
    dock_tag = lab.tag(lab.dock_tag_id)
    assert math.hypot(dock_tag.x - lab.dock.station.x, dock_tag.y - lab.dock.station.y) < 0.01
    assert dock_tag.z > 0.2  # above the dock
    for tag in lab.tags:  # every tag hangs on a wall, facing free floor
        pose = Pose2(tag.x, tag.y, tag.yaw)
        assert not _free(lab, pose, -0.03) and _free(lab, pose, 0.03), tag
    assert lab.start == lab.dock_pose
    assert lab.reachable_free().sum() == (lab.map.grid == FREE).sum()  # one connected lab


def test_bare_floor_plan_gets_a_dock_against_a_wall_and_starts_docked(floor_plans: Path) -> None:
    for name in ("loop", "room_with_corner", "corridor"):
        world = load_world(floor_plans / f"{name}.yaml")
        station = world.dock.station
        assert not _free(world, station, -0.02), "no wall behind the dock"
        for ahead in np.arange(0.05, 1.5, 0.1):  # ~1 m clear in front of the docked robot
            for side in (-0.4, 0.0, 0.4):
                p = station.compose(Pose2(0.0, side, 0.0))
                assert _free(world, p, ahead)
        assert world.start == world.dock_pose
        assert world.dock_pose.distance_to(station) == pytest.approx(DOCK_DEPTH + 0.176)
        assert load_world(floor_plans / f"{name}.yaml").dock == world.dock  # deterministic
    robot = SimRobot(world, seed=1, camera=False)
    assert robot.charging and robot.observe().battery.on_dock
    robot.close()


def test_reachable_free_is_the_start_component(floor_plans: Path) -> None:
    world = load_world(floor_plans / "loop.yaml")
    reach = world.reachable_free()
    assert reach.dtype == bool and reach.shape == world.map.grid.shape
    assert np.all(world.map.grid[reach] == FREE)
    assert reach[_cell(world, world.start, 0.0)]
    # the loop's corridor: 20 m square ring, 3 m wide → ~ 20² − 14² minus walls
    assert 150.0 < reach.sum() * world.map.resolution**2 < 204.0


def test_world_file_with_relative_map_auto_tags_patches_and_faults(tmp_path: Path) -> None:
    box_room(tmp_path / "maps", 8.0, 6.0, name="floor")
    path = world_file(tmp_path, """
name: boxy
map: maps/floor.yaml
dock: auto
tags: {auto: 8, size: 0.12, height: 0.4}
patches: [{x0: 1.0, y0: 1.0, x1: 2.0, y1: 2.5, slip: 5}]
battery: {base: {percent: 40}, computer: {percent: 60, idle_a: 2.0}}
faults: [{name: kidnap, at: 12.5, to: [2.0, 3.0, 0.5]}, {name: lidar_dropout, at: 3, duration: 2, fraction: 0.5}]
""")
    world = load_world(path)
    assert world.name == "boxy" and len(world.tags) == 9
    ids = [t.id for t in world.tags]
    assert sorted(ids) == list(range(9))
    for tag in world.tags[1:]:
        assert tag.size == 0.12 and tag.z == 0.4
        pose = Pose2(tag.x, tag.y, tag.yaw)
        assert not _free(world, pose, -0.03) and _free(world, pose, 0.03)
        assert math.hypot(tag.x - world.dock.station.x, tag.y - world.dock.station.y) >= 1.0
    gaps = [min(math.hypot(a.x - b.x, a.y - b.y) for b in world.tags if b is not a) for a in world.tags]
    assert min(gaps) > 1.0  # spread out
    assert world.patches[0].slip == 5 and world.battery_base.percent == 40
    assert world.battery_computer.idle_a == 2.0
    assert [f.name for f in world.faults] == ["kidnap", "lidar_dropout"]


def test_wall_mesh_is_boundary_faces_facing_free_space(tmp_path: Path) -> None:
    world = load_world(box_room(tmp_path, 3.0, 2.0))
    mesh = build_mesh(world.map, WALL_HEIGHT)
    assert mesh.n_quads == 4  # one merged quad per side of an empty room
    assert mesh.vertices[:, 2].max() == pytest.approx(WALL_HEIGHT) and WALL_HEIGHT >= 1.0
    tri = mesh.indices.reshape(-1, 3)
    v = mesh.vertices
    normals = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    centres = v[tri].mean(axis=1)
    inward = (np.array([1.5, 1.0, 0.0]) - centres)[:, :2]
    assert np.all(np.sum(normals[:, :2] * inward, axis=1) > 0)  # front faces look into the room


BAD = {
    "missing_image.yaml": ("image: nothere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "missing_image.yaml:1:8:"),
    "bad_resolution.yaml": ("image: m.pgm\nresolution: fine\norigin: [0, 0, 0]\n", "bad_resolution.yaml:2:13:"),
    "not_pgm.yaml": ("image: not_pgm.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "not_pgm.pgm:1:1: not a PGM"),
    "unknown_key.yaml": ("map: room.yaml\ntagz: {auto: 3}\n", "unknown_key.yaml:2:1: unknown key 'tagz'"),
    "bad_type.yaml": ("map: room.yaml\ndock:\n  x: one\n  y: 0\n", "bad_type.yaml:3:6:"),
    "bad_map_ref.yaml": ("map: elsewhere.yaml\n", "bad_map_ref.yaml:1:6:"),
    "bad_fault.yaml": ("map: room.yaml\nfaults:\n  - {name: kidnap, at: -3}\n", "bad_fault.yaml:3:"),
    "dup_tag.yaml": ("map: room.yaml\ntags:\n  - {id: 0, x: 1, y: 1, yaw: 0}\n", "dup_tag.yaml:3:"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_malformed_worlds_fail_with_file_line_and_exit_2(tmp_path: Path, name: str, capsys) -> None:
    box_room(tmp_path, 4.0, 3.0)
    (tmp_path / "not_pgm.pgm").write_text("hello, not an image\n")
    (tmp_path / "m.pgm").write_bytes(b"P5\n2 2\n255\n" + bytes(4))
    text, expected = BAD[name]
    path = world_file(tmp_path, text, name=name.removesuffix(".yaml"))
    with pytest.raises(UserError):
        load_world(path)
    assert main(["world", "show", str(path), "--out", str(tmp_path / "w.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0], err
    assert not (tmp_path / "w.png").exists()


def test_world_show_draws_a_picture(tmp_path: Path, capsys) -> None:
    out = tmp_path / "lab.png"
    assert main(["world", "show", "lab", "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import cv2

    img = cv2.imread(str(out))
    assert img is not None and img.shape[0] > 400 and img.shape[1] > 400


@pytest.mark.slow
def test_world_dock_traces_the_servo_then_the_ir_drive_onto_the_charger(capsys) -> None:
    assert main(["world", "dock", "lab", "--offset", "0.3", "-0.3", "10"]) == 0
    lines = capsys.readouterr().out.splitlines()
    servo = [ln for ln in lines if "tag servo" in ln]
    drive = [ln for ln in lines if "IR drive" in ln]
    assert servo and "succeeded" in servo[-1] and drive and "done" in drive[-1]
    assert lines.index(servo[-1]) < lines.index(drive[0])  # the servo first, then the drive
    # The truth columns: the servo ends within 5 cm of the staging pose, the drive on the docked pose.
    assert float(servo[-1].split()[4]) <= 0.05 and float(drive[-1].split()[6]) <= 0.05
    assert lines[-1].startswith("docked after")
    assert main(["world", "dock", "lab", "--offset", "5", "0", "0"]) == 2
    assert "--offset 5 0 0" in capsys.readouterr().err


def test_sim_robot_speaks_the_adapter_contract() -> None:
    from homing.robot import RobotAdapter

    robot = SimRobot(load_world("lab"), seed=1, camera=False)
    assert isinstance(robot, RobotAdapter)
    t0 = robot.clock.now()
    robot.step(0.25)
    assert robot.clock.now() == pytest.approx(t0 + 0.25)
    assert robot.observe().stamp == robot.clock.now()
    assert robot.limits.max_v == pytest.approx(0.7)
    robot.close()


PHYSICAL = {  # a 4 m × 3 m room (box_room): walls' faces at x = 0, 4 and y = 0, 3
    "dock_mid_room.yaml": ("map: room.yaml\ndock: {x: 2.0, y: 1.5, yaw: 0.0}\n", "dock_mid_room.yaml:2:7: the dock"),
    "dock_backwards.yaml": ("map: room.yaml\ndock: {x: 0.0, y: 1.5, yaw: 3.1416}\n", "dock_backwards.yaml:2:7:"),
    "tag_mid_room.yaml": ("map: room.yaml\ntags:\n  - {id: 3, x: 2.0, y: 1.5, yaw: 0.0}\n",
                          "tag_mid_room.yaml:3:5: tag 3 at (2, 1.5) must hang on a wall"),
    "tag_into_wall.yaml": ("map: room.yaml\ntags:\n  - {id: 3, x: 0.0, y: 1.5, yaw: 3.1416}\n",
                           "tag_into_wall.yaml:3:5: tag 3"),
    "tag_nan.yaml": ("map: room.yaml\ntags:\n  - {id: 3, x: .nan, y: 1.5, yaw: 0}\n", "tag_nan.yaml:3:"),
}


@pytest.mark.parametrize("name", sorted(PHYSICAL))
def test_a_dock_or_tag_off_the_wall_is_a_file_line_error(tmp_path: Path, name: str) -> None:
    box_room(tmp_path, 4.0, 3.0)
    text, expected = PHYSICAL[name]
    with pytest.raises(UserError) as info:
        load_world(world_file(tmp_path, text, name=name.removesuffix(".yaml")))
    assert str(info.value).startswith(str(tmp_path / expected)), str(info.value)


def test_a_dock_and_tag_on_the_wall_load(tmp_path: Path) -> None:
    box_room(tmp_path, 4.0, 3.0)
    world = load_world(world_file(tmp_path, "map: room.yaml\ndock: {x: 0.0, y: 1.5, yaw: 0.0}\n"
                                            "tags:\n  - {id: 3, x: 4.0, y: 1.0, yaw: 3.1416}\n"))
    assert world.dock.station.x == 0.0 and world.tag(3).x == 4.0


def test_a_map_larger_than_one_bullet_mesh_is_built_in_pieces(tmp_path: Path) -> None:
    """A real building's SLAM map can hold more wall faces than Bullet takes in one mesh shape (131 072 vertices:
    ACES at 5 cm has 181 000, Edmonton a million): the walls are cut into pieces, and rays meet them all."""
    from homing.sim.scene import Scene
    from homing.sim.walls import MAX_MESH_VERTICES

    from homing.map_server import OCCUPIED, MapData, save_map

    grid = np.full((240, 240), FREE, dtype=np.int8)  # 12 m × 12 m at 5 cm
    grid[0, :] = OCCUPIED  # a wall along the bottom, for the dock
    grid[40::2, 0::2] = OCCUPIED  # a field of one-cell pillars from y = 2 m up: 12 000 of them, four faces each
    world = load_world(save_map(tmp_path / "pillars.yaml", MapData(grid, 0.05, (0.0, 0.0, 0.0))))
    mesh = build_mesh(world.map, WALL_HEIGHT)
    pieces = mesh.pieces()
    assert len(mesh.vertices) > MAX_MESH_VERTICES and len(pieces) >= 2
    assert all(len(p.vertices) <= MAX_MESH_VERTICES for p in pieces)
    assert sum(p.n_quads for p in pieces) == mesh.n_quads
    whole = {tuple(np.round(mesh.vertices[t].ravel(), 6)) for t in mesh.indices.reshape(-1, 3)}
    cut = {tuple(np.round(p.vertices[t].ravel(), 6)) for p in pieces for t in p.indices.reshape(-1, 3)}
    assert cut == whole  # the same triangles, wound the same way
    scene = Scene(world, visuals=False)
    try:
        assert len(scene.wall_bodies) == len(pieces)
        # Up from the pillar-free strip along pillar columns at both ends of the room: the first pillar's face
        # is at y = 2 m, 1.5 m from y = 0.5; and along a column between pillars, the room's top edge at 12 m.
        xs = (0.025, 11.925, 11.975)
        frac, ids = scene.rays(np.array([[x, 0.5, 0.3] for x in xs]), np.array([[x, 12.5, 0.3] for x in xs]))
        assert frac[:2] * 12.0 == pytest.approx([1.5, 1.5], abs=1e-6)
        assert frac[2] * 12.0 == pytest.approx(11.5, abs=1e-6)
        assert all(int(i) in scene.wall_bodies for i in ids)
    finally:
        scene.close()
