"""``homing replay LOG``: replay any log — offline SLAM (grid or pose graph) on real robots' logs, landmark SLAM on homing runs, export to MCAP.

LOG is a homing run log (``homing run … --record``), a CARMEN log (plain or
``.gz``) or a ROS 1/2 bag (``.bag``; a rosbag2 folder, ``.db3`` or
``.mcap``; ``--scan-topic``/``--odom-topic`` choose its topics), read by
:func:`homing.logs.open_log`.

``--slam grid|graph`` (also ``odometry``, ``scan_matching``) maps the log
offline (:mod:`homing.logs.offline`): ``--out PNG`` draws the occupancy grid
and the trajectory (and the log's own corrected trajectory when it has
one), ``--save-map YAML`` writes the grid as a map_server map. ``--slam``
alone on a homing run log feeds its odometry, scans and tag sightings to
the same :class:`homing.mapping.landmark_slam.LandmarkSlam` the
``tag_slam`` service runs online (``tags``; the thesis's fig. 5-9 with
``--out``); on any other log it means ``graph``. ``--mcap DIR`` writes the
log as a ROS 2 bag in MCAP (:mod:`homing.logs.mcap_export`), with the map
and ``map → odom`` of the ``--slam`` method.
``--until T`` stops at T seconds of the log.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

OFFLINE = ("odometry", "scan_matching", "grid", "graph")
PICTURE_INCHES = 9.0  # the map picture's longer side
PICTURE_DPI = 110


def _defaults() -> dict[str, Any]:
    from homing.mapping.landmark_slam import SlamConfig

    c = SlamConfig()
    return {"keyframe_distance": c.keyframe_distance, "keyframe_angle": c.keyframe_angle, "robust": c.robust,
            "dock_tag": c.anchor_tag}


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file, output_map, plain_text, positive

    parser = sub.add_parser(
        "replay", help="replay a log (homing run, CARMEN, ROS bag): offline SLAM, map picture, MCAP export",
        description=plain_text(__doc__), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("run", metavar="LOG", help="a homing run log, a CARMEN log or a ROS 1/2 bag")
    parser.add_argument("--slam", nargs="?", const="default", choices=("tags", *OFFLINE, "default"), metavar="METHOD",
                        help="SLAM to run: grid, graph, odometry, scan_matching, or tags (a homing run's landmark "
                             "SLAM; the default for a homing run log; graph for any other log)")
    parser.add_argument("--out", metavar="PNG", type=output_file("--out"),
                        help="draw the map and trajectory (tags: trajectories and tags)")
    parser.add_argument("--save-map", metavar="YAML", type=output_map("--save-map"),
                        help="save the SLAM's occupancy grid as a map_server map")
    parser.add_argument("--mcap", metavar="DIR", help="export the log as a ROS 2 bag in MCAP to the new folder DIR")
    parser.add_argument("--until", type=positive, metavar="T", help="replay only the first T seconds [s]")
    parser.add_argument("--json", metavar="PATH", type=output_file("--json"),
                        help="write the result as JSON (landmarks, or the trajectory)")
    parser.add_argument("--scan-topic", metavar="TOPIC", help="a bag's sensor_msgs/LaserScan topic")
    parser.add_argument("--odom-topic", metavar="TOPIC", help="a bag's nav_msgs/Odometry topic")
    parser.add_argument("--salvage", action="store_true",
                        help="replay a damaged homing run log up to the damage (default: report it and stop)")
    parser.set_defaults(func=run)


def slam_config(meta: dict[str, Any]) -> Any:
    """The SlamConfig the online service used, from the log's ``meta["tag_slam"]`` (defaults otherwise)."""
    from homing.mapping.landmark_slam import SlamConfig

    p = {**_defaults(), **(meta.get("tag_slam") or {})}
    dock = p.get("dock_tag", 0)
    return SlamConfig(keyframe_distance=float(p["keyframe_distance"]), keyframe_angle=float(p["keyframe_angle"]),
                      robust=str(p["robust"]), anchor_tag=None if dock is None or dock < 0 else int(dock))


