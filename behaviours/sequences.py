"""Two more sequences: Nav2's ``PipelineSequence`` and BT.CPP's ``SequenceWithMemory``.

homing's ``sequence`` (BT.CPP ``Sequence``) resumes at a running child and
starts over after a failure; ``reactive_sequence`` re-ticks every child on
every tick. These two sit on either side:

- ``pipeline_sequence`` re-ticks the children it has already reached (so a
  rate-limited planner keeps replanning while the controller follows), but
  never starts a child before the one before it has succeeded once.
- ``sequence_with_memory`` does not even start over after a failure: the
  next activation retries the child that failed.

Both pass over a skipped child (one left INVALID by its tick, e.g. a
``run_once`` that already ran), as BT.CPP passes over SKIPPED.
"""

from __future__ import annotations

from collections.abc import Iterator
from collections.abc import Sequence as Seq

from homing.behaviours.branching import halt_running
from homing.behaviours.registry import register
from py_trees.behaviour import Behaviour
from py_trees.common import Status
from py_trees.composites import Composite


@register("pipeline_sequence", kind="composite")
class PipelineSequence(Composite):
    """Tick the first child until it succeeds, then the first two, then the first three…: Nav2's ``PipelineSequence``.

    Every tick walks the children from the first: a child that succeeds lets
    the walk go on; a RUNNING child before the furthest one reached is left
    running and the walk goes on too; a RUNNING child at or past the
    furthest stops the walk (RUNNING). Any FAILURE halts every running child
    and fails the node; when the last child succeeds, the running ones are
    halted and the node succeeds. A finished child that is reached again is
    started afresh. Nav2's navigators put ``rate_controller`` (replanning)
    before ``FollowPath`` in one. The furthest child reached is forgotten
    when the node finishes or is halted.
    """

    def __init__(self, name: str, children: Seq[Behaviour]):
        super().__init__(name=name, children=list(children))
        self.furthest = 0

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.furthest = 0
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self.initialise()
        for index, child in enumerate(self.children):
            self.current_child = child
            yield from child.tick()
            if child.status == Status.FAILURE:
                self.stop(Status.FAILURE)
                yield self
                return
            if child.status == Status.RUNNING and index >= self.furthest:
                self.furthest = index
                self.status = Status.RUNNING
                self.feedback_message = f"reached '{child.name}' ({index + 1} of {len(self.children)})"
                yield self
                return
        self.stop(Status.SUCCESS)
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halt_running(self.children)
        self.furthest = 0
        super().stop(new_status)


@register("sequence_with_memory", kind="composite")
class SequenceWithMemory(Composite):
    """A sequence that keeps its place even across a failure: BT.CPP ``SequenceWithMemory`` (``SequenceStar`` in v3).

    Children succeed in turn as in ``sequence``; on a FAILURE the node fails
    but remembers the child that failed, and the next activation starts
    there rather than at the first child. Only running through to the end
    (SUCCESS) starts it over. A halt keeps the place too (BT.CPP does not
    reset it in ``halt()``). Use it for steps that must not be repeated once
    done (undocking before a retry of the exploration that follows).
    """

    def __init__(self, name: str, children: Seq[Behaviour]):
        super().__init__(name=name, children=list(children))
        self.index = 0

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            for child in self.children[self.index:]:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self.initialise()
        while self.index < len(self.children):
            child = self.children[self.index]
            self.current_child = child
            yield from child.tick()
            if child.status == Status.RUNNING:
                self.status = Status.RUNNING
                yield self
                return
            if child.status == Status.FAILURE:
                self.feedback_message = f"failed at '{child.name}'; resumes there"
                self.stop(Status.FAILURE)
                yield self
                return
            self.index += 1
        self.index = 0
        self.stop(Status.SUCCESS)
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halt_running(self.children)
        super().stop(new_status)
