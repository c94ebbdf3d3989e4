"""Visual servo to a pose fixed relative to an AprilTag: the dock's staging pose from the dock tag (thesis §3.3.5).

The map may have drifted since the robot left (0.5 m and 10° after a long
trip is not unusual), so the "home" it navigated to is only roughly in
front of the dock. The tag above the dock is not: each sighting gives the
tag's pose in ``base_link`` at the image's stamp, hence, through odometry at
that stamp, the goal's pose in ``odom``::

    goal_odom = odom(t_image) ⊕ tag_in_base ⊕ goal_in_tag

and odometry is smooth and accurate over the few metres a servo drives. The
goal estimates of the last ``MEMORY`` sightings are averaged, each weighted by
the inverse of its variance at the goal (the tag's position variance plus the
lever arm times its heading variance: heading dominates at a metre and more),
so the goal sharpens as the robot closes in.

Phases, each on odometry alone between sightings:

1. SEARCH — no sighting yet: sweep in place, left to ``search_angle``, right
   to −``search_angle``, back to the start; FAILED (``no_tag``) after that.
2. APPROACH — turn towards the goal point, drive to it (backwards if it lies
   just behind), slowing as it closes (``K_V`` per metre to go, never below
   ``MIN_V``: at 0.8 and no floor the last 10 cm took 2 s; over the 100 runs
   of ``homing bench dock`` gain 1.5 and floor 5 cm/s saved 1.2 s, the median
   of the paired differences).
3. ALIGN — turn on the spot to the goal heading; SUCCEEDED within the
   tolerances once the base is still (its measured turn below
   ``SETTLED_OMEGA``, speed below ``SETTLED_V``; it is told to stop while
   not), back to APPROACH if the goal moved away (a better sighting). A real
   Kobuki answers a command 0.2 s late (kobuki#389); without the stillness
   check the servo, seeing odometry from before its last turn command took
   hold, declared success while swinging through the goal heading at up to
   1.2 rad/s, and the dock drive began 6-14° off (over the emulated serial
   port, 5 of 21 loaded runs then failed their first IR docking).

Frames: tag measurements in ``base_link`` (the tag's x axis is its face
normal, into the room), odometry in ``odom``, the goal in the tag's frame.
``homing world dock lab --offset DX DY DEG`` prints a trace from a drifted start in the simulator.
"""

from __future__ import annotations

import enum
import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from homing.robot import Pose2, Twist2
from homing.robot.frames import wrap_angle
from homing.robot.history import PoseHistory
from homing.robot.turtlebot import DOCKED_FROM_WALL

STAGING_DISTANCE = 1.0  # [m] staging pose out from the docked pose (thesis: "about a meter")
XY_TOLERANCE = 0.02  # [m] goal reached
YAW_TOLERANCE = math.radians(1.5)  # [rad]
MAX_V = 0.20  # [m/s]
MAX_OMEGA = 1.2  # [rad/s]
K_V = 1.5  # [1/s] speed per metre to go
MIN_V = 0.05  # [m/s] never slower than this while driving to the goal (kobuki creeps into its dock at 0.05)
K_OMEGA = 3.0  # [1/s] turn rate per radian of heading error
MIN_OMEGA = 0.12  # [rad/s] the base does not turn slower than this reliably
SETTLED_OMEGA = 0.15  # [rad/s] measured turn rate under which the base counts as still (above MIN_OMEGA)
SETTLED_V = 0.03  # [m/s] measured speed under which the base counts as still
DRIVE_HEADING = math.radians(20.0)  # [rad] turn on the spot first when the goal's bearing is off by more
REVERSE_RANGE = 0.40  # [m] a goal behind the robot and this close is reached backwards
SEARCH_ANGLE = math.radians(70.0)  # [rad] sweep half-width when the tag is not in view
SEARCH_OMEGA = 0.8  # [rad/s]
MEMORY = 8  # sightings averaged
HISTORY = 3.0  # [s] odometry kept to place a sighting at its image's stamp
MIN_VARIANCE = 1e-6  # [m²] floor of a sighting's goal variance


