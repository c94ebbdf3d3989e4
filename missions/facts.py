"""What a running mission shows a person: lifecycle state, batteries and thresholds, pose, goal, map growth.

The live view (:mod:`homing.missions.view`) draws these facts; a run
without the view prints them as plain lines (:func:`fact_line`), so both
tell the same story. Everything comes from the blackboard the runner
already holds (ARCHITECTURE.md, "Blackboard keys"); a key nothing writes
(the explore mission has no ``/energy/policy``) just leaves its fact out.

Units as a person reads them: positions in metres to the centimetre,
headings in whole degrees, areas in m², batteries in whole percent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from homing.behaviours.keys import (
    CYCLES_KEY,
    ENERGY_KEY,
    EXPLORE_GOAL_KEY,
    GRID_KEY,
    NAVIGATOR_KEY,
    POSE_KEY,
    STATE_KEY,
)
from rich.text import Text

from homing.map_server import FREE

VIEW_KEYS = (STATE_KEY, CYCLES_KEY, ENERGY_KEY, GRID_KEY, POSE_KEY, EXPLORE_GOAL_KEY, NAVIGATOR_KEY)
AREA_PERIOD = 5.0  # [s] adapter time between samples of the mapped area
AREA_SAMPLES = 120  # kept (10 minutes of adapter time)
SPARKS = "▁▂▃▄▅▆▇█"


@dataclass(frozen=True)
class Battery:
    """One battery as shown: ``percent`` now, and its thresholds when the energy service sets them [%]."""

    name: str
    percent: float
    charging: bool = False
    home: float | None = None  # head home below home + reserve
    reserve: float = 0.0
    undock: float | None = None  # leave the dock once this full


@dataclass
class Facts:
    """One moment of a run, read from the blackboard (None: not published by this mission)."""

    t: float  # [s] since the start, adapter clock
    state: str | None = None
    cycles: int | None = None
    pose: Any = None  # Pose2 in map
    goal: Any = None  # Pose2 in map
    path: Any = None  # (N, 2) [m] in map
    remaining: float | None = None  # [m] along the path
    batteries: list[Battery] = field(default_factory=list)
    grid: Any = None  # OccupancyGrid


def register_keys(runner: Any) -> None:
    """Let the runner's blackboard client read every key the facts come from."""
    from py_trees.common import Access

    for key in VIEW_KEYS:
        if key not in runner.bb.remappings:
            runner.bb.register_key(key=key, access=Access.READ)


def read_facts(runner: Any) -> Facts:
    """The facts of ``runner``'s last tick."""
    register_keys(runner)
    f = Facts(runner.now - runner.start)
    state = runner.read(STATE_KEY)
    f.state = str(state) if state is not None else None
    cycles = runner.read(CYCLES_KEY)
    f.cycles = int(cycles) if isinstance(cycles, (int, float)) else None
    f.pose, f.goal, f.grid = runner.read(POSE_KEY), runner.read(EXPLORE_GOAL_KEY), runner.read(GRID_KEY)
    nav = runner.read(NAVIGATOR_KEY)
    feedback = getattr(nav, "feedback", None)
    if feedback is not None:
        f.path = getattr(feedback, "path", None)
        remaining = getattr(feedback, "distance_remaining", None)
        f.remaining = remaining if isinstance(remaining, float) and math.isfinite(remaining) else None
        if f.goal is None:
            f.goal = getattr(feedback, "goal", None)
    f.batteries = _batteries(runner.read(ENERGY_KEY), runner.observation)
    return f


def _batteries(policy: Any, obs: Any) -> list[Battery]:
    readings = {"base": getattr(obs, "battery", None), "computer": getattr(obs, "computer_battery", None)}
    out = []
    for name in ("base", "computer"):
        reading = readings[name]
        levels = policy.get(name) if isinstance(policy, dict) else None
        if reading is None and not levels:
            continue
        percent = float(levels["percent"]) if levels and "percent" in levels else float(getattr(reading, "percent", 0.0))
        charging = bool(getattr(reading, "charging", False))
        if levels:
            out.append(Battery(name, percent, charging, levels.get("home"), float(levels.get("reserve", 0.0)),
                               levels.get("undock")))
        else:
            out.append(Battery(name, percent, charging))
    return out


