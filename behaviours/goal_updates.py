"""Nav2's goal-update decorators: ``GoalUpdater`` (take a new goal from outside) and ``GoalUpdatedController``.

Semantics from ``nav2_behavior_tree/plugins/decorator/goal_updater_node.cpp``
and ``goal_updated_controller.cpp``. Nav2's ``GoalUpdater`` listens to the
ROS topics ``goal_update`` / ``goals_update``; homing has no topics, so the
update is a blackboard entry (``/nav/goal_update``, ``/nav/goals_update`` by
default) that any leaf or a mission ``Script`` writes (homing has no command
that writes a running mission's blackboard from outside yet). Each
tick the decorator copies the latest update (else the input goal) to its
output and ticks its child, returning the child's status, as Nav2 does.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import py_trees
from homing.behaviours.keys import GOAL_UPDATE_KEY, GOALS_UPDATE_KEY
from homing.behaviours.paths import GOAL_KEY
from homing.behaviours.registry import Param, register
from homing.behaviours.throttles import _Trigger, changed
from py_trees.behaviour import Behaviour
from py_trees.common import Access, Status


@register("GoalUpdater", kind="decorator", params=(
    Param("input_goal", str, GOAL_KEY, doc="blackboard key of the goal in use ('' = none)"),
    Param("input_goals", str, "", doc="blackboard key of the goal list in use ('' = none)"),
    Param("output_goal", str, GOAL_KEY, doc="blackboard key the goal to pursue is written to ('' = none)"),
    Param("output_goals", str, "", doc="blackboard key the goal list to pursue is written to ('' = none)"),
    Param("update_key", str, GOAL_UPDATE_KEY, doc="blackboard key a new goal arrives at (Nav2's goal_update topic)"),
    Param("updates_key", str, GOALS_UPDATE_KEY, doc="blackboard key a new goal list arrives at (goals_update topic)"),
), reads=("$input_goal", "$input_goals"), writes=("$output_goal", "$output_goals"))  # fmt: skip
class GoalUpdater(py_trees.decorators.Decorator):
    """Pass the latest goal update (else the input goal) to the output goal, then tick the child: Nav2's ``GoalUpdater``.

    The update entries are optional: nothing in the tree needs to write them
    (``homing check`` does not ask for a writer), and while they are unset
    the input goal passes through unchanged. An empty goal list update is
    ignored, as Nav2 ignores an empty ``goals_update``. Returns the child's
    status every tick.
    """

    def __init__(self, name: str, child: Behaviour, input_goal: str = GOAL_KEY, input_goals: str = "",
                 output_goal: str = GOAL_KEY, output_goals: str = "", update_key: str = GOAL_UPDATE_KEY,
                 updates_key: str = GOALS_UPDATE_KEY):  # fmt: skip
        super().__init__(name=name, child=child)
        self.pairs = [(k_in, k_out, k_up) for k_in, k_out, k_up in
                      ((input_goal, output_goal, update_key), (input_goals, output_goals, updates_key)) if k_out]  # fmt: skip
        self.bb = self.attach_blackboard_client(name=name)
        for k_in, k_out, k_up in self.pairs:
            for key, access in ((k_in, Access.READ), (k_up, Access.READ), (k_out, Access.WRITE)):
                if key:
                    self.bb.register_key(key=key, access=access)

    def _read(self, key: str) -> Any:
        return self.bb.get(key) if key and self.bb.exists(key) else None

    def tick(self) -> Iterator[Behaviour]:
        for k_in, k_out, k_up in self.pairs:
            update = self._read(k_up)
            goal = update if update is not None and (not isinstance(update, list) or update) else self._read(k_in)
            if goal is not None:
                self.bb.set(k_out, goal, overwrite=True)
            self.feedback_message = "updated goal" if goal is update and update is not None else "goal unchanged"
        yield from super().tick()

    def update(self) -> Status:
        return self.decorated.status


@register("GoalUpdatedController", kind="decorator", params=(
    Param("goal_key", str, GOAL_KEY, doc="blackboard key of the goal watched ('' = none)"),
    Param("goals_key", str, "", doc="blackboard key of the goal list watched ('' = none)"),
), reads=("$goal_key", "$goals_key"))  # fmt: skip
class GoalUpdatedController(_Trigger):
    """Tick the child first, while it runs, and again whenever the goal changes; RUNNING otherwise: Nav2's ``GoalUpdatedController``.

    The goal (and goal list) are remembered when the decorator starts; a
    tick that finds them different ticks the child even after it finished,
    so a replanning child runs once per new goal. The child's status is
    returned when it is ticked (its SUCCESS or FAILURE ends the decorator).
    """

    def __init__(self, name: str, child: Behaviour, goal_key: str = GOAL_KEY, goals_key: str = ""):
        super().__init__(name=name, child=child)
        self.keys = [k for k in (goal_key, goals_key) if k]
        self.bb = self.attach_blackboard_client(name=name)
        for key in self.keys:
            self.bb.register_key(key=key, access=Access.READ)
        self.seen: list[Any] = []

    def _current(self) -> list[Any]:
        return [self.bb.get(k) if self.bb.exists(k) else None for k in self.keys]

    def tick(self) -> Iterator[Behaviour]:
        if self.status != Status.INVALID and self.decorated.status == Status.RUNNING:
            self.seen = self._current()  # Nav2 clears its "updated" flag whenever it ticks the running child
        yield from super().tick()

    def restart(self) -> None:
        self.seen = self._current()

    def fired(self) -> bool:
        now = self._current()
        if any(changed(old, new) for old, new in zip(self.seen, now, strict=True)):
            self.seen = now
            self.feedback_message = "goal updated"
            return True
        return False
