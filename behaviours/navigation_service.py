"""The ``navigation`` service: owns the :class:`~homing.navigation.navigator.Navigator` and keeps its costmap fresh.

Like Nav2's planner and controller servers beside a BT: the service builds
one navigator (costmap, planner and controller plugins chosen by name in the
mission's ``services:`` parameters), writes it to ``/nav/navigator``, and
every tick, before the tree, refreshes its costmap from ``/map/grid``, the
latest scan and ``/map/pose`` (written by ``grid_slam``, ``tag_slam`` or any
localiser on a known map: list it before ``navigation``), so leaves that only read the costmap (frontier
ranking, path checks) see the present world even when nothing navigates.
Leaves drive with it (:mod:`homing.behaviours.motion`).

What the lidar cannot see: the ``keepout`` parameter (and ``/nav/keepout``,
which starts with it and any leaf may overwrite) lists zones in ``map``
no path may cross, ``[x, y, r]`` discs and ``[[x, y], …]`` polygons; with
``dock_keepout`` the dock is one of them once the robot has stood on it (the
charging source says so), placed in front of its pose in ``map`` then.

Where the dock is: whenever the base reports charge from the dock, the
robot's pose in ``map`` is the docked pose, written to ``/nav/dock`` (a map
that has drifted since the last visit is followed). A value already on the
blackboard when the service starts (a resumed run) is taken as the dock.
Bumper presses mark the costmap by themselves (:mod:`homing.navigation.layers`).
"""

from __future__ import annotations

from typing import Any

from homing.behaviours.keys import DOCK_KEY, GRID_KEY, MAP_TO_ODOM_KEY, NAVIGATOR_KEY, POSE_KEY
from homing.behaviours.registry import Param, register_service
from homing.navigation.controller import CONTROLLERS
from homing.navigation.costmap import CostmapParams
from homing.navigation.layers import Keepout, dock_keepout, parse_keepout
from homing.navigation.navigator import Navigator
from homing.navigation.planner import PLANNERS
from homing.robot import Observation, Pose2, RobotAdapter
from homing.robot.frames import wrap_angle
from homing.robot.turtlebot import FOOTPRINT_RADIUS
from py_trees.common import Access

from homing.errors import UserError

GOAL_KEY = "/nav/goal"  # the default goal slot of NavigateToPose: created empty here, set by any leaf
KEEPOUT_KEY = "/nav/keepout"  # keep-out zones in map: the service's parameter at first, any leaf may set it
DOCK_MOVED = 0.01  # [m, rad] a docked pose this different from the known one replaces it


