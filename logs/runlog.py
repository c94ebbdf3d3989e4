"""Run logs: one self-describing, append-only file of everything a run sensed and commanded.

Format (version 1). The file starts with the magic line ``HOMINGLOG 1\\n``,
then a sequence of *frames*; each frame is an 8-byte header (payload length
and CRC-32 of the payload, both little-endian uint32) followed by a
zlib-compressed UTF-8 JSON payload. The first frame is the header
``{"meta": {...}, "schema": {...}}``: the run's metadata (world, seed,
mission, versions) and a description of every record kind and its fields.
Every later frame holds ``{"records": [...]}``, each record a JSON object
whose ``"k"`` names its kind (see :data:`SCHEMA`).

Writing: :class:`Recorder` buffers records and appends one frame per second
(of adapter time or of wall time, whichever comes first), each with a single
``write`` and an ``fsync``. A killed run therefore loses at most its last
second, and a frame cut short by the kill fails its length or CRC check and
is ignored: what was written before it stays readable. (The log is appended,
not written through ``homing.atomic.atomic_write``: rewriting the whole file
every second would cost O(n²); the CRC frame is the unit of atomicity.)

Truth (the simulator's real pose) is recorded as its own kind and never
mixed into what the robot sensed: :meth:`RunLog.observations` cannot see it,
only :meth:`RunLog.truth` can, for evaluation code.

Reading: :class:`RunLog` reads every intact frame (``truncated`` tells
whether the file ended mid-frame, as a killed run's may) and replays
observations, tag sightings, commands and status changes up to an optional
time cut. Damage is told apart from a kill: a frame whose bytes are all
there but fail their CRC, or one that claims more than any writer writes, is
corruption, reported with its byte offset (:class:`UserError`; with
``salvage=True`` the frames before it are read and ``damage`` says where it
is). A log whose magic line names a newer format version says so. Floats survive
exactly (JSON's shortest round-trip repr; scan ranges as float32 bytes), so
an offline replay feeds SLAM the same numbers the online run did.
"""

from __future__ import annotations

import base64
import json
import math
import os
import re
import struct
import time
import zlib
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from homing.perception.apriltag import TagMeasurement
from homing.robot.types import (
    IR,
    BatteryState,
    Bumpers,
    CameraImage,
    ChargingSource,
    ChargingState,
    DockIR,
    Observation,
    Odometry,
    Pose2,
    Scan,
    Twist2,
)

from homing.atomic import NEW_FILE_MODE
from homing.errors import UserError

MAGIC = b"HOMINGLOG 1\n"
VERSION = 1
FLUSH_PERIOD = 1.0  # [s] longest a record waits in memory (adapter or wall time)
MAX_FRAME = 256 * 2**20  # [bytes] no writer writes a bigger frame (one second of a run is ~100 kB): beyond, damage
JPEG_QUALITY = 85  # camera images in the log (``Recorder(images=True)``)
_FRAME = struct.Struct("<II")  # payload length, CRC-32
_MAGIC_LINE = re.compile(rb"HOMINGLOG (\d{1,9})\n")

