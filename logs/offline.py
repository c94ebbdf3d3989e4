"""Offline SLAM over any log: odometry alone, incremental scan matching, the scan-matched grid, the lidar pose graph.

One driver feeds a :class:`~homing.logs.runlog.RunLog` (a homing run,
a CARMEN log or a ROS bag, :func:`homing.logs.open_log`) tick by tick to a
SLAM method and returns the pose at every scan and the occupancy grid
drawn from those poses. The methods, as in Kümmerle et al. 2009's tables:

- ``odometry``: the wheels alone;
- ``scan_matching``: :class:`homing.mapping.graph_slam.GraphSlam` without
  loop closures (each scan matched to the few before it);
- ``grid``: :class:`homing.mapping.grid_slam.GridSlam`, scan-to-map
  matching into one log-odds grid, as the robot runs it online, with the
  search window and plausibility gate widened for sparse scans
  (``LOG_GRID_*``);
- ``graph``: :class:`~homing.mapping.graph_slam.GraphSlam` with lidar loop
  closures, re-optimised in one batch at the end;
- ``online``: :class:`~homing.mapping.lifelong.LifelongSlam`, the robot's
  online SLAM with loop closures (``grid``'s front end, same settings),
  every scan placed by the graph as it stands after the last scan (no batch
  at the end: what the robot's map is then). It does not look for itself
  over the whole map when a scan misfits (``relocalise_when_lost=False``):
  a logged robot is never carried, and on FHW, where people and glass make
  a scan misfit, the look took it 0.5 m off and kept it lost for 144 scans.

Every scan is clipped to ``max_range`` (longer returns read "no return"):
a SICK reports up to 80 m, and tracing and matching such rays costs time
and adds little. ``seconds_per_scan`` is the method's wall time divided by
the log's scans (the grid drawn for the picture not included),
``cpu_seconds_per_scan`` the same in the process's CPU time (on a machine
shared with other work, wall time also counts the waits).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from homing.logs.runlog import RunLog
from homing.mapping.graph_slam import MAX_RANGE, GraphConfig, GraphSlam
from homing.mapping.grid import OccupancyGrid
from homing.mapping.grid_slam import GridSlam
from homing.mapping.lifelong import LifelongConfig, LifelongSlam
from homing.mapping.scan_match import GN_ANCHOR_THETA, CorrelativeMatcher
from homing.robot.types import Odometry, Pose2, Scan

METHODS = ("odometry", "scan_matching", "grid", "graph", "online")
RESOLUTION = 0.05  # [m] cells of the grids drawn and matched
# GridSlam for scans a metre apart (a corrected log keeps one scan per ≈ 1 m / 0.5 s):
LOG_GRID_WINDOW = (0.5, math.radians(12.0))  # [m, rad] search half-widths
LOG_GRID_PRIOR = (0.10, math.radians(3.0))  # [m, rad] the pull towards odometry
LOG_GRID_MAX_CORRECTION = (0.5, math.radians(12.0))  # [m, rad]
# [rad] the heading's hold once a match is chosen: the match's own, no second step with the heading let go
# (grid_slam.TRACKING_ANCHOR_THETA). That step frees the robot's heading from its gyro, to which the tracking prior
# ties the correlative search (0.5°); here the prior is the wheels' 3° and the search's window 12°, so the match's
# heading is already the walls'. With the step, on the five Radish logs (grid SLAM, translational error [m]): ACES
# 0.072 → 0.169 (lost for a while: 5.8 m at most), FHW 1.50 → 1.80, Edmonton, Freiburg 079 and 101 0.054, 0.076,
# 0.044 → 0.056, 0.077, 0.047.
LOG_GRID_ANCHOR_THETA = GN_ANCHOR_THETA
# [m] ``online``: an old keyframe this near covers the place. A corrected log's scans are about a metre apart, so
# nearly every scan is a keyframe step and a hop's pose comes from the graph's estimates alone; with the robot's
# 0.45 m ACES came out at 0.209 ± 0.767 m (hops to keyframes farther off, then wrong ties), with 0.35 m 0.068 m.
LOG_COVER_RADIUS = 0.35
# [m] and a revisit ties to none farther off: the robot's tie_radius (1 m) is for patrol lanes passing between
# keyframes made 0.7 m apart; a corrected log's keyframes are about as far apart as its scans.
LOG_TIE_RADIUS = LOG_COVER_RADIUS


@dataclass
class OfflineResult:
    """A method's trajectory (pose of base_link in ``map`` at every scan stamp [s]), grid and cost."""

    method: str
    stamps: list[float]
    poses: list[Pose2]
    grid: OccupancyGrid
    seconds_per_scan: float  # wall time
    cpu_seconds_per_scan: float  # the process's CPU time: what the method costs on a machine others share
    info: dict[str, Any] = field(default_factory=dict)


def clip(scan: Scan, max_range: float) -> Scan:
    """``scan`` with returns beyond ``max_range`` [m] read as no return and ``range_max`` lowered to it."""
    if scan.range_max <= max_range:
        return scan
    r = np.where(scan.ranges > max_range, np.inf, scan.ranges).astype(np.float32)
    return Scan(scan.stamp, scan.angle_min, scan.angle_increment, r, scan.range_min, max_range, scan.laser_pose)


