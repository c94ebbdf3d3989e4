"""Ask the grid SLAM to find the robot in the whole map again: Nav2's ``ReinitializeGlobalLocalization``.

Nav2's node (``nav2_behavior_tree/plugins/action/
reinitialize_global_localization_service.cpp``) calls AMCL's
``reinitialize_global_localization`` service, which spreads the particles
over the whole map so that the robot is found wherever it stands. homing's
``grid_slam`` service does the same with its global relocalisation
(:mod:`homing.mapping.relocalize`): this leaf writes the request
``/map/relocalize``, and from its next update the service counts the robot
as lost and looks for each scan in the whole map until one fits
(``/map/localized`` is False meanwhile). Use it when the pose is known to be
wrong (the robot was carried, or the map and the scan disagree) and not as
a routine step: while lost, nothing is mapped.
"""

from __future__ import annotations

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import RELOCALIZE_KEY
from homing.behaviours.registry import register
from py_trees.common import Status


@register("ReinitializeGlobalLocalization")
class ReinitializeGlobalLocalization(HomingBehaviour):
    """Write ``True`` to ``/map/relocalize`` and SUCCEED: ``grid_slam`` then looks for the robot in the whole map.

    The request is acted on at the service's next update (the next tick);
    before the map has been started (its first three scans) it is dropped,
    as there is nothing to search.
    """

    WRITES = (RELOCALIZE_KEY,)

    def update(self) -> Status:
        self.write(RELOCALIZE_KEY, True)
        self.feedback_message = "grid_slam asked to look for the robot in the whole map"
        return Status.SUCCESS
