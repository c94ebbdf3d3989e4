"""Faults injected into the simulation by name and time (``NAME@T`` or a world file's ``faults:``).

Each fault starts at ``at`` [s] of simulated time and lasts ``duration`` [s]
(``None``: the kind's default; ``math.inf``: for the rest of the run). What
each does (the effects live in :class:`homing.sim.robot.SimRobot`):

- ``lidar_dropout``: a burst in which a ``fraction`` of each scan's rays
  return nothing (``inf``); default 5 s, all rays.
- ``camera_off``: no images at all; default 30 s.
- ``wheel_slip``: the wheels spin but the base moves only ``1 − amount`` of
  the commanded motion, while the encoders report all of it; default 10 s, 0.5.
- ``kidnap``: the robot is teleported to ``to`` = (x, y, yaw) [m, m, rad], or
  to a seeded random free pose; odometry does not notice. Instantaneous.
- ``dock_obstacle``: a 0.3 m box, tall enough for the lidar, stands with a
  gap of ``distance`` [m] to the dock's face (blocks the IR and the way in);
  default: for the rest of the run.
- ``bumper_hit``: a moving obstacle drives into the robot from ``side``
  ('left', 'centre', 'right'), presses that bumper, then goes away; ~1 s.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from homing.errors import UserError
from homing.section import Section

FAULT_NAMES = ("lidar_dropout", "camera_off", "wheel_slip", "kidnap", "dock_obstacle", "bumper_hit")
DEFAULT_DURATION = {  # [s]
    "lidar_dropout": 5.0,
    "camera_off": 30.0,
    "wheel_slip": 10.0,
    "kidnap": 0.0,
    "dock_obstacle": math.inf,
    "bumper_hit": 1.0,
}
SIDES = ("left", "centre", "right")
_SPEC = re.compile(r"^(?P<name>[a-z_]+)@(?P<at>[0-9.eE+-]+)(?::(?P<dur>[0-9.eE+-]+|inf))?$")


@dataclass(frozen=True)
class Fault:
    """One fault: its kind, start [s], duration [s] and kind-specific parameters."""

    name: str
    at: float  # [s] simulated time the fault starts
    duration: float | None = None  # [s]; None: the kind's default
    fraction: float = 1.0  # lidar_dropout: share of rays lost
    amount: float = 0.5  # wheel_slip: share of the commanded motion lost
    to: tuple[float, float, float] | None = None  # kidnap: target pose [m, m, rad]; None: random free
    side: str = "centre"  # bumper_hit: which bumper the obstacle hits
    distance: float = 0.6  # dock_obstacle: from the dock's face [m]

    def __post_init__(self) -> None:
        if self.name not in FAULT_NAMES:
            raise ValueError(f"unknown fault {self.name!r}; known: {', '.join(FAULT_NAMES)}")
        if self.side not in SIDES:
            raise ValueError(f"bumper_hit side must be one of {SIDES}, not {self.side!r}")

    @property
    def length(self) -> float:
        """Duration [s] with the kind's default applied."""
        return DEFAULT_DURATION[self.name] if self.duration is None else self.duration

    def active(self, t: float) -> bool:
        """Whether the fault acts at time ``t`` [s]."""
        return self.at <= t < self.at + self.length

    @staticmethod
    def parse(text: str) -> Fault:
        """``NAME@T`` or ``NAME@T:DURATION`` (seconds), as ``homing run --fault`` takes it."""
        m = _SPEC.match(text.strip())
        if m is None:
            raise UserError(f"bad fault {text!r}: expected NAME@SECONDS[:DURATION], e.g. kidnap@120")
        name = m.group("name")
        if name not in FAULT_NAMES:
            raise UserError(f"unknown fault {name!r}; known: {', '.join(FAULT_NAMES)}")
        try:
            at = float(m.group("at"))
            dur = float(m.group("dur")) if m.group("dur") else None
        except ValueError:
            raise UserError(f"bad fault time in {text!r}") from None
        if at < 0 or (dur is not None and dur < 0):
            raise UserError(f"fault times must not be negative in {text!r}")
        return Fault(name, at, dur)


def fault_from_section(sec: Section) -> Fault:
    """Read one item of a world file's ``faults:`` list."""
    sec.only(("name", "at", "duration", "fraction", "amount", "to", "side", "distance"))
    name = sec.string("name", choices=FAULT_NAMES)
    at = sec.number("at", lo=0.0)
    duration = sec.optional_number("duration", lo=0.0)
    to = sec.vector("to", 3) if sec.has("to") else None
    return Fault(
        name, at, duration,
        fraction=sec.number("fraction", 1.0, lo=0.0, hi=1.0),
        amount=sec.number("amount", 0.5, lo=0.0, hi=1.0),
        to=(to[0], to[1], to[2]) if to else None,
        side=sec.string("side", "centre", choices=SIDES),
        distance=sec.number("distance", 0.6, lo=0.2, hi=3.0),
    )
