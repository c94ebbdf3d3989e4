"""The terminal view of a running mission (rich ``Live``), its plain-text log, and the static tree.

The live view fits an 80 × 24 terminal (and uses a bigger one):

- a header line: mission, adapter time, real-time factor, tick;
- a small map (:class:`homing.missions.minimap.MiniMap`: the grid in
  braille, the robot, its planned path, its goal, the frontiers) beside the
  facts (:mod:`homing.missions.facts`): lifecycle state and dock cycles,
  both batteries with their go-home and undock levels, the pose, the goal,
  the mapped area and its growth over time;
- the tree with each node's status as colour and glyph and the running path
  in bold — when it has more lines than the screen, branches off the running
  path are folded first (``▸ name (+n)``), deepest first;
- the current leaf's feedback message and the mission's chosen blackboard
  entries.

When the run stops, the tree is halted (every node INVALID), but the final
frame still shows what was running when it stopped, marked as halted.
Redraws happen at most ``REFRESH_HZ`` times a real second, whatever the
simulation's pace; the map and the frontiers are cached on the grid's version.

``--no-view`` or a stdout that is not a terminal gets :class:`PlainLog`
instead: one timestamped line per status change, as the runner reports them,
and every ``FACTS_PERIOD`` of adapter time a line of the same facts.
"""

from __future__ import annotations

import numbers
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TextIO

from homing.missions.facts import (
    AreaHistory,
    Facts,
    battery_bar,
    fact_line,
    pose_text,
    read_facts,
    register_keys,
)
from homing.missions.minimap import MiniMap
from py_trees.behaviour import Behaviour
from py_trees.common import Status
from rich.console import Console, Group
from rich.live import Live
from rich.text import Text
from rich.tree import Tree

if TYPE_CHECKING:
    from homing.missions.compiler import CompiledMission
    from homing.missions.runner import Runner, StatusChange

STATUS_STYLE: dict[Status, tuple[str, str]] = {
    Status.SUCCESS: ("✔", "green"),
    Status.FAILURE: ("✘", "red"),
    Status.RUNNING: ("●", "yellow"),
    Status.INVALID: ("·", "grey50"),
}
KIND_MARK = {
    "sequence": "→", "reactive_sequence": "⇢", "fallback": "?", "selector": "?", "reactive_fallback": "⁇",
    "reactive_selector": "⁇", "parallel": "⇉", "round_robin": "↻", "recovery": "⟲", "guard": "⛨",
}  # fmt: skip
RTF_WINDOW = 0.5  # [s] wall time over which the header's real-time factor is measured
REFRESH_HZ = 8.0  # [Hz] redraws of the live view (real time)
HEADER_LINES = 1
FOOTER_MIN = 2  # feedback line and a rule
MAP_MIN_LINES, MAP_MAX_LINES = 8, 18  # [lines] the map's height, by the terminal's
MAP_MIN_WIDTH = 18  # [characters]
FACTS_MIN_WIDTH = 36  # [characters] beside the map
FACTS_MAX_WIDTH = 48  # [characters] (battery bars wider than this read no better)
FACTS_PERIOD = 30.0  # [s] adapter time between fact lines without the view
SUMMARY_LINES = 2  # printed by 'homing run' under the final frame


def label(node: Behaviour, mission: CompiledMission, *, status: bool = True, params: bool = False,
          shown: Status | None = None) -> Text:
    """One node's line: status glyph (``shown`` instead of its own if given), kind mark, name (and its spec and
    parameters if asked)."""
    info = mission.info.get(node.id)
    text = Text()
    current = shown if shown is not None else node.status
    if status:
        glyph, colour = STATUS_STYLE[current]
        text.append(f"{glyph} ", style=colour)
    spec = info.spec if info else type(node).__name__
    mark = KIND_MARK.get(spec, "◇" if info and info.kind == "decorator" else "")
    if mark:
        text.append(f"{mark} ", style="cyan")
    style = "bold" if current == Status.RUNNING and status else ""
    if info and info.subtree:
        text.append("⧉ ", style="magenta")
    text.append(node.name, style=style)
    extra = []
    if info and spec != node.name.split("#")[0]:
        extra.append(spec)
    if params and info and info.params:
        extra.extend(f"{k}={_short(v)}" for k, v in info.params.items())
    if extra:
        text.append("  " + " ".join(extra), style="grey62")
    return text