class AreaHistory:
    """The mapped area [m²] (free cells of ``/map/grid``) sampled every AREA_PERIOD of adapter time."""

    def __init__(self) -> None:
        self.samples: list[tuple[float, float]] = []  # (t [s], area [m²])
        self._version: tuple[int, int] | None = None
        self._area = 0.0

    def update(self, t: float, grid: Any) -> float | None:
        """The area now (counted once per grid version); a sample is kept every AREA_PERIOD."""
        if grid is None:
            return None
        key = (id(grid), grid.version)
        if key != self._version:
            self._area = float((grid.data == FREE).sum()) * grid.resolution**2
            self._version = key
        if not self.samples or t - self.samples[-1][0] >= AREA_PERIOD:
            self.samples.append((t, self._area))
            del self.samples[:-AREA_SAMPLES]
        return self._area

    def rate(self) -> float | None:
        """[m²/min] over the last minute of samples (None with fewer than two)."""
        if len(self.samples) < 2:
            return None
        t1, a1 = self.samples[-1]
        t0, a0 = next(((t, a) for t, a in self.samples if t >= t1 - 60.0), self.samples[0])
        return (a1 - a0) / (t1 - t0) * 60.0 if t1 > t0 else None

    def sparkline(self, width: int) -> str:
        """The last ``width`` samples as ▁…█ (scaled to the largest)."""
        values = [a for _, a in self.samples[-width:]]
        top = max(values, default=0.0)
        if top <= 0:
            return ""
        return "".join(SPARKS[min(len(SPARKS) - 1, int(v / top * (len(SPARKS) - 1) + 0.5))] for v in values)


def pose_text(pose: Any) -> str:
    """``(3.42, -1.07) m 87°``"""
    return f"({pose.x:.2f}, {pose.y:.2f}) m {math.degrees(pose.theta):.0f}°"


def battery_bar(b: Battery, width: int) -> Text:
    """``base  63% ▕██████▌│░░┊░▏`` with the go-home line (│, at home + reserve) and the undock level (┊)."""
    colour = "red" if b.home is not None and b.percent < b.home + b.reserve else \
        "green" if b.undock is None or b.percent >= b.undock else "yellow"
    text = Text(f"{b.name:<9}{b.percent:3.0f}%{'⚡' if b.charging else ' '}", style="bold" if b.charging else "")
    n = max(4, width - len(text.plain) - 2)
    filled = max(0.0, min(1.0, b.percent / 100.0)) * n
    marks = {}
    if b.home is not None:
        marks[min(n - 1, int((b.home + b.reserve) / 100.0 * n))] = "│"
    if b.undock is not None:
        marks[min(n - 1, int(b.undock / 100.0 * n))] = "┊"
    cells = []
    for i in range(n):
        if i in marks:
            cells.append((marks[i], "bold white"))
        elif i + 1 <= filled:
            cells.append(("█", colour))
        else:
            cells.append(("▌", colour) if i < filled else ("░", "grey35"))
    text.append("▕")
    start = 0
    for i in range(1, n + 1):  # one span per run of one style: the view redraws 8 times a second
        if i == n or cells[i][1] != cells[start][1]:
            text.append("".join(c for c, _ in cells[start:i]), style=cells[start][1])
            start = i
    text.append("▏")
    return text


def battery_line(b: Battery) -> str:
    """``base 63% (home 20+4.5, undock 90)``"""
    levels = []
    if b.home is not None:
        levels.append(f"home {b.home:g}+{b.reserve:.1f}")
    if b.undock is not None:
        levels.append(f"undock {b.undock:g}")
    return f"{b.name} {b.percent:.0f}%{' charging' if b.charging else ''}" + (f" ({', '.join(levels)})" if levels else "")


def fact_line(f: Facts, area: float | None, frontiers: int | None) -> str:
    """The facts as one plain line, for a run without the live view."""
    parts = [f"state {f.state}" if f.state else ""]
    if f.cycles is not None:
        parts.append(f"cycles {f.cycles}")
    parts += [battery_line(b) for b in f.batteries]
    if f.pose is not None:
        parts.append(f"pose {pose_text(f.pose)}")
    if f.goal is not None:
        away = f" {f.remaining:.1f} m to go" if f.remaining is not None else ""
        parts.append(f"goal ({f.goal.x:.2f}, {f.goal.y:.2f}){away}")
    if area is not None:
        parts.append(f"mapped {area:.1f} m²")
    if frontiers is not None:
        parts.append(f"frontiers {frontiers}")
    return f"[{f.t:10.2f} s] " + " · ".join(p for p in parts if p)