SCHEMA: dict[str, dict[str, str]] = {
    "obs": {
        "t": "observation stamp [s], adapter clock",
        "odom": "[stamp s, x m, y m, theta rad, v m/s, omega rad/s] base_link in odom",
        "bump": "[left, centre, right] bool",
        "ir": "[right, centre, left] dock IR bit sets (kobuki codes)",
        "bat": "[voltage V, percent, source, state] kobuki battery",
        "cbat": "computer battery like bat, or null",
        "scan_t": "stamp of the latest scan (its own 'scan' record), or null",
        "img_t": "stamp of the latest camera image, or null (pixels are not logged)",
    },
    "scan": {
        "t": "scan stamp [s]",
        "amin": "angle_min [rad]", "ainc": "angle_increment [rad]",
        "rmin": "range_min [m]", "rmax": "range_max [m]",
        "lp": "laser pose in base_link [x m, y m, theta rad]",
        "r": "ranges: base64 of little-endian float32 [m], inf = no return",
    },
    "tags": {
        "t": "stamp of the tick (observation) the sightings were fed to SLAM at [s]",
        "m": "list of [id, image stamp s, x m, y m, theta rad (face heading), cov 9 (x,y,theta row-major, base_link),"
             " range m, bearing rad, view_angle rad, decision_margin, hamming, height m, yaw source ('tag' or 'wall')]",
    },
    "cmd": {"t": "stamp [s]", "v": "forward speed sent [m/s]", "w": "yaw rate sent [rad/s]"},
    "status": {"t": "stamp [s]", "node": "tree node name", "s": "new status (SUCCESS/FAILURE/RUNNING/INVALID)"},
    "truth": {"t": "stamp [s]", "pose": "[x m, y m, theta rad] true base_link in the world (simulator only)"},
    "ref": {"t": "stamp [s]", "pose": "[x m, y m, theta rad] an imported log's own corrected base_link pose"
            " (e.g. a corrected CARMEN log's): a reference trajectory, not ground truth"},
    "event": {"t": "stamp [s]", "what": "free text", "data": "any JSON"},
    "plan": {"t": "stamp [s] of the tick it changed at", "path": "navigator's planned path [[x m, y m], …] in map, or null",
             "goal": "exploration goal [x m, y m, theta rad] in map, or null"},
    "img": {"t": "image stamp [s]", "jpeg": "base64 JPEG of the camera image",
            "K": "[fx, fy, cx, cy] pixels", "size": "[width, height] pixels"},
}


def _f32_b64(a: np.ndarray) -> str:
    return base64.b64encode(np.asarray(a, dtype="<f4").tobytes()).decode("ascii")


def _b64_f32(s: str) -> np.ndarray:
    return np.frombuffer(base64.b64decode(s, validate=True), dtype="<f4").astype(np.float32)


def _bat(b: BatteryState | None) -> list[Any] | None:
    return None if b is None else [b.voltage, b.percent, b.source.value, b.state.value]


def _unbat(a: list[Any] | None) -> BatteryState | None:
    return None if a is None else BatteryState(a[0], a[1], ChargingSource(a[2]), ChargingState(a[3]))


def encode_tag(m: TagMeasurement) -> list[Any]:
    """A :class:`TagMeasurement` as the JSON list of a ``tags`` record (pose and covariance only)."""
    return [m.tag_id, m.stamp, m.pose.x, m.pose.y, m.pose.theta, [float(v) for v in np.ravel(m.covariance)],
            m.range_m, m.bearing, m.view_angle, m.decision_margin, m.hamming, m.height, m.yaw_source]


def decode_tag(a: Sequence[Any]) -> TagMeasurement:
    """Inverse of :func:`encode_tag` (the 4 × 4 pose is rebuilt upright; corners are not kept)."""
    x, y, th, h = a[2], a[3], a[4], a[11]
    c, s = math.cos(th), math.sin(th)
    T = np.array([[-s, 0.0, -c, x], [c, 0.0, -s, y], [0.0, -1.0, 0.0, h], [0.0, 0.0, 0.0, 1.0]])
    return TagMeasurement(int(a[0]), a[1], Pose2(x, y, th), np.array(a[5], dtype=float).reshape(3, 3),
                          a[6], a[7], a[8], a[9], int(a[10]), h, T, np.zeros((4, 2)),
                          str(a[12]) if len(a) > 12 else "tag")


def _read_frame(raw: bytes, pos: int, first: bool) -> tuple[str, Any, int]:
    """(problem, decoded frame, end offset) of the frame at ``pos``; problem "" if sound, "torn" if cut short."""
    if pos + _FRAME.size > len(raw):
        return "torn", None, len(raw)
    n, crc = _FRAME.unpack_from(raw, pos)
    if n > MAX_FRAME:
        return f"a frame header claims {n} bytes, more than any writer writes (the header is damaged)", None, 0
    start, end = pos + _FRAME.size, pos + _FRAME.size + n
    if end > len(raw):
        return "torn", None, len(raw)
    if zlib.crc32(raw[start:end]) != crc:
        return f"the frame at bytes {pos}–{end - 1} fails its CRC check (its data is damaged)", None, 0
    try:
        frame = json.loads(zlib.decompress(raw[start:end]))
    except (zlib.error, ValueError) as err:
        return f"the frame at bytes {pos}–{end - 1} does not decode ({err})", None, 0
    problem = _check_header(frame) if first else _check_records(frame)
    return (f"the frame at bytes {pos}–{end - 1}: {problem}" if problem else ""), frame, end


