"""General leaves every mission needs: waiting, stopping, fixed outcomes, blackboard and battery checks.

They hold no algorithm (DESIGN.md): each reads the blackboard or the
adapter's clock, maybe writes the blackboard, and returns a status in one
tick. Conditions (``kind="condition"``) answer SUCCESS or FAILURE at once
and never RUNNING, so they can sit under a ``guard`` or at the head of a
``reactive_sequence``.
"""

from __future__ import annotations

import operator
from typing import Any

from homing.behaviours.base import (
    HomingBehaviour,
    LongAction,
)
from homing.behaviours.keys import CMD_VEL_KEY, OBSERVATION_KEY, STATE_KEY
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.common import Status

VALUE_TYPES = (str, int, float, bool, list)


@register("Wait")
class Wait(LongAction):
    """RUNNING until ``seconds`` of adapter time have passed since it started, then SUCCESS.

    Adapter clock (a simulated minute passes in a fraction of a real one);
    BT.CPP's ``Sleep`` counts milliseconds, homing seconds. Sends no command,
    so the robot stands still while it waits.
    """

    PARAMS = (Param("seconds", float, REQUIRED, "s", "how long to wait", minimum=0.0),)

    def __init__(self, name: str, seconds: float):
        if seconds < 0:
            raise ValueError(f"seconds must be ≥ 0, not {seconds}")
        super().__init__(name)
        self.seconds = float(seconds)  # [s]

    def on_running(self) -> Status:
        left = self.seconds - self.elapsed()
        self.feedback_message = f"{max(left, 0.0):.1f} s left"
        return Status.SUCCESS if self.has_run_for(self.seconds) else Status.RUNNING


@register("Drive")
class Drive(LongAction):
    """Drive open-loop at (v, omega) for ``seconds`` of adapter time, then SUCCESS.

    For scripted moves (back out of the dock, turn a circle to seed the map).
    Not for going somewhere: it knows nothing of obstacles; use navigation.
    """

    PARAMS = (
        Param("v", float, 0.0, "m/s", "forward speed in base_link"),
        Param("omega", float, 0.0, "rad/s", "yaw rate, counter-clockwise positive"),
        Param("seconds", float, REQUIRED, "s", "how long to drive", above=0.0),
    )
    WRITES = (CMD_VEL_KEY,)

    def __init__(self, name: str, seconds: float, v: float = 0.0, omega: float = 0.0):
        if seconds < 0:
            raise ValueError(f"seconds must be ≥ 0, not {seconds}")
        super().__init__(name)
        self.v, self.omega, self.seconds = float(v), float(omega), float(seconds)

    def on_running(self) -> Status:
        if self.has_run_for(self.seconds):
            return Status.SUCCESS
        self.drive(self.v, self.omega)
        self.feedback_message = f"v={self.v:.2f} m/s ω={self.omega:.2f} rad/s, {self.seconds - self.elapsed():.1f} s left"
        return Status.RUNNING


@register("Stop")
class Stop(HomingBehaviour):
    """Command zero velocity this tick and SUCCEED (the runner already sends zero when nobody drives)."""

    WRITES = (CMD_VEL_KEY,)

    def update(self) -> Status:
        self.drive(0.0, 0.0)
        return Status.SUCCESS


@register("Succeed")
class Succeed(HomingBehaviour):
    """Always SUCCESS (BT.CPP ``AlwaysSuccess``, py_trees ``Success``)."""

    def update(self) -> Status:
        return Status.SUCCESS


@register("Fail")
class Fail(HomingBehaviour):
    """Always FAILURE (BT.CPP ``AlwaysFailure``, py_trees ``Failure``)."""

    def update(self) -> Status:
        return Status.FAILURE


@register("Running")
class Running(HomingBehaviour):
    """Always RUNNING: a placeholder that never ends (py_trees ``Running``)."""

    def update(self) -> Status:
        return Status.RUNNING


@register("SetBlackboard")
class SetBlackboard(HomingBehaviour):
    """Write ``value`` to the blackboard ``key`` and SUCCEED (BT.CPP ``SetBlackboard``)."""

    PARAMS = (
        Param("key", str, REQUIRED, doc="absolute blackboard key, e.g. /mission/goal_count"),
        Param("value", VALUE_TYPES, REQUIRED, doc="the value to write"),
    )
    WRITES = ("$key",)

    def __init__(self, name: str, key: str, value: Any):
        self.key = key
        super().__init__(name)
        self.value = value

    def update(self) -> Status:
        self.write(self.key, self.value)
        return Status.SUCCESS


