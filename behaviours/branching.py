"""Branching control nodes: ``if_then_else``, ``while_do_else`` and ``switch`` (BehaviorTree.CPP's).

Each one picks a branch from a condition subtree or a blackboard value, with
the semantics of BT.CPP v4's ``IfThenElse``, ``WhileDoElse`` and
``Switch2``…``Switch6`` spelt out tick by tick below. py_trees has none of
them (its idiom is a selector over guarded sequences). Branches are named
slots in YAML (``if:``, ``then:``, ``else:``), positional children in
BT.CPP's XML (the importer maps one onto the other).

Whenever one of these nodes finishes, whatever is still RUNNING below it is
halted (BT.CPP's ``resetChildren``), so nothing below a finished node runs on.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from collections.abc import Sequence as Seq
from typing import Any

from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status
from py_trees.composites import Composite


def halt_running(nodes: Seq[Behaviour]) -> None:
    """Halt (``stop(INVALID)``) every node in ``nodes`` that is RUNNING."""
    for node in nodes:
        if node.status == Status.RUNNING:
            node.stop(Status.INVALID)


class _Branching(Composite):
    """A composite that halts whatever still runs below it whenever it finishes or is halted."""

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halt_running(self.children)
        super().stop(new_status)

    def _reset_children(self) -> None:
        for child in self.children:
            if child.status != Status.INVALID:
                child.stop(Status.INVALID)

    def _run(self, child: Behaviour) -> Iterator[Behaviour]:
        """Tick ``child`` and take its status: RUNNING goes on, anything else finishes this node."""
        self.current_child = child
        yield from child.tick()
        if child.status == Status.RUNNING:
            self.status = Status.RUNNING
        else:
            self.stop(child.status)
        yield self


@register("if_then_else", kind="composite", slots=("if", "then", "else"), optional=("else",))
class IfThenElse(_Branching):
    """Tick ``if`` until it decides, then run ``then`` (SUCCESS) or ``else`` (FAILURE) to the end: BT.CPP ``IfThenElse``.

    Not reactive: once a branch is chosen, the condition is not ticked again
    until the branch finishes; the node returns the branch's status. A
    condition that returns RUNNING makes the node RUNNING and is ticked
    again on the next tick. Without ``else``, a false condition returns
    FAILURE. Use ``while_do_else`` for a condition checked on every tick.
    """

    def __init__(self, name: str, **branches: Behaviour | None):
        condition, then, other = branches.get("if"), branches.get("then"), branches.get("else")
        if condition is None or then is None:
            raise ValueError("if_then_else needs 'if' and 'then' (and optionally 'else')")
        super().__init__(name=name, children=[c for c in (condition, then, other) if c is not None])
        self.branch = 0  # 0: deciding, 1: then, 2: else

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.branch = 0
            self._reset_children()
            self.initialise()
        if self.branch == 0:
            condition = self.children[0]
            self.current_child = condition
            yield from condition.tick()
            if condition.status == Status.SUCCESS:
                self.branch = 1
            elif condition.status == Status.FAILURE and len(self.children) == 3:
                self.branch = 2
            elif condition.status == Status.FAILURE:
                self.feedback_message = f"'{condition.name}' is false and there is no else"
                self.stop(Status.FAILURE)
                yield self
                return
            else:
                self.status = Status.RUNNING
                yield self
                return
        yield from self._run(self.children[self.branch])

    def stop(self, new_status: Status = Status.INVALID) -> None:
        self.branch = 0
        super().stop(new_status)


@register("while_do_else", kind="composite", slots=("while", "do", "else"), optional=("else",))
class WhileDoElse(_Branching):
    """Re-check ``while`` every tick: SUCCESS runs ``do``, FAILURE runs ``else``, switching halts the other: BT.CPP ``WhileDoElse``.

    Reactive: the condition is ticked first on every tick; when its answer
    changes, the branch that was running is halted and the other one ticked.
    A condition that returns RUNNING makes the node RUNNING without ticking
    either branch (a running branch is neither ticked nor halted, as in
    BT.CPP). Without ``else``, a false condition halts ``do`` and returns
    FAILURE. The node returns the ticked branch's status.
    """

    def __init__(self, name: str, **branches: Behaviour | None):
        condition, do, other = branches.get("while"), branches.get("do"), branches.get("else")
        if condition is None or do is None:
            raise ValueError("while_do_else needs 'while' and 'do' (and optionally 'else')")
        super().__init__(name=name, children=[c for c in (condition, do, other) if c is not None])

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self._reset_children()
            self.initialise()
        condition = self.children[0]
        self.current_child = condition
        yield from condition.tick()
        if condition.status == Status.RUNNING:
            self.status = Status.RUNNING
            yield self
            return
        if condition.status == Status.SUCCESS:
            chosen: Behaviour | None = self.children[1]
            halt_running(self.children[2:])
        else:
            chosen = self.children[2] if len(self.children) == 3 else None
            halt_running(self.children[1:2])
        if chosen is None:
            self.feedback_message = f"'{condition.name}' is false and there is no else"
            self.stop(Status.FAILURE)
            yield self
            return
        yield from self._run(chosen)


def same_value(value: Any, case: Any) -> bool:
    """BT.CPP's switch comparison: equal values, equal text, or equal numbers (``"1"`` matches ``1.0``)."""
    if value == case and type(value) is not bool and type(case) is not bool:
        return True
    if isinstance(value, bool) or isinstance(case, bool):
        return str(value).lower() == str(case).lower()
    if str(value) == str(case):
        return True
    try:
        return math.isclose(float(value), float(case), rel_tol=0.0, abs_tol=1e-9)
    except (TypeError, ValueError):
        return False


@register(
    "switch",
    kind="composite",
    params=(
        Param("key", str, REQUIRED, doc="blackboard key whose value picks the branch"),
        Param("cases", list, REQUIRED, doc="the values, one per child; the last child is the default"),
    ),
    reads=("$key",),
)
class Switch(_Branching):
    """Run the child whose case equals the value at ``key``, else the last (default) child: BT.CPP ``Switch2``…``Switch6``.

    ``cases: [explore, dock]`` takes three children: one per case and the
    default. Reactive: the value is read on every tick, and when it selects
    another child than the one RUNNING, that one is halted first. A value
    matches a case when they are equal as values, as text or as numbers
    (``"2"`` matches ``2``), as BT.CPP compares. An unset key selects the
    default. Returns the selected child's status.
    """

    def __init__(self, name: str, key: str, cases: list[Any], children: Seq[Behaviour]):
        if len(children) != len(cases) + 1:
            raise ValueError(
                f"switch needs one child per case plus a default: {len(cases)} cases, so {len(cases) + 1} "
                f"children, not {len(children)}"
            )
        super().__init__(name=name, children=list(children))
        self.key, self.cases = key, list(cases)
        self.bb = self.attach_blackboard_client(name=name)
        self.bb.register_key(key=key, access=Access.READ)

    def selected(self) -> int:
        """Index of the child the value at ``key`` selects now (the default when unset or unmatched)."""
        try:
            value = self.bb.get(self.key)
        except KeyError:
            return len(self.cases)
        return next((i for i, case in enumerate(self.cases) if same_value(value, case)), len(self.cases))

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self._reset_children()
            self.initialise()
        index = self.selected()
        halt_running([c for i, c in enumerate(self.children) if i != index])
        self.feedback_message = f"case {self.cases[index]!r}" if index < len(self.cases) else "default"
        yield from self._run(self.children[index])
