"""Smooth a blackboard path on the navigation costmap in one tick: Nav2's ``SmoothPath`` with its ``SimpleSmoother``.

Nav2's ``SmoothPath`` (``nav2_behavior_tree/plugins/action/smooth_path_action.cpp``)
asks the smoother server (``nav2_smoother``) to smooth a path with its
plugin, by default ``SimpleSmoother``, and optionally to check the result
for collisions. homing runs the same smoothing
(:func:`homing.navigation.smoother.smooth_path`) on its navigation
service's costmap, within the tick. Paths are homing's (N, 3) blackboard
paths (:mod:`homing.behaviours.paths`); the end heading is kept.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from homing.behaviours.base import HomingBehaviour
from homing.behaviours.keys import NAVIGATOR_KEY
from homing.behaviours.motion import FAILURE_KEY, FAILURE_PARAM
from homing.behaviours.paths import PATH_KEY
from homing.behaviours.registry import Param, register
from homing.navigation.costmap import INSCRIBED, LETHAL
from homing.navigation.smoother import smooth_path
from py_trees.common import Status

# The typed reasons SmoothPath writes that a recovery can help with (Nav2's WouldASmootherRecoveryHelp:
# UNKNOWN, TIMEOUT, FAILED_TO_SMOOTH_PATH, SMOOTHED_PATH_IN_COLLISION; homing's smoothing never times out or throws).
SMOOTHER_REASONS = ("smoothed_path_in_collision", "failed", "timed_out")


@register("SmoothPath")
class SmoothPath(HomingBehaviour):
    """Smooth the path at ``input_key`` and write it to ``output_key``: Nav2's ``SmoothPath`` (``SimpleSmoother``).

    Inner points move towards the mid-point of their neighbours while held
    to the original (weights 0.2 and 0.3, Nav2's defaults), never onto an
    inscribed or lethal cell of the costmap; the ends stay. SUCCESS with
    the smoothed path, and ``True`` at ``completed_key`` (when given) if
    the smoothing converged, ``False`` if it stopped early at the last
    admissible path (Nav2's ``was_completed``). With
    ``check_for_collisions``, FAILURE (reason ``smoothed_path_in_collision``)
    if a point of the result lies on an inscribed or lethal cell, where the
    round robot would touch an obstacle; FAILURE ``invalid_path`` for a
    missing or one-point path, ``no_navigator`` without the navigation service.
    """

    PARAMS = (
        Param("input_key", str, PATH_KEY, doc="blackboard key of the path to smooth"),
        Param("output_key", str, PATH_KEY, doc="blackboard key the smoothed path is written to"),
        Param("check_for_collisions", bool, False, doc="fail if the smoothed path touches an obstacle"),
        Param("completed_key", str, "", doc="blackboard key told whether smoothing converged ('' = none)"),
        FAILURE_PARAM,
    )
    READS = (NAVIGATOR_KEY, "$input_key")
    WRITES = ("$output_key", "$failure_key", "$completed_key")

    def __init__(self, name: str, input_key: str = PATH_KEY, output_key: str = PATH_KEY,
                 check_for_collisions: bool = False, completed_key: str = "",
                 failure_key: str = FAILURE_KEY) -> None:  # fmt: skip
        self.input_key, self.output_key, self.failure_key = input_key, output_key, failure_key
        self.completed_key = completed_key
        super().__init__(name)
        self.check = check_for_collisions

    def _keys(self, keys: Any) -> list[str]:  # '' means "no such key": nothing to register
        return [k for k in super()._keys(keys) if k]

    def _fail(self, reason: str, message: str) -> Status:
        self.write(self.failure_key, reason)
        self.feedback_message = message
        return Status.FAILURE

    def update(self) -> Status:
        navigator, raw = self.read(NAVIGATOR_KEY), self.read(self.input_key)
        if navigator is None:
            return self._fail("no_navigator", "no navigation service (add 'navigation' to services)")
        path = np.asarray(raw if raw is not None else np.zeros((0, 3)), dtype=float).reshape(-1, 3)
        if len(path) < 2:
            return self._fail("invalid_path", f"no path to smooth at {self.input_key}")
        xy, completed = smooth_path(path[:, :2], navigator.costmap.cost_at)
        out = path.copy()
        out[:, :2] = xy
        if self.check:
            cost = navigator.costmap.cost_at(xy)
            hit = np.flatnonzero((cost == INSCRIBED) | (cost == LETHAL))
            if len(hit):
                x, y = xy[hit[0]]
                return self._fail("smoothed_path_in_collision", f"the smoothed path touches an obstacle at ({x:.2f}, {y:.2f})")
        self.write(self.output_key, out)
        self.write(self.failure_key, None)
        if self.completed_key:
            self.write(self.completed_key, completed)
        self.feedback_message = f"{len(out)} points smoothed" + ("" if completed else " (stopped early)")
        return Status.SUCCESS
