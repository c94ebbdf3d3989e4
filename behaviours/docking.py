"""Lifecycle leaves: leave the dock, go home, servo on the dock's tag, IR-dock, charge (thesis §3.3).

Thin by design: :class:`Undock` runs two :mod:`homing.navigation.recovery`
motions (back out, turn a full circle to seed the costmap);
:class:`GoHome` is :class:`~homing.behaviours.motion.NavigateToPose` to the
staging pose in front of the dock the navigation service knows
(``/nav/dock``); :class:`ServoToStaging` feeds the dock tag's sightings
(``/perception/tags``) to :class:`homing.navigation.tag_servo.TagServo`;
:class:`AutoDock` feeds the IR receivers, bumpers and charger to
:class:`homing.navigation.dock_drive.DockDrive`; :class:`Charge` waits on the
dock, telling the runner that nothing needs a tick meanwhile
(``/runner/idle_until``). Failures are typed (``failure_reason``, also written
to ``failure_key``) so the mission can branch on them: ``no_home``,
``no_tag``, ``no_signal``, ``bumped``, ``not_docked``, ``still_docked``,
``blocked``, ``timed_out``, and the navigation reasons of ``GoHome``.
"""

from __future__ import annotations

import math
from typing import Any

from homing.behaviours.base import TIMEOUT_PARAM, HomingBehaviour
from homing.behaviours.energy_service import STAGING_DISTANCE, not_yet_charged, staging_pose
from homing.behaviours.keys import (
    CMD_VEL_KEY,
    DOCK_KEY,
    ENERGY_KEY,
    FOCUS_KEY,
    IDLE_KEY,
    NAVIGATOR_KEY,
    OBSERVATION_KEY,
    SAVE_KEY,
    STAGED_KEY,
    TAGS_KEY,
)
from homing.behaviours.motion import FAILURE_KEY, FAILURE_PARAM, NavigateToPose, _ReportsFailure
from homing.behaviours.registry import REQUIRED, Param, register
from homing.navigation.dock_drive import SERVOED_SLOW_ZONE, SLOW_ZONE, DockDrive, DockState
from homing.navigation.recovery import BackUp as BackUpMotion
from homing.navigation.recovery import MotionStatus
from homing.navigation.recovery import Spin as SpinMotion
from homing.navigation.tag_servo import (
    SEARCH_ANGLE,
    XY_TOLERANCE,
    YAW_TOLERANCE,
    ServoStatus,
    Sighting,
    TagServo,
    staging_in_tag,
)
from homing.robot import ChargingSource, Observation, Pose2
from homing.robot.frames import wrap_angle
from py_trees.common import Status

CHARGE_POLL = 10.0  # [s] adapter time between looks at the batteries while charging
REST_POLL = 60.0  # [s] adapter time between looks at the charger while resting between rounds
FOCUS_AHEAD = 0.5  # [s] the servo asks for every camera frame this far ahead, renewed every tick
STAGED_XY = 0.03  # [m] AutoDock starts where the tag servo left the robot if odometry has moved less than this
STAGED_YAW = math.radians(3.0)  # [rad] and turned less than this


def on_dock(obs: Observation | None) -> bool:
    """Whether the base reports charge coming from the dock (the contacts are closed)."""
    return obs is not None and obs.battery.source is ChargingSource.DOCK


