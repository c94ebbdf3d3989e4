"""The ``grid_slam`` service: odometry and lidar into a scan-matched occupancy grid, every tick (gmapping's role in the thesis, §2.3).

Glue only (ARCHITECTURE.md, services): each observation's odometry and
latest scan go to :class:`homing.mapping.grid_slam.GridSlam`, which fuses a
scan only when a new one has arrived (5.5 Hz on the TurtleBot's RPLIDAR,
so most ticks cost a dictionary lookup), and the service writes:

- ``/map/grid``: the :class:`~homing.mapping.grid.OccupancyGrid`, as a
  snapshot taken every ``publish_period`` [s] of adapter time (gmapping's
  ``map_update_interval``, 5 s there): every reader (costmap, frontier
  search) recomputes what it derives from the grid when a new snapshot
  appears, so publishing each of the 5.5 scans a second would cost them
  that work 5.5 times a second for a map that moved by a few cells. The
  obstacle layer still sees every scan. ``publish_period: 0`` publishes the
  live grid (changing with every scan);
- ``/map/pose``: base_link in ``map`` (``map_to_odom ⊕ odom``, fresh every tick);
- ``/map/map_to_odom``: the scan matcher's correction;
- ``/map/localized``: False while tracking has lost the robot (a kidnap) and
  the scans are looked for in the whole map (:mod:`homing.mapping.relocalize`);
- ``/map/relocalize``: reset to False after it reads True, which a leaf
  writes to have the robot looked for in the whole map from the next scan
  (``ReinitializeGlobalLocalization``, as Nav2 asks AMCL to spread its
  particles over the map).

The dock anchors the pose: a robot charging on its dock stands at the docked
pose the navigation service knows (``/nav/dock``). When the pose disagrees
with it by more than ``DOCK_ANCHOR`` the robot, not the dock, has moved in
the map (tracking slid along a corridor while the wheels slipped; IR docking
does not need the map to be right), so the pose is set back to the dock. A
smaller difference is the map's own drift, which navigation follows.

A robot on its dock does not move: the first ``DOCK_SCANS`` scans after it
docks settle its pose there, no more are fused until it leaves, and the pose
is held where they put it (the gyro drifts about 0.2° a minute standing still).
Matching the same view once a second for the hours a robot rests let the
pose creep (bench persist, lab, seed 2: 0.42 m on one rest, 0.56 m on the
next), the navigation service took each creep for the dock's place in the
map, and the next arrival was anchored to that wrong dock - the robot left
its dock half a metre from where it thought, drew scans into the map there,
and twice went 4 h without finding its way home.

``map`` is the ``odom`` frame at the first scan. When ``tag_slam`` runs after
this service in the same mission, its keys override these (it owns the grid).
Do not use ``use_matcher: false`` other than as a baseline: the grid then
drifts with the wheels.

``loop_closure: true`` runs :class:`homing.mapping.lifelong.LifelongSlam`
instead: the same tracking, with a keyframe pose graph that closes loops
and redraws the grid from its optimised keyframes, keyframes added only
where the robot has not been (memory grows with the area, not the days).
The dock anchor and a relocalisation are known poses to its graph; after a
restore from a snapshot the graph starts afresh, anchored on the restored
grid (the keyframes of the run before are not kept in the snapshot).
"""

from __future__ import annotations

import math
from typing import Any

from homing.behaviours.keys import (
    DOCK_KEY,
    GRID_KEY,
    LOCALIZED_KEY,
    MAP_TO_ODOM_KEY,
    POSE_KEY,
    RELOCALIZE_KEY,
)
from homing.behaviours.registry import Param, register_service
from homing.mapping.grid import OccupancyGrid
from homing.mapping.grid_slam import GridSlam
from homing.mapping.lifelong import LifelongSlam
from homing.robot import Observation, Pose2, RobotAdapter
from homing.robot.frames import wrap_angle
from py_trees.common import Access

PUBLISH_PERIOD = 1.0  # [s] between /map/grid snapshots
DOCK_ANCHOR = (0.3, math.radians(15.0))  # [m, rad] a docked pose this far from the known dock is reset to it
DOCK_SCANS = 10  # scans fused after docking, then none until the robot leaves (see module doc)