def _before(frames: list[Any]) -> str:
    stamps = [r["t"] for f in frames[1:] for r in f["records"]]
    return f"{len(frames)} intact frames before it, up to t={max(stamps):.1f} s" if stamps else \
        f"{len(frames)} intact frames before it"


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _numbers(v: Any, n: int) -> bool:
    return isinstance(v, list) and len(v) == n and all(_number(x) for x in v)


def _battery(v: Any) -> bool:
    return v is None or (isinstance(v, list) and len(v) == 4 and _number(v[0]) and _number(v[1])
                         and v[2] in {s.value for s in ChargingSource} and v[3] in {s.value for s in ChargingState})


_FIELDS: dict[str, dict[str, Any]] = {  # what each field of a record must be, per kind (SCHEMA says what it means)
    "obs": {"odom": lambda v: _numbers(v, 6), "bump": lambda v: isinstance(v, list) and len(v) == 3,
            "ir": lambda v: isinstance(v, list) and len(v) == 3 and all(isinstance(x, int) for x in v),
            "bat": _battery, "cbat": _battery, "scan_t": lambda v: v is None or _number(v),
            "img_t": lambda v: v is None or _number(v)},
    "scan": {"amin": _number, "ainc": _number, "rmin": _number, "rmax": _number, "lp": lambda v: _numbers(v, 3),
             "r": lambda v: isinstance(v, str)},
    "tags": {"m": lambda v: isinstance(v, list) and all(isinstance(m, list) and len(m) >= 12 for m in v)},
    "cmd": {"v": _number, "w": _number},
    "status": {"node": lambda v: isinstance(v, str), "s": lambda v: isinstance(v, str)},
    "truth": {"pose": lambda v: _numbers(v, 3)},
    "event": {"what": lambda v: isinstance(v, str), "data": lambda v: True},
    "ref": {"pose": lambda v: _numbers(v, 3)},
    "plan": {"path": lambda v: v is None or (isinstance(v, list) and all(_numbers(q, 2) for q in v)),
             "goal": lambda v: v is None or _numbers(v, 3)},
    "img": {"jpeg": lambda v: isinstance(v, str), "K": lambda v: _numbers(v, 4), "size": lambda v: _numbers(v, 2)},
}  # a kind not listed here (a later addition) is kept unchecked: readers pick the kinds they know


def _check_header(frame: Any) -> str:
    if not isinstance(frame, dict) or not isinstance(frame.get("meta", {}), dict):
        return "the header is not a mapping with 'meta'"
    return ""


def _check_records(frame: Any) -> str:
    """Why a frame's records do not fit the schema ("" if they do)."""
    records = frame.get("records") if isinstance(frame, dict) else None
    if not isinstance(records, list):
        return "no 'records' list"
    for i, r in enumerate(records):
        kind = r.get("k") if isinstance(r, dict) else None
        if not isinstance(kind, str) or not _number(r.get("t")):
            return f"record {i} has no kind and stamp"
        fields = _FIELDS.get(kind, {})
        for name, ok in fields.items():
            if name not in r or not ok(r[name]):
                return f"record {i} ({kind}) has a bad '{name}'"
    return ""


def scan_record(scan: Scan) -> dict[str, Any]:
    """A ``scan`` record of :data:`SCHEMA` holding ``scan`` exactly (ranges as float32)."""
    lp = scan.laser_pose
    return {"k": "scan", "t": scan.stamp, "amin": scan.angle_min, "ainc": scan.angle_increment,
            "rmin": scan.range_min, "rmax": scan.range_max, "lp": [lp.x, lp.y, lp.theta], "r": _f32_b64(scan.ranges)}


def odometry_record(stamp: float, odom: Odometry, scan_t: float | None = None) -> dict[str, Any]:
    """An ``obs`` record of a robot that reports odometry (and a scan at ``scan_t``) and nothing else.

    Bumpers released, no dock IR, no battery: what an imported log (a
    CARMEN log, a ROS bag) tells of a tick.
    """
    return {"k": "obs", "t": float(stamp),
            "odom": [odom.stamp, odom.pose.x, odom.pose.y, odom.pose.theta, odom.twist.v, odom.twist.omega],
            "bump": [False, False, False], "ir": [0, 0, 0], "bat": None, "cbat": None,
            "scan_t": scan_t, "img_t": None}


