"""Nav2's ``DriveOnHeading``: drive straight a signed distance at a signed speed on odometry, stopping short of obstacles.

Semantics from Nav2's ``nav2_behaviors/plugins/drive_on_heading.hpp`` (the
behaviour server's action behind the BT node): the distance and the speed
must have the same sign (else it fails at once); the robot drives at
``speed`` along its heading until odometry says it has covered
``|distance|``; it fails when the time allowance runs out (``timeout``, 0 =
none) or the scan shows something in the way (Nav2 checks the costmap ahead).
``BackUp`` is the same motion backwards, kept as its own leaf.
"""

from __future__ import annotations

from typing import Any

from homing.behaviours.base import TIMEOUT_PARAM
from homing.behaviours.keys import CMD_VEL_KEY, NAVIGATOR_KEY, OBSERVATION_KEY
from homing.behaviours.motion import FAILURE_KEY, FAILURE_PARAM, _ReportsFailure
from homing.behaviours.registry import Param, register
from homing.navigation.controller import SAFETY_MARGIN, safe_speed
from homing.robot import Pose2
from homing.robot.turtlebot import FOOTPRINT_RADIUS
from py_trees.common import Status

BLOCKED_SPEED = 1e-3  # [m/s] a safe speed below this means the way is blocked


@register("DriveOnHeading")
class DriveOnHeading(_ReportsFailure):
    """Drive straight ``distance`` (forward positive) at ``speed`` (same sign) on odometry: Nav2's ``DriveOnHeading``.

    Fails with reason ``bad_request`` when the signs differ, ``blocked``
    when the scan leaves no room to move on, ``timed_out`` after ``timeout``.
    Use it for short open-loop moves (odometry calibration, leaving a
    corner); use ``NavigateToPose`` to go somewhere.
    """

    PARAMS = (
        Param("distance", float, 0.15, "m", "how far along the heading; negative drives backwards"),
        Param("speed", float, 0.025, "m/s", "signed like distance"),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, NAVIGATOR_KEY)
    WRITES = (CMD_VEL_KEY, "$failure_key")

    def __init__(self, name: str, distance: float = 0.15, speed: float = 0.025, timeout: float = 0.0,
                 failure_key: str = FAILURE_KEY, **kwargs: Any) -> None:  # fmt: skip
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout, **kwargs)
        self.distance, self.speed = distance, speed
        self.origin = Pose2()

    def on_start(self) -> Status | None:
        if (self.distance > 0.0) != (self.speed > 0.0):
            return self.fail("bad_request", f"distance {self.distance:g} m and speed {self.speed:g} m/s differ in sign")
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        self.origin = obs.odom.pose
        return None

    def on_running(self) -> Status:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        travelled = self.origin.distance_to(obs.odom.pose)  # [m]
        if travelled >= abs(self.distance):
            self.drive(0.0, 0.0)
            self.feedback_message = f"drove {travelled:.2f} m"
            return Status.SUCCESS
        nav = self.read(NAVIGATOR_KEY)
        points = nav.scan_points_now(obs) if nav is not None else (obs.scan.points() if obs.scan else None)
        v = self.speed
        if points is not None and len(points):
            v = safe_speed(v, 0.0, points, FOOTPRINT_RADIUS + SAFETY_MARGIN)
            if abs(v) < BLOCKED_SPEED:
                self.drive(0.0, 0.0)
                return self.fail("blocked", "obstacle on the heading")
        self.drive(v, 0.0)
        self.feedback_message = f"{travelled:.2f} of {abs(self.distance):g} m"
        return Status.RUNNING
