"""The live view's map: walls, floor, robot, goal, path and frontiers land where the geometry says, cheaply."""

from __future__ import annotations

import math

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.missions.facts import Battery, _batteries, battery_bar
from homing.missions.minimap import ARROWS, FRONTIER_PERIOD, MiniMap, braille
from homing.robot import Pose2

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData

RES = 0.1  # [m/cell]


def _room() -> OccupancyGrid:
    """An 8 m × 4 m room (80 × 40 cells, walls on its border) with unknown space beyond x = 6 m."""
    data = np.full((40, 80), FREE, np.int8)
    data[[0, -1], :] = OCCUPIED
    data[:, [0, -1]] = OCCUPIED
    data[:, 60:79] = UNKNOWN
    return OccupancyGrid.from_map_data(MapData(data, RES, (0.0, 0.0, 0.0)), grow=False)


def _find(lines, char: str) -> tuple[int, int]:  # type: ignore[no-untyped-def]
    hits = [(i, line.plain.index(char)) for i, line in enumerate(lines) if char in line.plain]
    assert len(hits) == 1, (char, [line.plain for line in lines])
    return hits[0]


def test_braille_sets_the_dot_bits_of_each_2_by_4_block() -> None:
    dots = np.zeros((4, 4), bool)
    dots[0, 0] = dots[3, 1] = True  # dots 1 and 8 of the first character
    dots[:, 2:] = True  # every dot of the second
    assert [chr(c) for c in braille(dots)[0]] == ["⢁", "⣿"]


def test_walls_robot_goal_and_path_are_where_the_geometry_puts_them() -> None:
    grid = _room()
    mm = MiniMap(frontiers=lambda data, res: [])
    # 40 × 10 characters = 80 × 40 dots: one cell per dot, the room fills the panel exactly.
    robot, goal = Pose2(1.05, 1.05, 0.0), Pose2(4.05, 1.05, 0.0)
    path = np.array([[1.05, 1.05], [4.05, 1.05]])
    lines = mm.render(grid, 40, 10, robot, path, goal)
    assert mm.scale() == 1.0 and len(lines) == 10 and all(len(line.plain) == 40 for line in lines)
    # Row 10 of the grid (y = 1.05 m) is dot row 10 from the bottom: character line 9 - 10 // 4 = 7.
    assert _find(lines, "→") == (7, 10 // 2) and _find(lines, "◎") == (7, 40 // 2)
    # The path between them is drawn in cyan on that line, and only there.
    cyan = [(i, j) for i, line in enumerate(lines) for span in line.spans if "cyan" in str(span.style)
            for j in range(span.start, span.end)]
    assert cyan and {i for i, _ in cyan} == {7} and min(j for _, j in cyan) > 5 and max(j for _, j in cyan) < 20
    # The walls: the whole top line and the left column are braille with dots, in white.
    assert all(ch != "⠀" and 0x2800 < ord(ch) <= 0x28FF for ch in lines[0].plain[:30])
    assert all(0x2800 < ord(line.plain[0]) <= 0x28FF for line in lines)
    # Free floor has a background, the unknown part (x > 6 m, characters 30..39) has none.
    inside = lines[4]
    floor = {j for span in inside.spans if "on grey19" in str(span.style) for j in range(span.start, span.end)}
    assert set(range(2, 29)) <= floor and not floor & set(range(31, 39))


def test_the_heading_picks_the_arrow() -> None:
    grid = _room()
    mm = MiniMap(frontiers=lambda data, res: [])
    for k, arrow in enumerate(ARROWS):
        lines = mm.render(grid, 40, 10, Pose2(2.05, 2.05, k * math.pi / 4))
        assert _find(lines, arrow)[0] >= 0


def test_frontiers_are_drawn_and_computed_at_most_once_a_second_per_new_grid() -> None:
    grid = _room()
    calls: list[int] = []
    now = [0.0]

    def frontiers(data: np.ndarray, res: float) -> list[np.ndarray]:
        calls.append(1)
        return [np.array([[20, 59], [21, 59], [22, 59]])]  # cells on the free/unknown border

    mm = MiniMap(frontiers=frontiers, clock=lambda: now[0])
    lines = mm.render(grid, 40, 10, Pose2(1.0, 1.0, 0.0))
    magenta = [(i, j) for i, line in enumerate(lines) for span in line.spans if "magenta" in str(span.style)
               for j in range(span.start, span.end)]
    assert magenta and all(j == 59 // 2 for _, j in magenta), "drawn at column 59 // 2"
    for _ in range(50):  # redraws with the same grid: no new computation
        mm.render(grid, 40, 10, Pose2(1.0, 1.0, 0.0))
    assert len(calls) == 1
    grid.integrate_rays(np.array([3.0, 2.0]), np.array([0.0]), np.array([1.0]), np.array([True]))  # a new version
    now[0] += FRONTIER_PERIOD / 2
    mm.render(grid, 40, 10)
    assert len(calls) == 1, "not twice within a second"
    now[0] += FRONTIER_PERIOD / 2
    mm.render(grid, 40, 10)
    assert len(calls) == 2 and mm.frontier_count == 1


def test_battery_bar_marks_the_go_home_and_undock_levels() -> None:
    bar = battery_bar(Battery("base", 63.0, False, home=20.0, reserve=4.5, undock=90.0), 40).plain
    cells = bar[bar.index("▕") + 1 : bar.index("▏")]
    n = len(cells)
    assert cells[int(24.5 / 100 * n)] == "│" and cells[int(90 / 100 * n)] == "┊"
    assert cells.count("█") == int(0.63 * n) - 1  # the full cells below 63 %, less the go-home mark among them
    policy = {"base": {"percent": 63.0, "undock": 90.0, "home": 20.0, "reserve": 4.5}}
    shown = _batteries(policy, None)
    assert shown == [Battery("base", 63.0, False, 20.0, 4.5, 90.0)], "thresholds only where the policy gives them"