class Recorder:
    """Append a run's records to ``path`` in CRC-checked frames, one per second at most.

    ``meta`` describes the run (world, seed, mission…; JSON-serialisable).
    Call :meth:`close` at the end (also a context manager). Not thread-safe.
    """

    def __init__(self, path: str | Path, meta: Mapping[str, Any] | None = None,
                 flush_period: float = FLUSH_PERIOD, fsync: bool = True, images: bool = False) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.flush_period = float(flush_period)
        self.fsync = fsync
        self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, NEW_FILE_MODE)  # less the umask
        os.write(self._fd, MAGIC)
        self._write_frame({"meta": dict(meta or {}), "schema": SCHEMA, "version": VERSION})
        self._buf: list[dict[str, Any]] = []
        self._buf_t0: float | None = None
        self._wall0 = time.monotonic()
        self._last_scan_t: float | None = None
        self.images = images  # also log camera images (JPEG)
        self._last_image_t: float | None = None
        self._last_plan: Any = (None, None)
        self._ticked = False  # an observation was recorded: frames break at tick starts only
        self._in_tick = False  # the previous record was a scan or an observation

    # -- records -----------------------------------------------------------

    def record_observation(self, obs: Observation) -> None:
        """Everything the robot sensed this tick (the scan only when it is new)."""
        scan = obs.scan
        if scan is not None and scan.stamp != self._last_scan_t:
            self._last_scan_t = scan.stamp
            self._add(scan_record(scan))
        o = obs.odom
        self._add({
            "k": "obs", "t": obs.stamp,
            "odom": [o.stamp, o.pose.x, o.pose.y, o.pose.theta, o.twist.v, o.twist.omega],
            "bump": [obs.bumpers.left, obs.bumpers.centre, obs.bumpers.right],
            "ir": [int(obs.dock_ir.right), int(obs.dock_ir.centre), int(obs.dock_ir.left)],
            "bat": _bat(obs.battery), "cbat": _bat(obs.computer_battery),
            "scan_t": None if scan is None else scan.stamp,
            "img_t": None if obs.image is None else obs.image.stamp,
        })

    def record_tags(self, stamp: float, tags: Sequence[TagMeasurement]) -> None:
        """The tag sightings fed to SLAM at the tick ``stamp`` [s] (nothing if empty)."""
        if tags:
            self._add({"k": "tags", "t": float(stamp), "m": [encode_tag(m) for m in tags]})

    def record_plan(self, stamp: float, path: np.ndarray | None, goal: Pose2 | None) -> None:
        """The navigator's path ((N, 2) [m], map) and the exploration goal, when either changed since the last call."""
        key = (None if path is None else np.asarray(path, dtype=float).round(4).tobytes(),
               None if goal is None else (goal.x, goal.y, goal.theta))
        if key == self._last_plan:
            return
        self._last_plan = key
        self._add({"k": "plan", "t": float(stamp),
                   "path": None if path is None else np.asarray(path, dtype=float).round(4).tolist(),
                   "goal": None if goal is None else [goal.x, goal.y, goal.theta]})

    def record_image(self, image: CameraImage | None) -> None:
        """A new camera image, as JPEG (only with ``images=True``: a run's images are large)."""
        if not self.images or image is None or image.stamp == self._last_image_t:
            return
        import cv2

        self._last_image_t = image.stamp
        pixels = image.image if image.image.ndim == 2 else image.image[..., ::-1]  # OpenCV writes BGR
        ok, jpeg = cv2.imencode(".jpg", pixels, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
        if ok:
            i = image.info
            self._add({"k": "img", "t": image.stamp, "jpeg": base64.b64encode(jpeg.tobytes()).decode("ascii"),
                       "K": [i.fx, i.fy, i.cx, i.cy], "size": [i.width, i.height]})

    def record_command(self, stamp: float, twist: Twist2) -> None:
        """The velocity command sent at ``stamp`` [s]."""
        self._add({"k": "cmd", "t": float(stamp), "v": twist.v, "w": twist.omega})

    def record_status(self, node: str, status: str, stamp: float) -> None:
        """A tree node's status change at ``stamp`` [s]."""
        self._add({"k": "status", "t": float(stamp), "node": node, "s": str(status)})

    def record_truth(self, pose: Pose2, stamp: float) -> None:
        """The simulator's true pose (evaluation only; kept apart from what was sensed)."""
        self._add({"k": "truth", "t": float(stamp), "pose": [pose.x, pose.y, pose.theta]})

    def record_event(self, stamp: float, what: str, data: Any = None) -> None:
        """Anything else worth keeping (a fault injected, a mission state)."""
        self._add({"k": "event", "t": float(stamp), "what": what, "data": data})

    # -- frames ------------------------------------------------------------

    def _add(self, rec: dict[str, Any]) -> None:
        t = float(rec["t"])
        # Frames break only where a tick starts (before its scan/observation), so a
        # tick's observation and the sightings SLAM took at it never straddle a
        # frame that a kill could tear.
        if rec["k"] in ("scan", "obs"):
            self._ticked = True
        starts_tick = rec["k"] == "scan" or (rec["k"] == "obs" and not self._in_tick)
        if (starts_tick or not self._ticked) and self._due(t):
            self.flush()
        self._in_tick = rec["k"] in ("scan", "obs")
        if self._buf_t0 is None:
            self._buf_t0 = t
        self._buf.append(rec)

    def _due(self, t: float) -> bool:
        if self._buf_t0 is None:
            return False
        return t - self._buf_t0 >= self.flush_period or time.monotonic() - self._wall0 >= self.flush_period

    def flush(self) -> None:
        """Append the buffered records as one frame now."""
        if self._buf:
            self._write_frame({"records": self._buf})
        self._buf, self._buf_t0, self._wall0 = [], None, time.monotonic()

    def _write_frame(self, payload: Mapping[str, Any]) -> None:
        data = zlib.compress(json.dumps(payload, separators=(",", ":")).encode("utf-8"), 6)
        os.write(self._fd, _FRAME.pack(len(data), zlib.crc32(data)) + data)
        if self.fsync:
            os.fsync(self._fd)

    def close(self) -> None:
        """Flush and close (idempotent)."""
        if self._fd >= 0:
            self.flush()
            os.close(self._fd)
            self._fd = -1

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True)
class Tick:
    """One replayed tick: the observation and the tag sightings SLAM took at it."""

    obs: Observation
    tags: list[TagMeasurement]