def scans_of(log: RunLog, max_range: float = MAX_RANGE) -> list[tuple[float, Odometry, Scan | None]]:
    """(stamp, odometry, new scan or None) per tick of ``log``; each scan given once, clipped."""
    out: list[tuple[float, Odometry, Scan | None]] = []
    last = -math.inf
    for tick in log.ticks():
        s = tick.obs.scan
        fresh = s is not None and s.stamp > last
        if fresh and s is not None:
            last = s.stamp
        out.append((tick.obs.stamp, tick.obs.odom, clip(s, max_range) if fresh and s is not None else None))
    return out


def run_method(log: RunLog, method: str, max_range: float = MAX_RANGE, resolution: float = RESOLUTION) -> OfflineResult:
    """Run one of :data:`METHODS` over ``log`` (module doc)."""
    if method not in METHODS:
        raise ValueError(f"unknown method '{method}' (known: {', '.join(METHODS)})")
    data = scans_of(log, max_range)
    n_scans = sum(s is not None for _, _, s in data)
    info: dict[str, Any] = {}
    t0, c0 = time.perf_counter(), time.process_time()
    if method == "grid":
        stamps, poses, grid = _grid(data, max_range, resolution)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    elif method == "online":
        online = _online(data, max_range, resolution)
        stamps, poses = online.trajectory()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        ls = online.stats
        info = {"keyframes": len(online.nodes), "ties": ls.ties, "hops": ls.hops, "closures": ls.closures,
                "closure_attempts": ls.closure_attempts, "rebuilds": ls.rebuilds, "jumps": ls.jumps,
                "times_lost": online.times_lost, "factors_skipped": dict(sorted(ls.skipped.items())),
                "qr_rebuilds": ls.qr_rebuilds}
        grid = draw(data, stamps, poses, resolution)
    else:
        slam = GraphSlam(GraphConfig(max_range=max_range, scan_matching=method != "odometry",
                                     closure_radius=0.0 if method != "graph" else GraphConfig().closure_radius,
                                     keyframe_distance=0.0 if method == "odometry" else GraphConfig().keyframe_distance,
                                     keyframe_angle=0.0 if method == "odometry" else GraphConfig().keyframe_angle))
        for _stamp, odom, scan in data:
            slam.update(odom.stamp, odom.pose, scan)  # the wheels' reading's own time: a gap in them shows
        if method == "graph":
            slam.finish()
        stamps, poses = slam.trajectory()
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        st = slam.stats
        info = {"keyframes": len(slam.keyframes), "matches": st.matches, "match_failures": st.match_failures,
                "closures": st.closures, "closure_attempts": st.closure_attempts,
                "factors_skipped": dict(sorted(st.skipped.items())), "qr_rebuilds": st.qr_rebuilds}
        grid = draw(data, stamps, poses, resolution)
    return OfflineResult(method, stamps, poses, grid, wall / max(n_scans, 1), cpu / max(n_scans, 1), info)


def _log_matcher() -> CorrelativeMatcher:
    """The grid front end's matcher for scans a metre apart (``LOG_GRID_*``)."""
    return CorrelativeMatcher(window_xy=LOG_GRID_WINDOW[0], window_theta=LOG_GRID_WINDOW[1],
                              prior_xy=LOG_GRID_PRIOR[0], prior_theta=LOG_GRID_PRIOR[1], refine=True,
                              whole_field=True)


def _grid(data: list[tuple[float, Odometry, Scan | None]], max_range: float,
          resolution: float) -> tuple[list[float], list[Pose2], OccupancyGrid]:
    slam = GridSlam(resolution, matcher=_log_matcher(), max_correction=LOG_GRID_MAX_CORRECTION,
                    match_range=max_range - 1.0, anchor_theta=LOG_GRID_ANCHOR_THETA)
    stamps, poses = [], []
    for _stamp, odom, scan in data:
        if slam.update(odom, scan) and scan is not None:
            stamps.append(scan.stamp)
            poses.append(slam.scan_pose)
    return stamps, poses, slam.grid


def _online(data: list[tuple[float, Odometry, Scan | None]], max_range: float, resolution: float) -> LifelongSlam:
    slam = LifelongSlam(LifelongConfig(max_range=max_range, cover_radius=LOG_COVER_RADIUS,
                                       tie_radius=LOG_TIE_RADIUS), record=True, resolution=resolution,
                        matcher=_log_matcher(), max_correction=LOG_GRID_MAX_CORRECTION, match_range=max_range - 1.0,
                        relocalise_when_lost=False)
    for _stamp, odom, scan in data:
        slam.update(odom, scan)
    return slam


def draw(data: list[tuple[float, Odometry, Scan | None]], stamps: list[float], poses: list[Pose2],
         resolution: float = RESOLUTION) -> OccupancyGrid:
    """The log-odds grid of every scan drawn at its pose (``stamps`` [s] → ``poses`` [map])."""
    grid = OccupancyGrid(resolution)
    at = dict(zip(stamps, poses, strict=True))
    for _, _, scan in data:
        if scan is not None and scan.stamp in at:
            grid.integrate(scan, at[scan.stamp])
    return grid
