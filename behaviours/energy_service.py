"""The ``energy`` service and its conditions: go-home levels that grow with the way home (:mod:`homing.lifecycle.energy`).

Glue only: every tick the service reads both batteries from the observation
and feeds their drains; every ``period`` [s] of adapter time it measures the
planned travel distance from the robot to the staging pose in front of the
dock (fast marching from the staging pose over the navigation service's
costmap, so a wall between the robot and its dock counts) and writes:

- ``/energy/policy``: per battery (``base``, ``computer``) its ``percent``,
  ``undock`` and ``home`` thresholds and the ``reserve`` [%] the way home needs;
- ``/energy/distance_home`` [m].

Where the dock is comes from the navigation service (``/nav/dock``). Before
the robot has a way home (no dock known, or it lies beyond the costmap) the
distance is the straight line times ``detour``.

Conditions: :class:`EnoughEnergy` (every battery above home + reserve: the
guard that preempts exploration) and :class:`Charged` (every battery at its
undock level or full: time to leave the dock).
"""

from __future__ import annotations

import math
from typing import Any

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import (
    DOCK_KEY,
    ENERGY_KEY,
    HOME_DISTANCE_KEY,
    NAVIGATOR_KEY,
    OBSERVATION_KEY,
    POSE_KEY,
)
from homing.behaviours.registry import Param, register, register_service
from homing.lifecycle.energy import (
    DOCKING_ALLOWANCE,
    MARGIN,
    RETURN_SPEED,
    Drain,
    Thresholds,
    charged,
    must_go_home,
    reserve,
)
from homing.navigation.planner import FIELD_BLOCK, distance_map
from homing.robot import ChargingState, Observation, Pose2, RobotAdapter
from py_trees.common import Access, Status

from homing.errors import UserError

PERIOD = 5.0  # [s] adapter time between distance and drain updates
SAMPLE_PERIOD = 2.0  # [s] between drain samples
DETOUR = 1.5  # straight line × this when no planned distance is known
STAGING_DISTANCE = 1.0  # [m] the staging pose out from the docked pose
BATTERIES = ("base", "computer")


def staging_pose(docked: Pose2, distance: float = STAGING_DISTANCE) -> Pose2:
    """The staging pose ``distance`` [m] straight out from the docked pose, facing the dock."""
    return docked.compose(Pose2(-distance, 0.0, 0.0))


def battery_reading(obs: Observation, battery: str) -> Any:
    """The observation's reading of ``battery`` (``base`` or ``computer``), or None."""
    return obs.battery if battery == "base" else obs.computer_battery


