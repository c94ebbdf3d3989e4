"""Nav2's ``PauseResumeController``: run the RESUMED child; on a pause request run ON_PAUSE, then PAUSED until resumed.

Semantics from ``nav2_behavior_tree/plugins/control/pause_resume_controller.cpp``
(and its header's state machine). Nav2 takes its requests as two ROS
``std_srvs/Trigger`` services; homing has no services, so a request is a
blackboard entry set to true (by a leaf or a ``Script``; nothing writes a
running mission's blackboard from outside yet):
``pause_key`` asks to pause, ``resume_key`` to resume; the node takes the
request (sets the entry back to false) on its next tick. As with Nav2's
services, a pause is taken unless already PAUSED, a resume only when PAUSED.

Children, in order: RESUMED (required), PAUSED, ON_PAUSE, ON_RESUME
(optional). States go RESUMED → (pause) → ON_PAUSE → PAUSED → (resume) →
ON_RESUME → RESUMED; a request halts the running child; ON_PAUSE and
ON_RESUME last until their child succeeds (at once when there is none); a
missing PAUSED child keeps the node RUNNING while paused. The node succeeds
only when the RESUMED child succeeds and fails when any child fails.
"""

from __future__ import annotations

from collections.abc import Iterator
from collections.abc import Sequence as Seq

import py_trees
from homing.behaviours.branching import halt_running
from homing.behaviours.registry import Param, register
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status
from py_trees.composites import Composite

RESUMED, PAUSED, PAUSE_REQUESTED, ON_PAUSE, RESUME_REQUESTED, ON_RESUME = (
    "RESUMED", "PAUSED", "PAUSE_REQUESTED", "ON_PAUSE", "RESUME_REQUESTED", "ON_RESUME")  # fmt: skip
CHILD_INDEX = {RESUMED: 0, PAUSED: 1, ON_PAUSE: 2, ON_RESUME: 3}
NEXT_STATE = {PAUSE_REQUESTED: ON_PAUSE, ON_PAUSE: PAUSED, RESUME_REQUESTED: ON_RESUME, ON_RESUME: RESUMED}


@register("pause_resume_controller", kind="composite", params=(
    Param("pause_key", str, "/pause", doc="blackboard entry set true to ask for a pause (Nav2's pause service)"),
    Param("resume_key", str, "/resume", doc="blackboard entry set true to ask to resume (Nav2's resume service)"),
), writes=("$pause_key", "$resume_key"))  # fmt: skip
class PauseResumeController(Composite):
    """Run the work child; pause and resume it on request, with optional paused, on-pause and on-resume children: Nav2's ``PauseResumeController``.

    Use it to let an operator (or a mission rule) hold a running task and
    carry it on later: the RESUMED child is halted on a pause and started
    afresh on resume.
    """

    def __init__(self, name: str, children: Seq[Behaviour], pause_key: str = "/pause", resume_key: str = "/resume"):
        if not 1 <= len(children) <= 4:
            raise ValueError(f"pause_resume_controller takes 1 to 4 children, not {len(children)}")
        super().__init__(name=name, children=list(children))
        self.pause_key, self.resume_key = pause_key, resume_key
        self.bb = py_trees.blackboard.Client(name=name)
        for key in (pause_key, resume_key):
            self.bb.register_key(key=key, access=Access.WRITE)
        self.state = RESUMED

    def _take(self, key: str) -> bool:
        """Whether a request is waiting at ``key``; it is taken (set false) either way, as a service call is answered."""
        asked = bool(self.bb.get(key)) if self.bb.exists(key) else False
        if asked:
            self.bb.set(key, False, overwrite=True)
        return asked

    def _next(self) -> None:
        self.state = NEXT_STATE.get(self.state, self.state)

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.RUNNING:
            self.state = RESUMED
            self.initialise()
        if self._take(self.pause_key) and self.state != PAUSED:
            self.state = PAUSE_REQUESTED
        if self._take(self.resume_key) and self.state == PAUSED:
            self.state = RESUME_REQUESTED
        if self.state in (PAUSE_REQUESTED, RESUME_REQUESTED):
            halt_running(self.children)
            for child in self.children:
                if child.status != Status.INVALID:
                    child.stop(Status.INVALID)
            self._next()
        index = CHILD_INDEX[self.state]
        self.feedback_message = self.state
        if index >= len(self.children):
            self._next()
            self.status = Status.RUNNING
            yield self
            return
        child = self.children[index]
        self.current_child = child
        yield from child.tick()
        if child.status == Status.RUNNING:
            self.status = Status.RUNNING
        elif child.status == Status.FAILURE:
            self.stop(Status.FAILURE)
        elif self.state == RESUMED:
            self.stop(Status.SUCCESS)
        else:
            self._next()
            self.status = Status.RUNNING
        yield self

    def stop(self, new_status: Status = Status.INVALID) -> None:
        halt_running(self.children)
        if new_status == Status.INVALID:
            self.state = RESUMED
        super().stop(new_status)
