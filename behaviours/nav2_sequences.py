"""Nav2's two newer sequences: ``NonblockingSequence`` and ``PersistentSequence``.

Semantics from ``nav2_behavior_tree/plugins/control/nonblocking_sequence.cpp``
and ``persistent_sequence.cpp`` (Nav2 rolling):

- ``nonblocking_sequence`` ticks every child on every tick, from the first,
  whether or not the ones before it still run (a child that succeeded on an
  earlier tick is started again); the first FAILURE halts them all and
  fails the node; it succeeds when every child succeeds in the same tick.
- ``persistent_sequence`` keeps its place in a blackboard entry
  (``current_child_idx`` in Nav2), read on every tick and written as it
  moves on, so the place survives the node being halted or the tree
  being rebuilt; a failure or the end writes 0 back.
"""

from __future__ import annotations

from collections.abc import Iterator
from collections.abc import Sequence as Seq
from typing import Any

import py_trees
from homing.behaviours.branching import halt_running
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status
from py_trees.composites import Composite


@register("nonblocking_sequence", kind="composite")
class NonblockingSequence(Composite):
    """Tick every child each tick; fail on the first failure, succeed when all succeed together: Nav2's ``NonblockingSequence``.

    Unlike ``sequence`` a running child does not hold back the ones after
    it; unlike ``parallel`` a child that already succeeded is ticked again
    (and restarted) on the next tick, so the node succeeds only on a tick in
    which every child succeeds. Use it for checks and actions that must all
    hold at once (e.g. "arrived" and "stopped").
    """

    def __init__(self, name: str, children: Seq[Behaviour]):
        super().__init__(name=name, children=list(children))

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        all_success = True
        for child in self.children:
            self.current_child = child
            yield from child.tick()
            if child.status == Status.FAILURE:
                self.feedback_message = f"'{child.name}' failed"
                self.stop(Status.FAILURE)
                yield self
                return
            if child.status == Status.RUNNING:
                all_success = False
        if all_success:
            self.stop(Status.SUCCESS)
        else:
            self.status = Status.RUNNING
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halt_running(self.children)
        super().stop(new_status)


@register("persistent_sequence", kind="composite", params=(
    Param("index_key", str, REQUIRED, doc="blackboard key of the index of the child to run (Nav2's current_child_idx)"),),
    reads=(), writes=("$index_key",))  # fmt: skip
class PersistentSequence(Composite):
    """A sequence whose place is a blackboard entry, read each tick and written as it moves on: Nav2's ``PersistentSequence``.

    Each tick starts at the child the entry names (0 when unset) and goes on
    while children succeed (a skipped one is passed over), writing the index
    of the next one; a RUNNING child makes the node RUNNING; a FAILURE
    writes 0 and fails the node; the end writes 0 and succeeds. Another node
    (a ``Script``, say) may write the entry to jump to a child.
    """

    def __init__(self, name: str, children: Seq[Behaviour], index_key: str):
        super().__init__(name=name, children=list(children))
        self.index_key = index_key
        self.bb = py_trees.blackboard.Client(name=name)
        self.bb.register_key(key=index_key, access=Access.WRITE)

    def _index(self) -> int:
        value: Any = self.bb.get(self.index_key) if self.bb.exists(self.index_key) else 0
        return int(value or 0)

    def _write(self, index: int) -> None:
        self.bb.set(self.index_key, index, overwrite=True)

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.initialise()
        index = self._index()
        while index < len(self.children):
            child = self.children[index]
            self.current_child = child
            yield from child.tick()
            if child.status == Status.RUNNING:
                self.status = Status.RUNNING
                self.feedback_message = f"at child {index} ('{child.name}')"
                yield self
                return
            if child.status == Status.FAILURE:
                self._write(0)
                self.feedback_message = f"'{child.name}' failed: back to child 0"
                self.stop(Status.FAILURE)
                yield self
                return
            index += 1
            self._write(index)
        self._write(0)
        self.stop(Status.SUCCESS)
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halt_running(self.children)
        super().stop(new_status)
