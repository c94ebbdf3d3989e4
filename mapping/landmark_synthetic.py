"""A synthetic tagged drive with known truth for :mod:`homing.mapping.landmark_slam` (tests, demo, timing).

The robot laps a rectangle past tags on the walls around it; odometry
integrates the true motion with slip, a gyro scale error and heading noise,
and the tags are measured with the detector's own covariance model
(:func:`homing.perception.apriltag.measurement_covariance`) and noise drawn
from it. No scans: not for testing anything lidar-based. Demo:
``python -m homing.mapping.landmark_synthetic --plot out.png`` runs SLAM on a
loop and draws odometry, optimised and true trajectories and the tags.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from homing.mapping.landmark_slam import LandmarkSlam
from homing.perception.apriltag import TagMeasurement
from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2


@dataclass
class SyntheticRun:
    """A drive with known truth: per tick (stamp [s], true pose, odometry pose, sightings)."""

    tags: dict[int, Pose2]
    ticks: list[tuple[float, Pose2, Pose2, list[TagMeasurement]]]


def synthetic_loop(seed: int = 0, laps: int = 2, size: tuple[float, float] = (6.0, 4.0),
                   speed: float = 0.3, dt: float = 0.1, camera_period: float = 0.3,
                   slip: float = 0.04, yaw_bias: float = 0.002, tag_noise: float = 1.0,
                   yaw_noise: float = 0.002) -> SyntheticRun:
    """Drive ``laps`` laps of a rectangle (``size`` [m]) past tags on the walls around it.

    Odometry integrates the true motion with multiplicative noise ``slip``
    and a gyro scale error ``yaw_bias`` [rad/s per rad/s] (so it drifts like a
    real base) plus ``yaw_noise`` [rad/m] of heading noise per metre driven; ``tag_noise`` scales the sightings' noise. Tags within 3 m, ±29° and 60° of view are measured with the
    detector's covariance model at 320 px and noise drawn from it. Tag 0
    faces the start pose, like the dock's tag.
    """
    from homing.perception.apriltag import MAX_RANGE, MAX_VIEW_ANGLE, measurement_covariance

    rng = np.random.default_rng(seed)
    w, h = size
    fx = 0.5 * 320 / math.tan(math.radians(29.0))
    corners = [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)]
    tags = {0: Pose2(-1.2, 0.0, 0.0)}
    for i in range(4):
        (ax, ay), (bx, by) = corners[i], corners[(i + 1) % 4]
        heading = math.atan2(by - ay, bx - ax)
        u = np.array([math.cos(heading), math.sin(heading)])
        left = np.array([-u[1], u[0]])
        for side, off in ((1, 0.4), (2, -0.4)):  # on the wall past the leg's end, facing back
            p = np.array([bx, by]) + 1.2 * u + off * left
            tags[3 * i + side] = Pose2(float(p[0]), float(p[1]), wrap_angle(heading + math.pi))
        mid = 0.5 * (np.array([ax, ay]) + np.array([bx, by])) + 1.0 * left
        face = -1.5 * u - 1.0 * left  # beside the leg's middle, turned towards the approach
        tags[3 * i + 3] = Pose2(float(mid[0]), float(mid[1]), math.atan2(face[1], face[0]))
    # Waypoints: drive the rectangle counter-clockwise, turning on the spot at corners.
    truth = Pose2(0.0, 0.0, math.pi)  # docked, facing the dock's tag
    odom = truth
    ticks: list[tuple[float, Pose2, Pose2, list[TagMeasurement]]] = []
    t, next_cam = 0.0, 0.0
    goals: list[tuple[tuple[float, float], tuple[str, ...]]] = [(c, ("turn", "drive")) for c in [corners[(i + 1) % 4] for i in range(4)] * laps]
    goals.append(((-1.0, 0.0), ("turn",)))  # back at the dock, facing its tag again
    for (gx, gy), phases in goals:
        for phase in phases:
            while True:
                dx, dy = gx - truth.x, gy - truth.y
                dist = math.hypot(dx, dy)
                err = wrap_angle(math.atan2(dy, dx) - truth.theta) if dist > 1e-6 else 0.0
                if phase == "turn":
                    if abs(err) < 1e-3:
                        break
                    v, om = 0.0, float(np.clip(err / dt, -0.8, 0.8))
                else:
                    if dist < 1e-3:
                        break
                    v, om = min(speed, dist / dt), float(np.clip(err / dt, -0.8, 0.8))
                truth = truth.compose(Pose2(v * dt, 0.0, om * dt))
                nv = v * (1.0 + slip * rng.normal())
                nom = om * (1.0 + yaw_bias + slip * rng.normal()) + yaw_noise * v * rng.normal()
                odom = odom.compose(Pose2(nv * dt, 0.0, nom * dt))
                t += dt
                seen: list[TagMeasurement] = []
                if t >= next_cam:
                    next_cam = t + camera_period
                    for tag_id, tag in tags.items():
                        rel = truth.between(tag)
                        r, b = math.hypot(rel.x, rel.y), math.atan2(rel.y, rel.x)
                        view = abs(wrap_angle(rel.theta - (b + math.pi)))
                        if r > MAX_RANGE or abs(b) > math.radians(29.0) or view > MAX_VIEW_ANGLE:
                            continue
                        cov = measurement_covariance(r, b, view, fx, 0.16)
                        noisy = rel.as_array() + tag_noise * rng.multivariate_normal(np.zeros(3), cov)
                        seen.append(TagMeasurement(
                            tag_id, t, Pose2.from_array(noisy), cov, r, b, view, 100.0, 0, 0.4,
                            np.eye(4), np.zeros((4, 2)),
                        ))
                ticks.append((t, truth, odom, seen))
    return SyntheticRun(tags, ticks)


def main() -> None:
    """Run SLAM on a synthetic loop and plot odometry, optimised and true trajectories and tags."""
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", metavar="PNG")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    run = synthetic_loop(args.seed)
    slam = LandmarkSlam()
    for stamp, _, odom, seen in run.ticks:
        slam.update(stamp, odom, None, seen)
    slam.flush()
    est = slam.landmarks()
    errs = [est[i].distance_to(p) for i, p in run.tags.items() if i in est]
    print(f"{len(slam.keyframes)} keyframes, {len(est)} tags, mean tag error {100 * np.mean(errs):.1f} cm, "
          f"iSAM2 update median {np.median(slam.update_ms):.2f} ms")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 6))
        tr = np.array([p.as_array() for _, p, _, _ in run.ticks])
        od = np.array([o.as_array() for _, _, o, _ in run.ticks])
        kf = np.array([p.as_array() for p in slam.keyframe_poses()])
        ax.plot(tr[:, 0], tr[:, 1], "g-", label="truth")
        ax.plot(od[:, 0], od[:, 1], "r:", label="odometry")
        ax.plot(kf[:, 0], kf[:, 1], "b.-", ms=3, label="iSAM2 keyframes")
        for i, p in run.tags.items():
            ax.plot(p.x, p.y, "gs")
            if i in est:
                ax.plot(est[i].x, est[i].y, "bx")
                ax.annotate(str(i), (est[i].x, est[i].y))
        ax.set_aspect("equal")
        ax.legend()
        fig.savefig(args.plot, dpi=90)


if __name__ == "__main__":
    main()
