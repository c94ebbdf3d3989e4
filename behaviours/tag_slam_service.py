"""The ``tag_slam`` service: AprilTag sightings and odometry into online landmark SLAM, every tick.

Glue only (ARCHITECTURE.md, services): on each observation it detects tags
in a *new* camera image (:mod:`homing.perception.apriltag`), takes their
headings from the wall behind them (:mod:`homing.perception.tag_wall`), feeds odometry,
the latest scan and the sightings to :class:`homing.mapping.landmark_slam.LandmarkSlam`,
and writes the results:

- ``/perception/tags``: the tag measurements (base_link) taken *this tick*
  (an empty list on ticks without a new image) — the run log records them
  so that ``homing replay --slam`` feeds SLAM exactly the same input;
- ``/slam/landmarks``: tag id → optimised tag pose in ``map``;
- ``/map/map_to_odom`` and ``/map/pose``: the tag-corrected map frame;
- ``/map/grid``: an occupancy grid drawn from the keyframes' scans at their
  optimised poses. New keyframes are drawn as they come; when the optimiser
  has moved past keyframes (a loop closed), a fresh grid is rebuilt a batch
  of scans per tick and swapped in when complete, so no tick waits for it.

Run it after ``grid_slam`` in a mission's ``services`` list when both are
present: its map keys then override grid_slam's.

With ``grid: false`` it maps the tags only, in the frame of the mapper
before it (``grid_slam``, which keeps the grid and the pose): its keyframes
are tied to that mapper's pose (``matched``), and it writes only
``/perception/tags`` and ``/slam/landmarks``. It then works in **sessions**,
for a robot that lives for days: whenever the robot docks (the charger
reports the dock), the graph of the trip is folded into priors on the tags
(their marginals) and a new graph starts from them, so memory and update
cost stay bounded by one trip, not the robot's lifetime. The tags' estimates
(:meth:`TagSlamService.landmark_estimates`) are what a run directory keeps.
"""

from __future__ import annotations

import math
from typing import Any

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import (
    FOCUS_KEY,
    GRID_KEY,
    LANDMARKS_KEY,
    MAP_TO_ODOM_KEY,
    POSE_KEY,
    TAGS_KEY,
)
from homing.behaviours.registry import Param, register, register_service
from homing.robot import Observation, Pose2, RobotAdapter
from py_trees.common import Access, Status

REBUILD_SHIFT = 0.03  # [m] a keyframe moved this far since drawn → rebuild the grid
REBUILD_PERIOD = 5.0  # [s] adapter time between checks for a rebuild
REBUILD_BATCH = 25  # scans drawn into the grid being rebuilt per tick
TOUR_GOAL_KEY = "/tag_tour/goal"
LANDMARKS_PERIOD = 2.0  # [s] tags-only mode: the tags' estimates are published at most this often
# At ``image_rate`` a robot that has not moved this far (odometry) since its last look sees the same tags from
# the same place: another look adds nothing to the graph but its cost (a charging robot looks at its dock's tag
# for hours). Frames asked for by a servo (``/camera/focus``) are always looked at.
STILL_XY = 0.02  # [m]
STILL_THETA = math.radians(1.0)  # [rad]


