"""SLAM accuracy from relative pose relations: the metric of Kümmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009.

A *relation* says how pose 2 lies seen from pose 1 — ``δ*_ij = x*_i⁻¹ ⊕ x*_j`` —
between the robot's poses at two timestamps. A trajectory is scored by
the same relative motion taken from its own poses, ``δ_ij = x_i⁻¹ ⊕ x_j``,
and the difference ``δ_ij ⊖ δ*_ij = δ*_ij⁻¹ ⊕ δ_ij``: its translation's norm
is the translational error [m], its angle the rotational error [deg]. The
paper's tables give, per data set, the mean ± standard deviation of the
absolute errors over all relations (the sample standard deviation, as its
reference implementation in Cartographer computes it) and the maximum.
Unlike an absolute trajectory error, the metric needs no alignment of the
map frames and charges an error once, where it was made.

Relations come from a file (the data sets' ``*.relations``, one per line:
``t1 t2 x y z roll pitch yaw``; z, roll and pitch are ignored in 2-D) or are
drawn from a reference trajectory (:func:`relations_from_poses`): between
each pose and the first one at least ``LOCAL_PATH`` of path later, and
between each pose and the pose of a later revisit (at least
``REVISIT_PATH`` of path later, within ``REVISIT_RADIUS`` and
``REVISIT_ANGLE``: where both scans saw the same walls). The reference of
a *corrected* log is itself a SLAM's estimate, not ground truth: errors
below its own (a few centimetres) cannot be measured against it.

Poses are looked up at a relation's stamps among the scored trajectory's
stamps, within ``STAMP_TOLERANCE``; a relation with a stamp not found is
left out and counted.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from homing.robot.types import Pose2

from homing.errors import UserError

LOCAL_PATH = 1.0  # [m] of reference path between the two poses of a local relation
REVISIT_PATH = 10.0  # [m] of path at least between the two poses of a revisit relation
REVISIT_RADIUS = 1.5  # [m] at most between their positions
REVISIT_ANGLE = math.radians(45.0)  # [rad] at most between their headings (the scans overlap)
STAMP_TOLERANCE = 1e-3  # [s] a relation's stamp matches a trajectory stamp this close


@dataclass(frozen=True)
class Relation:
    """Pose at ``t2`` [s] seen from the pose at ``t1`` [s]: ``delta`` (x, y [m], θ [rad] in the frame at t1)."""

    t1: float
    t2: float
    delta: Pose2


@dataclass(frozen=True)
class RelationErrors:
    """Absolute errors over the relations scored: translational [m] and rotational [deg], mean, std, max."""

    trans_mean: float
    trans_std: float
    trans_max: float
    rot_mean: float
    rot_std: float
    rot_max: float
    n: int  # relations scored
    missing: int  # relations whose stamps the trajectory has not got


def relation_error(est1: Pose2, est2: Pose2, delta: Pose2) -> tuple[float, float]:
    """(translational [m], rotational [rad] ≥ 0) error of the estimated poses ``est1``, ``est2`` against ``delta``."""
    e = delta.inverse().compose(est1.between(est2))
    return math.hypot(e.x, e.y), abs(e.theta)


def _stats(values: np.ndarray) -> tuple[float, float, float]:
    if len(values) == 0:
        return math.nan, math.nan, math.nan
    std = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
    return float(np.mean(values)), std, float(np.max(values))


def score(relations: Sequence[Relation], stamps: Sequence[float], poses: Sequence[Pose2],
          tolerance: float = STAMP_TOLERANCE) -> RelationErrors:
    """Score the trajectory (``stamps`` [s] ascending, one pose each) against ``relations`` (module doc)."""
    t = list(stamps)
    trans, rot, missing = [], [], 0
    for r in relations:
        i, j = _find(t, r.t1, tolerance), _find(t, r.t2, tolerance)
        if i is None or j is None:
            missing += 1
            continue
        e_t, e_r = relation_error(poses[i], poses[j], r.delta)
        trans.append(e_t)
        rot.append(math.degrees(e_r))
    tm, ts, tx = _stats(np.array(trans))
    rm, rs, rx = _stats(np.array(rot))
    return RelationErrors(tm, ts, tx, rm, rs, rx, len(trans), missing)


def _find(stamps: list[float], t: float, tolerance: float) -> int | None:
    i = bisect.bisect_left(stamps, t)
    best = min((k for k in (i - 1, i) if 0 <= k < len(stamps)), key=lambda k: abs(stamps[k] - t), default=None)
    return best if best is not None and abs(stamps[best] - t) <= tolerance else None


def relations_from_poses(stamps: Sequence[float], poses: Sequence[Pose2]) -> list[Relation]:
    """Local and revisit relations drawn from a reference trajectory (rules in the module doc)."""
    xy = np.array([(p.x, p.y) for p in poses]).reshape(-1, 2)
    th = np.array([p.theta for p in poses])
    path = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))]) if len(xy) else np.zeros(0)
    out: list[Relation] = []
    for i in range(len(poses)):
        j = int(np.searchsorted(path, path[i] + LOCAL_PATH))
        if j < len(poses):
            out.append(Relation(stamps[i], stamps[j], poses[i].between(poses[j])))
        later = np.nonzero(path >= path[i] + REVISIT_PATH)[0]
        if len(later):
            d = np.hypot(xy[later, 0] - xy[i, 0], xy[later, 1] - xy[i, 1])
            turn = np.abs(np.angle(np.exp(1j * (th[later] - th[i]))))
            ok = (d <= REVISIT_RADIUS) & (turn <= REVISIT_ANGLE)
            if ok.any():
                k = int(later[ok][np.argmin(d[ok])])
                out.append(Relation(stamps[i], stamps[k], poses[i].between(poses[k])))
    return out


def read_relations(path: str | Path) -> list[Relation]:
    """A relations file: ``t1 t2 x y z roll pitch yaw`` per line (``#`` comments); a bad line is a UserError."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as err:
        raise UserError(f"cannot read relations: {err.strerror or err}", p) from None
    out = []
    for n, line in enumerate(text.splitlines(), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        if len(words) != 8:
            raise UserError(f"a relation has 8 numbers (t1 t2 x y z roll pitch yaw), this line {len(words)}", p, n, 1)
        try:
            t1, t2, x, y, _z, _roll, _pitch, yaw = (float(w) for w in words)
        except ValueError:
            col = 1 + line.index(next(w for w in words if not _is_float(w)))
            raise UserError("not a number", p, n, col) from None
        if not all(math.isfinite(v) for v in (t1, t2, x, y, yaw)):
            raise UserError("a relation's numbers must be finite", p, n, 1)
        out.append(Relation(t1, t2, Pose2(x, y, yaw)))
    if not out:
        raise UserError("no relations in the file", p)
    return out


def _is_float(w: str) -> bool:
    try:
        float(w)
    except ValueError:
        return False
    return True
