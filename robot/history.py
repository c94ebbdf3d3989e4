"""Odometry history: where ``base_link`` was in ``odom`` at a past stamp (a sensor's, an image's).

Sensors stamp their readings when they were taken, not when the tree sees
them: a scan or an image is a fraction of a second older than the
observation's odometry. :class:`PoseHistory` keeps the last ``span`` seconds
of poses and interpolates between the two samples that bracket a stamp.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence

from homing.robot.frames import wrap_angle
from homing.robot.types import Pose2


def interpolate_pose(history: Sequence[tuple[float, Pose2]], stamp: float) -> Pose2:
    """Pose at ``stamp`` [s], linear between the two bracketing samples of ``history`` (ordered by stamp).

    Outside the history's span the nearest end is used. Raises ValueError on an empty history.
    """
    if not history:
        raise ValueError("no odometry yet")
    stamps = [t for t, _ in history]
    i = bisect.bisect_left(stamps, stamp)
    if i <= 0:
        return history[0][1]
    if i >= len(history):
        return history[-1][1]
    (t0, p0), (t1, p1) = history[i - 1], history[i]
    a = 0.0 if t1 <= t0 else (stamp - t0) / (t1 - t0)
    return Pose2(p0.x + a * (p1.x - p0.x), p0.y + a * (p1.y - p0.y),
                 wrap_angle(p0.theta + a * wrap_angle(p1.theta - p0.theta)))


class PoseHistory:
    """The last ``span`` seconds of (stamp, pose); :meth:`at` interpolates. A stamp going back clears it."""

    def __init__(self, span: float) -> None:
        self.span = float(span)  # [s]
        self.samples: list[tuple[float, Pose2]] = []

    def add(self, stamp: float, pose: Pose2) -> None:
        """Append a sample (a repeated stamp is ignored; an older one starts a new history)."""
        if self.samples and stamp <= self.samples[-1][0]:
            if stamp == self.samples[-1][0]:
                return
            self.samples.clear()
        self.samples.append((float(stamp), pose))
        cut = 0
        while cut < len(self.samples) - 2 and self.samples[cut][0] < stamp - self.span:
            cut += 1
        if cut:
            del self.samples[:cut]

    def at(self, stamp: float) -> Pose2:
        """Pose at ``stamp`` [s] (see :func:`interpolate_pose`)."""
        return interpolate_pose(self.samples, stamp)

    def __len__(self) -> int:
        return len(self.samples)