def _short(value: Any, width: int = 24, live: bool = False) -> str:
    """``value`` in at most ``width`` characters: a parameter as written, or (``live``) a blackboard reading."""
    if all(hasattr(value, a) for a in ("x", "y", "theta")):  # a Pose2: centimetres and whole degrees
        return pose_text(value)[:width]
    if live and isinstance(value, numbers.Real) and not isinstance(value, numbers.Integral):  # numpy's floats too
        # a reading changes every tick: hundredths are plenty on a dashboard
        v = float(value)
        s = f"{v:.2f}".rstrip("0").rstrip(".") if abs(v) < 1e6 else f"{v:.3g}"
        s = "0" if s == "-0" else s
    else:
        s = f"{value:g}" if isinstance(value, float) else repr(value) if isinstance(value, str) else str(value)
    return s if len(s) <= width else s[: width - 1] + "…"


def static_tree(mission: CompiledMission) -> Tree:
    """The whole tree with kinds and parameters, no statuses (``homing view``)."""
    root = Tree(label(mission.root, mission, status=False, params=True), guide_style="grey50")

    def grow(node: Behaviour, branch: Tree) -> None:
        for child in node.children:
            grow(child, branch.add(label(child, mission, status=False, params=True)))

    grow(mission.root, root)
    return root


def _preorder(node: Behaviour, depth: int = 0) -> Iterator[tuple[Behaviour, int]]:
    yield node, depth
    for child in node.children:
        yield from _preorder(child, depth + 1)


def fold(root: Behaviour, budget: int, statuses: dict[Any, Status] | None = None) -> set[Any]:
    """Ids of the nodes whose children are shown, so that at most ``budget`` lines are drawn.

    Running nodes are unfolded first, then finished ones, then idle ones,
    shallow before deep, each only if its children still fit. ``statuses``
    (node id → status) stands in for the nodes' own (a halted tree's last).
    """
    nodes = list(_preorder(root))
    rank = {Status.RUNNING: 0, Status.SUCCESS: 1, Status.FAILURE: 1, Status.INVALID: 2}

    def status(node: Behaviour) -> Status:
        return statuses.get(node.id, node.status) if statuses is not None else node.status

    order = sorted((n for n in nodes if n[0].children), key=lambda nd: (rank[status(nd[0])], nd[1]))
    shown, lines = {root.id}, 1
    opened: set[Any] = set()
    for _ in range(2):
        for node, _depth in order:
            if node.id in opened or node.id not in shown:
                continue
            if lines + len(node.children) <= budget:
                opened.add(node.id)
                shown.update(c.id for c in node.children)
                lines += len(node.children)
    return opened


def tree_lines(mission: CompiledMission, budget: int, statuses: dict[Any, Status] | None = None) -> list[Text]:
    """The tree as at most ``budget`` indented lines with statuses (``statuses`` overriding); running path in bold."""
    opened = fold(mission.root, budget, statuses)
    out: list[Text] = []

    def walk(node: Behaviour, prefix: str) -> None:
        line = Text()
        line.append(prefix, style="grey50")
        line.append_text(label(node, mission, shown=statuses.get(node.id) if statuses is not None else None))
        if node.children and node.id not in opened:
            line.append(f" ▸(+{sum(1 for _ in node.iterate()) - 1})", style="grey50")
        out.append(line)
        if node.id in opened:
            for child in node.children:
                walk(child, prefix + "  ")

    walk(mission.root, "")
    return out[:budget]


