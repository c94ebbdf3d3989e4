"""Coulomb-counting battery model for the Kobuki base and the on-board computer.

State of charge ``soc`` ∈ [0, 1] integrates current: a constant idle draw,
plus a motion draw proportional to |v| and |ω| (the motors), minus the
charging current while the dock's contacts are closed. The base reports
voltage the way a Kobuki does, linear in ``soc`` between the dangerous
(13.2 V, soc 0) and full (16.5 V, soc 1) voltages, so its percent is
Kobuki's formula 95·(V − 13.2)/(16.5 − 13.2) + 5
(:func:`homing.robot.turtlebot.battery_percent`). The computer (a laptop)
reports percent = 100·soc directly, its voltage linear between
``v_empty`` and ``v_full``. Both charge only when docked, at a constant
current until full (DOCKING_CHARGING), then hold (DOCKING_CHARGED).

Parameters come from a world file's ``battery: {base: {...}, computer: {...}}``
section; the defaults make the computer the short pole, as in the thesis.
Not an electrochemical model: no voltage sag, temperature or ageing.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

from homing.robot.turtlebot import (
    BATTERY_CAPACITY_AH,
    BATTERY_DANGEROUS_V,
    BATTERY_FULL_V,
    battery_percent,
)
from homing.robot.types import BatteryState, ChargingSource, ChargingState

from homing.section import Section

SECONDS_PER_HOUR = 3600.0  # [s/h]


@dataclass(frozen=True)
class BatteryParams:
    """One battery: capacity, draws and charge current (currents in A, capacity in Ah)."""

    kind: str = "kobuki"  # 'kobuki' (percent from voltage) or 'linear' (percent = 100·soc)
    capacity_ah: float = BATTERY_CAPACITY_AH  # [Ah]
    percent: float = 100.0  # initial charge [%] as the battery reports it
    idle_a: float = 0.25  # [A] electronics, sensors
    drive_a_per_mps: float = 1.2  # [A/(m/s)] motors when driving
    turn_a_per_radps: float = 0.3  # [A/(rad/s)] motors when turning
    charge_a: float = 1.5  # [A] dock charging current
    v_empty: float = BATTERY_DANGEROUS_V  # [V] at soc 0
    v_full: float = BATTERY_FULL_V  # [V] at soc 1


BASE_DEFAULT = BatteryParams()
# A laptop on the top plate: 11.1 V 3S pack of 4.4 Ah drawing ~14 W, charged from the dock.
COMPUTER_DEFAULT = BatteryParams(
    kind="linear", capacity_ah=4.4, percent=100.0, idle_a=1.3, drive_a_per_mps=0.0,
    turn_a_per_radps=0.0, charge_a=2.0, v_empty=9.6, v_full=12.6,
)
_KEYS = ("capacity_ah", "percent", "idle_a", "drive_a_per_mps", "turn_a_per_radps", "charge_a")


def params_from_section(sec: Section, default: BatteryParams) -> BatteryParams:
    """Read one battery's parameters from a world file section (unknown keys are errors)."""
    sec.only(_KEYS)
    kw: dict[str, Any] = {}
    for key in _KEYS:
        if sec.has(key):
            kw[key] = sec.number(key, hi=100.0 if key == "percent" else None,
                                 lo=0.0, positive=key == "capacity_ah")
    return replace(default, **kw)


class Battery:
    """A battery's charge, drained by time and motion and charged on the dock."""

    def __init__(self, params: BatteryParams):
        self.params = params
        self.soc = self._soc_from_percent(params.percent)

    def _soc_from_percent(self, percent: float) -> float:
        if self.params.kind == "kobuki":
            return min(1.0, max(0.0, (percent - 5.0) / 95.0))
        return min(1.0, max(0.0, percent / 100.0))

    def current(self, v: float, omega: float, charging: bool) -> float:
        """Net current out of the battery [A] (negative while charging)."""
        p = self.params
        draw = p.idle_a + p.drive_a_per_mps * abs(v) + p.turn_a_per_radps * abs(omega)
        if charging:  # the dock powers the load and charges the cell until full
            return -p.charge_a if self.soc < 1.0 else 0.0
        return draw

    def update(self, dt: float, v: float, omega: float, on_dock: bool) -> None:
        """Integrate ``dt`` [s] at speeds ``v`` [m/s], ``omega`` [rad/s]; charges only ``on_dock``."""
        amps = self.current(v, omega, on_dock)
        self.soc = min(1.0, max(0.0, self.soc - amps * dt / (self.params.capacity_ah * SECONDS_PER_HOUR)))

    @property
    def voltage(self) -> float:
        p = self.params
        return p.v_empty + (p.v_full - p.v_empty) * self.soc

    @property
    def percent(self) -> float:
        if self.params.kind == "kobuki":
            return battery_percent(self.voltage)
        return 100.0 * self.soc

    def state(self, on_dock: bool) -> BatteryState:
        """The reading an adapter reports."""
        if not on_dock:
            return BatteryState(self.voltage, self.percent, ChargingSource.NONE, ChargingState.DISCHARGING)
        full = self.soc >= 1.0
        return BatteryState(
            self.voltage, self.percent, ChargingSource.DOCK,
            ChargingState.DOCKING_CHARGED if full else ChargingState.DOCKING_CHARGING,
        )
