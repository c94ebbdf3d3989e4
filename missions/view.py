"""The terminal view of a running mission (rich ``Live``), its plain-text log, and the static tree.

The live view fits an 80 × 24 terminal: one header line (mission, adapter
time, real-time factor, battery, lifecycle state ``/mission/state``), the
tree with each node's status as colour and glyph and the running path in
bold, then the current leaf's feedback message and the selected blackboard
entries. When the tree has more lines than the screen, branches off the
running path are folded first (``▸ name (+n)``), deepest first.

``--no-view`` or a stdout that is not a terminal gets :class:`PlainLog`
instead: one timestamped line per status change, as the runner reports them.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any, TextIO

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


def label(node: Behaviour, mission: CompiledMission, *, status: bool = True, params: bool = False) -> Text:
    """One node's line: status glyph, kind mark, name (and its spec and parameters if asked)."""
    info = mission.info.get(node.id)
    text = Text()
    if status:
        glyph, colour = STATUS_STYLE[node.status]
        text.append(f"{glyph} ", style=colour)
    spec = info.spec if info else type(node).__name__
    mark = KIND_MARK.get(spec, "◇" if info and info.kind == "decorator" else "")
    if mark:
        text.append(f"{mark} ", style="cyan")
    style = "bold" if node.status == Status.RUNNING and status else ""
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


def _short(value: Any, width: int = 24) -> str:
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


def fold(root: Behaviour, budget: int) -> set[Any]:
    """Ids of the nodes whose children are shown, so that at most ``budget`` lines are drawn.

    Running nodes are unfolded first, then finished ones, then idle ones,
    shallow before deep, each only if its children still fit.
    """
    nodes = list(_preorder(root))
    rank = {Status.RUNNING: 0, Status.SUCCESS: 1, Status.FAILURE: 1, Status.INVALID: 2}
    order = sorted((n for n in nodes if n[0].children), key=lambda nd: (rank[nd[0].status], nd[1]))
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


def tree_lines(mission: CompiledMission, budget: int) -> list[Text]:
    """The tree as at most ``budget`` indented lines with statuses; the running path in bold."""
    opened = fold(mission.root, budget)
    out: list[Text] = []

    def walk(node: Behaviour, prefix: str) -> None:
        line = Text()
        line.append(prefix, style="grey50")
        line.append_text(label(node, mission))
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

    def __enter__(self) -> LiveView:
        self.live.__enter__()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.live.__exit__(*exc)

    def update(self, runner: Runner, *, force: bool = False) -> None:
        wall = time.monotonic()
        if not force and wall - self.last_draw < 1.0 / REFRESH_HZ and runner.mission.root.status == Status.RUNNING:
            return
        # Measure the pace over at least RTF_WINDOW of wall time: a forced redraw right
        # after the previous one (the final frame) would otherwise read as ×0.
        if self.last_draw > 0 and wall - self.last_wall >= RTF_WINDOW:
            self.rtf = (runner.now - self.last_sim) / (wall - self.last_wall)
            self.last_wall, self.last_sim = wall, runner.now
        elif self.last_draw <= 0:
            self.last_wall, self.last_sim = wall, runner.now
        self.last_draw = wall
        self.live.update(self.render(runner), refresh=True)

    def render(self, runner: Runner) -> Group:
        width, height = self.console.size
        keys = self.mission.source.view_keys
        footer = FOOTER_MIN + len(keys)
        budget = max(3, height - HEADER_LINES - footer - 1)
        parts: list[Text] = [self.header(runner, width)]
        parts.extend(tree_lines(self.mission, budget))
        parts.append(Text("─" * min(width, 80), style="grey35"))
        tip = runner.tree.tip()
        feedback = Text()
        feedback.append("▶ ", style="yellow")
        if tip is not None:
            feedback.append(tip.name, style="bold")
            feedback.append(f": {tip.feedback_message}" if tip.feedback_message else "")
        else:
            feedback.append(f"root {runner.mission.root.status.value}", style="bold")
        feedback.truncate(width, overflow="ellipsis")
        parts.append(feedback)
        for key in keys:
            line = Text()
            line.append(f"{key} = ", style="cyan")
            line.append(_short(runner.read(key), max(8, width - len(key) - 4)))
            parts.append(line)
        return Group(*parts)

    def header(self, runner: Runner, width: int) -> Text:
        obs = runner.observation
        battery = f"{obs.battery.percent:.0f} %{' ⚡' if obs.battery.charging else ''}" if obs is not None else "–"
        state = runner.read("/mission/state") or "–"
        t = runner.now - runner.start
        text = Text()
        text.append(f"{self.mission.name} ", style="bold")
        text.append(f"t {_clock(t)}  ×{self.rtf:.1f}  battery {battery}  state ")
        text.append(str(state), style="bold magenta")
        text.append(f"  tick {runner.ticks}", style="grey50")
        text.truncate(width, overflow="ellipsis")
        return text


def _clock(seconds: float) -> str:
    h, rem = divmod(int(seconds), 3600)
    m, s = divmod(rem, 60)
    return f"{h:d}:{m:02d}:{s:02d}.{int((seconds % 1) * 10)}"


class PlainLog:
    """Timestamped status-change lines for a pipe or ``--no-view``: ``[  12.30 s] Wait: RUNNING -> SUCCESS``."""

    def __init__(self, stream: TextIO):
        self.stream = stream

    def __call__(self, change: StatusChange) -> None:
        self.stream.write(change.line() + "\n")
