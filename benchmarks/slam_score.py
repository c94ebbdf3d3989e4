"""Scoring a landmark map against the truth for ``homing bench slam``: alignments, errors, and the run collector.

Thesis table 5.3 compares maps of tag positions. Each estimated map is
aligned to the true tags two ways — on the dock's tag (every map moved so
that its dock tag sits on the true one, as the thesis did) and by the
best-fit rigid transform (Kabsch/Umeyama without scale) — and scored by the
total and mean per-tag distance [m]; the keyframe trajectory by its ATE
(Sturm et al. 2012). :class:`Collector` feeds one run's observations to the
three mappers compared (GTSAM, the scan-matched grid, raw odometry) and
keeps the truth beside them. Evaluation code: it reads ground truth, so it
must not be used by the robot's own services or behaviours.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from homing.mapping.landmark_slam import TAG_YAW_SIGMA, LandmarkSlam, interpolate_pose
from homing.robot import Pose2


def best_fit(est: np.ndarray, truth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (2, 2) and translation (2,) minimising ‖R·est + t − truth‖ (Kabsch/Umeyama, no scale)."""
    ma, mb = est.mean(0), truth.mean(0)
    U, _, Vt = np.linalg.svd((est - ma).T @ (truth - mb))
    d = np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0
    R = Vt.T @ np.diag([1.0, d]) @ U.T
    return R, mb - R @ ma


def tag_errors(est: dict[int, Pose2], truth: dict[int, Pose2], dock_id: int) -> dict[str, float]:
    """Total and mean per-tag error [m] after dock-tag alignment and after the best rigid fit.

    Also each true tag's own dock-aligned error as ``tag<id>_m`` (NaN where the
    map lacks it or has no dock tag): which tags a mean hides, and where they are.
    """
    ids = sorted(i for i in est if i in truth)
    out = {"n_tags": float(len(ids))}
    out.update({f"tag{i}_m": math.nan for i in sorted(truth)})
    if dock_id in est and dock_id in truth:
        move = truth[dock_id].compose(est[dock_id].inverse())  # puts the estimated dock tag on the true one
        e = [move.compose(est[i]).distance_to(truth[i]) for i in ids]
        out.update(dock_total_m=float(np.sum(e)), dock_mean_m=float(np.mean(e)))
        out.update({f"tag{i}_m": err for i, err in zip(ids, e, strict=True)})
    else:
        out.update(dock_total_m=math.nan, dock_mean_m=math.nan)
    if len(ids) >= 2:
        A = np.array([[est[i].x, est[i].y] for i in ids])
        B = np.array([[truth[i].x, truth[i].y] for i in ids])
        R, t = best_fit(A, B)
        e2 = np.linalg.norm(A @ R.T + t - B, axis=1)
        out.update(fit_total_m=float(e2.sum()), fit_mean_m=float(e2.mean()))
    else:
        out.update(fit_total_m=math.nan, fit_mean_m=math.nan)
    return out


def ate(est: list[Pose2], truth: list[Pose2]) -> float:
    """RMS position error [m] of a trajectory after the best rigid fit (Sturm et al. 2012's ATE)."""
    return math.hypot(*ate_along_across(est, truth))


def ate_along_across(est: list[Pose2], truth: list[Pose2]) -> tuple[float, float]:
    """RMS position error [m] after the best rigid fit split along and across each true pose's heading.

    A robot drives where it faces, so along is what only the wheels measure
    where the lidar sees no wall ahead (a corridor longer than its range),
    across what the side walls pin; (NaN, NaN) for fewer than two poses.
    """
    if len(est) < 2:
        return math.nan, math.nan
    A = np.array([[p.x, p.y] for p in est])
    B = np.array([[p.x, p.y] for p in truth])
    R, t = best_fit(A, B)
    d = A @ R.T + t - B
    heading = np.array([p.theta for p in truth])
    along = d[:, 0] * np.cos(heading) + d[:, 1] * np.sin(heading)
    across = -d[:, 0] * np.sin(heading) + d[:, 1] * np.cos(heading)
    return float(np.sqrt(np.mean(along**2))), float(np.sqrt(np.mean(across**2)))


def mean_pose(poses: list[Pose2], weights: list[float] | None = None) -> Pose2:
    """Mean position [m] and circular-mean heading [rad] of ``poses`` (a tag placed by several sightings), the
    headings weighted by ``weights`` (default: alike)."""
    xy = np.array([[p.x, p.y] for p in poses]).mean(0)
    w = np.ones(len(poses)) if weights is None else np.asarray(weights, float)
    c = float(np.dot(w, [math.cos(p.theta) for p in poses]))
    s = float(np.dot(w, [math.sin(p.theta) for p in poses]))
    return Pose2(float(xy[0]), float(xy[1]), math.atan2(s, c))


def heading_weight(m: Any) -> float:
    """How much a sighting's heading counts when the baselines average a tag's sightings: its inverse variance,
    a heading from the tag's own corners taken as no surer than GTSAM takes it (``TAG_YAW_SIGMA``: weak, and now
    and then the mirrored pose), one from the wall behind it as measured — the same care as the pose graph's."""
    var = float(np.asarray(m.covariance)[2, 2])
    if getattr(m, "yaw_source", "tag") != "wall":
        var = max(var, TAG_YAW_SIGMA**2)
    return 1.0 / max(var, 1e-12)