def replay_slam(log: Any, until: float | None = None) -> Any:
    """A LandmarkSlam fed every tick of ``log`` up to ``until`` [s], exactly as the service fed it, then flushed."""
    from homing.mapping.landmark_slam import LandmarkSlam

    slam = LandmarkSlam(slam_config(log.meta))
    for tick in log.ticks(until):
        slam.update(tick.obs.stamp, tick.obs.odom.pose, tick.obs.scan, tick.tags)
    slam.flush()
    return slam


def _true_tags(meta: dict[str, Any]) -> dict[int, Any]:
    """True tag poses from the world the run was in (evaluation only); empty if it cannot be loaded."""
    world = meta.get("world")
    if not world:
        return {}
    try:
        from homing.robot import Pose2
        from homing.sim import load_world

        return {t.id: Pose2(t.x, t.y, t.yaw) for t in load_world(world).tags}
    except Exception:
        return {}


def world_from_map_frame(log: Any, until: float | None = None) -> Any:
    """The map frame in the true world (evaluation only): ``map`` is the odom frame at the start."""
    truth = log.truth(until)[:1]
    first = next(iter(log.ticks(until)), None)
    if not truth or first is None:
        return None
    return truth[0][1].compose(first.obs.odom.pose.inverse())


def _check_outputs(args: argparse.Namespace) -> None:
    """The --mcap folder must be new and makeable (the files were checked while parsing), before SLAM runs."""
    from homing.errors import UserError
    from homing.outputs import check_folder

    if args.mcap and Path(args.mcap).exists():
        raise UserError("--mcap: already exists (a bag is written to a new folder)", args.mcap)
    if args.mcap:
        check_folder(args.mcap, "--mcap")


def run(args: argparse.Namespace) -> int:
    from homing.logs import open_log

    from homing.errors import UserError

    if not (args.slam or args.out or args.json or args.mcap or args.save_map):
        raise UserError("nothing to do: give --slam [METHOD], --out PNG, --save-map YAML, --mcap DIR or --json PATH",
                        args.run)
    _check_outputs(args)
    log = open_log(args.run, args.scan_topic, args.odom_topic, salvage=args.salvage)
    for w in log.warnings[:10]:
        print(f"warning: {w}")
    if len(log.warnings) > 10:
        print(f"warning: … and {len(log.warnings) - 10} more lines skipped")
    native = log.meta.get("format", "homing") == "homing"
    method = args.slam if args.slam not in (None, "default") else ("tags" if native else "graph")
    if method == "tags" and not native:
        raise UserError("--slam tags needs a homing run log (tag sightings); use grid or graph", args.run)
    if args.until is not None:
        log.records = [r for r in log.records if r["t"] <= args.until]
    if method != "tags":
        return run_offline(args, log, method)
    if args.save_map:
        raise UserError("--save-map needs a grid: --slam grid or graph")
    slam = replay_slam(log, args.until)
    if args.mcap:
        from homing.logs.mcap_export import export_mcap

        m2o = slam.map_to_odom
        _report_export(args.mcap, export_mcap(log, args.mcap, map_to_odom=lambda _t: m2o))
    truth_tags = _true_tags(log.meta)
    world_from_map = world_from_map_frame(log, args.until)
    landmarks = slam.landmarks()
    if log.damage:
        print(f"warning: {args.run}: damaged at {log.damage}: replayed up to {log.end:.1f} s", file=sys.stderr)
    elif log.truncated:
        print(f"{args.run}: log ends mid-frame (killed run?): replayed up to {log.end:.1f} s")
    if args.slam or not (args.out or args.json or args.mcap):
        print(f"{len(slam.keyframes)} keyframes, {len(landmarks)} tags, {slam.n_tag_factors} tag factors; "
              f"map→odom = ({slam.map_to_odom.x:.3f} m, {slam.map_to_odom.y:.3f} m, "
              f"{math.degrees(slam.map_to_odom.theta):.2f}°)")
        for tag_id, p in sorted(landmarks.items()):
            line = f"  tag {tag_id:3d}: x {p.x:8.3f}  y {p.y:8.3f}  θ {math.degrees(p.theta):7.1f}°"
            if world_from_map is not None and tag_id in truth_tags:
                err = world_from_map.compose(p).distance_to(truth_tags[tag_id])
                line += f"   error {100 * err:5.1f} cm"
            print(line)
    if args.json:
        from homing.atomic import atomic_write

        out = {"landmarks": {str(k): [v.x, v.y, v.theta] for k, v in landmarks.items()},
               "map_to_odom": slam.map_to_odom.as_array().tolist(), "keyframes": len(slam.keyframes),
               "truncated": log.truncated, "end_s": log.end}
        atomic_write(args.json, json.dumps(out, indent=2) + "\n")
    if args.out:
        plot(log, slam, truth_tags, world_from_map, args.until, Path(args.out))
    return 0


