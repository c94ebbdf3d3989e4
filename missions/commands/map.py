"""``homing map show MAP --out map.png``: a saved map with its frontier segments, each strategy's goal, path and the robot (thesis figs 2-3 to 2-6).

One panel per strategy (``--strategy NAME``, repeatable; default every
registered strategy), side by side: the grid (free white, walls black,
unknown grey), the frontier segments the strategy sees (one colour each; the
chosen one drawn thick), the goal it chooses (green disc), the path the
navigator's planner plans there (blue) and the robot (red, with its heading).
The robot stands at ``--robot X Y THETA`` (map frame; default: the map's
origin, where a run started, or the nearest free cell to it).
"""

from __future__ import annotations

import argparse
import math

PANEL_COLUMNS = 3  # panels per row of the picture
TITLE_HEIGHT = 22  # [px] band above each panel for its title
MAX_SCALE = 16  # [px/cell] a 500-cell map is then 8000 px a side


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file, seed, whole

    parser = sub.add_parser(
        "map",
        help="inspect a saved occupancy grid (map_server YAML + PGM)",
        description="Inspect a saved occupancy grid.",
    )
    actions = parser.add_subparsers(dest="map_action", metavar="ACTION", parser_class=type(parser))
    show = actions.add_parser(
        "show",
        help="draw a map with frontier segments, each strategy's goal and path, and the robot",
        description="Draw a map_server map with the frontiers, goal and path each exploration strategy "
        "chooses from the robot's pose (the thesis's figures 2-3 to 2-6).",
    )
    show.add_argument("map", metavar="MAP", help="map_server YAML (e.g. saved by homing bench explore --save-maps)")
    show.add_argument("--out", required=True, metavar="PNG", type=output_file("--out"), help="picture to write")
    show.add_argument("--strategy", action="append", metavar="NAME", help="strategy to draw (repeatable; default: all)")
    show.add_argument("--robot", nargs=3, type=float, metavar=("X", "Y", "THETA"),
                      help="robot pose in the map frame [m, m, rad] (default: the map frame's origin)")
    show.add_argument("--seed", type=seed, default=0, help="seed of the strategies' random choices")
    show.add_argument("--scale", type=whole(0, MAX_SCALE), default=0,
                      help=f"pixels per cell, 1 … {MAX_SCALE} (default: fit ~500 px per panel)")
    show.set_defaults(func=_show)
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])


def _show(args: argparse.Namespace) -> int:
    import cv2
    import numpy as np
    from homing.mapping.map_io import load_grid
    from homing.mapping.strategies import STRATEGIES

    from homing.atomic import atomic_write
    from homing.errors import UserError

    names = args.strategy or list(STRATEGIES)
    for name in names:
        if name not in STRATEGIES:
            from homing.missions.schema import suggest

            raise UserError(f"--strategy: unknown strategy '{name}'{suggest(name, STRATEGIES)} "
                            f"(known: {', '.join(sorted(STRATEGIES))})")
    grid = load_grid(args.map)
    robot = _robot_pose(grid, args.robot)
    panels, lines = [], []
    for name in names:
        panel, line = strategy_panel(grid, name, robot, args.seed, args.scale)
        panels.append(panel)
        lines.append(line)
    ok, png = cv2.imencode(".png", _tile(panels, np))
    if not ok:
        raise UserError(f"cannot encode {args.out}")
    atomic_write(args.out, png.tobytes())
    print(f"{args.out}: {grid.shape[1]}×{grid.shape[0]} cells at {grid.resolution:g} m, robot at "
          f"({robot.x:.2f}, {robot.y:.2f})")
    for line in lines:
        print("  " + line)
    return 0


