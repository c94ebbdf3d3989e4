"""A scripted leaf for testing trees without writing Python: ``StatusQueue`` (py_trees' ``StatusQueue``).

A mission author checks a recovery branch or a fallback's order by putting
``StatusQueue`` leaves where the real actions will go and running the
mission (``homing run … --adapter`` or the simulator): each leaf answers the
statuses it was given, one per tick.
"""

from __future__ import annotations

from typing import Any

from homing.behaviours.base import HomingBehaviour
from homing.behaviours.registry import REQUIRED, Param, register
from py_trees.common import Status

STATUS_NAMES = {"success": Status.SUCCESS, "failure": Status.FAILURE, "running": Status.RUNNING}


def parse_status(text: Any) -> Status:
    """``"success"`` / ``"FAILURE"`` / ``"Running"`` → the py_trees status; ValueError otherwise."""
    status = STATUS_NAMES.get(str(text).strip().lower())
    if status is None:
        raise ValueError(f"a status is one of success, failure, running, not {text!r}")
    return status


@register("StatusQueue")
class StatusQueue(HomingBehaviour):
    """Answer ``statuses`` one per tick, then ``eventually`` for ever (or the list again if it is null).

    py_trees ``StatusQueue``: ``statuses: [running, running, success]``
    runs for two ticks and succeeds on the third. The queue goes on where it
    was across activations (it scripts the leaf's whole life, not one run):
    ``[failure, success]`` under a ``retry`` fails the first attempt and
    succeeds the second. A halt does not rewind it.
    """

    PARAMS = (
        Param("statuses", list, REQUIRED, doc="success, failure or running, one per tick"),
        Param("eventually", str, None, doc="status once the list is used up (null: start the list again)",
              choices=tuple(STATUS_NAMES)),
    )

    def __init__(self, name: str, statuses: list[Any], eventually: str | None = None):
        if not statuses:
            raise ValueError("statuses needs at least one status")
        super().__init__(name)
        self.queue = [parse_status(s) for s in statuses]
        self.eventually = parse_status(eventually) if eventually is not None else None
        self.played = 0

    def update(self) -> Status:
        n = len(self.queue)
        if self.played < n or self.eventually is None:
            status = self.queue[self.played % n]
        else:
            status = self.eventually
        self.played += 1
        self.feedback_message = f"step {self.played}: {status.value}"
        return status
