"""BehaviorTree.CPP 4's ``TryCatch``: run children 1..N-1 as a sequence; if one fails, run the last ("catch") and fail.

Semantics from BT.CPP's ``src/controls/try_catch_node.cpp`` (registered
as ``TryCatch`` in BT.CPP 4's factory): the try block is a sequence with
memory (a RUNNING child is resumed on the next tick, a SUCCESS moves on, a
skipped child is passed over); when a try child fails, the try block is
reset and the catch child is ticked in the same tick; while it runs the node
is RUNNING, and whatever it ends with, the node returns FAILURE. With
``catch_on_halt`` a halt during the try block ticks the catch child once
(halting it if it is still running), as cleanup.
"""

from __future__ import annotations

from collections.abc import Iterator
from collections.abc import Sequence as Seq

from homing.behaviours.branching import halt_running
from homing.behaviours.registry import Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import Status
from py_trees.composites import Composite


@register("try_catch", kind="composite", params=(
    Param("catch_on_halt", bool, False, doc="also run the catch child (one tick) when halted in the try block"),))
class TryCatch(Composite):
    """Children 1..N-1 in sequence; on a failure run the last child, then FAIL: BT.CPP 4's ``TryCatch``.

    Use it for cleanup that must follow a failed attempt (stop the base,
    release a lock) without hiding the failure: the node fails even when the
    catch child succeeds. Needs at least two children. When the try block
    succeeds the catch child is not ticked.
    """

    def __init__(self, name: str, children: Seq[Behaviour], catch_on_halt: bool = False):
        if len(children) < 2:
            raise ValueError(f"try_catch needs at least 2 children (the try block and the catch), not {len(children)}")
        super().__init__(name=name, children=list(children))
        self.catch_on_halt = bool(catch_on_halt)
        self.index = 0
        self.in_catch = False

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.index, self.in_catch = 0, False
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self.initialise()
        if not self.in_catch:
            while self.index < len(self.children) - 1:
                child = self.children[self.index]
                self.current_child = child
                yield from child.tick()
                if child.status == Status.RUNNING:
                    self.status = Status.RUNNING
                    yield self
                    return
                if child.status == Status.FAILURE:
                    halt_running(self.children)
                    self.index, self.in_catch = 0, True
                    self.feedback_message = f"'{child.name}' failed: catching"
                    break
                self.index += 1
            else:
                self.index = 0
                self.stop(Status.SUCCESS)
                yield self
                return
        catch = self.children[-1]
        self.current_child = catch
        yield from catch.tick()
        if catch.status == Status.RUNNING:
            self.status = Status.RUNNING
            yield self
            return
        self.in_catch = False
        self.stop(Status.FAILURE)
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        if new_status == Status.INVALID and self.status == Status.RUNNING and self.catch_on_halt and not self.in_catch:
            halt_running(self.children[:-1])
            catch = self.children[-1]
            for _ in catch.tick():
                pass
            self.feedback_message = f"halted: ran the catch child ({catch.status.value})"
        halt_running(self.children)
        self.index, self.in_catch = 0, False
        super().stop(new_status)