@register_service(
    "tag_slam",
    params=(
        Param("tag_size", float, 0.16, "m", "black square's edge of the tags", above=0.0),
        Param("dock_tag", int, 0, "", "id of the dock's tag, the map's anchor (-1: none)", minimum=-1),
        Param("keyframe_distance", float, 0.25, "m", "odometry travelled before a new keyframe", above=0.0),
        Param("keyframe_angle", float, 0.35, "rad", "odometry turn before a new keyframe", above=0.0),
        Param("robust", str, "cauchy", "", "M-estimator on tag factors", choices=("cauchy", "huber", "none")),
        Param("max_range", float, 3.0, "m", "tags farther than this are ignored", above=0.0),
        Param("resolution", float, 0.05, "m", "cell size of the rebuilt occupancy grid", minimum=0.01, maximum=1.0),
        Param("grid", bool, True, "", "own the grid and the pose (false: map the tags in grid_slam's frame, per trip)"),
        Param("image_rate", float, 0.0, "Hz", "look for tags in at most this many frames a second (0: every frame); "
              "every frame while a leaf asks to (/perception/focus_until)"),
    ),
    writes=(TAGS_KEY, LANDMARKS_KEY, MAP_TO_ODOM_KEY, POSE_KEY, GRID_KEY),
)
class TagSlamService:
    """Online AprilTag landmark SLAM (GTSAM iSAM2) that refines the map frame and rebuilds the grid."""

    name = "tag_slam"
    writes = (TAGS_KEY, LANDMARKS_KEY, MAP_TO_ODOM_KEY, POSE_KEY, GRID_KEY)

    def __init__(self, tag_size: float = 0.16, dock_tag: int = 0, keyframe_distance: float = 0.25,
                 keyframe_angle: float = 0.35, robust: str = "cauchy", max_range: float = 3.0,
                 resolution: float = 0.05, grid: bool = True, image_rate: float = 0.0) -> None:
        from homing.mapping.landmark_slam import (
            CLOSURE_RADIUS,
            SCAN_LINKS,
            LandmarkSlam,
            SlamConfig,
        )
        from homing.perception.apriltag import TagDetector, TagFilter
        from homing.perception.tag_wall import TagPerception

        self.detector = TagDetector(tag_size=tag_size, filt=TagFilter(max_range=max_range))
        self.perception = TagPerception(self.detector)
        self.config = SlamConfig(
            keyframe_distance=keyframe_distance, keyframe_angle=keyframe_angle, robust=robust,
            anchor_tag=None if dock_tag < 0 or not grid else dock_tag,
            # Tags only: the grid's mapper keeps the headings consistent (the keyframes are tied to its poses),
            # so the lidar closures and links would only cost time.
            closure_radius=CLOSURE_RADIUS if grid else 0.0, scan_links=SCAN_LINKS if grid else (),
        )
        self.slam = LandmarkSlam(self.config)
        self.owns_grid = grid
        if not (math.isfinite(image_rate) and image_rate >= 0):
            raise ValueError(f"image_rate must be ≥ 0 Hz, not {image_rate}")
        self.image_period = 1.0 / image_rate if image_rate > 0 else 0.0  # [s]
        self._next_detect = -math.inf
        self._looked_from: Pose2 | None = None  # odometry pose at the last look at ``image_rate``
        self._published_updates = -1
        self._next_landmarks = -math.inf
        self.sessions = 1
        self._was_docked = False
        self.resolution = resolution
        self.bb: Any = None
        self.robot: RobotAdapter | None = None
        self._grid: Any = None
        self._drawn: list[Pose2] = []  # pose each keyframe's scan was drawn at
        self._rebuild: tuple[Any, list[Pose2], int] | None = None
        self._next_check = 0.0

    def setup(self, robot: RobotAdapter, blackboard: Any) -> None:
        from homing.mapping.grid import OccupancyGrid

        self.robot = robot
        self.bb = blackboard
        blackboard.register_key(key=FOCUS_KEY, access=Access.READ)
        self._grid = OccupancyGrid(self.resolution)

    def update(self, obs: Observation) -> None:
        """Detect, update SLAM and write the blackboard (bounded work: one iSAM2 update per keyframe)."""
        tags = self.perception.measure(obs, detect=self._wants_image(obs))
        if not self.owns_grid:
            self._update_tags_only(obs, tags)
            return
        added = self.slam.update(obs.stamp, obs.odom.pose, obs.scan, tags)
        if added:
            self._draw_latest()
        self._maintain_grid(obs.stamp)
        self.bb.set(TAGS_KEY, tags, overwrite=True)
        self.bb.set(LANDMARKS_KEY, self.slam.landmarks(), overwrite=True)
        self.bb.set(MAP_TO_ODOM_KEY, self.slam.map_to_odom, overwrite=True)
        self.bb.set(POSE_KEY, self.slam.pose(obs.odom.pose), overwrite=True)
        self.bb.set(GRID_KEY, self._grid, overwrite=True)

    def _wants_image(self, obs: Observation) -> bool:
        """Whether to look for tags in this tick's image: at ``image_rate``, or every new frame when asked to."""
        if self.image_period <= 0.0 or obs.image is None:
            return True
        focus = self._get(FOCUS_KEY)
        if focus is not None and obs.stamp <= focus:
            return True
        if obs.stamp < self._next_detect:
            return False
        self._next_detect = obs.stamp + self.image_period
        last, here = self._looked_from, obs.odom.pose
        if last is not None:
            d = last.between(here)
            if math.hypot(d.x, d.y) < STILL_XY and abs(d.theta) < STILL_THETA:
                return False
        self._looked_from = here
        return True

    def _update_tags_only(self, obs: Observation, tags: list[Any]) -> None:
        pose, map_to_odom = self._get(POSE_KEY), self._get(MAP_TO_ODOM_KEY)
        docked = obs.battery.on_dock
        if docked and not self._was_docked and self.slam.keyframes:
            self.new_session(map_to_odom)
        self._was_docked = docked
        if not self.slam.keyframes and map_to_odom is not None:
            self.slam.set_start_frame(map_to_odom)  # the first keyframe starts where the grid's mapper has it
        self.slam.update(obs.stamp, obs.odom.pose, obs.scan, tags, matched=pose)
        self.bb.set(TAGS_KEY, tags, overwrite=True)
        if self.slam.updates != self._published_updates and obs.stamp >= self._next_landmarks:
            # The tags' estimates are read back from iSAM2 (a call per tag): at most every LANDMARKS_PERIOD.
            self._published_updates, self._next_landmarks = self.slam.updates, obs.stamp + LANDMARKS_PERIOD
            self.bb.set(LANDMARKS_KEY, self.slam.landmarks(), overwrite=True)

    def landmark_estimates(self) -> dict[int, tuple[Pose2, Any]]:
        """Tag id → (pose in map, (3, 3) marginal covariance): the state a run directory keeps."""
        self.slam.flush()
        return self.slam.landmark_estimates()

    def snapshot(self, snap: Any) -> None:
        """Keep the tags' estimates (the trip's graph folded into priors) in a run directory's snapshot."""
        snap.landmarks = self.landmark_estimates()

    def restore(self, snap: Any, obs: Observation) -> None:
        """Start a new graph from a snapshot's tag estimates (the map frame is the grid's, set at the first update)."""
        if snap.landmarks:
            self.new_session(None, priors=dict(snap.landmarks))

    def new_session(self, map_to_odom: Pose2 | None = None,
                    priors: dict[int, tuple[Pose2, Any]] | None = None) -> None:
        """Fold the trip's graph into priors on the tags (or take ``priors``) and start a new graph from them."""
        from homing.mapping.landmark_slam import LandmarkSlam

        known = self.landmark_estimates() if priors is None else priors
        self.slam = LandmarkSlam(self.config, map_to_odom=map_to_odom, landmark_priors=known)
        self.sessions += 1

    def _get(self, key: str) -> Any:
        try:
            return self.bb.get(key)
        except KeyError:
            return None

    def _draw_latest(self) -> None:
        kf = self.slam.keyframes[-1]
        pose = self.slam.pose(kf.odom)  # the newest keyframe's optimised pose
        self._drawn.append(pose)
        if kf.scan is not None:
            self._grid.integrate(kf.scan, pose.compose(kf.scan_offset))

    def _maintain_grid(self, now: float) -> None:
        from homing.mapping.grid import OccupancyGrid

        if self._rebuild is None and now >= self._next_check:
            self._next_check = now + REBUILD_PERIOD
            poses = self.slam.keyframe_poses()
            moved = max((p.distance_to(d) for p, d in zip(poses, self._drawn, strict=False)), default=0.0)
            if moved > REBUILD_SHIFT:
                self._rebuild = (OccupancyGrid(self.resolution), poses, 0)
        if self._rebuild is None:
            return
        grid, poses, i = self._rebuild
        end = min(i + REBUILD_BATCH, len(poses))
        for kf, pose in zip(self.slam.keyframes[i:end], poses[i:end], strict=False):
            if kf.scan is not None:
                grid.integrate(kf.scan, pose.compose(kf.scan_offset))
        if end < len(poses):
            self._rebuild = (grid, poses, end)
            return
        # Keyframes added while rebuilding are drawn at the poses they were drawn at.
        for kf, pose in zip(self.slam.keyframes[end:], self._drawn[end:], strict=False):
            if kf.scan is not None:
                grid.integrate(kf.scan, pose.compose(kf.scan_offset))
        self._grid = grid
        self._drawn[:end] = poses
        self._rebuild = None

    def shutdown(self) -> None:
        self.slam.flush()