def staging_in_tag(distance: float = STAGING_DISTANCE, docked_from_wall: float = DOCKED_FROM_WALL,
                   tag_from_wall: float = 0.0) -> Pose2:
    """The staging pose in the dock tag's frame: ``distance`` [m] out from the docked pose, facing the tag.

    The tag hangs on the wall on the dock's centre line, its face ``tag_from_wall`` [m] off the wall.
    """
    return Pose2(docked_from_wall + distance - tag_from_wall, 0.0, math.pi)


class ServoStatus(enum.Enum):
    SEARCH = "search"
    APPROACH = "approach"
    ALIGN = "align"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


@dataclass(frozen=True)
class Sighting:
    """The tag seen at ``stamp`` [s]: its pose in base_link and (3, 3) covariance of (x, y, θ)."""

    stamp: float
    pose: Pose2
    covariance: np.ndarray


class TagServo:
    """Servo to ``goal_in_tag`` from sightings of one tag (see the module doc). One run per :meth:`start`."""

    def __init__(self, goal_in_tag: Pose2 | None = None, xy_tolerance: float = XY_TOLERANCE,
                 yaw_tolerance: float = YAW_TOLERANCE, max_v: float = MAX_V, max_omega: float = MAX_OMEGA,
                 search_angle: float = SEARCH_ANGLE) -> None:
        self.goal_in_tag = goal_in_tag or staging_in_tag()
        self.xy_tolerance = float(xy_tolerance)  # [m]
        self.yaw_tolerance = float(yaw_tolerance)  # [rad]
        self.max_v = float(max_v)  # [m/s]
        self.max_omega = float(max_omega)  # [rad/s]
        self.search_angle = float(search_angle)  # [rad]
        self.odom = PoseHistory(HISTORY)
        self.start(0.0, Pose2())

    def start(self, now: float, odom: Pose2) -> None:
        """Begin at ``now`` [s] with the robot at ``odom``; forgets earlier sightings."""
        self.status = ServoStatus.SEARCH
        self.reason: str | None = None
        self.message = "looking for the tag"
        self.goal: Pose2 | None = None  # in odom
        self.sightings = 0
        self._estimates: deque[tuple[Pose2, float]] = deque(maxlen=MEMORY)
        self._pending: list[Sighting] = []
        self._search_origin = odom.theta
        self._search_leg = 0  # 0: left, 1: right, 2: back to the start
        self.odom.samples.clear()
        self.odom.add(now, odom)

    def see(self, sighting: Sighting) -> None:
        """A new sighting of the tag (placed in ``odom`` at the next :meth:`step`, which knows odometry then)."""
        self._pending.append(sighting)

    # ----------------------------------------------------------------------- estimate
    def _take_sightings(self) -> None:
        for s in self._pending:
            at = self.odom.at(s.stamp)
            goal = at.compose(s.pose).compose(self.goal_in_tag)
            lever = math.hypot(self.goal_in_tag.x, self.goal_in_tag.y)
            cov = np.asarray(s.covariance, dtype=float)
            variance = max(float(cov[0, 0] + cov[1, 1]) + lever**2 * float(cov[2, 2]), MIN_VARIANCE)
            self._estimates.append((goal, 1.0 / variance))
            self.sightings += 1
        self._pending.clear()
        if self._estimates:
            self.goal = _weighted_mean([g for g, _ in self._estimates], np.array([w for _, w in self._estimates]))

    # --------------------------------------------------------------------------- step
    def step(self, now: float, odom: Pose2, twist: Twist2 | None = None) -> Twist2:
        """One tick at ``now`` [s] with the robot at ``odom``, moving at ``twist`` (measured; None: not checked).

        Returns the command (base_link).
        """
        self.odom.add(now, odom)
        self._take_sightings()
        if self.status in (ServoStatus.SUCCEEDED, ServoStatus.FAILED):
            return Twist2()
        if self.goal is None:
            return self._search(odom)
        to_goal = odom.between(self.goal)  # the goal seen from the robot
        dist = math.hypot(to_goal.x, to_goal.y)
        if self.status is ServoStatus.ALIGN and dist > 2.0 * self.xy_tolerance:
            self.status = ServoStatus.APPROACH
        if self.status is not ServoStatus.ALIGN and dist > self.xy_tolerance:
            self.status = ServoStatus.APPROACH
            return self._approach(to_goal, dist)
        self.status = ServoStatus.ALIGN
        err = wrap_angle(to_goal.theta)
        if abs(err) <= self.yaw_tolerance:
            if twist is not None and (abs(twist.omega) > SETTLED_OMEGA or abs(twist.v) > SETTLED_V):
                self.message = f"at the goal, settling ({twist.omega:+.2f} rad/s)"
                return Twist2()
            self.status = ServoStatus.SUCCEEDED
            self.message = f"at the goal: {100 * dist:.1f} cm, {math.degrees(err):.1f}°"
            return Twist2()
        self.message = f"aligning, {math.degrees(err):.1f}° to go"
        return Twist2(0.0, self._turn(err))

    def _approach(self, to_goal: Pose2, dist: float) -> Twist2:
        bearing = math.atan2(to_goal.y, to_goal.x)
        backwards = dist <= REVERSE_RANGE and abs(bearing) > math.pi / 2
        heading_err = wrap_angle(bearing + math.pi) if backwards else bearing
        self.message = f"{100 * dist:.0f} cm to the goal{' (backwards)' if backwards else ''}"
        if abs(heading_err) > DRIVE_HEADING:
            return Twist2(0.0, self._turn(heading_err))
        v = min(self.max_v, max(K_V * dist, MIN_V)) * (-1.0 if backwards else 1.0)
        return Twist2(v, float(np.clip(K_OMEGA * heading_err, -self.max_omega, self.max_omega)))

    def _search(self, odom: Pose2) -> Twist2:
        turned = wrap_angle(odom.theta - self._search_origin)
        targets = (self.search_angle, -self.search_angle, 0.0)
        while self._search_leg < 3:
            err = targets[self._search_leg] - turned
            if abs(err) > math.radians(2.0):
                self.message = f"looking for the tag ({math.degrees(turned):+.0f}°)"
                # Proportional near the leg's end: a fixed rate would step past a narrow window for ever.
                return Twist2(0.0, self._turn(err, SEARCH_OMEGA))
            self._search_leg += 1
        self.status = ServoStatus.FAILED
        self.reason = "no_tag"
        self.message = f"no sighting of the tag within ±{math.degrees(self.search_angle):.0f}°"
        return Twist2()

    def _turn(self, err: float, limit: float | None = None) -> float:
        """Turn rate [rad/s] towards a heading error ``err`` [rad]: proportional, within MIN_OMEGA and ``limit``."""
        limit = self.max_omega if limit is None else limit
        w = float(np.clip(K_OMEGA * err, -limit, limit))
        return math.copysign(max(abs(w), MIN_OMEGA), err)


def _weighted_mean(poses: list[Pose2], weights: np.ndarray) -> Pose2:
    """Weighted mean of poses: positions averaged, headings averaged on the circle."""
    w = weights / weights.sum()
    x = float(sum(wi * p.x for wi, p in zip(w, poses, strict=True)))
    y = float(sum(wi * p.y for wi, p in zip(w, poses, strict=True)))
    c = float(sum(wi * math.cos(p.theta) for wi, p in zip(w, poses, strict=True)))
    s = float(sum(wi * math.sin(p.theta) for wi, p in zip(w, poses, strict=True)))
    return Pose2(x, y, math.atan2(s, c))
