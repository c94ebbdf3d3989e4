"""Decorators that decide *when* to tick their child: Nav2's rate, distance and speed controllers and BT.CPP's ``Delay``.

All on the adapter's clock (DESIGN.md, one clock). The three Nav2
controllers share one pattern (``nav2_behavior_tree/plugins/decorator/``):
the child is ticked on the decorator's first tick, on every tick while it
runs, and again each time the trigger fires (a period has passed, the robot
has moved far enough); in between the decorator returns RUNNING without
ticking it. That RUNNING is what a ``pipeline_sequence`` expects from a
replanning branch: it lets the walk go on to the controller. (homing's
``rate_limit`` replays the child's last status instead, which suits a
``reactive_sequence``.) A decorator that is halted, or reset by its parent,
starts over with a tick of its child.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np
import py_trees
from homing.behaviours.decorators import _Clock
from homing.behaviours.keys import OBSERVATION_KEY, POSE_KEY
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status


def changed(old: Any, new: Any) -> bool:
    """Whether a blackboard value changed: a new object that is not equal (arrays compared element-wise)."""
    if old is new:
        return False
    try:
        return not bool(np.array_equal(old, new)) if isinstance(old, np.ndarray) or isinstance(new, np.ndarray) else old != new
    except (TypeError, ValueError):
        return True


class _Trigger(_Clock, py_trees.decorators.Decorator):
    """Nav2's controller pattern: tick the child first, while it runs, and when :meth:`fired`; else RUNNING."""

    def __init__(self, name: str, child: Behaviour):
        super().__init__(name=name, child=child)
        self.first = True

    def restart(self) -> None:
        """A new activation (the decorator was idle): reset the trigger."""

    def fired(self) -> bool:
        """Whether the trigger has fired since the child last succeeded."""
        return False

    def succeeded(self) -> None:
        """The child has just succeeded: re-arm the trigger."""

    def update(self) -> Status:
        return self.decorated.status

    def tick(self) -> Iterator[Behaviour]:
        if self.status == Status.INVALID:
            self.first = True
            self.restart()
        if self.first or self.decorated.status == Status.RUNNING or self.fired():
            self.first = False
            yield from self.decorated.tick()
            status = self.decorated.status
            if status == Status.SUCCESS:
                self.succeeded()
            if status == Status.RUNNING:
                self.status = Status.RUNNING
            else:
                self.stop(status)
        else:
            self.status = Status.RUNNING
        yield self


@register(
    "rate_controller",
    kind="decorator",
    params=(Param("hz", float, REQUIRED, "Hz", "tick the child again this often after it succeeds"),),
)
class RateController(_Trigger):
    """Tick the child at most ``hz`` times a second, RUNNING in between: Nav2's ``RateController``.

    The child is ticked on the first tick, on every tick while it runs, and
    again once ``1/hz`` seconds have passed since it last succeeded (or since
    the decorator started); the decorator returns the child's status when it
    ticks it and RUNNING otherwise. Nav2's replanning at 1 Hz under a
    ``pipeline_sequence``. A failure does not re-arm the timer, as in Nav2.
    """

    def __init__(self, name: str, child: Behaviour, hz: float):
        if not hz > 0:
            raise ValueError(f"hz must be > 0, not {hz}")
        super().__init__(name=name, child=child)
        self.period = 1.0 / float(hz)  # [s]
        self.start = 0.0  # [s] adapter clock: the decorator's start or the child's last success

    PORT_PARAMS = ("hz",)

    def set_port(self, name: str, value: Any) -> None:
        if not value > 0:
            raise ValueError(f"hz must be > 0, not {value}")
        self.period = 1.0 / float(value)

    def restart(self) -> None:
        self.start = self.now()

    def fired(self) -> bool:
        left = self.period - (self.now() - self.start)
        self.feedback_message = "" if left <= 0 else f"next tick in {left:.2f} s"
        return left <= 0

    def succeeded(self) -> None:
        self.start = self.now()