@register("NextTagView")
class NextTagView(HomingBehaviour):
    """Write a view pose in front of the least-visited mapped tag (nearest first among equals) and SUCCEED.

    The tag tour after exploration (thesis ch. 4: re-observing landmarks is
    what closes loops): the goal is ``distance`` [m] out from the tag's
    optimised pose in ``map`` (``/slam/landmarks``), facing it, for a
    ``NavigateToPose`` reading ``goal_key``. FAILURE while no tag is mapped
    or no map pose is known. Picks from the robot's own map only (no truth);
    not for driving *to* a tag (the goal is in front of it, not on it).

    ``anchor_every`` > 0 makes every n-th pick the ``anchor_tag`` (the dock's
    tag, the map's anchor) once it is mapped: every tag's position is read
    relative to the anchor, and in a large world the dock's corner is tied
    to the rest only through odometry between sightings (encoder slip
    ≈ 4 cm per 8 m each way), so each return to it averages that error down.
    """

    PARAMS = (
        Param("distance", float, 1.0, "m", "how far in front of the tag the view pose is", above=0.0),
        Param("goal_key", str, TOUR_GOAL_KEY, doc="blackboard key the Pose2 goal is written to"),
        Param("anchor_tag", int, -1, "", "the map's anchor tag (the dock's) revisited every anchor_every picks",
              minimum=-1),
        Param("anchor_every", int, 0, "", "every n-th pick is the anchor tag (0: never singled out)", minimum=0),
    )
    READS = (LANDMARKS_KEY, POSE_KEY)
    WRITES = ("$goal_key",)

    def __init__(self, name: str, distance: float = 1.0, goal_key: str = TOUR_GOAL_KEY,
                 anchor_tag: int = -1, anchor_every: int = 0) -> None:
        self.goal_key = goal_key
        super().__init__(name)
        self.distance = float(distance)  # [m]
        self.anchor_tag, self.anchor_every = int(anchor_tag), int(anchor_every)
        self.visits: dict[int, int] = {}  # tag id → times chosen
        self.picks = 0

    def update(self) -> Status:
        tags: dict[int, Pose2] | None = self.read(LANDMARKS_KEY)
        here: Pose2 | None = self.read(POSE_KEY)
        if not tags or here is None:
            self.feedback_message = "no mapped tag yet"
            return Status.FAILURE
        views = {i: p.compose(Pose2(self.distance, 0.0, math.pi)) for i, p in tags.items()}
        self.picks += 1
        anchored = self.anchor_every > 0 and self.anchor_tag in views
        others = [i for i in views if i != self.anchor_tag] if anchored else list(views)
        if anchored and (self.picks % self.anchor_every == 0 or not others):
            best = self.anchor_tag
        else:
            best = min(others, key=lambda i: (self.visits.get(i, 0), here.distance_to(views[i]), i))
        self.visits[best] = self.visits.get(best, 0) + 1
        self.write(self.goal_key, views[best])
        self.feedback_message = f"tag {best} (visit {self.visits[best]})"
        return Status.SUCCESS