class RunLog:
    """A run log read back: every intact frame, up to the first torn or damaged one.

    ``meta`` and ``schema`` come from the header; ``truncated`` is True if
    the file ended inside a frame (a killed run). A damaged frame (bytes all
    there, CRC wrong; an impossible length; a record that does not fit the
    schema) raises :class:`UserError` naming its byte offset, unless
    ``salvage`` is set: then reading stops before it and ``damage`` holds
    the report. ``warnings`` lists what a reader skipped (an imported log's
    malformed lines, each naming its place); :meth:`from_records` builds one
    from records in memory (the importers of :mod:`homing.logs`).
    """

    def __init__(self, path: str | Path, *, salvage: bool = False) -> None:
        self.path = Path(path)
        try:
            raw = self.path.read_bytes()
        except OSError as err:
            raise UserError(f"cannot read run log: {err.strerror}", self.path) from None
        magic = _MAGIC_LINE.match(raw)
        if magic is None:
            raise UserError("not a homing run log (bad magic line)", self.path, 1, 1)
        version = int(magic.group(1))
        if version > VERSION:
            raise UserError(f"run log format version {version} is newer than this homing reads (version {VERSION}): "
                            "replay it with a newer homing", self.path, 1, 1)
        if version != VERSION:
            raise UserError(f"unknown run log format version {version} (this homing reads version {VERSION})",
                            self.path, 1, 1)
        frames: list[Any] = []
        self.truncated = False
        self.damage: str | None = None
        pos = magic.end()
        while pos < len(raw):
            problem, frame, end = _read_frame(raw, pos, first=not frames)
            if problem == "torn":
                self.truncated = True
                break
            if problem:
                self.damage = f"byte {pos}: {problem} ({_before(frames)})"
                if not salvage:
                    raise UserError(f"corrupted run log at {self.damage}; 'homing replay --salvage' reads up to it",
                                    self.path)
                break
            frames.append(frame)
            pos = end
        if not frames:
            raise UserError("run log has no header", self.path)
        head = frames[0]
        self.meta: dict[str, Any] = head.get("meta", {})
        self.schema: dict[str, Any] = head.get("schema", {})
        self.records: list[dict[str, Any]] = [r for f in frames[1:] for r in f["records"]]
        self.warnings: list[str] = []

    @classmethod
    def from_records(cls, path: str | Path, meta: Mapping[str, Any], records: Sequence[dict[str, Any]],
                     warnings: Sequence[str] = ()) -> RunLog:
        """A run log held in memory: ``records`` of :data:`SCHEMA`'s kinds in stamp order, read from ``path``."""
        log = cls.__new__(cls)
        log.path, log.meta, log.schema = Path(path), dict(meta), dict(SCHEMA)
        log.records, log.truncated, log.warnings = list(records), False, list(warnings)
        log.damage = None
        return log

    def of_kind(self, kind: str, until: float | None = None) -> Iterator[dict[str, Any]]:
        """Raw records of one kind, in order, with stamp ≤ ``until`` [s] if given."""
        for r in self.records:
            if r["k"] == kind and (until is None or r["t"] <= until):
                yield r

    def ticks(self, until: float | None = None) -> Iterator[Tick]:
        """Each tick as the robot saw it, with the tag sightings SLAM took at it, up to ``until`` [s].

        Image pixels are not logged, so ``obs.image`` is None; ``obs.scan``
        is the latest scan, exactly as it was.
        """
        scan: Scan | None = None
        current: Tick | None = None
        for r in self.records:
            if until is not None and r["t"] > until:
                break
            k = r["k"]
            try:
                if k == "scan":
                    lp = r["lp"]
                    scan = Scan(r["t"], r["amin"], r["ainc"], _b64_f32(r["r"]), r["rmin"], r["rmax"], Pose2(*lp))
                elif k == "obs":
                    if current is not None:
                        yield current
                    current = Tick(self._obs(r, scan), [])
                elif k == "tags" and current is not None and r["t"] == current.obs.stamp:
                    current.tags.extend(decode_tag(m) for m in r["m"])
            except (ValueError, TypeError, IndexError) as err:  # binascii.Error is a ValueError
                raise UserError(f"malformed {k} record at t={r['t']} s: {err}", self.path) from None
        if current is not None:
            yield current

    @staticmethod
    def _obs(r: dict[str, Any], scan: Scan | None) -> Observation:
        od = r["odom"]
        return Observation(
            stamp=r["t"],
            odom=Odometry(od[0], Pose2(od[1], od[2], od[3]), Twist2(od[4], od[5])),
            scan=scan if r["scan_t"] is not None else None,
            image=None,
            bumpers=Bumpers(*r["bump"]),
            dock_ir=DockIR(IR(r["ir"][0]), IR(r["ir"][1]), IR(r["ir"][2])),
            battery=_unbat(r["bat"]),  # type: ignore[arg-type]
            computer_battery=_unbat(r["cbat"]),
        )

    def truth(self, until: float | None = None) -> list[tuple[float, Pose2]]:
        """The simulator's true poses (evaluation code only)."""
        return [(r["t"], Pose2(*r["pose"])) for r in self.of_kind("truth", until)]

    def reference(self, until: float | None = None) -> list[tuple[float, Pose2]]:
        """An imported log's own corrected poses (``ref`` records): a reference to score against, not truth."""
        return [(r["t"], Pose2(*r["pose"])) for r in self.of_kind("ref", until)]

    def commands(self, until: float | None = None) -> list[tuple[float, Twist2]]:
        return [(r["t"], Twist2(r["v"], r["w"])) for r in self.of_kind("cmd", until)]

    def statuses(self, until: float | None = None) -> list[tuple[float, str, str]]:
        return [(r["t"], r["node"], r["s"]) for r in self.of_kind("status", until)]

    @property
    def end(self) -> float:
        """Stamp of the last intact record [s] (the cut, for a killed run)."""
        return max((r["t"] for r in self.records), default=0.0)
