"""``homing world show WORLD --out world.png``: draw a simulated world (map, dock, tags, patches, start).

``homing world dock WORLD [--offset DX DY DEG]``: a trace of the docking algorithms in the simulator — the tag
servo (:mod:`homing.navigation.tag_servo`, the real detector on rendered frames) from the staging pose moved
by the offset (a drifted map's error), then the IR drive (:mod:`homing.navigation.dock_drive`) to the charger.
"""

from __future__ import annotations

import argparse
import io
import math
from typing import Any

MIN_DPI, MAX_DPI = 30, 600  # [dots/inch] the 8-inch figure: 240 … 4800 pixels a side
FIGURE_INCHES = 8  # the picture's side, before its margins
TRACE_TICK = 0.1  # [s] control period of `world dock`


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
    dock = actions.add_parser(
        "dock",
        help="trace the tag servo and the IR dock drive from the staging pose moved by an offset",
        description="Run the docking algorithms in the simulator and print each change of state: the tag "
                    "servo from the staging pose moved by --offset (as a drifted map leaves the robot), then "
                    "kobuki's IR dock drive until the charger reports the dock.",
    )
    dock.add_argument("world", metavar="WORLD", help="bundled world name (e.g. lab) or path to a YAML file")
    dock.add_argument("--offset", nargs=3, type=float, default=[0.3, -0.3, 10.0], metavar=("DX", "DY", "DEG"),
                      help="start pose in the staging pose's frame [m, m, degrees] (default 0.3 -0.3 10)")
    dock.add_argument("--seed", type=int, default=1, help="simulator seed (default 1)")
    dock.set_defaults(func=_dock)
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])


def _show(args: argparse.Namespace) -> int:
    from homing.sim.world import load_world

    from homing.atomic import atomic_write

    world = load_world(args.world)
    png = draw_world(world, dpi=args.dpi)
    atomic_write(args.out, png)
    print(f"{args.out}: {world.name}, {len(world.tags)} tags, dock at "
          f"({world.dock.station.x:.2f}, {world.dock.station.y:.2f})")
    print(f"{world.name}: {navigable_area(world).summary()}")
    return 0


def navigable_area(world):  # noqa: ANN001, ANN201 - homing.sim.world.World → homing.mapping.navigable.Navigable
    """The world's navigable area from its start (the rule the costmap and bench explore use)."""
    from homing.mapping.evaluate import navigable_truth

    return navigable_truth(world.map, (world.start.x, world.start.y))


def _dock(args: argparse.Namespace) -> int:
    from homing.navigation.dock_drive import SERVOED_SLOW_ZONE, DockDrive, DockState
    from homing.navigation.tag_servo import ServoStatus, Sighting, TagServo
    from homing.perception.apriltag import TagDetector
    from homing.perception.tag_wall import TagPerception
    from homing.robot import Pose2
    from homing.sim import SimRobot
    from homing.sim.world import load_world

    from homing.errors import UserError

    dx, dy, deg = args.offset
    if not all(math.isfinite(v) for v in args.offset) or math.hypot(dx, dy) > 2.0 or abs(deg) > 90.0:
        raise UserError(f"--offset {dx:g} {dy:g} {deg:g}: the start must lie within 2 m and 90° of the staging pose")
    world = load_world(args.world)
    staging = world.staging_pose(1.0)
    robot = SimRobot(world, seed=args.seed, start=staging.compose(Pose2(dx, dy, math.radians(deg))))
    seen, servo, drive = TagPerception(TagDetector()), TagServo(), DockDrive()
    print(f"{world.name}: from the staging pose moved by ({dx:g} m, {dy:g} m, {deg:g}°); truth columns are the"
          f" simulator's\n{'time s':>7}  {'algorithm':<10} {'state':<13} {'to staging':>10} {'to dock':>8}  message")

    def row(t: float, who: str, state: str, message: str) -> None:
        truth = robot.truth_pose()
        off = staging.between(truth)
        print(f"{t:7.1f}  {who:<10} {state:<13} {math.hypot(off.x, off.y):8.2f} m "
              f"{truth.distance_to(world.dock_pose):6.2f} m  {message}")

    def servo_step(obs: Any) -> Any:
        for m in seen.measure(obs):
            if m.tag_id == world.dock_tag_id:
                servo.see(Sighting(m.stamp, m.pose, m.covariance))
        cmd = servo.step(obs.stamp, obs.odom.pose, obs.odom.twist)
        return cmd, servo.status, f"{servo.message} ({servo.sightings} sightings)"

    def drive_step(obs: Any) -> Any:
        cmd = drive.step(obs.stamp, obs.dock_ir, obs.bumpers, obs.battery.on_dock, obs.odom.pose)
        return cmd, drive.state, f"{drive.message} (v {cmd.v:.2f} m/s)"

    def follow(obs: Any, who: str, step: Any, finished: Any, limit: float) -> Any:
        """Command the robot with ``step`` each tick until ``finished()`` or ``limit`` [s]; a row per new state."""
        last = None
        while not finished() and obs.stamp < limit:
            cmd, state, message = step(obs)
            if state != last:
                row(obs.stamp, who, state.value, message)
                last = state
            robot.command(cmd.v, cmd.omega)
            robot.step(TRACE_TICK)
            obs = robot.observe()
        return obs

    try:
        obs = robot.observe()
        servo.start(obs.stamp, obs.odom.pose)
        obs = follow(obs, "tag servo", servo_step,
                     lambda: servo.status in (ServoStatus.SUCCEEDED, ServoStatus.FAILED), 120.0)
        servoed = servo.status is ServoStatus.SUCCEEDED  # as the mission's AutoDock: on the staging pose, known
        drive.start(obs.stamp, obs.odom.pose, approach=1.0 if servoed else 0.0, slow_zone=SERVOED_SLOW_ZONE)
        obs = follow(obs, "IR drive", drive_step, lambda: drive.state.finished, obs.stamp + 150.0)
        docked = drive.state is DockState.DONE and robot.charging
        print(f"{'docked' if docked else 'not docked'} after {obs.stamp:.1f} s"
              + ("" if docked else f" ({drive.reason or servo.reason or 'time limit'})"))
    finally:
        robot.close()
    return 0 if docked else 1


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
    nav = navigable_area(world)
    reach = nav.mask
    overlay = np.zeros(walls.shape + (4,), np.uint8)
    overlay[block_any(reach, k) & ~walls] = (140, 204, 255, 64)
    left_out = block_any(world.reachable_free() & ~reach, k) & ~walls
    overlay[left_out] = (255, 120, 120, 80)
    ax.imshow(overlay, origin="lower", extent=extent, interpolation="nearest")
    for b in nav.blocked:
        ax.text(b.x, b.y, f"{b.area:.0f} m² behind {b.width:.2f} m", ha="center", va="center", fontsize=7,
                color="tab:red")

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
                 f"navigable area {area:.1f} m²" + (f" ({nav.blocked_area:.1f} m² behind narrow passages)"
                                                     if nav.blocked else ""))
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