def plot(log: Any, slam: Any, truth_tags: dict[int, Any], world_from_map: Any, until: float | None, out: Path) -> None:
    """Thesis fig. 5-9 side by side: odometry (left) and optimised (right) trajectories, truth and tags, in the map frame."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from homing.atomic import atomic_write

    odo = np.array([t.obs.odom.pose.as_array() for t in log.ticks(until)]).reshape(-1, 3)
    opt = np.array([p.as_array() for p in slam.keyframe_poses()]).reshape(-1, 3)
    map_from_world = world_from_map.inverse() if world_from_map is not None else None
    tru = np.array([map_from_world.compose(p).as_array() for _, p in log.truth(until)]).reshape(-1, 3) \
        if map_from_world is not None else np.zeros((0, 3))
    # Tags placed through raw odometry: each sighting through the odometry pose of its tick.
    odo_tags: dict[int, list[Any]] = {}
    for t in log.ticks(until):
        for m in t.tags:
            q = t.obs.odom.pose.compose(m.pose)
            odo_tags.setdefault(m.tag_id, []).append((q.x, q.y))
    fig, axes = plt.subplots(1, 2, figsize=(13, 6), sharex=True, sharey=True)
    for ax, traj, title, tags in (
        (axes[0], odo, "odometry", {k: np.mean(v, axis=0) for k, v in odo_tags.items()}),
        (axes[1], opt, "GTSAM iSAM2 (optimised keyframes)", {k: (p.x, p.y) for k, p in slam.landmarks().items()}),
    ):
        if len(tru):
            ax.plot(tru[:, 0], tru[:, 1], "-", color="0.6", lw=1, label="truth")
        ax.plot(traj[:, 0], traj[:, 1], "b-" if ax is axes[1] else "r-", lw=1, label=title)
        for tag_id, (x, y) in tags.items():
            ax.plot(x, y, "ks", ms=5)
            ax.annotate(str(tag_id), (x, y), textcoords="offset points", xytext=(4, 4), fontsize=8)
        if map_from_world is not None:
            for p in truth_tags.values():
                q = map_from_world.compose(p)
                ax.plot(q.x, q.y, "g+", ms=9)
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.set_xlabel("x [m] (map)")
        ax.legend(loc="best", fontsize=8)
    axes[0].set_ylabel("y [m] (map)")
    fig.suptitle(f"{log.path.name}: tags ■ estimated, + true")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    atomic_write(out, buf.getvalue())


def run_offline(args: argparse.Namespace, log: Any, method: str) -> int:
    """Grid or pose-graph SLAM over the log; picture, map, JSON and MCAP as asked."""
    from homing.logs.offline import run_method

    from homing.atomic import atomic_write

    result = run_method(log, method)
    scans = len(result.stamps)
    print(f"{log.path.name}: {method} over {scans} scans, {1e3 * result.seconds_per_scan:.1f} ms per scan"
          + (f"; {', '.join(f'{k} {v}' for k, v in result.info.items())}" if result.info else ""))
    if args.save_map:
        from homing.mapping.map_io import save_grid

        print(f"map saved: {save_grid(args.save_map, result.grid)}")
    if args.json:
        atomic_write(args.json, json.dumps({"method": method, "stamps": result.stamps,
                                            "poses": [[p.x, p.y, p.theta] for p in result.poses],
                                            "seconds_per_scan": result.seconds_per_scan, **result.info}) + "\n")
    if args.out:
        plot_map(log, result, Path(args.out))
    if args.mcap:
        export_offline(log, result, args.mcap)
    return 0


def export_offline(log: Any, result: Any, out: str) -> None:
    """The log as MCAP, with ``map → odom`` and a growing ``/map`` from the offline SLAM's poses."""
    import bisect

    from homing.logs.mcap_export import export_mcap
    from homing.logs.offline import scans_of
    from homing.mapping.grid import OccupancyGrid

    data = [(scan, odom.pose) for _, odom, scan in scans_of(log) if scan is not None]
    at = dict(zip(result.stamps, result.poses, strict=True))
    fixes = sorted((s.stamp, at[s.stamp].compose(o.inverse())) for s, o in data if s.stamp in at)
    stamps = [t for t, _ in fixes]
    grid = OccupancyGrid(result.grid.resolution)
    drawn = [0]

    def map_to_odom(t: float) -> Any:
        i = bisect.bisect_right(stamps, t) - 1
        return fixes[max(i, 0)][1] if fixes else None

    def grid_at(t: float) -> Any:
        while drawn[0] < len(data) and data[drawn[0]][0].stamp <= t:
            scan = data[drawn[0]][0]
            if scan.stamp in at:
                grid.integrate(scan, at[scan.stamp])
            drawn[0] += 1
        return grid

    _report_export(out, export_mcap(log, out, map_to_odom=map_to_odom if fixes else None, grid_at=grid_at))


