"""The energy policy: when to go home, and when to leave again (thesis §3.3 and §5.2.2).

The thesis undocked at 90 % and went home at 20 % of the on-board
computer's battery (the short pole; the Kobuki base had higher limits of
its own). A fixed threshold is not enough for a robot that may be 30 m
from its dock: the way home costs energy too. So each battery's go-home
level is its threshold plus a **reserve** for the trip home::

    reserve [%] = margin · drain [%/s] · (distance_home [m] / speed [m/s] + docking [s])

where ``drain`` is the battery's own measured discharge rate (the slope of
its readings over the last ``window`` seconds away from the dock, never
below ``min_drain`` — the prior — so a battery that has not been watched
long enough is not trusted to be cheap), ``distance_home`` the planned
travel distance to the dock, and ``docking`` an allowance for the servo and
the IR approach with a retry. The robot heads home while every battery is
still above ``home + reserve``; it leaves the dock once every battery has
reached ``undock``.

No battery model is assumed: the drain is measured, the distance planned,
so the same policy holds on the simulator and on a real TurtleBot.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

UNDOCK_PERCENT = 90.0  # [%] charge to this before leaving (thesis)
HOME_PERCENT = 20.0  # [%] go home at this, plus the reserve (thesis, the computer's battery)
RETURN_SPEED = 0.25  # [m/s] planned speed home (navigation cruises at 0.5; corners, replanning and the servo cost)
DOCKING_ALLOWANCE = 180.0  # [s] servo, IR approach and one retry from the staging pose
MARGIN = 1.5  # safety factor on the reserve
DRAIN_WINDOW = 300.0  # [s] discharge readings the drain is measured over
MIN_DRAIN = 0.005  # [%/s] the drain never counts as less than this (18 %/h)


@dataclass(frozen=True)
class Thresholds:
    """One battery's levels [%]: charge to ``undock`` before leaving; head home at ``home`` plus the reserve."""

    undock: float = UNDOCK_PERCENT
    home: float = HOME_PERCENT

    def __post_init__(self) -> None:
        for name in ("undock", "home"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 100.0):
                raise ValueError(f"{name} must be a percentage within 0..100, not {value}")
        if self.home >= self.undock:
            raise ValueError(f"home ({self.home:g} %) must be below undock ({self.undock:g} %)")


@dataclass
class Drain:
    """A battery's discharge rate [%/s] from its readings while away from the dock (see the module doc)."""

    window: float = DRAIN_WINDOW  # [s]
    floor: float = MIN_DRAIN  # [%/s]
    samples: deque[tuple[float, float]] = field(default_factory=deque)

    def add(self, stamp: float, percent: float, on_dock: bool) -> None:
        """One reading at ``stamp`` [s]; readings on the dock (charging) start a new window."""
        if on_dock:
            self.samples.clear()
            return
        if self.samples and stamp <= self.samples[-1][0]:
            return
        self.samples.append((float(stamp), float(percent)))
        while len(self.samples) > 2 and self.samples[0][0] < stamp - self.window:
            self.samples.popleft()

    @property
    def rate(self) -> float:
        """Measured drain [%/s] (least-squares slope over the window), at least ``floor``."""
        if len(self.samples) < 2 or self.samples[-1][0] - self.samples[0][0] < 10.0:
            return self.floor
        t0 = self.samples[0][0]
        ts = [t - t0 for t, _ in self.samples]
        ps = [p for _, p in self.samples]
        n = len(ts)
        mt, mp = sum(ts) / n, sum(ps) / n
        var = sum((t - mt) ** 2 for t in ts)
        slope = sum((t - mt) * (p - mp) for t, p in zip(ts, ps, strict=True)) / var if var > 0 else 0.0
        return max(-slope, self.floor)


def reserve(drain: float, distance_home: float, speed: float = RETURN_SPEED,
            docking: float = DOCKING_ALLOWANCE, margin: float = MARGIN) -> float:
    """Percent of charge the way home needs: ``margin · drain · (distance / speed + docking)``.

    ``drain`` [%/s], ``distance_home`` [m] (inf when no way home is known:
    then the reserve is what a trip at the longest distance seen would cost,
    which the caller supplies instead), ``speed`` [m/s], ``docking`` [s].
    """
    if not math.isfinite(distance_home):
        raise ValueError("distance_home must be finite")
    return margin * drain * (max(distance_home, 0.0) / speed + docking)


def must_go_home(percent: float, thresholds: Thresholds, reserve_pct: float) -> bool:
    """Whether a battery at ``percent`` is at or below its go-home level (``home + reserve``)."""
    return percent <= thresholds.home + reserve_pct


def charged(percent: float, thresholds: Thresholds, full: bool = False) -> bool:
    """Whether a battery may leave the dock: at ``undock`` or above, or reported full by its charger."""
    return full or percent >= thresholds.undock