@register("NextWallView")
class NextWallView(HomingBehaviour):
    """Write the nearest wall view pose not yet visited this lap (:mod:`homing.perception.tag_search`) and SUCCEED.

    The search half of the tag tour: frontier exploration ends once the
    lidar has mapped the walls, long before the camera has seen them. Goals
    come from the robot's own grid (``/map/grid``) and pose; when every view
    has been visited a new lap starts — or, with ``one_lap``, the node FAILS
    once (``lap done``: a patrol round is over) and the next tick starts the
    new lap. FAILURE while no grid or pose is known or the grid has no view pose.
    """

    PARAMS = (
        Param("distance", float, 1.2, "m", "how far from the wall the view pose is", above=0.0),
        Param("spacing", float, 2.0, "m", "between view poses along a wall", above=0.0),
        Param("goal_key", str, TOUR_GOAL_KEY, doc="blackboard key the Pose2 goal is written to"),
        Param("one_lap", bool, False, doc="FAIL once at the end of each lap (a patrol round) instead of going on"),
    )
    READS = (GRID_KEY, POSE_KEY)
    WRITES = ("$goal_key",)

    def __init__(self, name: str, distance: float = 1.2, spacing: float = 2.0, goal_key: str = TOUR_GOAL_KEY,
                 one_lap: bool = False) -> None:
        self.goal_key = goal_key
        super().__init__(name)
        self.distance, self.spacing = float(distance), float(spacing)  # [m]
        self.one_lap = bool(one_lap)
        self.visited: list[Pose2] = []
        self.laps = 0
        self._wall_views: Any = None  # a WallViews: the views worked out again only where the map changed

    def update(self) -> Status:
        from homing.perception.tag_search import WallViews, next_view

        grid, here = self.read(GRID_KEY), self.read(POSE_KEY)
        if grid is None or here is None:
            self.feedback_message = "no map yet"
            return Status.FAILURE
        if self._wall_views is None:
            self._wall_views = WallViews()
        views = self._wall_views(grid.data, grid.resolution, grid.origin, self.distance, self.spacing)
        goal = next_view(views, here, self.visited, self.spacing / 2)
        if goal is None and views:
            self.visited, self.laps = [], self.laps + 1
            if self.one_lap:
                self.feedback_message = f"lap {self.laps} done"
                return Status.FAILURE
            goal = next_view(views, here, self.visited, self.spacing / 2)
        if goal is None:
            self.feedback_message = "no wall to look at"
            return Status.FAILURE
        self.visited.append(goal)
        self.write(self.goal_key, goal)
        self.feedback_message = f"view {len(self.visited)}/{len(views)} (lap {self.laps + 1})"
        return Status.SUCCESS