@dataclass
class Collector:
    """Feeds one run's observations to GTSAM, a scan-matched grid and raw odometry, with the truth beside them."""

    dock_id: int
    scan_matched: bool = False  # feed GTSAM the grid's scan-matched motion between keyframes too
    slam: LandmarkSlam = field(default_factory=LandmarkSlam)
    grid: Any = None
    detector: Any = None
    last_tags: list[Any] = field(default_factory=list)
    last_stamp: float = -math.inf
    history: list[tuple[float, Pose2]] = field(default_factory=list)
    grid_history: list[tuple[float, Pose2]] = field(default_factory=list)
    placed_odom: dict[int, list[Pose2]] = field(default_factory=dict)
    placed_grid: dict[int, list[Pose2]] = field(default_factory=dict)
    heading_weights: dict[int, list[float]] = field(default_factory=dict)  # per placed sighting (heading_weight)
    keyframe_truth: list[Pose2] = field(default_factory=list)
    world_from_odom0: Pose2 | None = None
    external: bool = False  # tags, grid pose and SLAM come from a mission's services (see step_external)

    def __post_init__(self) -> None:
        if self.external:
            return
        from homing.mapping.grid_slam import GridSlam
        from homing.perception.apriltag import TagDetector
        from homing.perception.tag_wall import TagPerception

        self.grid = GridSlam()
        self.detector = TagPerception(TagDetector())

    def step(self, obs: Any, truth: Pose2) -> None:
        self.last_stamp = obs.stamp
        if self.world_from_odom0 is None:
            self.world_from_odom0 = truth.compose(obs.odom.pose.inverse())
        self.grid.update(obs.odom, obs.scan)
        self.history = (self.history + [(obs.stamp, obs.odom.pose)])[-60:]
        self.grid_history = (self.grid_history + [(obs.stamp, self.grid.pose)])[-60:]
        tags = self.detector.measure(obs)
        self.last_tags = tags
        matched = self.grid.pose if self.scan_matched else None
        if self.slam.update(obs.stamp, obs.odom.pose, obs.scan, tags, matched):
            self.keyframe_truth.append(truth)
        self._place(tags)

    def step_external(self, obs: Any, truth: Pose2, tags: list[Any], grid_pose: Pose2) -> None:
        """One tick of a mission whose services ran the mappers: record truth per keyframe and place the tags."""
        self.last_stamp = obs.stamp
        self.history = (self.history + [(obs.stamp, obs.odom.pose)])[-60:]
        self.grid_history = (self.grid_history + [(obs.stamp, grid_pose)])[-60:]
        self.last_tags = list(tags)
        while len(self.keyframe_truth) < len(self.slam.keyframes):
            self.keyframe_truth.append(truth)
        self._place(tags)

    def _place(self, tags: list[Any]) -> None:
        for m in tags:
            self.placed_odom.setdefault(m.tag_id, []).append(interpolate_pose(self.history, m.stamp).compose(m.pose))
            self.placed_grid.setdefault(m.tag_id, []).append(interpolate_pose(self.grid_history, m.stamp).compose(m.pose))
            self.heading_weights.setdefault(m.tag_id, []).append(heading_weight(m))

    def result(self, true_tags: dict[int, Pose2]) -> dict[str, float]:
        self.slam.flush()
        est = self.slam.landmarks()
        g = tag_errors(est, true_tags, self.dock_id)
        w = self.heading_weights
        gr = tag_errors({k: mean_pose(v, w[k]) for k, v in self.placed_grid.items()}, true_tags, self.dock_id)
        od = tag_errors({k: mean_pose(v, w[k]) for k, v in self.placed_odom.items()}, true_tags, self.dock_id)
        keyframes = self.slam.keyframe_poses()
        along, across = ate_along_across(keyframes, self.keyframe_truth)
        return {
            "gtsam_total_m": g["dock_total_m"], "grid_total_m": gr["dock_total_m"], "odom_total_m": od["dock_total_m"],
            "gtsam_mean_m": g["dock_mean_m"], "grid_mean_m": gr["dock_mean_m"], "odom_mean_m": od["dock_mean_m"],
            "gtsam_fit_total_m": g["fit_total_m"], "grid_fit_total_m": gr["fit_total_m"],
            "odom_fit_total_m": od["fit_total_m"], "gtsam_fit_mean_m": g["fit_mean_m"],
            "ate_m": ate(keyframes, self.keyframe_truth),
            "ate_along_m": along, "ate_across_m": across,
            "isam_update_ms_median": float(np.median(self.slam.update_ms)) if self.slam.update_ms else math.nan,
            "tags_seen": g["n_tags"], "tags_total": float(len(true_tags)), "keyframes": float(len(self.slam.keyframes)),
            **{f"{who}_{k}": v for who, errs in (("gtsam", g), ("grid", gr)) for k, v in errs.items() if k.startswith("tag")},
        }
