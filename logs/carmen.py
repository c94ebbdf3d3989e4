"""CARMEN log files (plain or ``.gz``) read into homing's run-log model: laser scans, raw odometry, corrected poses.

The format is CARMEN's logger text (Montemerlo et al., CARMEN, 2003; the
Radish repository's logs): one message per line, fields separated by
spaces, the message name first. Read here:

- ``FLASER n r_1 … r_n x y θ odom_x odom_y odom_θ ipc_stamp host logger_stamp``
  (front laser) and ``RLASER`` (the same, rear laser, looking backwards):
  beam i points at −90° + i·res in the laser frame, ``res`` = 180°/n
  rounded to the SICK's 1°, 0.5° or 0.25° (n = 180 or 181 → 1°, 360 or 361
  → 0.5°, …); the laser sits ``robot_frontlaser_offset`` (``PARAM``, [m])
  ahead of the robot's centre;
- ``ROBOTLASER1 type start_angle fov res max_range accuracy remission_mode
  n r_1 … r_n m e_1 … e_m laser_x laser_y laser_θ robot_x robot_y robot_θ
  tv rv forward_safety side_safety turn_axis ipc_stamp host logger_stamp``:
  any field of view and resolution; the laser's pose on the robot is
  ``robot⁻¹ ⊕ laser``;
- ``ODOM x y θ tv rv accel ipc_stamp host logger_stamp``: wheel odometry.

Every other message (``PARAM``, ``NEFF``, ``SYNC``, ``TRUEPOS``, …) and
``#`` comments are skipped; a line of a known message that does not parse
(too few fields, a word where a number belongs, a range count that does not
fit) is counted and skipped with a warning naming ``file:line``.

"No return" is a range at the sensor's saturation value (a SICK's 50 m,
51.15 m or 81.91 m): the largest range of the log, when at least
``NO_RETURN_SHARE`` of all beams sit within ``NO_RETURN_BAND`` of it, is
(and at least ``NO_RETURN_BEAMS``) taken as that value and every beam there reads ``inf`` (the run-log model's
"no return"); the scan's ``range_max`` is put just under it.

Odometry. In a raw log the odometry of ``ODOM`` lines (or, in a log
without any, the laser lines' ``odom_*`` fields) is one continuous stream.
A *corrected* log (a SLAM run over the raw data kept a subset of scans and
wrote its estimate into them) stores the corrected pose in the laser line
and starts the wheels afresh from it: the ``ODOM`` line right after each
laser line repeats that pose, and the following ones integrate the wheels
from there. Such a log is recognised by that repetition (on most laser
lines), and its raw odometry is rebuilt by chaining the increments
``inv(anchor) ⊕ odom`` between anchors, so that SLAM sees only what the
wheels measured; the corrected poses become the log's ``ref`` records
(a reference trajectory, not ground truth).

Frames: base_link poses in ``odom`` (the rebuilt stream starts at the
first sample's pose); scans in ``laser`` (REP-103), stamps in seconds as
the log gives them (``ipc_stamp``).
"""

from __future__ import annotations

import gzip
import math
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from homing.logs.runlog import RunLog, odometry_record, scan_record
from homing.robot.types import Odometry, Pose2, Scan, Twist2

from homing.errors import UserError

NO_RETURN_BAND = 0.2  # [m] ranges this close under the saturation value are "no return"
NO_RETURN_SHARE = 1e-3  # share of all beams that must sit at the largest range for it to mean "no return"
NO_RETURN_BEAMS = 10  # and at least this many (a log without saturation has one or two beams at its largest range)
ANCHOR_SHARE = 0.5  # share of laser lines followed by an ODOM line repeating their pose: a corrected log
SAME_POSE = 1e-9  # [m, rad] two poses this close are the same number written twice
SICK_STEPS = (1.0, 0.5, 0.25)  # [deg] angular resolutions of SICK LMS lasers (FLASER gives only n)
MIN_RANGE = 0.0  # [m] a range at or below this is a reading error (no return)
LASERS = ("FLASER", "RLASER", "ROBOTLASER1")


@dataclass
class _Laser:
    """One laser line, parsed: its scan geometry, the robot's pose fields and stamp."""

    line: int
    stamp: float
    ranges: np.ndarray  # (n,) [m] as written
    angle_min: float  # [rad]
    angle_increment: float  # [rad]
    laser_pose: Pose2  # laser in base_link
    odom: Pose2  # the robot's pose the line carries (odometry, or the corrected pose in a corrected log)
    corrected: Pose2  # the line's own estimate of the robot's pose (FLASER x y θ less the laser offset)
    max_range: float | None = None  # [m] the sensor's reach when the line states it (ROBOTLASER1)


@dataclass
class _Odom:
    line: int
    stamp: float
    pose: Pose2
    v: float
    w: float