def _robot_pose(grid, given):  # noqa: ANN001, ANN202 - OccupancyGrid and Pose2, imported lazily
    import numpy as np
    from homing.mapping.frontier import accessible_mask
    from homing.robot import Pose2

    from homing.errors import UserError

    if given is not None:
        pose = Pose2(*given)
        r, c = grid.world_to_cell(pose.x, pose.y)
        if not grid.in_bounds(r, c):
            raise UserError(f"--robot ({pose.x:g}, {pose.y:g}) lies outside the map")
        return pose
    ok = accessible_mask(grid.data, grid.resolution)
    if not ok.any():
        raise UserError("the map has no free cell the robot fits in: give --robot X Y THETA")
    r0, c0 = grid.world_to_cell(0.0, 0.0)
    rows, cols = np.nonzero(ok)
    i = int(np.argmin((rows - int(r0)) ** 2 + (cols - int(c0)) ** 2))
    x, y = grid.cell_to_world(rows[i], cols[i])
    return Pose2(float(x), float(y), 0.0)


def strategy_panel(grid, name: str, robot, seed: int = 0, scale: int = 0):  # noqa: ANN001, ANN201
    """(BGR image with a title band, one summary line) for one strategy's choice on ``grid`` from ``robot``."""
    import cv2
    import numpy as np
    from homing.mapping.explorer import Explorer
    from homing.mapping.render import render_grid
    from homing.mapping.strategies import make_strategy
    from homing.navigation.costmap import Costmap
    from homing.navigation.planner import FIELD_BLOCK, PlanningError, distance_map, make_planner

    costmap = Costmap()
    costmap.update_static(grid)
    distance = distance_map(costmap, robot, allow_unknown=False, coarse=FIELD_BLOCK)  # as the Explore leaf
    explorer = Explorer(make_strategy(name), np.random.default_rng(seed))
    step = explorer.update(grid, robot, distance, 0.0)
    choice = step.choice
    path_cells = None
    if step.goal is not None:
        try:
            path = make_planner("fmm").plan(costmap, robot, step.goal)
            path_cells = np.column_stack([(path[:, 1] - grid.origin[1]) / grid.resolution - 0.5,
                                          (path[:, 0] - grid.origin[0]) / grid.resolution - 0.5])
        except PlanningError:
            path_cells = None
    if choice is not None:
        segments, goal, label = choice.segments, choice.cell, (choice.segment.label if choice.segment else None)
    else:
        segments, goal, label = [], None, None
    h, w = grid.shape
    s = scale or max(1, int(round(500 / max(h, w))))
    rr = (robot.y - grid.origin[1]) / grid.resolution - 0.5
    rc = (robot.x - grid.origin[0]) / grid.resolution - 0.5
    img = render_grid(grid.data, segments, goal, (rr, rc, robot.theta), path_cells, scale=s, highlight=label)
    band = np.full((TITLE_HEIGHT, img.shape[1], 3), 255, np.uint8)
    if goal is None:
        summary = f"{name}: no frontier left ({len(segments)} segments)"
    else:
        gx, gy = grid.cell_to_world(*goal)
        d = float(distance[goal])
        summary = f"{name}: goal ({float(gx):.2f}, {float(gy):.2f}), {d:.1f} m away, {len(segments)} segments"
    title = name if goal is None else f"{name} ({float(distance[goal]):.1f} m)"
    cv2.putText(band, title, (4, 16), cv2.FONT_HERSHEY_SIMPLEX,
                0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([band, img]), summary


def _tile(panels, np):  # noqa: ANN001, ANN202
    cols = min(PANEL_COLUMNS, len(panels))
    ph = max(p.shape[0] for p in panels)
    pw = max(p.shape[1] for p in panels)
    rows = math.ceil(len(panels) / cols)
    out = np.full((rows * (ph + 4), cols * (pw + 4), 3), 255, np.uint8)
    for i, p in enumerate(panels):
        r, c = divmod(i, cols)
        out[r * (ph + 4) : r * (ph + 4) + p.shape[0], c * (pw + 4) : c * (pw + 4) + p.shape[1]] = p
    return out
