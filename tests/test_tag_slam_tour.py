"""The tag tour's goal pickers: view poses in front of mapped tags (least-visited first) and facing unseen walls."""

from __future__ import annotations

import math

import numpy as np
import py_trees
from homing.behaviours.tag_slam_service import LANDMARKS_KEY, POSE_KEY, TOUR_GOAL_KEY, NextTagView
from homing.perception.tag_search import WallViews, next_view, wall_views
from homing.robot import Pose2
from py_trees.common import Access, Status


def _board(tags: dict[int, Pose2] | None, pose: Pose2 | None) -> py_trees.blackboard.Client:
    py_trees.blackboard.Blackboard.clear()
    bb = py_trees.blackboard.Client(name="test")
    for key in (LANDMARKS_KEY, POSE_KEY, TOUR_GOAL_KEY):
        bb.register_key(key=key, access=Access.WRITE)
    if tags is not None:
        bb.set(LANDMARKS_KEY, tags)
    if pose is not None:
        bb.set(POSE_KEY, pose)
    return bb


def test_goal_is_in_front_of_the_nearest_tag_facing_it():
    # tag 1 on a wall at x = 3 facing -x; tag 2 far away facing +y
    bb = _board({1: Pose2(3.0, 0.0, math.pi), 2: Pose2(-5.0, 4.0, math.pi / 2)}, Pose2(0.0, 0.0, 0.0))
    leaf = NextTagView("pick", distance=1.2)
    leaf.tick_once()
    assert leaf.status is Status.SUCCESS
    goal = bb.get(TOUR_GOAL_KEY)
    assert math.hypot(goal.x - 1.8, goal.y) < 1e-9  # 1.2 m out from the tag along its facing direction
    assert abs(math.cos(goal.theta) - 1.0) < 1e-9  # looking back at the tag (+x)


def test_every_tag_is_visited_before_any_twice():
    tags = {i: Pose2(float(i), 3.0, -math.pi / 2) for i in range(4)}
    bb = _board(tags, Pose2(0.0, 0.0, 0.0))
    leaf = NextTagView("pick", distance=1.0)
    seen = []
    for _ in range(8):
        leaf.tick_once()
        goal = bb.get(TOUR_GOAL_KEY)
        assert abs(goal.y - 2.0) < 1e-9 and abs(math.sin(goal.theta) - 1.0) < 1e-9
        seen.append(round(goal.x))
    assert sorted(seen[:4]) == [0, 1, 2, 3] and sorted(seen[4:]) == [0, 1, 2, 3]


def test_every_nth_pick_returns_to_the_anchor_tag():
    # the anchor (tag 0, the dock's) is nearest; the others are still visited least-visited first
    tags = {i: Pose2(float(i), 3.0, -math.pi / 2) for i in range(4)}
    bb = _board(tags, Pose2(0.0, 0.0, 0.0))
    leaf = NextTagView("pick", distance=1.0, anchor_tag=0, anchor_every=2)
    seen = []
    for _ in range(8):
        leaf.tick_once()
        seen.append(round(bb.get(TOUR_GOAL_KEY).x))
    assert seen[1::2] == [0, 0, 0, 0]
    assert sorted(seen[0:6:2]) == [1, 2, 3]  # each other tag once before any twice
    # an anchor not yet mapped is not waited for
    bb = _board({2: Pose2(2.0, 3.0, -math.pi / 2)}, Pose2(0.0, 0.0, 0.0))
    leaf = NextTagView("pick", distance=1.0, anchor_tag=0, anchor_every=2)
    for _ in range(2):
        leaf.tick_once()
        assert leaf.status is Status.SUCCESS and round(bb.get(TOUR_GOAL_KEY).x) == 2


def test_fails_while_nothing_is_mapped():
    _board({}, Pose2(0.0, 0.0, 0.0))
    leaf = NextTagView("pick")
    leaf.tick_once()
    assert leaf.status is Status.FAILURE
    _board({3: Pose2(1.0, 1.0, 0.0)}, None)
    leaf = NextTagView("pick")
    leaf.tick_once()
    assert leaf.status is Status.FAILURE


