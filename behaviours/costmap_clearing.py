"""Clear the costmap's obstacle layer in a square round the robot or a pose, or everywhere but round the robot (Nav2).

Nav2's ``ClearCostmapAroundRobot``, ``ClearCostmapAroundPose`` and
``ClearCostmapExceptRegion`` (``nav2_behavior_tree/plugins/action/
clear_costmap_service.cpp``) are service calls to a costmap's
``clear_around_*`` / ``clear_except_*`` services, which reset the cells of
the layers filled by sensors within (or outside) a square of side
``reset_distance`` centred on the point (``nav2_costmap_2d/
clear_costmap_service.cpp``). homing calls its navigation service's costmap
directly (:meth:`homing.navigation.costmap.Costmap.clear_region`): its
obstacle marks and bumper marks are cleared there, the static map and the
keep-out zones never. Each leaf SUCCEEDS in the tick it is ticked, or FAILS
without a navigation service or a pose. Use ``ClearCostmap`` to empty the
whole obstacle layer.
"""

from __future__ import annotations

from typing import Any, ClassVar

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import NAVIGATOR_KEY, POSE_KEY
from homing.behaviours.paths import as_pose
from homing.behaviours.registry import REQUIRED, Param, register
from homing.robot import Pose2
from py_trees.common import Status

RESET_DISTANCE = 1.0  # [m] Nav2's default side of the square
RESET_PARAM = Param("reset_distance", float, RESET_DISTANCE, "m",
                    "side of the square (centred on the point, axis-aligned in map)", minimum=0.0)


class _ClearRegion(HomingBehaviour):
    """Clear the navigation costmap inside (``INSIDE``) or outside a square round :meth:`centre`."""

    INSIDE = True
    READS: ClassVar[tuple[str, ...]] = (NAVIGATOR_KEY, POSE_KEY)

    def __init__(self, name: str, reset_distance: float = RESET_DISTANCE, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.reset_distance = reset_distance

    def centre(self) -> Pose2 | None:
        """The point the square is centred on (``map``); the robot's pose unless overridden."""
        return self.read(POSE_KEY)

    def update(self) -> Status:
        nav, centre = self.read(NAVIGATOR_KEY), self.centre()
        if nav is None or centre is None:
            self.feedback_message = "no navigation service" if nav is None else "no pose to clear round"
            return Status.FAILURE
        n = nav.costmap.clear_region(centre.x, centre.y, self.reset_distance, inside=self.INSIDE)
        where = "within" if self.INSIDE else "outside"
        self.feedback_message = (f"{n} obstacle cells cleared {where} {self.reset_distance:g} m "
                                 f"round ({centre.x:.2f}, {centre.y:.2f})")
        return Status.SUCCESS


@register("ClearCostmapAroundRobot")
class ClearCostmapAroundRobot(_ClearRegion):
    """Clear the obstacle layer in the ``reset_distance`` [m] square centred on the robot (``/map/pose``): Nav2's ``ClearCostmapAroundRobot``.

    What the scan marked near the robot goes (a person who walked away, a
    phantom from a reflection) while the rest of the costmap stays; the
    scan marks again whatever is still there. Static map and keep-out zones stay.
    """

    PARAMS = (RESET_PARAM,)


@register("ClearCostmapAroundPose")
class ClearCostmapAroundPose(_ClearRegion):
    """Clear the obstacle layer in the ``reset_distance`` [m] square centred on the pose at ``pose_key`` (``map``): Nav2's ``ClearCostmapAroundPose``.

    Typically the goal, before planning to it again. The pose is a Pose2 or
    ``[x, y(, theta)]`` in metres; its heading plays no part (the square is
    axis-aligned in ``map``, as Nav2's is in the costmap's frame).
    """

    PARAMS = (Param("pose_key", str, REQUIRED, doc="blackboard key of the pose to clear round"), RESET_PARAM)
    READS = (NAVIGATOR_KEY, "$pose_key")

    def __init__(self, name: str, pose_key: str, reset_distance: float = RESET_DISTANCE) -> None:
        self.pose_key = pose_key
        super().__init__(name, reset_distance)

    def centre(self) -> Pose2 | None:
        return as_pose(self.read(self.pose_key))


@register("ClearCostmapExceptRegion")
class ClearCostmapExceptRegion(_ClearRegion):
    """Clear the obstacle layer everywhere but the ``reset_distance`` [m] square centred on the robot: Nav2's ``ClearCostmapExceptRegion``.

    Keeps what the robot sees around it now and forgets every older mark
    farther away (obstacles that may have gone since). Static map and keep-out zones stay.
    """

    INSIDE = False
    PARAMS = (RESET_PARAM,)