def _positive(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be positive, not {value}")
    return float(value)


@register("IsDocked", kind="condition")
class IsDocked(HomingBehaviour):
    """SUCCESS while the base reports charge coming from the dock (charging or full), FAILURE otherwise.

    Judged by the charger, not by a pose: a robot 3 mm off its contacts is not docked.
    """

    READS = (OBSERVATION_KEY,)

    def update(self) -> Status:
        docked = on_dock(self.observation())
        self.feedback_message = "on the dock" if docked else "not on the dock"
        return Status.SUCCESS if docked else Status.FAILURE


@register("Undock")
class Undock(_ReportsFailure):
    """Back straight out of the dock ``distance``, then turn ``turn`` on the spot to seed the costmap all round.

    Fails with ``still_docked`` if the charger still reports the dock after
    backing out, ``blocked`` if the scan shows something behind, ``timed_out``.
    """

    PARAMS = (
        Param("distance", float, 0.4, "m", "how far to back out", above=0.0),
        Param("speed", float, 0.1, "m/s", "backing speed", above=0.0),
        Param("turn", float, 2 * math.pi, "rad", "turn on the spot afterwards (0: none)", minimum=0.0),
        Param("omega", float, 0.8, "rad/s", "turning speed", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, NAVIGATOR_KEY)
    WRITES = (CMD_VEL_KEY, "$failure_key")

    def __init__(self, name: str, distance: float = 0.4, speed: float = 0.1, turn: float = 2 * math.pi,
                 omega: float = 0.8, timeout: float = 60.0, failure_key: str = FAILURE_KEY) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout)
        self.distance, self.speed = _positive("distance", distance), _positive("speed", speed)
        self.turn, self.omega = float(turn), _positive("omega", omega)
        self.motion: Any = None
        self.phase = ""

    def on_start(self) -> Status | None:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        self.phase = "back"
        self.motion = BackUpMotion(self.distance, self.speed, time_allowance=self.distance / self.speed + 10.0)
        self.motion.start(obs.stamp, obs.odom.pose)
        return None

    def on_running(self) -> Status:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        nav = self.read(NAVIGATOR_KEY)
        pts = nav.scan_points_now(obs) if nav is not None else (obs.scan.points() if obs.scan else None)
        status, cmd = self.motion.step(obs.stamp, obs.odom.pose, pts)
        self.drive(cmd.v, cmd.omega)
        self.feedback_message = f"{self.phase}: {self.motion.message}"
        if status is MotionStatus.FAILED:
            return self.fail("blocked" if "obstacle" in self.motion.message else "timed_out", self.motion.message)
        if status is MotionStatus.RUNNING:
            return Status.RUNNING
        if self.phase == "back":
            if on_dock(obs):
                return self.fail("still_docked", "backed out but the charger still reports the dock")
            if abs(self.turn) < 1e-9:
                return Status.SUCCESS
            self.phase = "turn"
            self.motion = SpinMotion(self.turn, self.omega, time_allowance=abs(self.turn) / self.omega + 20.0)
            self.motion.start(obs.stamp, obs.odom.pose)
            return Status.RUNNING
        return Status.SUCCESS


@register("GoHome")
class GoHome(NavigateToPose):
    """Navigate to the staging pose ``staging_distance`` in front of the dock (``/nav/dock``), facing it.

    The dock's pose in ``map`` is the one the navigation service recorded the
    last time the base charged on it; FAILURE ``no_home`` if it never has.
    The map may have drifted since: :class:`ServoToStaging` corrects on the tag.
    """

    PARAMS = (
        Param("staging_distance", float, STAGING_DISTANCE, "m", "how far in front of the docked pose", above=0.0),
        *(p for p in NavigateToPose.PARAMS if p.name not in ("x", "y", "theta", "goal_key")),
    )
    READS = (*NavigateToPose.READS, DOCK_KEY)

    def __init__(self, name: str, staging_distance: float = STAGING_DISTANCE, **kwargs: Any) -> None:
        super().__init__(name, **kwargs)
        self.staging_distance = _positive("staging_distance", staging_distance)

    def on_start(self) -> Status | None:
        dock = self.read(DOCK_KEY)
        if dock is None:
            self.navigator = None
            return self.fail("no_home", "no dock known (the robot has never charged on one)")
        goal = staging_pose(dock, self.staging_distance)
        self.x, self.y, self.theta = goal.x, goal.y, goal.theta
        return super().on_start()


@register("ServoToStaging")
class ServoToStaging(_ReportsFailure):
    """Servo to the staging pose from sightings of the dock's tag (thesis §3.3.5); SUCCESS there, facing the dock.

    Looks for the tag by sweeping ±``search_angle`` when it is not in view;
    FAILURE ``no_tag`` when the sweep finds nothing. Reads the tags the
    ``tag_slam`` service measured this tick (``/perception/tags``).
    """

    PARAMS = (
        Param("tag", int, 0, "", "id of the tag above the dock", minimum=0),
        Param("staging_distance", float, STAGING_DISTANCE, "m", "how far in front of the docked pose", above=0.0),
        Param("xy_tolerance", float, XY_TOLERANCE, "m", "reached within this distance", above=0.0),
        Param("yaw_tolerance", float, YAW_TOLERANCE, "rad", "and this heading error", above=0.0),
        Param("search_angle", float, SEARCH_ANGLE, "rad", "sweep this far each way to find the tag", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, TAGS_KEY)
    WRITES = (CMD_VEL_KEY, FOCUS_KEY, STAGED_KEY, "$failure_key")

    def __init__(self, name: str, tag: int = 0, staging_distance: float = STAGING_DISTANCE,
                 xy_tolerance: float = XY_TOLERANCE, yaw_tolerance: float = YAW_TOLERANCE,
                 search_angle: float = SEARCH_ANGLE, timeout: float = 60.0,
                 failure_key: str = FAILURE_KEY) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout)
        self.tag = int(tag)
        self.servo = TagServo(staging_in_tag(_positive("staging_distance", staging_distance)),
                              _positive("xy_tolerance", xy_tolerance), _positive("yaw_tolerance", yaw_tolerance),
                              search_angle=_positive("search_angle", search_angle))

    def on_start(self) -> Status | None:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        self.servo.start(obs.stamp, obs.odom.pose)
        self.write(STAGED_KEY, None)
        return None

    def on_running(self) -> Status:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        self.write(FOCUS_KEY, obs.stamp + FOCUS_AHEAD)  # every frame counts while servoing
        for m in self.read(TAGS_KEY) or ():
            if m.tag_id == self.tag:
                self.servo.see(Sighting(m.stamp, m.pose, m.covariance))
        cmd = self.servo.step(obs.stamp, obs.odom.pose, obs.odom.twist)
        self.drive(cmd.v, cmd.omega)
        self.feedback_message = f"{self.servo.message} ({self.servo.sightings} sightings)"
        if self.servo.status is ServoStatus.SUCCEEDED:
            self.write(STAGED_KEY, obs.odom.pose)  # AutoDock trusts its approach distance from here
            return Status.SUCCESS
        if self.servo.status is ServoStatus.FAILED:
            return self.fail(self.servo.reason or "failed", self.servo.message)
        return Status.RUNNING


@register("AutoDock")
class AutoDock(_ReportsFailure):
    """IR docking after kobuki's dock_drive (:mod:`homing.navigation.dock_drive`); SUCCESS once the base charges.

    Start it on the staging pose. Docked means the charger says so, held for
    a moment, never a pose. FAILURE ``no_signal`` (the dock's IR is not seen),
    ``bumped`` (pressed into something ``max_bumps`` times), ``timed_out``.
    """

    PARAMS = (
        Param("max_bumps", int, 3, "", "bumper presses before the attempt fails", minimum=1),
        Param("approach", float, 0.0, "m", "it starts on the staging pose this far from the docked pose, facing "
              "the dock: drive in faster until 0.3 m out, 0.2 m if the tag servo has just put it there (0: unknown, "
              "kobuki's speeds)", minimum=0.0, maximum=3.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY,)
    OPTIONAL_READS = (STAGED_KEY,)  # written by ServoToStaging, if the tree has one
    WRITES = (CMD_VEL_KEY, "$failure_key")

    def __init__(self, name: str, max_bumps: int = 3, approach: float = 0.0, timeout: float = 120.0,
                 failure_key: str = FAILURE_KEY) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout)
        if max_bumps < 1:
            raise ValueError(f"max_bumps must be ≥ 1, not {max_bumps}")
        if not 0.0 <= approach <= 3.0:
            raise ValueError(f"approach must be within [0, 3] m, not {approach}")
        self.approach = float(approach)  # [m]
        self.dock_drive = DockDrive(max_bumps=max_bumps)

    def on_start(self) -> Status | None:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        self.dock_drive.start(obs.stamp, obs.odom.pose, self.approach, self._slow_zone(obs.odom.pose))
        return None

    def _slow_zone(self, odom: Pose2) -> float:
        """SERVOED_SLOW_ZONE if the robot stands where the tag servo left it on the staging pose, else SLOW_ZONE."""
        staged = self.read(STAGED_KEY)
        if staged is None:
            return SLOW_ZONE
        moved = staged.between(odom)
        servoed = math.hypot(moved.x, moved.y) <= STAGED_XY and abs(wrap_angle(moved.theta)) <= STAGED_YAW
        return SERVOED_SLOW_ZONE if servoed else SLOW_ZONE

    def on_running(self) -> Status:
        obs = self.observation()
        if obs is None:
            return self.fail("no_observation")
        dd = self.dock_drive
        cmd = dd.step(obs.stamp, obs.dock_ir, obs.bumpers, on_dock(obs), obs.odom.pose)
        self.drive(cmd.v, cmd.omega)
        self.feedback_message = f"{dd.state.value}: {dd.message}"
        if dd.state is DockState.DONE:
            return Status.SUCCESS
        if dd.state.finished:
            return self.fail(dd.reason or "failed", dd.message)
        return Status.RUNNING


class _OnDock(_ReportsFailure):
    """A leaf that waits on the charger, looking every ``poll`` [s]; FAILURE ``not_docked`` once off it."""

    def __init__(self, name: str, poll: float, timeout: float, failure_key: str) -> None:
        self.failure_key = failure_key
        super().__init__(name, timeout=timeout)
        self.poll = _positive("poll", poll)

    def docked(self) -> Observation | None:
        """This tick's observation while the charger reports the dock, else None (and the failure recorded)."""
        obs = self.observation()
        if not on_dock(obs):
            self.fail("not_docked", "the charger no longer reports the dock")
            return None
        return obs


@register("Charge")
class Charge(_OnDock):
    """Stay on the dock until every battery reaches its undock level (``/energy/policy``) or reports full.

    Sends no command. Between looks at the batteries (every ``poll`` [s])
    it tells the runner the tree has nothing to do (``/runner/idle_until``),
    so a docked robot costs almost nothing to tick or simulate. FAILURE
    ``not_docked`` if the charger stops reporting the dock.
    """

    PARAMS = (
        Param("poll", float, CHARGE_POLL, "s", "adapter time between looks at the batteries", above=0.0),
        FAILURE_PARAM,
        TIMEOUT_PARAM,
    )
    READS = (OBSERVATION_KEY, ENERGY_KEY)
    WRITES = (IDLE_KEY, "$failure_key")

    def __init__(self, name: str, poll: float = CHARGE_POLL, timeout: float = 0.0,
                 failure_key: str = FAILURE_KEY) -> None:
        super().__init__(name, poll, timeout, failure_key)

    def on_running(self) -> Status:
        obs = self.docked()
        if obs is None:
            return Status.FAILURE
        policy = self.read(ENERGY_KEY) or {}
        waiting = not_yet_charged(policy, obs)
        if policy and not waiting:
            self.feedback_message = "charged"
            return Status.SUCCESS
        self.feedback_message = "charging: " + ", ".join(waiting) if waiting else "waiting for the energy policy"
        self.write(IDLE_KEY, obs.stamp + self.poll)
        return Status.RUNNING


@register("Rest")
class Rest(_OnDock):
    """Stay on the dock for ``seconds`` of adapter time, then SUCCEED: the robot waits for its next round.

    A robot that has mapped its whole building has nothing new to find: it
    goes out for a patrol round now and then (``missions/persistent.yaml``)
    and spends the time between on its charger, as a security or inventory
    robot does between rounds. Sends no command; between looks at the
    charger (every ``poll`` [s]) it tells the runner the tree has nothing to
    do (``/runner/idle_until``), so a resting robot costs almost nothing to
    simulate. FAILURE ``not_docked`` if the charger stops reporting the dock
    (someone lifted the robot off it).
    """

    PARAMS = (
        Param("seconds", float, REQUIRED, "s", "how long to stay", minimum=0.0),
        Param("poll", float, REST_POLL, "s", "adapter time between looks at the charger", above=0.0),
        FAILURE_PARAM,
    )
    READS = (OBSERVATION_KEY,)
    WRITES = (IDLE_KEY, "$failure_key")

    def __init__(self, name: str, seconds: float, poll: float = REST_POLL, failure_key: str = FAILURE_KEY) -> None:
        if not (math.isfinite(seconds) and seconds >= 0):
            raise ValueError(f"seconds must be ≥ 0, not {seconds}")
        super().__init__(name, poll, 0.0, failure_key)
        self.seconds = float(seconds)  # [s]

    def on_running(self) -> Status:
        obs = self.docked()
        if obs is None:
            return Status.FAILURE
        left = self.seconds - self.elapsed()
        if self.has_run_for(self.seconds):
            self.feedback_message = "rested"
            return Status.SUCCESS
        self.feedback_message = f"resting: next round in {left / 60.0:.0f} min"
        self.write(IDLE_KEY, obs.stamp + min(left, self.poll))
        return Status.RUNNING


@register("SaveRun")
class SaveRun(HomingBehaviour):
    """Ask the runner to save a snapshot to the run directory after this tick (``/runner/save``) and SUCCEED.

    What is kept (the map, the tags' estimates, the counters, the dock) and
    where is the runner's business (``homing run --run-dir``,
    :mod:`homing.lifecycle.rundir`); without a run directory it does nothing.
    The persistent mission saves at every dock.
    """

    WRITES = (SAVE_KEY,)

    def update(self) -> Status:
        self.write(SAVE_KEY, True)
        self.feedback_message = "snapshot requested"
        return Status.SUCCESS