class _PoseReader:
    """Reads the robot's pose in ``map`` (``/map/pose``) through a blackboard client."""

    def _attach_pose(self, name: str) -> None:
        self.bb = py_trees.blackboard.Client(name=name)
        self.bb.register_key(key=POSE_KEY, access=Access.READ)

    def pose(self) -> Any:
        try:
            return self.bb.get(POSE_KEY)
        except KeyError:
            return None


@register(
    "distance_controller",
    kind="decorator",
    params=(Param("distance", float, REQUIRED, "m", "tick the child again after the robot moved this far"),),
    reads=(POSE_KEY,),
)
class DistanceController(_PoseReader, _Trigger):
    """Tick the child again each time the robot has moved ``distance`` metres, RUNNING in between: Nav2's ``DistanceController``.

    Straight-line distance in ``map`` (``/map/pose``) from where the child
    last succeeded (or where the decorator started); ticked first, and on
    every tick while it runs. FAILURE when there is no pose yet, as Nav2
    fails without a transform.
    """

    def __init__(self, name: str, child: Behaviour, distance: float):
        if not distance > 0:
            raise ValueError(f"distance must be > 0, not {distance}")
        super().__init__(name=name, child=child)
        self.distance = float(distance)  # [m]
        self.anchor: Any = None  # Pose2 in map
        self._attach_pose(name)

    def tick(self) -> Iterator[Behaviour]:
        if self.pose() is None:
            self.feedback_message = f"no robot pose at {POSE_KEY}"
            self.stop(Status.FAILURE)
            yield self
            return
        yield from super().tick()

    def restart(self) -> None:
        self.anchor = self.pose()

    def fired(self) -> bool:
        pose = self.pose()
        moved = math.hypot(pose.x - self.anchor.x, pose.y - self.anchor.y)
        self.feedback_message = f"moved {moved:.2f} of {self.distance:g} m"
        return moved >= self.distance

    def succeeded(self) -> None:
        self.anchor = self.pose()


