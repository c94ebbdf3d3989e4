"""Costmap layers the lidar cannot see, and growth to a goal beyond the grid: checked against exact geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from homing.navigation.costmap import INSCRIBED, LETHAL, NO_INFORMATION, Costmap
from homing.navigation.layers import BUMP_MEMORY, BUMP_RIM, Keepout, dock_keepout, parse_keepout
from homing.navigation.planner import GoalOccupied, make_planner
from homing.robot import Bumpers, Pose2, Scan
from homing.robot.frames import wrap_angle
from homing.robot.turtlebot import BASE_RADIUS, FOOTPRINT_RADIUS

RES = 0.05  # [m]
HALF_DIAG = RES / math.sqrt(2)  # [m] a cell centre is this close to any point of its cell


def _open_costmap(size: int = 80) -> Costmap:
    cm = Costmap()
    cm.set_static(np.zeros((size, size), dtype=np.int8), RES, (0.0, 0.0))
    return cm


def _lethal_xy(cm: Costmap) -> np.ndarray:
    return cm.cell_to_world(np.argwhere(cm.cost == LETHAL))


@pytest.mark.parametrize(("side", "lo", "hi"), [("centre", -30, 30), ("left", 30, 90), ("right", -90, -30)])
def test_a_bump_marks_its_sectors_arc_at_the_rim(side: str, lo: float, hi: float) -> None:
    cm = _open_costmap()
    pose = Pose2(2.0, 2.0, 0.7)
    assert cm.mark_bumpers(Bumpers(**{side: True}), pose, stamp=5.0)
    xy = _lethal_xy(cm)
    assert len(xy) >= 3
    rel = pose.inverse().transform_points(xy)
    r = np.hypot(rel[:, 0], rel[:, 1])
    bearing = np.degrees(np.arctan2(rel[:, 1], rel[:, 0]))
    # Every lethal cell holds a point of the rim arc: its centre is within half a cell diagonal of it.
    assert np.all(np.abs(r - BUMP_RIM) <= HALF_DIAG + 1e-9)
    slack = math.degrees(HALF_DIAG / BUMP_RIM)
    assert np.all((bearing >= lo - slack) & (bearing <= hi + slack))
    # …and the whole sector is covered: the arc's ends and middle are marked.
    for a in (lo, 0.5 * (lo + hi), hi):
        p = pose.transform_points([[BUMP_RIM * math.cos(math.radians(a)), BUMP_RIM * math.sin(math.radians(a))]])
        assert cm.cost_at(p)[0] == LETHAL
    # The robot itself is now within the footprint of the mark; the cell behind it is not.
    assert cm.cost_at([[pose.x, pose.y]])[0] == INSCRIBED
    away = pose.transform_points([[-0.3 * math.cos(math.radians(0.5 * (lo + hi))),
                                   -0.3 * math.sin(math.radians(0.5 * (lo + hi)))]])
    assert cm.cost_at(away)[0] < INSCRIBED


def test_bump_marks_fade_resist_the_scan_and_go_with_clear_costmap() -> None:
    cm = _open_costmap()
    pose = Pose2(2.0, 2.0, 0.0)
    cm.mark_bumpers(Bumpers(centre=True), pose, stamp=0.0)
    ahead = pose.transform_points([[BUMP_RIM, 0.0]])
    # A scan from the robot whose rays pass over the (low) obstacle does not clear it.
    ranges = np.full(360, 3.0, dtype=np.float32)
    cm.update_scan(Scan(0.0, -math.pi, 2 * math.pi / 360, ranges, 0.15, 6.0), pose)
    assert cm.cost_at(ahead)[0] == LETHAL
    cm.forget_bumps(BUMP_MEMORY - 1.0)
    assert cm.cost_at(ahead)[0] == LETHAL
    cm.forget_bumps(BUMP_MEMORY + 1.0)
    assert cm.cost_at(ahead)[0] != LETHAL
    cm.mark_bumpers(Bumpers(centre=True), pose, stamp=100.0)
    cm.clear()
    assert not (cm.cost == LETHAL).any() and len(cm.bumps) == 0


def test_keepout_disc_and_polygon_are_lethal_where_they_lie_and_survive_clearing() -> None:
    cm = _open_costmap()
    disc = Keepout.disc(1.0, 1.0, 0.3)
    square = Keepout(np.array([[2.5, 2.5], [3.0, 2.5], [3.0, 3.2], [2.5, 3.2]]))
    cm.set_keepout([disc, square])
    centres = cm.cell_to_world(np.argwhere(np.ones(cm.shape, bool)))
    lethal = (cm.cost == LETHAL).ravel()
    inside = disc.contains(centres) | square.contains(centres)
    assert np.all(lethal[inside])  # every cell whose centre lies in a zone
    # Cells marked lethal touch a zone (edge cells), none lies farther than half a cell diagonal away.
    d_disc = np.abs(np.hypot(*(centres - [1.0, 1.0]).T) - 0.3)
    d_sq = np.hypot(*np.maximum(np.column_stack([2.5 - centres[:, 0], 2.5 - centres[:, 1]]),
                                np.column_stack([centres[:, 0] - 3.0, centres[:, 1] - 3.2])).clip(min=0).T)
    assert np.all((np.minimum(d_disc, d_sq) <= HALF_DIAG + 1e-9)[lethal & ~inside])
    # The footprint keeps clear: inscribed all round.
    assert cm.cost_at([[1.0 + 0.3 + FOOTPRINT_RADIUS, 1.0]])[0] >= INSCRIBED
    cm.clear()
    assert cm.cost_at([[1.0, 1.0]])[0] == LETHAL
    # Removing the zones frees the cells again.
    cm.set_keepout(None)
    assert not (cm.cost == LETHAL).any()


def test_dock_keepout_covers_the_dock_box_and_leaves_the_docked_robot_free() -> None:
    docked = Pose2(1.0, 2.0, -2.0)
    zone = dock_keepout(docked)
    # The dock's box: from the robot's rim 0.12 m ahead, 0.30 m wide (kobuki dock).
    xs, ys = np.meshgrid(np.linspace(BASE_RADIUS + 0.01, BASE_RADIUS + 0.12, 6), np.linspace(-0.15, 0.15, 7))
    box = docked.transform_points(np.column_stack([xs.ravel(), ys.ravel()]))
    assert zone.contains(box).all()
    # Never behind the rim: the robot's own disc is not in it.
    a = np.linspace(0, 2 * math.pi, 72)
    disc = docked.transform_points(np.column_stack([BASE_RADIUS * np.cos(a), BASE_RADIUS * np.sin(a)]))
    assert not zone.contains(disc).any()
    cm = _open_costmap()
    cm.set_keepout([zone])
    # The docked robot can plan away from it (its start is inscribed, not lethal).
    assert cm.cost_at([[docked.x, docked.y]])[0] != LETHAL
    path = make_planner("fmm").plan(cm, docked, Pose2(3.0, 3.0))
    assert not zone.contains(path[1:]).any()


def test_parse_keepout_spellings_and_mistakes() -> None:
    zones = parse_keepout([[1.0, 2.0, 0.5], [[0, 0], [1, 0], [1, 1]]])
    assert zones[0].radius == 0.5 and len(zones[1].points) == 3
    assert parse_keepout(None) == []
    with pytest.raises(ValueError, match=r"keepout\[0\]"):
        parse_keepout([[1.0, 2.0]])
    with pytest.raises(ValueError, match="positive radius"):
        parse_keepout([[1.0, 2.0, -1.0]])


def test_costmap_grows_to_a_goal_beyond_the_grid_on_the_grids_lattice() -> None:
    g = np.full((40, 60), -1, dtype=np.int8)
    g[10:30, 10:50] = 0
    g[20:30, 30] = 100  # a wall across the upper half of the known band
    cm = Costmap()
    cm.set_static(g, RES, (-1.0, -0.5))
    goal = Pose2(6.0, 4.0)  # far outside the 3 m × 2 m grid
    cm.require(goal.x - 0.5, goal.y - 0.5, goal.x + 0.5, goal.y + 0.5)
    assert cm.inside(cm.world_to_cell([[goal.x + 0.45, goal.y + 0.45]]))[0]
    # Same lattice: every grid cell centre lands on a cell with the grid's own content.
    rc = np.argwhere(np.ones(g.shape, bool))
    xy = -np.array([1.0, 0.5]) + (rc[:, ::-1] + 0.5) * RES
    cells = cm.world_to_cell(xy)
    assert np.array_equal(cm.static[cells[:, 0], cells[:, 1]] == LETHAL, (g >= 50).ravel())
    assert np.array_equal(cm.static[cells[:, 0], cells[:, 1]] == NO_INFORMATION, (g < 0).ravel())
    # Beyond the grid: unknown.
    assert cm.cost_at([[goal.x, goal.y]])[0] == NO_INFORMATION
    # Plannable through the unknown (Nav2's allow_unknown), not without it.
    path = make_planner("fmm").plan(cm, Pose2(0.0, 0.0), goal)
    assert np.hypot(*(path[-1] - [goal.x, goal.y])) < 1e-9
    with pytest.raises(GoalOccupied):
        make_planner("fmm", allow_unknown=False).plan(cm, Pose2(0.0, 0.0), goal)
    # A new grid keeps the growth; release shrinks back to the grid.
    cm.set_static(g, RES, (-1.0, -0.5))
    assert cm.cost_at([[goal.x, goal.y]])[0] == NO_INFORMATION and cm.shape != g.shape
    cm.release()
    assert cm.shape == g.shape and cm.origin == (-1.0, -0.5)


def test_a_goal_inside_the_grid_does_not_grow_it() -> None:
    cm = _open_costmap()
    cm.require(1.0, 1.0, 2.0, 2.0)
    assert cm.shape == (80, 80) and cm.origin == (0.0, 0.0)


def test_virtual_points_hand_the_unseen_to_the_controller() -> None:
    cm = _open_costmap()
    cm.set_keepout([Keepout.disc(1.0, 1.0, 0.2)])
    cm.mark_bumpers(Bumpers(left=True), Pose2(3.0, 3.0, 0.0), 0.0)
    near_disc = cm.virtual_points(Pose2(1.5, 1.0), 1.0)
    assert len(near_disc) > 0
    assert np.allclose(np.hypot(*(near_disc - [1.0, 1.0]).T), 0.2)
    near_bump = cm.virtual_points(Pose2(3.0, 3.0), 0.5)
    bearing = np.arctan2(near_bump[:, 1] - 3.0, near_bump[:, 0] - 3.0)
    assert np.all((bearing >= math.radians(30) - 1e-9) & (bearing <= math.radians(90) + 1e-9))
    assert np.allclose([wrap_angle(b) for b in bearing], bearing)


def test_a_zones_kept_edge_is_the_edge_worked_out_afresh_and_cannot_be_changed() -> None:
    for zone in (Keepout.disc(1.0, -2.0, 0.3), dock_keepout(Pose2(0.4, 0.2, 0.7))):
        for step in (0.02, 0.025, 0.1):
            kept = zone.edge(step)
            assert zone.edge(step) is kept  # asked again: the same array, not worked out again
            assert np.array_equal(kept, Keepout(zone.points, zone.radius).edge(step))  # a new zone's, afresh
            assert np.all(np.hypot(*np.diff(np.vstack([kept, kept[:1]]), axis=0).T) <= step + 1e-9)
            with pytest.raises(ValueError):
                kept[0, 0] = 0.0  # read-only: a caller cannot spoil what the next one gets
