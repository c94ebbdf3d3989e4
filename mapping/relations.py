"""SLAM accuracy from relative pose relations: the metric of Kümmerle et al., "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4), 2009.

A *relation* says how pose 2 lies seen from pose 1 — ``δ*_ij = x*_i⁻¹ ⊕ x*_j`` —
between the robot's poses at two timestamps. A trajectory is scored by
the same relative motion taken from its own poses, ``δ_ij = x_i⁻¹ ⊕ x_j``,
and the difference ``δ_ij ⊖ δ*_ij = δ*_ij⁻¹ ⊕ δ_ij``: its translation's norm
is the translational error [m], its angle the rotational error [deg]. The
paper's tables give, per data set, the mean ± standard deviation of the
absolute errors over all relations (the sample standard deviation, as its
reference implementation in Cartographer computes it) and the maximum, and
the same of the squared errors [m², deg²] (metricEvaluator's ``-q``).
Unlike an absolute trajectory error, the metric needs no alignment of the
map frames and charges an error once, where it was made.

Poses at a relation's stamps: a trajectory pose whose stamp is the
relation's as printed (within ``SAME_STAMP``: CARMEN's six significant
digits round to 10 ms past 1000 s); otherwise, inside the trajectory's
span, the pose interpolated between the two poses around the stamp
(position linearly, heading along the shorter arc), as Cartographer's
``compute_relations_metrics`` looks poses up; beyond the trajectory's ends,
the end pose if it lies within ``MATCH_TOLERANCE`` (0.1 s, the nearest-pose
tolerance of the authors' evaluator, metricEvaluator), else the relation is
listed unmatched with that reason. Taking the nearest pose up to 0.1 s away
inside the span would charge a method up to 5 cm of motion (0.5 m/s) that
is not its error — more than the graph methods' published errors — so
inside the span the pose is always interpolated. Every relation is either
scored or listed.

Relations come from a file (the data sets' ``*.relations``, one per line:
``t1 t2 x y z roll pitch yaw``; z, roll and pitch are ignored in 2-D) or are
drawn from a reference trajectory (:func:`relations_from_poses`): between
each pose and the first one at least ``LOCAL_PATH`` of path later, and
between each pose and the pose of a later revisit (at least
``REVISIT_PATH`` of path later, within ``REVISIT_RADIUS`` and
``REVISIT_ANGLE``: where both scans saw the same walls). The reference of
a *corrected* log is itself a SLAM's estimate, not ground truth: errors
below its own (a few centimetres) cannot be measured against it.

A relations file and a log may count time differently: absolute (Unix
epoch) stamps in one, seconds from the start of logging in the other (the
Radish CARMEN logs are relative: their FLASER and ODOM stamps start near
0 s, printed with six significant digits, i.e. 10 ms steps past 1000 s).
:func:`time_offset` finds the offset that puts the relations' stamps on the
log's scan stamps when one offset does so clearly better than any other,
and otherwise refuses with the offset a user would have to give.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from homing.robot.history import interpolate_pose
from homing.robot.types import Pose2

from homing.errors import UserError

LOCAL_PATH = 1.0  # [m] of reference path between the two poses of a local relation
REVISIT_PATH = 10.0  # [m] of path at least between the two poses of a revisit relation
REVISIT_RADIUS = 1.5  # [m] at most between their positions
REVISIT_ANGLE = math.radians(45.0)  # [rad] at most between their headings (the scans overlap)
SAME_STAMP = 0.006  # [s] a stamp this close to a pose's is that pose's (printed rounding: ≤ 5 ms)
MATCH_TOLERANCE = 0.1  # [s] a stamp this far beyond the trajectory's ends takes the end pose (metricEvaluator's)
EPOCH = 1e8  # [s] stamps above this are absolute (Unix time, after 1973); below, seconds from the log's start
ALIGN_BIN = 0.02  # [s] offsets this close count as one (two printed decimals past 1000 s, both ways)
ALIGN_SAMPLE = 200  # relation stamps at most tried against every scan stamp for an offset
ALIGN_MIN_SHARE = 0.5  # of the stamps tried, the share an offset must put on a scan stamp to be taken
ALIGN_MARGIN = 2.0  # and it must put this many times as many there as any other offset


@dataclass(frozen=True)
class Relation:
    """Pose at ``t2`` [s] seen from the pose at ``t1`` [s]: ``delta`` (x, y [m], θ [rad] in the frame at t1)."""

    t1: float
    t2: float
    delta: Pose2


@dataclass(frozen=True)
class Unmatched:
    """A relation that could not be scored, and why (a stamp the trajectory cannot place)."""

    relation: Relation
    reason: str


@dataclass(frozen=True)
class RelationErrors:
    """Errors over the relations scored: absolute [m], [deg] and squared [m²], [deg²]; mean, std, max each."""

    trans_mean: float
    trans_std: float
    trans_max: float
    rot_mean: float
    rot_std: float
    rot_max: float
    trans_sq_mean: float
    trans_sq_std: float
    trans_sq_max: float
    rot_sq_mean: float
    rot_sq_std: float
    rot_sq_max: float
    n: int  # relations scored
    interpolated: int  # of those, relations with a stamp between two poses (interpolated)
    unmatched: tuple[Unmatched, ...] = ()

    @property
    def missing(self) -> int:
        """Relations not scored (each listed in ``unmatched`` with its reason)."""
        return len(self.unmatched)


def relation_error(est1: Pose2, est2: Pose2, delta: Pose2) -> tuple[float, float]:
    """(translational [m], rotational [rad] ≥ 0) error of the estimated poses ``est1``, ``est2`` against ``delta``."""
    e = delta.inverse().compose(est1.between(est2))
    return math.hypot(e.x, e.y), abs(e.theta)


def _stats(values: np.ndarray) -> tuple[float, float, float]:
    if len(values) == 0:
        return math.nan, math.nan, math.nan
    std = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
    return float(np.mean(values)), std, float(np.max(values))


def pose_at(stamps: Sequence[float], poses: Sequence[Pose2], t: float,
            tolerance: float = MATCH_TOLERANCE) -> tuple[Pose2 | None, str]:
    """The trajectory's pose at ``t`` [s] and how it was found ("nearest", "interpolated"), or None and why not.

    ``stamps`` [s] ascending, one pose each (module doc: the pose of the same
    stamp, else interpolated inside the span, else an end within ``tolerance``).
    """
    if not stamps:
        return None, "the trajectory is empty"
    i = bisect.bisect_left(stamps, t)
    k = min((j for j in (i - 1, i) if 0 <= j < len(stamps)), key=lambda j: abs(stamps[j] - t))
    if abs(stamps[k] - t) <= min(SAME_STAMP, tolerance) or (abs(stamps[k] - t) <= tolerance
                                                               and not stamps[0] < t < stamps[-1]):
        return poses[k], "nearest"
    if stamps[0] < t < stamps[-1]:
        return interpolate_pose([(stamps[i - 1], poses[i - 1]), (stamps[i], poses[i])], t), "interpolated"
    if t < stamps[0]:
        return None, f"{t:.3f} s is {stamps[0] - t:.3f} s before the trajectory's first pose ({stamps[0]:.3f} s)"
    return None, f"{t:.3f} s is {t - stamps[-1]:.3f} s after the trajectory's last pose ({stamps[-1]:.3f} s)"


def score(relations: Sequence[Relation], stamps: Sequence[float], poses: Sequence[Pose2],
          tolerance: float = MATCH_TOLERANCE) -> RelationErrors:
    """Score the trajectory (``stamps`` [s] ascending, one pose each) against ``relations`` (module doc)."""
    t = [float(s) for s in stamps]
    trans, rot, interpolated, unmatched = [], [], 0, []
    for r in relations:
        (p1, how1), (p2, how2) = pose_at(t, poses, r.t1, tolerance), pose_at(t, poses, r.t2, tolerance)
        if p1 is None or p2 is None:
            unmatched.append(Unmatched(r, f"t1 {how1}" if p1 is None else f"t2 {how2}"))
            continue
        interpolated += "interpolated" in (how1, how2)
        e_t, e_r = relation_error(p1, p2, r.delta)
        trans.append(e_t)
        rot.append(math.degrees(e_r))
    tr, ro = np.array(trans), np.array(rot)
    return RelationErrors(*_stats(tr), *_stats(ro), *_stats(tr**2), *_stats(ro**2), len(trans), interpolated,
                          tuple(unmatched))


def _clock(t: float) -> str:
    return "absolute (epoch)" if t > EPOCH else "relative"


def time_offset(relations: Sequence[Relation], stamps: Sequence[float], source: str | Path = "relations") -> float:
    """[s] to subtract from the relations' stamps to put them on the log's clock (``stamps``: its scans', ascending).

    The offset that puts the most relation stamps within ``ALIGN_BIN`` of a
    scan stamp is taken when it stands out: it puts at least
    ``ALIGN_MIN_SHARE`` of them there and ``ALIGN_MARGIN`` times as many as
    any other offset, 0 included. Otherwise 0 when both count time alike,
    most relation stamps fall inside the log's span (relations from a
    denser log than this one seldom fall on its scans) and no offset puts
    most of them on scans where 0 does not; else a UserError (``source``)
    naming the offset the relations would need (the best found if it
    stands out, else the one lining up both starts).
    """
    rel = np.unique([t for r in relations for t in (r.t1, r.t2)])
    log = np.sort(np.asarray(stamps, dtype=float))
    if len(rel) == 0 or len(log) == 0:
        return 0.0
    tried = np.unique(rel[np.linspace(0, len(rel) - 1, min(len(rel), ALIGN_SAMPLE)).round().astype(int)])
    best, best_n, second_n = _best_offset(tried, log)
    at_zero = int(np.sum(_on_scans(tried, log)))
    clear = best_n >= ALIGN_MIN_SHARE * len(tried) and best_n >= ALIGN_MARGIN * second_n
    if clear and (abs(best) <= ALIGN_BIN or best_n >= ALIGN_MARGIN * max(at_zero, 1)):
        return 0.0 if abs(best) <= ALIGN_BIN else best
    inside = np.mean((rel >= log[0] - MATCH_TOLERANCE) & (rel <= log[-1] + MATCH_TOLERANCE))
    elsewhere = best_n >= ALIGN_MIN_SHARE * len(tried) and best_n >= ALIGN_MARGIN * max(at_zero, 1)
    if (np.median(rel) > EPOCH) == (np.median(log) > EPOCH) and inside >= ALIGN_MIN_SHARE and not elsewhere:
        return 0.0
    # The offset to name: the best one if it stands out, else the one lining up both starts.
    need = best if best_n >= 2 and best_n >= ALIGN_MARGIN * second_n else float(rel[0] - log[0])
    raise UserError(f"the relations' stamps ({_clock(rel[0])}, {rel[0]:.2f}–{rel[-1]:.2f} s) do not fall on the "
                    f"log's scans ({_clock(log[0])}, {log[0]:.2f}–{log[-1]:.2f} s) and no offset aligns them "
                    f"unambiguously ({best_n} of {len(tried)} stamps on scans at best, {second_n} at another "
                    f"offset); give --relations-offset {need:.3f} if that is the offset", source)


def _on_scans(t: np.ndarray, log: np.ndarray) -> np.ndarray:
    """Which stamps ``t`` [s] lie within ``ALIGN_BIN`` of a scan stamp in ``log`` (ascending)."""
    i = np.clip(np.searchsorted(log, t), 1, len(log) - 1) if len(log) > 1 else np.zeros(len(t), int)
    near = np.minimum(np.abs(log[i] - t), np.abs(log[np.maximum(i - 1, 0)] - t))
    return near <= ALIGN_BIN


def _best_offset(tried: np.ndarray, log: np.ndarray) -> tuple[float, int, int]:
    """The offset [s] putting most ``tried`` stamps on ``log``'s, how many it puts there, and the next offset's."""
    diff = (tried[:, None] - log[None, :]).ravel()  # every offset that puts a tried stamp on a scan stamp
    who = np.repeat(np.arange(len(tried), dtype=np.int64), len(log))
    best, best_n, second_n = 0.0, 0, 0
    for shift in (0.0, ALIGN_BIN / 2):  # two grids, so that a cluster on a bin edge is whole in one of them
        keys = np.floor((diff + shift) / ALIGN_BIN).astype(np.int64)
        pairs = np.unique((keys - keys.min()) * len(tried) + who)  # each tried stamp once per offset
        ks, counts = np.unique(pairs // len(tried) + keys.min(), return_counts=True)
        top = int(np.argmax(counts))
        if counts[top] > best_n:
            far = np.abs(ks - ks[top]) > 2
            best_n, second_n = int(counts[top]), int(counts[far].max(initial=0))
            best = float(np.median(diff[keys == ks[top]]))
    return best, best_n, second_n


def shifted(relations: Sequence[Relation], offset: float) -> list[Relation]:
    """``relations`` with ``offset`` [s] subtracted from both stamps."""
    return [Relation(r.t1 - offset, r.t2 - offset, r.delta) for r in relations]


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