class LiveView:
    """The live terminal view, redrawn at most ``REFRESH_HZ`` times a real second."""

    def __init__(self, mission: CompiledMission, console: Console | None = None):
        self.mission = mission
        self.console = console or Console()
        self.live = Live(console=self.console, auto_refresh=False, transient=False, vertical_overflow="crop")
        self.last_draw = -1.0
        self.last_wall = 0.0
        self.last_sim = 0.0
        self.rtf = 0.0
        self.minimap = MiniMap()
        self.area = AreaHistory()
        self._statuses: dict[Any, Status] = {}  # every node's status at the last redraw of a running tree
        self._running: list[Any] = []  # ids on the running path at the last tick of a running tree
        self._tip: tuple[str, str] | None = None  # (name, feedback) of the running leaf then
        self.gone = False  # the terminal went away: draw no more

    def __enter__(self) -> LiveView:
        self.live.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        try:
            self.live.__exit__(*exc)
        except OSError:  # the terminal is gone (a hang-up): nothing left to restore
            self.gone = True

    def attach(self, runner: Runner) -> Callable[[Runner], None]:
        """Let ``runner``'s blackboard client read what the view shows; the callback to call after each tick."""
        register_keys(runner)
        return self.update

    def update(self, runner: Runner, *, force: bool = False) -> None:
        running = runner.mission.root.status == Status.RUNNING
        if running:  # cheap, every tick: the running path (depth of the tree), for the final frame
            tip = runner.tree.tip()
            self._running, node = [], tip
            while node is not None:
                self._running.append(node.id)
                node = node.parent
            self._tip = (tip.name, tip.feedback_message) if tip is not None else None
        wall = time.monotonic()
        if not force and wall - self.last_draw < 1.0 / REFRESH_HZ and running:
            return
        # Measure the pace over at least RTF_WINDOW of wall time: a forced redraw right
        # after the previous one (the final frame) would otherwise read as ×0.
        if self.last_draw > 0 and wall - self.last_wall >= RTF_WINDOW:
            self.rtf = (runner.now - self.last_sim) / (wall - self.last_wall)
            self.last_wall, self.last_sim = wall, runner.now
        elif self.last_draw <= 0:
            self.last_wall, self.last_sim = wall, runner.now
        self.last_draw = wall
        if running:
            self._statuses = {n.id: n.status for n in runner.mission.root.iterate()}
        if self.gone:
            return
        try:
            self.live.update(self.render(runner), refresh=True)
        except OSError:  # the terminal hung up (SIGHUP follows): keep running, stop drawing
            self.gone = True

    def halted_statuses(self, runner: Runner) -> dict[Any, Status] | None:
        """The statuses to draw for a tree halted by the stop (None while running or when it finished itself)."""
        if runner.mission.root.status != Status.INVALID or not self._running:
            return None
        shown = dict(self._statuses)
        shown.update({i: Status.RUNNING for i in self._running})
        return shown

    def render(self, runner: Runner) -> Group:
        width, height = self.console.size
        if runner.mission.root.status != Status.RUNNING:
            height -= SUMMARY_LINES  # the final frame leaves room for the run's summary below it
        keys = self.mission.source.view_keys
        facts = read_facts(runner)
        area = self.area.update(facts.t, facts.grid)
        if facts.grid is not None:
            map_h = max(MAP_MIN_LINES, min(MAP_MAX_LINES, (height - 12) // 2))
            map_w = max(MAP_MIN_WIDTH, min(width - FACTS_MIN_WIDTH - 1, 2 * map_h + map_h // 2))
        else:
            map_h = map_w = 0  # no map in this mission: the facts alone
        panel = self.panel(facts, area, map_w, map_h, min(FACTS_MAX_WIDTH, width - map_w - 1))
        halted = self.halted_statuses(runner)
        footer = FOOTER_MIN + len(keys)
        budget = max(3, height - HEADER_LINES - len(panel) - footer - 1)
        parts: list[Text] = [self.header(runner, width), *panel]
        parts.extend(tree_lines(self.mission, budget, halted))
        parts.append(Text("─" * min(width, 80), style="grey35"))
        parts.append(self.feedback(runner, halted is not None, width))
        for key in keys:
            line = Text()
            line.append(f"{key} = ", style="cyan")
            line.append(_short(runner.read(key), max(8, width - len(key) - 4), live=True))
            parts.append(line)
        return Group(*parts)

    def panel(self, facts: Facts, area: float | None, map_w: int, map_h: int, facts_w: int) -> list[Text]:
        """The map (``map_w`` × ``map_h``) and the facts beside it, as ``map_h`` lines."""
        right = self.fact_lines(facts, area, facts_w)
        if not map_w:
            return right
        path = facts.path if facts.path is not None and len(facts.path) else None
        chart = self.minimap.render(facts.grid, map_w, map_h, facts.pose, path, facts.goal)
        lines = [Text(no_wrap=True, overflow="ellipsis") for _ in range(map_h)]
        for i in range(map_h):
            lines[i].append_text(chart[i])
            lines[i].append(" ")
            if i < len(right):
                lines[i].append_text(right[i])
            lines[i].truncate(map_w + 1 + facts_w, overflow="ellipsis")
        return lines

    def fact_lines(self, f: Facts, area: float | None, width: int) -> list[Text]:
        out: list[Text] = []
        head = Text()
        head.append("state ", style="grey62")
        head.append(f.state or "–", style="bold magenta")
        if f.cycles is not None:
            head.append("  cycles ", style="grey62")
            head.append(str(f.cycles), style="bold")
        out.append(head)
        out.extend(battery_bar(b, width) for b in f.batteries)
        if f.pose is not None:
            out.append(Text("pose ", style="grey62").append(pose_text(f.pose), style=""))
        if f.goal is not None:
            togo = f" · {f.remaining:.1f} m to go" if f.remaining is not None else ""
            out.append(Text("goal ", style="grey62").append(f"({f.goal.x:.2f}, {f.goal.y:.2f}){togo}", style="green"))
        if area is not None:
            rate = self.area.rate()
            grow = f" · {round(rate, 1) + 0.0:+.1f} m²/min" if rate is not None else ""
            out.append(Text("mapped ", style="grey62").append(f"{area:.1f} m²{grow}"))
            spark = self.area.sparkline(max(4, width - 2))
            if spark:
                out.append(Text(spark, style="cyan"))
            scale = self.minimap.scale()
            res = getattr(f.grid, "resolution", None)
            key = Text("frontiers ", style="grey62").append(str(self.minimap.frontier_count), style="magenta")
            if scale is not None and res is not None:
                key.append(f" · dot {scale * res:.2f} m", style="grey50")
            out.append(key)
        return out

    def feedback(self, runner: Runner, halted: bool, width: int) -> Text:
        text = Text()
        if halted and self._tip is not None:
            name, message = self._tip
            text.append("■ ", style="red")
            text.append(f"halted: {name}", style="bold")
            text.append(f" was running: {message}" if message else " was running")
        else:
            tip = runner.tree.tip()
            text.append("▶ ", style="yellow")
            if tip is not None:
                text.append(tip.name, style="bold")
                text.append(f": {tip.feedback_message}" if tip.feedback_message else "")
            else:
                text.append(f"root {runner.mission.root.status.value}", style="bold")
        text.truncate(width, overflow="ellipsis")
        return text

    def header(self, runner: Runner, width: int) -> Text:
        t = runner.now - runner.start
        text = Text()
        text.append(f"{self.mission.name} ", style="bold")
        text.append(f"t {_clock(t)}  ×{self.rtf:.1f}")
        text.append(f"  tick {runner.ticks}", style="grey50")
        status = runner.mission.root.status
        if status != Status.RUNNING:
            text.append(f"  stopped ({'halted' if status == Status.INVALID else status.value})", style="bold red")
        text.truncate(width, overflow="ellipsis")
        return text


def _clock(seconds: float) -> str:
    h, rem = divmod(int(seconds), 3600)
    m, s = divmod(rem, 60)
    return f"{h:d}:{m:02d}:{s:02d}.{int((seconds % 1) * 10)}"


class PlainLog:
    """Timestamped status-change lines for a pipe or ``--no-view``: ``[  12.30 s] Wait: RUNNING -> SUCCESS``.

    Attached to a runner (:meth:`attach`), it also prints the live view's facts as one line every
    ``FACTS_PERIOD`` of adapter time (:func:`homing.missions.facts.fact_line`), and at the end.
    """

    def __init__(self, stream: TextIO):
        self.stream = stream
        self.area = AreaHistory()
        self.minimap = MiniMap()
        self._next = 0.0

    def __call__(self, change: StatusChange) -> None:
        self.stream.write(change.line() + "\n")

    def attach(self, runner: Runner) -> Callable[[Runner], None]:
        """Let ``runner``'s client read the facts; the callback to call after each tick (a fact line when due)."""
        register_keys(runner)
        return self.tick

    def tick(self, runner: Runner) -> None:
        t = runner.now - runner.start
        if t < self._next and runner.mission.root.status == Status.RUNNING:
            return
        self._next = t + FACTS_PERIOD
        facts = read_facts(runner)
        area = self.area.update(t, facts.grid)
        frontiers = None
        if facts.grid is not None:
            self.minimap.frontiers(facts.grid)
            frontiers = self.minimap.frontier_count
        self.stream.write(fact_line(facts, area, frontiers) + "\n")
