"""Decorators that rewrite their child's outcome: keep running, run once, and py_trees' status mappings.

``inverter``, ``force_success`` and ``force_failure`` live in
:mod:`homing.behaviours.decorators`; these complete the set BT.CPP, Nav2
and py_trees users reach for. A decorator that maps a finished child to
RUNNING starts the child afresh on its next tick (py_trees re-initialises a
child whose status is not RUNNING), so ``keep_running_until_failure`` over
a one-tick action runs it once per tick.
"""

from __future__ import annotations

from collections.abc import Iterator

import py_trees
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status


@register("keep_running_until_failure", kind="decorator")
class KeepRunningUntilFailure(py_trees.decorators.Decorator):
    """SUCCESS becomes RUNNING (the child starts again next tick); FAILURE ends it: BT.CPP ``KeepRunningUntilFailure``.

    The way to loop a sequence until one of its steps fails (``repeat: -1``
    is the same loop for success counting).
    """

    def __init__(self, name: str, child: Behaviour):
        super().__init__(name=name, child=child)

    def update(self) -> Status:
        status = self.decorated.status
        return Status.RUNNING if status == Status.SUCCESS else status


@register(
    "run_once",
    kind="decorator",
    params=(Param("then_skip", bool, True, doc="after the run: skip the node (true) or repeat its final status (false)"),),
)
class RunOnce(py_trees.decorators.Decorator):
    """Run the child to completion once for the whole run; afterwards skip it: BT.CPP ``RunOnce``.

    After the child's first SUCCESS or FAILURE, the decorator never ticks it
    again. With ``then_skip: true`` (BT.CPP's default) it is then *skipped*:
    it reports INVALID ("not ticked", ``·`` in the view), and a sequence or
    fallback passes over it as over an absent child (BT.CPP's SKIPPED). With
    ``then_skip: false`` it returns the child's final status every time, as
    ``one_shot`` does. Halts and restarts of its parents do not reset it.
    """

    def __init__(self, name: str, child: Behaviour, then_skip: bool = True):
        super().__init__(name=name, child=child)
        self.then_skip = bool(then_skip)
        self.final: Status | None = None

    def tick(self) -> Iterator[Behaviour]:
        if self.final is None:
            yield from super().tick()
            return
        self.feedback_message = "ran already: skipped" if self.then_skip else f"ran already: {self.final.value}"
        self.status = Status.INVALID if self.then_skip else self.final
        yield self

    def update(self) -> Status:
        status = self.decorated.status
        if status in (Status.SUCCESS, Status.FAILURE):
            self.final = status
        return status


@register("single_trigger", kind="decorator")
class SingleTrigger(py_trees.decorators.Decorator):
    """Run the child once per activation of the decorator, then FAILURE until it is reset: Nav2's ``SingleTrigger``.

    The child is ticked until it finishes and its status returned; after that
    the decorator answers FAILURE without ticking it, until its parent
    restarts it (py_trees resets children when a composite starts over) or
    it is halted. ``run_once`` never resets.
    """

    def __init__(self, name: str, child: Behaviour):
        super().__init__(name=name, child=child)
        self.done = False

    def tick(self) -> Iterator[Behaviour]:
        if self.status == Status.INVALID:
            self.done = False
        if not self.done:
            yield from super().tick()
            return
        self.feedback_message = "triggered already"
        self.status = Status.FAILURE
        yield self

    def update(self) -> Status:
        status = self.decorated.status
        self.done = status in (Status.SUCCESS, Status.FAILURE)
        return status


def _mapping(name: str, base: type, doc: str) -> type:
    """A registered status-mapping decorator over a py_trees class (they all take just a name and a child)."""
    cls = type(base.__name__, (base,), {"__doc__": doc, "__module__": __name__})
    return register(name, kind="decorator")(cls)


RunningIsSuccess = _mapping(
    "running_is_success", py_trees.decorators.RunningIsSuccess,
    "RUNNING becomes SUCCESS (the running child is halted); SUCCESS and FAILURE pass (py_trees ``RunningIsSuccess``).",
)  # fmt: skip
RunningIsFailure = _mapping(
    "running_is_failure", py_trees.decorators.RunningIsFailure,
    "RUNNING becomes FAILURE (the running child is halted); SUCCESS and FAILURE pass (py_trees ``RunningIsFailure``).",
)  # fmt: skip
SuccessIsRunning = _mapping(
    "success_is_running", py_trees.decorators.SuccessIsRunning,
    "SUCCESS becomes RUNNING; FAILURE passes (py_trees ``SuccessIsRunning``): wait for a failure.",
)  # fmt: skip
FailureIsRunning = _mapping(
    "failure_is_running", py_trees.decorators.FailureIsRunning,
    "FAILURE becomes RUNNING; SUCCESS passes (py_trees ``FailureIsRunning``, ``Condition(SUCCESS)``): wait until it succeeds.",
)  # fmt: skip


@register(
    "status_to_blackboard",
    kind="decorator",
    params=(Param("key", str, REQUIRED, doc="blackboard key the child's status is written to"),),
    writes=("$key",),
)
class StatusToBlackboard(py_trees.decorators.Decorator):
    """Pass the child's status through and write it (``SUCCESS``, ``FAILURE``, ``RUNNING``) to ``key`` each tick.

    py_trees ``StatusToBlackboard``; the text is what a ``Script`` compares
    against (``status == 'FAILURE'``) or a ``switch`` switches on.
    """

    def __init__(self, name: str, child: Behaviour, key: str):
        super().__init__(name=name, child=child)
        self.key = key
        self.bb = self.attach_blackboard_client(name=name)
        self.bb.register_key(key=key, access=Access.WRITE)

    def update(self) -> Status:
        status = self.decorated.status
        self.bb.set(self.key, status.value, overwrite=True)
        return status