@register_service(
    "navigation",
    params=(
        Param("planner", str, "fmm", "", "global planner plugin", choices=tuple(sorted(PLANNERS))),
        Param("controller", str, "rpp", "", "local controller plugin", choices=tuple(sorted(CONTROLLERS))),
        Param("fallback", str, "dwb", "", "rpp's fallback when its arc is blocked ('none': stop and report blocked)",
              choices=("dwb", "none")),
        Param("footprint_radius", float, FOOTPRINT_RADIUS, "m", "robot radius the costmap inflates by", above=0.0),
        Param("inflation_radius", float, 0.55, "m", "inflation cost reaches this far from obstacles", minimum=0.0),
        Param("cost_scaling_factor", float, 5.0, "1/m", "decay rate of the inflation cost", above=0.0),
        Param("max_speed", float, 0.5, "m/s", "controller's cruising speed (never above 0.5)", above=0.0, maximum=0.5),
        Param("xy_tolerance", float, 0.15, "m", "goal reached within this distance", above=0.0),
        Param("yaw_tolerance", float, 0.25, "rad", "and this heading error", above=0.0),
        Param("allow_unknown", bool, True, "", "plan through unknown cells"),
        Param("keepout", list, [], "m", "zones in map no path may cross: [x, y, r] discs, [[x, y], ...] polygons"),
        Param("dock_keepout", bool, True, "", "keep paths off the dock, placed where the robot charged"),
    ),
    writes=(NAVIGATOR_KEY, GOAL_KEY, KEEPOUT_KEY, DOCK_KEY),
)
class NavigationService:
    """Costmap, global planner and local controller, chosen by name; writes ``/nav/navigator``."""

    name = "navigation"
    writes = (NAVIGATOR_KEY, GOAL_KEY, KEEPOUT_KEY, DOCK_KEY)
    reads = (GRID_KEY, POSE_KEY, MAP_TO_ODOM_KEY)

    def __init__(self, planner: str = "fmm", controller: str = "rpp", footprint_radius: float = FOOTPRINT_RADIUS,
                 inflation_radius: float = 0.55, cost_scaling_factor: float = 5.0, max_speed: float = 0.5,
                 xy_tolerance: float = 0.15, yaw_tolerance: float = 0.25, allow_unknown: bool = True,
                 fallback: str = "dwb", keepout: list[Any] | None = None, dock_keepout: bool = True) -> None:
        self.navigator = Navigator(
            planner=planner, controller=controller,
            costmap=CostmapParams(footprint_radius=footprint_radius, inflation_radius=inflation_radius,
                                  cost_scaling_factor=cost_scaling_factor),
            planner_params={"allow_unknown": allow_unknown},
            controller_params=controller_params(controller, max_speed, footprint_radius, fallback),
            xy_tolerance=xy_tolerance, yaw_tolerance=yaw_tolerance,
        )
        self.bb: Any = None
        try:
            self.keepout = parse_keepout(keepout or [])
        except ValueError as err:
            raise UserError(f"navigation service: {err}") from None
        self.dock_keepout = dock_keepout
        self.dock_zone: Keepout | None = None
        self.dock: Pose2 | None = None

    def setup(self, robot: RobotAdapter, blackboard: Any) -> None:
        self.bb = blackboard
        for key in self.reads:
            blackboard.register_key(key=key, access=Access.READ)
        blackboard.set(NAVIGATOR_KEY, self.navigator, overwrite=True)
        blackboard.set(GOAL_KEY, None, overwrite=False)
        blackboard.set(KEEPOUT_KEY, list(self.keepout), overwrite=False)
        blackboard.set(DOCK_KEY, None, overwrite=False)
        self._set_dock(blackboard.get(DOCK_KEY))

    def update(self, obs: Observation) -> None:
        """Refresh the costmap (cheap when neither the grid nor the scan changed)."""
        grid, pose = self._get(GRID_KEY), self._get(POSE_KEY)
        if pose is not None and obs.battery.on_dock and (self.dock is None or self.dock.distance_to(pose) > DOCK_MOVED
                                                         or abs(wrap_angle(self.dock.theta - pose.theta)) > DOCK_MOVED):
            self._set_dock(pose)  # the robot sits on the dock, facing it
            self.bb.set(DOCK_KEY, pose, overwrite=True)
        zones = parse_keepout(self._get(KEEPOUT_KEY))
        self.navigator.set_keepout([*zones, self.dock_zone] if self.dock_zone is not None else zones)
        if grid is not None and pose is not None:
            self.navigator.update_costmap(obs, grid, pose, self._get(MAP_TO_ODOM_KEY))

    def _set_dock(self, pose: Pose2 | None) -> None:
        self.dock = pose
        self.dock_zone = dock_keepout(pose) if pose is not None and self.dock_keepout else None

    def shutdown(self) -> None:
        self.navigator.cancel()

    def _get(self, key: str) -> Any:
        try:
            return self.bb.get(key)
        except KeyError:
            return None


def controller_params(controller: str, max_speed: float, footprint_radius: float, fallback: str) -> dict[str, Any]:
    """The service's parameters in the named controller's own spelling."""
    if controller == "dwb":
        return {"max_v": max_speed, "footprint_radius": footprint_radius}
    return {"desired_v": max_speed, "footprint_radius": footprint_radius,
            "fallback": None if fallback == "none" else fallback}