@dataclass
class _Parsed:
    messages: list[_Laser | _Odom] = field(default_factory=list)
    params: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    malformed: int = 0
    lines: int = 0


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    """(1-based line number, text) of a plain or gzipped text file; corrupt gzip data is a UserError."""
    try:
        with path.open("rb") as probe:
            gz = probe.read(2) == b"\x1f\x8b"
        opener: Any = gzip.open if gz else open
        with opener(path, "rt", encoding="utf-8", errors="replace") as f:
            n = 0
            try:
                for n, text in enumerate(f, 1):  # noqa: B007 (n is reported below)
                    yield n, text
            except (EOFError, zlib.error, gzip.BadGzipFile) as err:
                raise UserError(f"corrupt or truncated gzip data after line {n}: {err}", path, n + 1) from None
    except OSError as err:
        raise UserError(f"cannot read CARMEN log: {err.strerror or err}", path) from None


def _sick_increment(n: int) -> float:
    """FLASER's beam spacing [rad]: 180° over n beams, snapped to a SICK resolution (180 and 181 beams → 1°)."""
    raw = 180.0 / n
    for step in SICK_STEPS:
        if abs(raw - step) <= 0.02 * step or abs(180.0 / max(n - 1, 1) - step) <= 1e-9:
            return math.radians(step)
    return math.radians(raw)


def _pose(words: list[str], i: int) -> Pose2:
    return Pose2(float(words[i]), float(words[i + 1]), float(words[i + 2]))


def _parse_flaser(words: list[str], line: int, params: dict[str, str]) -> _Laser:
    n = int(words[1])
    if n < 1 or len(words) < 2 + n + 9:
        raise ValueError(f"{words[0]} with {n} ranges needs {2 + n + 9} fields, has {len(words)}")
    ranges = np.array(words[2:2 + n], dtype=float)
    rear = words[0] == "RLASER"
    offset = float(params.get("robot_rearlaser_offset" if rear else "robot_frontlaser_offset", 0.0) or 0.0)
    laser_pose = Pose2(offset, 0.0, math.pi if rear else 0.0)
    inc = _sick_increment(n)
    laser_world = _pose(words, 2 + n)
    odom = _pose(words, 5 + n)
    stamp = float(words[8 + n])
    return _Laser(line, stamp, ranges, -math.pi / 2, inc, laser_pose, odom,
                  laser_world.compose(laser_pose.inverse()))


def _parse_robotlaser(words: list[str], line: int) -> _Laser:
    start, _fov, res, max_range = (float(w) for w in words[2:6])
    n = int(words[8])
    if n < 1 or len(words) < 9 + n + 1:
        raise ValueError(f"ROBOTLASER1 with {n} ranges is cut short ({len(words)} fields)")
    ranges = np.array(words[9:9 + n], dtype=float)
    m = int(words[9 + n])
    rest = 10 + n + m
    if m < 0 or len(words) < rest + 14:
        raise ValueError(f"ROBOTLASER1 with {n} ranges and {m} remissions needs {rest + 14} fields, has {len(words)}")
    laser_world, robot = _pose(words, rest), _pose(words, rest + 3)
    stamp = float(words[rest + 11])
    return _Laser(line, stamp, ranges, start, res, robot.between(laser_world), robot, robot,
                  max_range if max_range > 0 else None)


def _parse_odom(words: list[str], line: int) -> _Odom:
    if len(words) < 10:
        raise ValueError(f"ODOM needs 10 fields, has {len(words)}")
    return _Odom(line, float(words[7]), _pose(words, 1), float(words[4]), float(words[5]))


def parse(path: Path) -> _Parsed:
    """Every laser and odometry message of the file in order, the PARAMs, and the malformed lines' warnings."""
    out = _Parsed()
    for n, text in _lines(path):
        out.lines = n
        words = text.split()
        if not words or words[0].startswith("#"):
            continue
        name = words[0]
        try:
            if name == "PARAM" and len(words) >= 3:
                out.params[words[1]] = words[2]
            elif name in ("FLASER", "RLASER"):
                out.messages.append(_parse_flaser(words, n, out.params))
            elif name == "ROBOTLASER1":
                out.messages.append(_parse_robotlaser(words, n))
            elif name == "ODOM":
                out.messages.append(_parse_odom(words, n))
        except (ValueError, IndexError) as err:
            out.malformed += 1
            detail = str(err) if isinstance(err, ValueError) and "field" in str(err) else "a field is not a number"
            out.warnings.append(f"{path}:{n}: skipped malformed {name} line ({detail})")
            continue
        msg = out.messages[-1] if name in (*LASERS, "ODOM") and out.messages else None
        if msg is not None and not _finite(msg):
            out.messages.pop()
            out.malformed += 1
            out.warnings.append(f"{path}:{n}: skipped malformed {name} line (a field is nan or infinite)")
    return out


def _finite(m: _Laser | _Odom) -> bool:
    poses = [m.pose] if isinstance(m, _Odom) else [m.odom, m.laser_pose]
    return all(math.isfinite(v) for p in poses for v in (p.x, p.y, p.theta)) and math.isfinite(m.stamp)


