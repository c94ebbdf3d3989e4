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
from py_trees.common import Status


@register("DevicesOk", kind="condition")
class DevicesOk(HomingBehaviour):
    """SUCCESS while the adapter has every device (the simulator always does); FAILURE naming the lost ones."""

    READS = (OBSERVATION_KEY,)

    def update(self) -> Status:
        obs = self.observation()
        if obs is None:
            self.feedback_message = "no observation yet"
            return Status.FAILURE
        if obs.devices_lost:
            self.feedback_message = f"lost: {', '.join(obs.devices_lost)}"
            return Status.FAILURE
        self.feedback_message = "all devices present"
        return Status.SUCCESS


@register("WheelsDown", kind="condition")
class WheelsDown(HomingBehaviour):
    """SUCCESS while both wheels touch the floor; FAILURE when the base reports a wheel drop (lifted)."""

    READS = (OBSERVATION_KEY,)

    def update(self) -> Status:
        obs = self.observation()
        if obs is None:
            self.feedback_message = "no observation yet"
            return Status.FAILURE
        if obs.switches.wheel_drop():
            self.feedback_message = "wheel dropped: the robot is lifted or over an edge"
            return Status.FAILURE
        self.feedback_message = "wheels down"
        return Status.SUCCESS