@register_service(
    "grid_slam",
    params=(
        Param("resolution", float, 0.05, "m", "cell size of the occupancy grid", minimum=0.01, maximum=1.0),
        Param("use_matcher", bool, True, "", "correct odometry by scan-to-map matching (false: odometry-only baseline)"),
        Param("publish_period", float, PUBLISH_PERIOD, "s", "adapter time between grid snapshots on /map/grid (0: live)",
              minimum=0.0),
        Param("loop_closure", bool, False, "", "close loops with a lifelong keyframe pose graph and redraw the grid "
              "from it (homing.mapping.lifelong)"),
    ),
    writes=(GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY, LOCALIZED_KEY, RELOCALIZE_KEY),
)
class GridSlamService:
    """Scan-matched log-odds occupancy grid; writes ``/map/grid``, ``/map/pose`` and ``/map/map_to_odom``."""

    name = "grid_slam"
    writes = (GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY, LOCALIZED_KEY, RELOCALIZE_KEY)

    def __init__(self, resolution: float = 0.05, use_matcher: bool = True,
                 publish_period: float = PUBLISH_PERIOD, loop_closure: bool = False) -> None:
        if not resolution > 0:
            raise ValueError(f"resolution must be positive, not {resolution}")
        if publish_period < 0:
            raise ValueError(f"publish_period must be ≥ 0, not {publish_period}")
        if loop_closure and not use_matcher:
            raise ValueError("loop_closure needs use_matcher: the pose graph is built on the scan matcher's motion")
        self.slam = (LifelongSlam(resolution=resolution) if loop_closure
                     else GridSlam(resolution=resolution, use_matcher=use_matcher))
        self.publish_period = float(publish_period)  # [s]
        self.published: OccupancyGrid = self.slam.grid if publish_period == 0 else self.slam.grid.copy()
        self.bb: Any = None
        self.scans_fused = 0
        self.anchored = 0  # times the pose was set back to the dock
        self.reinitialised = 0  # times a leaf had the robot looked for in the whole map
        self.dock_scans = 0  # scans fused since the robot last docked
        self._held: Pose2 | None = None  # the pose a resting robot keeps
        self._next_publish = -math.inf

    def setup(self, robot: RobotAdapter, blackboard: Any) -> None:
        self.bb = blackboard
        blackboard.register_key(key=DOCK_KEY, access=Access.READ)
        blackboard.set(GRID_KEY, self.published, overwrite=True)

    def update(self, obs: Observation) -> None:
        """Fuse a new scan if there is one (one scan match + ray trace, ≈ a few ms), then publish."""
        if self.bb.exists(RELOCALIZE_KEY) and self.bb.get(RELOCALIZE_KEY):
            self.bb.set(RELOCALIZE_KEY, False, overwrite=True)
            self.reinitialised += int(self.slam.forget_pose())
        if not obs.battery.on_dock:
            self.dock_scans, self._held = 0, None
        resting = obs.battery.on_dock and self.dock_scans >= DOCK_SCANS
        if self.slam.update(obs.odom, None if resting else obs.scan):
            self.scans_fused += 1
            self.dock_scans += 1
            if self.publish_period > 0 and obs.stamp >= self._next_publish:
                self._next_publish = obs.stamp + self.publish_period
                self.published = self.slam.grid.copy()
        if resting:  # it stands where its last scan put it, whatever the gyro's drift says
            if self._held is None:
                self._held = self.slam.pose
            self.slam.set_pose(self._held, obs.odom.pose)
        if obs.battery.on_dock:
            self._anchor(obs)
        self.bb.set(GRID_KEY, self.published, overwrite=True)
        self.bb.set(POSE_KEY, self.slam.pose, overwrite=True)
        self.bb.set(MAP_TO_ODOM_KEY, self.slam.map_to_odom, overwrite=True)
        self.bb.set(LOCALIZED_KEY, not self.slam.lost, overwrite=True)

    def _anchor(self, obs: Observation) -> None:
        """On the dock, far from where the dock is known to be: the robot stands on the dock (see module doc)."""
        dock = self.bb.get(DOCK_KEY) if self.bb.exists(DOCK_KEY) else None
        if not isinstance(dock, Pose2):
            return
        pose = self.slam.pose
        if (pose.distance_to(dock) > DOCK_ANCHOR[0] or abs(wrap_angle(pose.theta - dock.theta)) > DOCK_ANCHOR[1]
                or self.slam.lost):
            self.slam.set_pose(dock, obs.odom.pose)
            self.anchored += 1
            if self._held is not None:
                self._held = dock

    def snapshot(self, snap: Any) -> None:
        """Keep the grid in a run directory's snapshot (:mod:`homing.lifecycle.rundir`)."""
        snap.grid = self.slam.grid.copy()

    def restore(self, snap: Any, obs: Observation) -> None:
        """Start from a snapshot's grid: on the dock at the dock's pose, elsewhere at ``snap.pose`` or lost (it finds itself)."""
        if snap.grid is None:
            return
        self.slam.adopt(snap.grid)
        if obs.battery.on_dock and snap.dock is not None:
            self.slam.set_pose(snap.dock, obs.odom.pose)
        elif snap.pose is not None:
            self.slam.set_pose(snap.pose, obs.odom.pose)
        else:
            self.slam.lost = True
        self.published = self.slam.grid if self.publish_period == 0 else self.slam.grid.copy()
        self.bb.set(GRID_KEY, self.published, overwrite=True)

    def shutdown(self) -> None:
        """Publish the final grid, so whoever saves the map at the end gets every scan."""
        if self.bb is not None:
            self.published = self.slam.grid.copy() if self.publish_period > 0 else self.slam.grid
            self.bb.set(GRID_KEY, self.published, overwrite=True)
