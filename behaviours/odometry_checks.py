"""Nav2's odometry conditions: ``IsStopped`` (slow for long enough) and ``IsStuck`` (a sudden hard deceleration).

Semantics from ``nav2_behavior_tree/plugins/condition/is_stopped_condition.cpp``
and ``is_stuck_condition.cpp``, read on the wheel odometry's twist of each
tick's observation (``/robot/observation``) instead of Nav2's odometry
topic. Nav2's ``IsStuck`` sees every odometry message; homing sees one per
tick, so its acceleration is the change over a tick.
"""

from __future__ import annotations

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import OBSERVATION_KEY
from homing.behaviours.registry import Param, register
from py_trees.common import Status

BRAKE_ACCEL_LIMIT = -10.0  # [m/s²] Nav2's brake_accel_limit_: a harder deceleration means a collision


@register("IsStopped", kind="condition")
class IsStopped(HomingBehaviour):
    """RUNNING while the robot is slow, SUCCESS once it has been slow ``duration``, FAILURE while it moves: Nav2's ``IsStopped``.

    Slow: |v| [m/s] and |ω| [rad/s] both under ``velocity_threshold`` (Nav2
    compares both against the one threshold). Use it before an action that
    needs the robot at rest (docking, a measurement).
    """

    PARAMS = (
        Param("velocity_threshold", float, 0.1, doc="below this |v| [m/s] and |ω| [rad/s] the robot is slow", above=0.0),
        Param("duration", float, 1.0, "s", "how long it must stay slow", minimum=0.0),
    )
    READS = (OBSERVATION_KEY,)

    def __init__(self, name: str, velocity_threshold: float = 0.1, duration: float = 1.0):
        super().__init__(name)
        self.velocity_threshold, self.duration = velocity_threshold, duration
        self.since: float | None = None  # [s] adapter time the robot became slow

    def update(self) -> Status:
        obs = self.observation()
        if obs is None:
            self.feedback_message = "no observation"
            return Status.FAILURE
        twist = obs.odom.twist
        if abs(twist.v) >= self.velocity_threshold or abs(twist.omega) >= self.velocity_threshold:
            self.since = None
            self.feedback_message = "moving"
            return Status.FAILURE
        if self.since is None:
            self.since = obs.odom.stamp
        slow_for = self.now() - self.since
        self.feedback_message = f"slow for {slow_for:.1f} s"
        return Status.SUCCESS if slow_for > self.duration else Status.RUNNING


@register("IsStuck", kind="condition")
class IsStuck(HomingBehaviour):
    """SUCCESS when the odometry shows a deceleration harder than 10 m/s² (a bump), else FAILURE: Nav2's ``IsStuck``.

    The acceleration is the change of the odometry's forward speed between
    the last two ticks (Nav2 waits for three odometry messages before it
    estimates one). It detects collisions that stop the wheels, not a robot
    that slides or spins in place.
    """

    READS = (OBSERVATION_KEY,)

    def __init__(self, name: str):
        super().__init__(name)
        self.history: list[tuple[float, float]] = []  # (stamp [s], v [m/s]) of the last ticks, oldest first
        self.accel = 0.0  # [m/s²]

    def update(self) -> Status:
        obs = self.observation()
        if obs is not None and (not self.history or obs.odom.stamp > self.history[-1][0]):
            self.history = [*self.history[-2:], (obs.odom.stamp, obs.odom.twist.v)]
            if len(self.history) > 2:
                (t0, v0), (t1, v1) = self.history[-2], self.history[-1]
                self.accel = (v1 - v0) / (t1 - t0)
        stuck = self.accel < BRAKE_ACCEL_LIMIT
        self.feedback_message = f"acceleration {self.accel:.1f} m/s²" + (": stuck" if stuck else "")
        return Status.SUCCESS if stuck else Status.FAILURE
