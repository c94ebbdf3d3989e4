"""Conditions on the robot's devices: all present, no wheel lifted (hardware adapters report them).

A hardware adapter names the devices it has lost in
``Observation.devices_lost`` and stops the base meanwhile; these leaves let
a mission see it, e.g. as the guard of the lifecycle's Error state::

    fallback:
      - reactive_sequence: [DevicesOk, {subtree: lifecycle}]
      - sequence: [{MissionState: {state: Error}}, Stop]

Conditions answer SUCCESS or FAILURE in one tick, never RUNNING.
"""

from __future__ import annotations

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import OBSERVATION_KEY
from homing.behaviours.registry import register
from homing.robot import Observation
from py_trees.common import Status


class _ObservationCondition(HomingBehaviour):
    """A condition on this tick's observation: subclasses say whether it holds, and why."""

    READS = (OBSERVATION_KEY,)

    def check(self, obs: Observation) -> tuple[bool, str]:
        raise NotImplementedError

    def update(self) -> Status:
        obs = self.observation()
        ok, self.feedback_message = (False, "no observation yet") if obs is None else self.check(obs)
        return Status.SUCCESS if ok else Status.FAILURE


@register("DevicesOk", kind="condition")
class DevicesOk(_ObservationCondition):
    """SUCCESS while the adapter has every device (the simulator always does); FAILURE naming the lost ones."""

    def check(self, obs: Observation) -> tuple[bool, str]:
        if obs.devices_lost:
            return False, f"lost: {', '.join(obs.devices_lost)}"
        return True, "all devices present"


@register("WheelsDown", kind="condition")
class WheelsDown(_ObservationCondition):
    """SUCCESS while both wheels touch the floor; FAILURE when the base reports a wheel drop (lifted)."""

    def check(self, obs: Observation) -> tuple[bool, str]:
        if obs.switches.wheel_drop():
            return False, "wheel dropped: the robot is lifted or over an edge"
        return True, "wheels down"