def _report_export(out: str, counts: dict[str, int]) -> None:
    print(f"MCAP written: {out} ({', '.join(f'{t} {n}' for t, n in sorted(counts.items()))})")


def plot_map(log: Any, result: Any, out: Path) -> None:
    """The occupancy grid with the trajectory (and the log's corrected one, aligned at the first scan)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from homing.atomic import atomic_write
    from homing.map_server import FREE, OCCUPIED

    g = result.grid
    h, w = g.shape
    img = np.full((h, w), 0.75)
    img[g.data == FREE] = 1.0
    # A wall one cell thick is thinner than a pixel of the picture: thicken walls to ~2 pixels, for display only.
    cells_per_pixel = max(w, h) / (PICTURE_INCHES * PICTURE_DPI)
    walls = (g.data == OCCUPIED).astype(np.uint8)
    k = int(math.ceil(2 * cells_per_pixel))
    if k > 1:
        import cv2

        walls = cv2.dilate(walls, np.ones((k, k), np.uint8))
    img[walls > 0] = 0.0
    extent = (g.origin[0], g.origin[0] + w * g.resolution, g.origin[1], g.origin[1] + h * g.resolution)
    side = PICTURE_INCHES
    fig, ax = plt.subplots(figsize=(side, side * h / w) if w >= h else (side * w / max(h, 1), side))
    ax.imshow(img, cmap="gray", vmin=0, vmax=1, origin="lower", extent=extent, interpolation="nearest")
    est = np.array([p.as_array() for p in result.poses]).reshape(-1, 3)
    ref = log.reference()
    if ref and result.poses:
        first = dict(ref).get(result.stamps[0])
        if first is not None:
            align = result.poses[0].compose(first.inverse())
            r = np.array([align.compose(p).as_array() for _, p in ref])
            ax.plot(r[:, 0], r[:, 1], "-", color="tab:green", lw=0.8, label="log's corrected poses")
    ax.plot(est[:, 0], est[:, 1], "-", color="tab:blue", lw=0.8, label=f"{result.method} trajectory")
    ax.set_title(f"{log.path.name}: {result.method}, {len(result.stamps)} scans, "
                 f"{1e3 * result.seconds_per_scan:.1f} ms/scan")
    ax.set_xlabel("x [m] (map)")
    ax.set_ylabel("y [m] (map)")
    ax.legend(loc="best", fontsize=8)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=PICTURE_DPI, bbox_inches="tight")
    plt.close(fig)
    atomic_write(out, buf.getvalue())
