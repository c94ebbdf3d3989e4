"""``homing replay RUN``: replay a run log — landmark SLAM offline, and the thesis's fig. 5-9 plot.

``--slam`` feeds the log's odometry, scans and tag sightings, tick by tick,
to the same :class:`homing.mapping.landmark_slam.LandmarkSlam` the
``tag_slam`` service runs online, so the result equals the online one for
the same run (as the thesis ran GTSAM offline on its logs). ``--out PNG``
draws the odometry, optimised and true trajectories and the tags;
``--until T`` stops at T seconds of the run.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any


def _defaults() -> dict[str, Any]:
    from homing.mapping.landmark_slam import SlamConfig

    c = SlamConfig()
    return {"keyframe_distance": c.keyframe_distance, "keyframe_angle": c.keyframe_angle, "robust": c.robust,
            "dock_tag": c.anchor_tag}


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file, plain_text, positive

    parser = sub.add_parser(
        "replay", help="replay a run log: landmark SLAM offline (--slam), trajectories and tags (--out PNG)",
        description=plain_text(__doc__), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("run", metavar="RUN", help="run log written by 'homing run … --record RUN'")
    parser.add_argument("--slam", action="store_true", help="run landmark SLAM on the log and print the tags")
    parser.add_argument("--out", metavar="PNG", type=output_file("--out"),
                        help="draw odometry, optimised and true trajectories and the tags")
    parser.add_argument("--until", type=positive, metavar="T", help="replay only the first T seconds [s]")
    parser.add_argument("--json", metavar="PATH", type=output_file("--json"),
                        help="write the optimised landmarks and map→odom as JSON")
    parser.add_argument("--salvage", action="store_true",
                        help="replay a damaged log up to the damage (default: report it and stop)")
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


def run(args: argparse.Namespace) -> int:
    from homing.missions.runlog import RunLog

    from homing.errors import UserError

    log = RunLog(args.run, salvage=args.salvage)
    if not (args.slam or args.out or args.json):
        raise UserError("nothing to do: give --slam, --out PNG or --json PATH", args.run)
    slam = replay_slam(log, args.until)
    truth_tags = _true_tags(log.meta)
    world_from_map = world_from_map_frame(log, args.until)
    landmarks = slam.landmarks()
    if log.damage:
        print(f"warning: {args.run}: damaged at {log.damage}: replayed up to {log.end:.1f} s", file=sys.stderr)
    elif log.truncated:
        print(f"{args.run}: log ends mid-frame (killed run?): replayed up to {log.end:.1f} s")
    if args.slam:
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