@register(
    "speed_controller",
    kind="decorator",
    params=(
        Param("min_rate", float, 0.1, "Hz", "rate at min_speed and below"),
        Param("max_rate", float, 1.0, "Hz", "rate at max_speed and above"),
        Param("min_speed", float, 0.0, "m/s", "speed of the slowest rate"),
        Param("max_speed", float, 0.5, "m/s", "speed of the fastest rate"),
        Param("filter_duration", float, 0.3, "s", "odometry speed averaged over this long"),
        Param("goal_key", str, "", doc="restart the period when the value at this key changes ('' = never)"),
    ),
    reads=(OBSERVATION_KEY, "$goal_key"),
)
class SpeedController(_Trigger):
    """Tick the child at a rate that grows with the robot's speed, RUNNING in between: Nav2's ``SpeedController``.

    The period is re-chosen each time it runs out, from the odometry speed
    averaged over ``filter_duration``: ``min_rate`` at ``min_speed`` and
    below, ``max_rate`` at ``max_speed`` and above, linear between (Nav2's
    ``getScaledRate``). As in Nav2 the child is ticked first, on every tick
    while it runs, and when the period has run out; with ``goal_key`` a new
    goal restarts the period with a tick at once (Nav2 watches ``{goal}``).
    """

    def __init__(self, name: str, child: Behaviour, min_rate: float = 0.1, max_rate: float = 1.0,
                 min_speed: float = 0.0, max_speed: float = 0.5, filter_duration: float = 0.3,
                 goal_key: str = ""):  # fmt: skip
        if not 0 < min_rate <= max_rate:
            raise ValueError(f"rates must satisfy 0 < min_rate ≤ max_rate, not {min_rate} and {max_rate}")
        if not 0 <= min_speed <= max_speed:
            raise ValueError(f"speeds must satisfy 0 ≤ min_speed ≤ max_speed, not {min_speed} and {max_speed}")
        super().__init__(name=name, child=child)
        self.min_rate, self.max_rate = float(min_rate), float(max_rate)  # [Hz]
        self.min_speed, self.max_speed = float(min_speed), float(max_speed)  # [m/s]
        self.filter_duration = float(filter_duration)  # [s]
        self.goal_key = goal_key
        self.period = 1.0 / self.max_rate  # [s]
        self.start = 0.0  # [s] adapter clock
        self.speeds: deque[tuple[float, float]] = deque()  # (stamp [s], speed [m/s])
        self.goal: Any = None
        self._speed = 0.0  # [m/s] filtered, this tick
        self.bb = self.attach_blackboard_client(name=name)
        self.bb.register_key(key=OBSERVATION_KEY, access=Access.READ)
        if goal_key:
            self.bb.register_key(key=goal_key, access=Access.READ)

    def rate(self, speed: float) -> float:
        """Nav2's scaled rate [Hz] for a speed [m/s]."""
        if speed < self.min_speed or self.max_speed == self.min_speed:
            return self.min_rate
        if speed > self.max_speed:
            return self.max_rate
        return self.min_rate + (speed - self.min_speed) * (self.max_rate - self.min_rate) / (self.max_speed - self.min_speed)

    def _read(self, key: str) -> Any:
        try:
            return self.bb.get(key)
        except KeyError:
            return None

    def _filtered_speed(self) -> float:
        obs = self._read(OBSERVATION_KEY)
        if obs is not None and (not self.speeds or self.speeds[-1][0] < obs.stamp):
            self.speeds.append((float(obs.stamp), abs(obs.odom.twist.v)))
        while self.speeds and self.speeds[0][0] < self.now() - self.filter_duration:
            self.speeds.popleft()
        return sum(v for _, v in self.speeds) / len(self.speeds) if self.speeds else 0.0

    def tick(self) -> Iterator[Behaviour]:
        speed = self._filtered_speed()
        if self.goal_key:
            goal = self._read(self.goal_key)
            if changed(self.goal, goal):
                self.goal = goal
                if self.status != Status.INVALID:
                    self.first = True
                    self.start = self.now()
        self._speed = speed
        yield from super().tick()

    def restart(self) -> None:
        self.start = self.now()

    def fired(self) -> bool:
        if self.now() - self.start < self.period:
            return False
        self.period = 1.0 / self.rate(self._speed)
        self.start = self.now()
        self.feedback_message = f"{self._speed:.2f} m/s → every {self.period:.2f} s"
        return True


@register(
    "delay",
    kind="decorator",
    params=(Param("seconds", float, REQUIRED, "s", "wait this long before ticking the child"),),
)
class Delay(_Clock, py_trees.decorators.Decorator):
    """RUNNING for ``seconds`` after it starts, then tick the child and return its status: BT.CPP ``Delay``.

    Adapter clock, seconds (BT.CPP's ``delay_msec`` counts milliseconds).
    The delay restarts each time the decorator starts again (after the child
    finished, or after a halt). With ``seconds: 0`` the child is ticked on
    the first tick (BT.CPP's timer always costs one tick).
    """

    def __init__(self, name: str, child: Behaviour, seconds: float):
        if seconds < 0:
            raise ValueError(f"seconds must be ≥ 0, not {seconds}")
        super().__init__(name=name, child=child)
        self.seconds = float(seconds)  # [s]
        self.start = 0.0  # [s] adapter clock

    def update(self) -> Status:
        return self.decorated.status

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.start = self.now()
            self.initialise()
        left = self.seconds - (self.now() - self.start)
        if left > 0 and self.decorated.status != Status.RUNNING:
            self.feedback_message = f"{left:.1f} s to wait"
            self.status = Status.RUNNING
            yield self
            return
        self.feedback_message = ""
        yield from self.decorated.tick()
        status = self.decorated.status
        if status == Status.RUNNING:
            self.status = Status.RUNNING
        else:
            self.stop(status)
        yield self
