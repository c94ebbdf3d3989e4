"""``homing world show WORLD --out world.png``: draw a simulated world (map, dock, tags, patches, start)."""

from __future__ import annotations

import argparse
import io
import math

MIN_DPI, MAX_DPI = 30, 600  # [dots/inch] the 8-inch figure: 240 … 4800 pixels a side
FIGURE_INCHES = 8  # the picture's side, before its margins


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file, whole

    parser = sub.add_parser(
        "world",
        help="inspect a simulated world (a bundled name, a world YAML or a map_server YAML)",
        description="Inspect a simulated world.",
    )
    actions = parser.add_subparsers(dest="world_action", metavar="ACTION", parser_class=type(parser))
    show = actions.add_parser(
        "show",
        help="draw the world: floor plan, dock and its IR field, tags, low-friction patches, start pose",
        description="Draw a world to a PNG: floor plan, dock, tags, patches and start pose.",
    )
    show.add_argument("world", metavar="WORLD", help="bundled world name (e.g. lab) or path to a YAML file")
    show.add_argument("--out", required=True, metavar="PNG", type=output_file("--out"), help="picture to write")
    show.add_argument("--dpi", type=whole(MIN_DPI, MAX_DPI), default=120, help=f"resolution of the picture ({MIN_DPI}…{MAX_DPI}, default 120)")
    show.set_defaults(func=_show)
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])


def _show(args: argparse.Namespace) -> int:
    from homing.sim.world import load_world

    from homing.atomic import atomic_write

    world = load_world(args.world)
    png = draw_world(world, dpi=args.dpi)
    atomic_write(args.out, png)
    print(f"{args.out}: {world.name}, {len(world.tags)} tags, dock at "
          f"({world.dock.station.x:.2f}, {world.dock.station.y:.2f})")
    return 0


def block_any(mask, k: int):  # noqa: ANN001, ANN201 - numpy, imported lazily
    """(⌈H/k⌉, ⌈W/k⌉) bool: whether any cell of each k × k block of the (H, W) bool ``mask`` is True."""
    import numpy as np

    if k == 1:
        return mask
    h, w = mask.shape
    padded = np.zeros((-(-h // k) * k, -(-w // k) * k), bool)
    padded[:h, :w] = mask
    return padded.reshape(padded.shape[0] // k, k, padded.shape[1] // k, k).any(axis=(1, 3))


def draw_world(world, dpi: int = 120) -> bytes:  # noqa: ANN001 - homing.sim.world.World, imported lazily
    """PNG bytes of a world's picture."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from homing.robot.turtlebot import BASE_RADIUS
    from homing.robot.types import Pose2
    from homing.sim.dock import DOCK_DEPTH, DOCK_WIDTH, FIELD_DEPTH, FIELD_HALF_WIDTH, NEAR_RANGE
    from matplotlib.patches import Circle, Polygon, Rectangle

    from homing.map_server import FREE, OCCUPIED, UNKNOWN

    m = world.map
    grid = np.asarray(m.grid)
    # A large map is drawn in blocks of k × k cells (a wall anywhere in a block shows), so the picture never
    # holds more pixels than the figure has: a 5000 × 5000 map costs megabytes, not gigabytes.
    k = max(1, math.ceil(max(grid.shape) / (FIGURE_INCHES * dpi)))
    walls, free = block_any(grid == OCCUPIED, k), block_any(grid == FREE, k)
    img = np.full(walls.shape, 191, np.uint8)
    img[free] = 255
    img[walls] = 0
    ox, oy, _ = m.origin
    extent = (ox, ox + walls.shape[1] * k * m.resolution, oy, oy + walls.shape[0] * k * m.resolution)
    fig, ax = plt.subplots(figsize=(FIGURE_INCHES, FIGURE_INCHES))
    ax.imshow(img, cmap="gray", origin="lower", extent=extent, vmin=0, vmax=255, interpolation="nearest")
    reach = world.reachable_free()
    overlay = np.zeros(walls.shape + (4,), np.uint8)
    overlay[block_any(reach, k) & ~walls] = (140, 204, 255, 64)
    ax.imshow(overlay, origin="lower", extent=extent, interpolation="nearest")

    for p in world.patches:
        ax.add_patch(Rectangle((p.x0, p.y0), p.x1 - p.x0, p.y1 - p.y0, color="tab:purple", alpha=0.25, lw=0))
        ax.text((p.x0 + p.x1) / 2, (p.y0 + p.y1) / 2, f"slip ×{p.slip:g}", ha="center", va="center",
                fontsize=7, color="tab:purple")

    dock = world.dock
    e = dock.emitter
    field = [e.compose(Pose2(x, y, 0.0)) for x, y in
             ((0, -FIELD_HALF_WIDTH), (FIELD_DEPTH, -FIELD_HALF_WIDTH), (FIELD_DEPTH, FIELD_HALF_WIDTH),
              (0, FIELD_HALF_WIDTH))]
    ax.add_patch(Polygon([(q.x, q.y) for q in field], closed=True, fill=False, ls="--", lw=0.8,
                         color="tab:red", alpha=0.6, label="dock IR field"))
    ax.add_patch(Circle((e.x, e.y), NEAR_RANGE, fill=False, ls=":", lw=0.8, color="tab:red", alpha=0.6))
    body = [dock.station.compose(Pose2(x, y, 0.0)) for x, y in
            ((0, -DOCK_WIDTH / 2), (DOCK_DEPTH, -DOCK_WIDTH / 2), (DOCK_DEPTH, DOCK_WIDTH / 2), (0, DOCK_WIDTH / 2))]
    ax.add_patch(Polygon([(q.x, q.y) for q in body], closed=True, color="tab:red", label="dock"))
    st = world.staging_pose()
    ax.plot([st.x], [st.y], "x", color="tab:red", ms=6, label="staging (1 m)")

    s = world.start
    ax.add_patch(Circle((s.x, s.y), BASE_RADIUS, fill=False, color="tab:green", lw=1.5, label="start"))
    ax.arrow(s.x, s.y, 0.35 * math.cos(s.theta), 0.35 * math.sin(s.theta), color="tab:green",
             width=0.03, length_includes_head=True)

    for t in world.tags:
        colour = "tab:orange" if t.id == world.dock_tag_id else "tab:blue"
        half = t.quad_width / 2
        dx, dy = -math.sin(t.yaw) * half, math.cos(t.yaw) * half
        ax.plot([t.x - dx, t.x + dx], [t.y - dy, t.y + dy], color=colour, lw=3)
        ax.annotate(str(t.id), (t.x, t.y), xytext=(t.x + 0.35 * math.cos(t.yaw), t.y + 0.35 * math.sin(t.yaw)),
                    fontsize=7, color=colour, ha="center", va="center",
                    arrowprops=dict(arrowstyle="<-", color=colour, lw=0.8))

    area = float(reach.sum()) * m.resolution ** 2
    ax.set_title(f"{world.name}: {len(world.tags)} tags (dock tag {world.dock_tag_id}), "
                 f"reachable free area {area:.1f} m²")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    known = grid != UNKNOWN
    xs, ys = np.flatnonzero(known.any(axis=0)), np.flatnonzero(known.any(axis=1))
    if xs.size:
        pad = 0.5
        ax.set_xlim(ox + xs[0] * m.resolution - pad, ox + (xs[-1] + 1) * m.resolution + pad)
        ax.set_ylim(oy + ys[0] * m.resolution - pad, oy + (ys[-1] + 1) * m.resolution + pad)
    ax.set_aspect("equal")
    ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    plt.close(fig)
    return buf.getvalue()