def _box(width: float, height: float, res: float = 0.05) -> tuple[np.ndarray, float, tuple[float, float]]:
    """A walled rectangle, free inside, ``width`` × ``height`` [m] with the origin at its lower-left outer corner."""
    h, w = int(round(height / res)), int(round(width / res))
    data = np.full((h, w), 0, dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    return data, res, (0.0, 0.0)


def test_wall_views_stand_off_the_walls_facing_them_and_spaced():
    data, res, origin = _box(8.0, 6.0)
    views = wall_views(data, res, origin, distance=1.2, spacing=2.0)
    assert len(views) >= 8  # a 8 × 6 m room has ~ (2·(5.6 + 3.6)) / 2 ≈ 9 stretches of wall 1.2 m in
    for v in views:
        d = min(v.x, v.y, 8.0 - v.x, 6.0 - v.y) - res  # to the nearest wall cell's face
        assert abs(d - 1.2) < 0.2
        # facing the nearest wall: the unit heading points along the shortest way out
        walls = {(-1.0, 0.0): v.x, (1.0, 0.0): 8.0 - v.x, (0.0, -1.0): v.y, (0.0, 1.0): 6.0 - v.y}
        near = min(walls.values())
        ok = [u for u, dist in walls.items() if dist < near + 0.1]
        assert any(math.cos(v.theta) * u[0] + math.sin(v.theta) * u[1] > 0.7 for u in ok)
    for i, a in enumerate(views):
        assert all(a.distance_to(b) >= 2.0 - 1e-9 for b in views[i + 1:])


def test_unknown_space_keeps_views_away_and_visited_views_are_skipped():
    data, res, origin = _box(8.0, 6.0)
    data[:, 80:] = -1  # right half never seen: no view pose may be near it
    views = wall_views(data, res, origin)
    assert views and all(v.x < 4.0 - 0.35 + 1e-9 for v in views)
    here = Pose2(2.0, 3.0, 0.0)
    first = next_view(views, here, [])
    assert first == min(views, key=here.distance_to)
    second = next_view(views, here, [first])
    assert second is not None and second.distance_to(first) > 1.0
    assert next_view(views, here, views) is None


def _rooms(rng: np.random.Generator) -> np.ndarray:
    """A 15 × 20 m floor (5 cm cells) of rooms: an outer wall and 12 interior walls, each with a 1 m door."""
    data = np.zeros((300, 400), dtype=np.int8)
    data[0, :] = data[-1, :] = data[:, 0] = data[:, -1] = 100
    for _ in range(12):  # interior walls with doors
        if rng.random() < 0.5:
            r = int(rng.integers(20, 280))
            data[r, :] = 100
            data[r, int(rng.integers(10, 380)):][:20] = 0
        else:
            c = int(rng.integers(20, 380))
            data[:, c] = 100
            data[int(rng.integers(10, 280)):, c][:20] = 0
    return data


def test_wall_views_are_a_greedy_thinning_of_every_candidate_anywhere_on_the_floor():
    """The thinning keeps the poses the row-major greedy rule keeps, on a floor of many rooms with its origin at
    negative coordinates (the kept poses are looked up by squares of the spacing): kept poses are pairwise at
    least the spacing apart, and every candidate of the band lies within the spacing of one kept before it."""
    from scipy import ndimage

    res, origin, spacing = 0.05, (-7.3, -4.1), 2.0
    data = _rooms(np.random.default_rng(3))
    views = wall_views(data, res, origin, distance=1.2, spacing=spacing)
    assert len(views) > 20
    xy = np.array([(v.x, v.y) for v in views])
    d = np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])
    assert (d[np.triu_indices(len(xy), 1)] >= spacing).all()
    occupied = data >= 50
    d_wall = ndimage.distance_transform_edt(~occupied) * res
    d_other = ndimage.distance_transform_edt(data == 0) * res
    rows, cols = np.nonzero((data == 0) & (np.abs(d_wall - 1.2) <= 0.15) & (d_other >= 0.35))
    cx, cy = origin[0] + (cols + 0.5) * res, origin[1] + (rows + 0.5) * res
    near = np.hypot(cx[:, None] - xy[None, :, 0], cy[:, None] - xy[None, :, 1]) < spacing
    assert near.any(axis=1).all()


def test_wall_views_kept_between_calls_are_the_views_of_the_map_as_it_is() -> None:
    """The patrol's next wall view is chosen at every goal on a map that changed a little since (floor:1: 60–430 of
    0.97 M cells): WallViews works the views out again only round what changed, and gives the poses a call from
    scratch gives, to the bit, after every change: a wall drawn, a door opened, speckle far off, a change at the
    map's edge, the array changed in place; another size, origin or spacing: worked out anew."""
    rng = np.random.default_rng(7)
    res, origin = 0.05, (-7.3, -4.1)
    data = _rooms(rng)
    kept = WallViews()

    def same(d: np.ndarray, o: tuple[float, float] = origin, **kw: float) -> list[Pose2]:
        got = kept(d, res, o, **kw)
        assert got == wall_views(d.copy(), res, o, **kw)
        return got

    first = same(data)
    assert first and same(data) == first  # unchanged: the last poses
    changes = [(slice(140, 141), slice(60, 200), 100),  # a wall drawn across a room
               (slice(0, 1), slice(150, 175), 0),  # the outer wall opened at the map's edge
               (slice(250, 256), slice(300, 304), -1)]  # unknown speckle
    for rows, cols, value in changes:
        data = data.copy()
        data[rows, cols] = value
        assert same(data) != first
    for _ in range(60):  # a few cells changed at a time, here and there, as scans do
        data = data.copy()
        r, c = rng.integers(0, 298), rng.integers(0, 398)
        data[r : r + 2, c : c + 2] = rng.choice(np.array([-1, 0, 100], np.int8), (2, 2))
        last = same(data)
    data[150:, :200] = -1  # the array the last call had, changed in place
    assert same(data) != last
    same(data, (-7.0, -4.1))
    same(data, spacing=1.5)
    same(np.pad(data, ((0, 20), (0, 0)), constant_values=-1))  # the grid grew
    # A pillar in an open hall: views round it as far as the band reaches (1.35 m), a change that far off
    hall, _, _ = _box(12.0, 12.0)
    kept = WallViews()
    same(hall)
    for r, c in ((120, 120), (120, 121), (121, 120), (93, 120), (92, 150)):
        hall = hall.copy()
        hall[r, c] = 100
        same(hall)