@register("Increment")
class Increment(HomingBehaviour):
    """Add ``by`` to the integer at blackboard ``key`` (0 if unset) and SUCCEED: a counter the mission keeps.

    The persistent mission counts its dock cycles with it (``/mission/cycles``).
    """

    PARAMS = (
        Param("key", str, REQUIRED, doc="absolute blackboard key, e.g. /mission/cycles"),
        Param("by", int, 1, doc="how much to add"),
    )
    READS = ("$key",)
    WRITES = ("$key",)

    def __init__(self, name: str, key: str, by: int = 1):
        self.key = key
        super().__init__(name)
        self.by = int(by)

    def setup(self, **kwargs: Any) -> None:
        """An unset counter starts at 0 (so the view shows it before its first count; a resumed one is kept)."""
        super().setup(**kwargs)
        if self.read(self.key) is None:
            self.write(self.key, 0)

    def update(self) -> Status:
        value = self.read(self.key, 0)
        if not isinstance(value, int) or isinstance(value, bool):
            self.feedback_message = f"{self.key} holds {value!r}, not an integer"
            return Status.FAILURE
        self.write(self.key, value + self.by)
        self.feedback_message = f"{self.key} = {value + self.by}"
        return Status.SUCCESS


_OPS = {
    "==": operator.eq,
    "!=": operator.ne,
    "<": operator.lt,
    "<=": operator.le,
    ">": operator.gt,
    ">=": operator.ge,
}


@register("CheckBlackboard", kind="condition")
class CheckBlackboard(HomingBehaviour):
    """SUCCESS if blackboard ``key`` compares true against ``value`` with ``op``; FAILURE otherwise or if unset.

    ``op: exists`` ignores ``value`` and only asks whether the key is set
    (py_trees ``CheckBlackboardVariableExists``).
    """

    PARAMS = (
        Param("key", str, REQUIRED, doc="absolute blackboard key"),
        Param("op", str, "==", doc="comparison", choices=(*_OPS, "exists")),
        Param("value", VALUE_TYPES, None, doc="right-hand side of the comparison"),
    )
    READS = ("$key",)

    def __init__(self, name: str, key: str, op: str = "==", value: Any = None):
        if op not in _OPS and op != "exists":
            raise ValueError(f"op must be one of {', '.join([*_OPS, 'exists'])}, not {op!r}")
        self.key = key
        super().__init__(name)
        self.op, self.value = op, value

    def update(self) -> Status:
        missing = object()
        current = self.read(self.key, missing)
        if current is missing:
            self.feedback_message = f"{self.key} is not set"
            return Status.FAILURE
        if self.op == "exists":
            return Status.SUCCESS
        try:
            ok = bool(_OPS[self.op](current, self.value))
        except TypeError:
            ok = False
        self.feedback_message = f"{self.key}={current!r} {self.op} {self.value!r}: {ok}"
        return Status.SUCCESS if ok else Status.FAILURE


class _BatteryCondition(HomingBehaviour):
    PARAMS = (
        Param("percent", float, REQUIRED, "%", "threshold, 0..100", minimum=0.0, maximum=100.0),
        Param("battery", str, "base", doc="which battery: the Kobuki base or the on-board computer", choices=("base", "computer")),
    )
    READS = (OBSERVATION_KEY,)
    ABOVE = True

    def __init__(self, name: str, percent: float, battery: str = "base"):
        if not 0.0 <= percent <= 100.0:
            raise ValueError(f"percent must be within 0..100, not {percent}")
        if battery not in ("base", "computer"):
            raise ValueError(f"battery must be 'base' or 'computer', not {battery!r}")
        super().__init__(name)
        self.percent, self.battery = float(percent), battery

    def update(self) -> Status:
        obs = self.observation()
        state = None if obs is None else (obs.battery if self.battery == "base" else obs.computer_battery)
        if state is None:
            self.feedback_message = f"no {self.battery} battery reading"
            return Status.FAILURE
        ok = state.percent > self.percent if self.ABOVE else state.percent < self.percent
        self.feedback_message = f"{self.battery} battery {state.percent:.0f} % {'>' if self.ABOVE else '<'} {self.percent:g} %: {ok}"
        return Status.SUCCESS if ok else Status.FAILURE


@register("BatteryAbove", kind="condition")
class BatteryAbove(_BatteryCondition):
    """SUCCESS while the battery's percentage is strictly above ``percent`` (reads /robot/observation)."""

    ABOVE = True


@register("BatteryBelow", kind="condition")
class BatteryBelow(_BatteryCondition):
    """SUCCESS while the battery's percentage is strictly below ``percent`` (Nav2 ``IsBatteryLow``)."""

    ABOVE = False


@register("BatteryCharging", kind="condition")
class BatteryCharging(HomingBehaviour):
    """SUCCESS while the base battery is charging, on the dock or an adapter (Nav2 ``IsBatteryCharging``; reads /robot/observation)."""

    READS = (OBSERVATION_KEY,)

    def update(self) -> Status:
        obs = self.observation()
        charging = obs is not None and obs.battery.charging
        self.feedback_message = "charging" if charging else "not charging"
        return Status.SUCCESS if charging else Status.FAILURE


@register("MissionState")
class MissionState(HomingBehaviour):
    """Write the lifecycle state shown in the view (``/mission/state``) and SUCCEED."""

    PARAMS = (Param("state", str, REQUIRED, doc="e.g. Docked, Undocking, Exploring, MapHome, AutoDocking, Error"),)
    WRITES = (STATE_KEY,)

    def __init__(self, name: str, state: str):
        super().__init__(name)
        self.state = state

    def update(self) -> Status:
        self.write(STATE_KEY, self.state)
        self.feedback_message = self.state
        return Status.SUCCESS