def _no_return(lasers: list[_Laser]) -> float | None:
    """The saturation range meaning "no return" [m], or None when the log has none (see module doc)."""
    stated = [las for las in lasers if las.max_range is None]
    if not stated:
        return None
    ranges = np.concatenate([las.ranges for las in stated])
    top = float(ranges.max(initial=0.0))
    at_top = np.count_nonzero(ranges >= top - NO_RETURN_BAND)
    if top <= 0 or at_top < max(NO_RETURN_SHARE * len(ranges), NO_RETURN_BEAMS):
        return None
    return top


def _is_corrected(messages: list[_Laser | _Odom]) -> bool:
    """Whether the ODOM line after most laser lines repeats the pose the laser line carries (module doc)."""
    lasers = anchored = 0
    pending: _Laser | None = None
    for m in messages:
        if isinstance(m, _Laser):
            lasers += 1
            pending = m
        elif pending is not None:
            anchored += _same(m.pose, pending.odom)
            pending = None
    return lasers > 0 and anchored >= ANCHOR_SHARE * lasers


def _same(a: Pose2, b: Pose2) -> bool:
    return abs(a.x - b.x) <= SAME_POSE and abs(a.y - b.y) <= SAME_POSE and abs(a.theta - b.theta) <= SAME_POSE


def read_carmen(path: str | Path) -> RunLog:
    """The CARMEN log at ``path`` as a :class:`~homing.logs.runlog.RunLog` (scans, odometry, ``ref`` poses).

    ``meta`` holds ``format`` ("carmen"), ``corrected`` (the log stores a
    SLAM's corrected poses, see the module doc), ``no_return`` [m] and
    ``malformed_lines``; ``warnings`` names each skipped line. A file with
    no laser line is a :class:`~homing.errors.UserError`.
    """
    path = Path(path)
    parsed = parse(path)
    lasers = [m for m in parsed.messages if isinstance(m, _Laser)]
    if not lasers:
        raise UserError(f"no laser scans ({', '.join(LASERS)} lines) in {parsed.lines} lines: not a CARMEN log?",
                        path, 1, 1)
    no_return = _no_return(lasers)
    corrected = _is_corrected(parsed.messages)
    has_odom_lines = any(isinstance(m, _Odom) for m in parsed.messages)
    records: list[dict[str, Any]] = []
    raw = Pose2()  # the rebuilt odometry, odom frame
    src: Pose2 | None = None  # the last odometry sample as the log wrote it
    previous: _Laser | _Odom | None = None
    twist = Twist2()
    read_at = -math.inf  # [s] stamp of the wheels' reading ``raw`` holds (a scan's tick carries it, not its own)
    for m in parsed.messages:
        if isinstance(m, _Odom):
            twist = Twist2(m.v, m.w)
            if corrected and isinstance(previous, _Laser) and _same(m.pose, previous.odom):
                src = m.pose  # the wheels start afresh from the corrected pose: no motion (freiburg-079 stamps it 0)
            else:
                read_at = m.stamp
                raw, src = _advance(raw, src, m.pose)
                records.append(odometry_record(m.stamp, Odometry(m.stamp, raw, twist)))
        else:
            if (not corrected and not has_odom_lines) or src is None:
                raw, src = _advance(raw, src, m.odom)  # the scan line's odometry (or the first scan's)
                read_at = m.stamp
            scan = _scan(m, no_return)
            records.append(scan_record(scan))
            records.append(odometry_record(m.stamp, Odometry(min(read_at, m.stamp), raw, twist), m.stamp))
            if corrected:
                records.append({"k": "ref", "t": m.stamp, "pose": [m.corrected.x, m.corrected.y, m.corrected.theta]})
        previous = m
    meta = {"format": "carmen", "source": str(path), "corrected": corrected, "no_return": no_return,
            "malformed_lines": parsed.malformed, "scans": len(lasers)}
    return RunLog.from_records(path, meta, records, parsed.warnings)


def _advance(raw: Pose2, src: Pose2 | None, sample: Pose2) -> tuple[Pose2, Pose2]:
    """The rebuilt odometry moved by the wheels' increment from ``src`` to ``sample`` (both as the log wrote them)."""
    if src is None:
        return sample, sample
    return raw.compose(src.between(sample)), sample


def _scan(m: _Laser, no_return: float | None) -> Scan:
    ranges = m.ranges.astype(np.float32)
    reach = m.max_range if m.max_range is not None else no_return
    if reach is not None:
        cut = reach - NO_RETURN_BAND if m.max_range is None else reach
        ranges = np.where(ranges >= cut, np.inf, ranges).astype(np.float32)
        range_max = float(cut) - 1e-3 if m.max_range is None else float(reach)
    else:
        finite = ranges[np.isfinite(ranges)]
        range_max = float(finite.max(initial=0.0))
    ranges = np.where(ranges <= MIN_RANGE, np.inf, ranges).astype(np.float32)
    return Scan(m.stamp, m.angle_min, m.angle_increment, ranges, 0.0, range_max, m.laser_pose)