@register_service(
    "energy",
    params=(
        Param("computer_undock", float, 90.0, "%", "leave the dock once the computer's battery is this full (thesis)", minimum=0.0, maximum=100.0),
        Param("computer_home", float, 20.0, "%", "head home at this level of the computer's battery plus the reserve (thesis)", minimum=0.0, maximum=100.0),
        Param("base_undock", float, 90.0, "%", "leave the dock once the base's battery is this full", minimum=0.0, maximum=100.0),
        Param("base_home", float, 30.0, "%", "head home at this level of the base's battery plus the reserve", minimum=0.0, maximum=100.0),
        Param("return_speed", float, RETURN_SPEED, "m/s", "planned speed of the way home", above=0.0),
        Param("docking_allowance", float, DOCKING_ALLOWANCE, "s", "time the servo and IR docking may take, with a retry", minimum=0.0),
        Param("margin", float, MARGIN, "", "safety factor on the reserve", minimum=1.0),
        Param("period", float, PERIOD, "s", "adapter time between updates of the distance home", above=0.0),
    ),
    writes=(ENERGY_KEY, HOME_DISTANCE_KEY),
)
class EnergyService:
    """Per-battery go-home and undock levels with a reserve for the planned way home; writes ``/energy/policy``."""

    name = "energy"
    writes = (ENERGY_KEY, HOME_DISTANCE_KEY)
    reads = (DOCK_KEY, NAVIGATOR_KEY, POSE_KEY)

    def __init__(self, computer_undock: float = 90.0, computer_home: float = 20.0, base_undock: float = 90.0,
                 base_home: float = 30.0, return_speed: float = RETURN_SPEED,
                 docking_allowance: float = DOCKING_ALLOWANCE, margin: float = MARGIN, period: float = PERIOD) -> None:
        try:
            self.thresholds = {"base": Thresholds(base_undock, base_home),
                               "computer": Thresholds(computer_undock, computer_home)}
        except ValueError as err:
            raise UserError(f"energy service: {err}") from None
        for name, value in (("return_speed", return_speed), ("margin", margin), ("period", period)):
            if not (math.isfinite(value) and value > 0):
                raise UserError(f"energy service: {name} must be positive, not {value:g}")
        if not (math.isfinite(docking_allowance) and docking_allowance >= 0):
            raise UserError(f"energy service: docking_allowance must be ≥ 0 s, not {docking_allowance:g}")
        self.return_speed, self.docking_allowance, self.margin = return_speed, docking_allowance, margin
        self.period = period
        self.drains = {b: Drain() for b in BATTERIES}
        self.distance_home = 0.0  # [m]
        self.bb: Any = None
        self._field: Any = None
        self._field_key: tuple[Any, ...] | None = None
        self._next = -math.inf
        self._next_sample = -math.inf
        self._reserve = {b: 0.0 for b in BATTERIES}

    def setup(self, robot: RobotAdapter, blackboard: Any) -> None:
        self.bb = blackboard
        for key in self.reads:
            blackboard.register_key(key=key, access=Access.READ)

    def update(self, obs: Observation) -> None:
        """Sample the batteries; every ``period`` refresh the distance home and the reserves; publish."""
        now = obs.stamp
        if now >= self._next_sample:
            self._next_sample = now + SAMPLE_PERIOD
            for b in BATTERIES:
                reading = battery_reading(obs, b)
                if reading is not None:
                    self.drains[b].add(now, reading.percent, reading.on_dock)
        if now >= self._next:
            self._next = now + self.period
            self.distance_home = self._distance_home()
            for b in BATTERIES:
                self._reserve[b] = reserve(self.drains[b].rate, self.distance_home, self.return_speed,
                                           self.docking_allowance, self.margin)
        policy = {}
        for b in BATTERIES:
            reading = battery_reading(obs, b)
            if reading is None:
                continue
            t = self.thresholds[b]
            policy[b] = {"percent": float(reading.percent), "undock": t.undock, "home": t.home,
                         "reserve": float(self._reserve[b])}
        self.bb.set(ENERGY_KEY, policy, overwrite=True)
        self.bb.set(HOME_DISTANCE_KEY, float(self.distance_home), overwrite=True)

    def _distance_home(self) -> float:
        dock, pose, nav = self._get(DOCK_KEY), self._get(POSE_KEY), self._get(NAVIGATOR_KEY)
        if dock is None or pose is None:
            return 0.0  # no dock known: the robot has not left it yet
        home = staging_pose(dock)
        straight = DETOUR * pose.distance_to(home)
        if nav is None or nav.costmap.static.size == 0:
            return straight
        # The field from home only changes with the costmap and home: reuse it until either moves.
        key = (nav.costmap.shape, nav.costmap.origin, round(home.x, 2), round(home.y, 2), nav.costmap.version // 200)
        if key != self._field_key:
            self._field = distance_map(nav.costmap, home, allow_unknown=False, coarse=FIELD_BLOCK)
            self._field_key = key
        rc = nav.costmap.world_to_cell([[pose.x, pose.y]])[0]
        h, w = self._field.shape
        if 0 <= rc[0] < h and 0 <= rc[1] < w and math.isfinite(self._field[rc[0], rc[1]]):
            return max(float(self._field[rc[0], rc[1]]), pose.distance_to(home))
        return straight

    def shutdown(self) -> None:
        pass

    def _get(self, key: str) -> Any:
        try:
            return self.bb.get(key)
        except KeyError:
            return None


def not_yet_charged(policy: dict[str, dict[str, float]], obs: Observation | None) -> list[str]:
    """The batteries of ``policy`` below their undock level and not reported full, as ``"name 71.2 % → 90 %"``."""
    waiting = []
    for name, lv in sorted(policy.items()):
        reading = None if obs is None else battery_reading(obs, name)
        full = reading is not None and reading.state is ChargingState.DOCKING_CHARGED
        if not charged(lv["percent"], Thresholds(lv["undock"], lv["home"]), full):
            waiting.append(f"{name} {lv['percent']:.1f} % → {lv['undock']:g} %")
    return waiting


class _EnergyCondition(HomingBehaviour):
    READS = (ENERGY_KEY, OBSERVATION_KEY)

    def batteries(self) -> list[tuple[str, dict[str, float], Any]]:
        policy = self.read(ENERGY_KEY) or {}
        obs = self.observation()
        out = []
        for name, levels in sorted(policy.items()):
            out.append((name, levels, None if obs is None else battery_reading(obs, name)))
        return out


@register("EnoughEnergy", kind="condition")
class EnoughEnergy(_EnergyCondition):
    """SUCCESS while every battery is above its go-home level (home + the reserve for the way home); FAILURE otherwise.

    The guard that sends the robot home (thesis §3.3.3). Reads
    ``/energy/policy`` (the ``energy`` service): FAILURE before the service
    has published, so a mission without it never leaves the dock unknowingly.
    """

    def update(self) -> Status:
        batteries = self.batteries()
        if not batteries:
            self.feedback_message = "no energy policy (add the 'energy' service)"
            return Status.FAILURE
        for name, lv, _ in batteries:
            t = Thresholds(lv["undock"], lv["home"])
            if must_go_home(lv["percent"], t, lv["reserve"]):
                self.feedback_message = (f"{name} battery {lv['percent']:.1f} % ≤ {lv['home']:g} % "
                                         f"+ {lv['reserve']:.1f} % for the way home")
                return Status.FAILURE
        self.feedback_message = ", ".join(f"{n} {lv['percent']:.0f} % > {lv['home'] + lv['reserve']:.1f} %"
                                          for n, lv, _ in batteries)
        return Status.SUCCESS


@register("Charged", kind="condition")
class Charged(_EnergyCondition):
    """SUCCESS once every battery has reached its undock level or its charger reports it full; FAILURE otherwise."""

    def update(self) -> Status:
        policy = self.read(ENERGY_KEY)
        if not policy:
            self.feedback_message = "no energy policy (add the 'energy' service)"
            return Status.FAILURE
        waiting = not_yet_charged(policy, self.observation())
        self.feedback_message = "charged" if not waiting else "charging: " + ", ".join(waiting)
        return Status.FAILURE if waiting else Status.SUCCESS
