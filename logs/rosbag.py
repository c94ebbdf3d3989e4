"""ROS 1 and ROS 2 bags (``.bag``; a rosbag2 folder, ``.db3`` or ``.mcap``) read into homing's run-log model, through ``rosbags``.

`rosbags <https://gitlab.com/ternaris/rosbags>`_ (pure Python, no ROS
install) opens the bag and decodes its messages with the definitions the
bag carries. Read here:

- ``sensor_msgs/LaserScan`` (``--scan-topic``, or the only topic of that
  type): any field of view, beam count and range limits; a range that is
  NaN, infinite or outside ``[range_min, range_max]`` is "no return"
  (``inf``, as in the run-log model);
- ``nav_msgs/Odometry`` (``--odom-topic``, or the only topic of that
  type): base_link in ``odom``, position, yaw and twist (v, ω);
- ``/tf_static`` and ``/tf`` (``tf2_msgs/TFMessage``): the laser's pose in
  the robot's frame (the Odometry's ``child_frame_id``), composed along the
  tree; identity, with a warning, if the bag does not say.

Stamps are the messages' header stamps [s]. The odometry pose at a scan's
stamp is interpolated between the two odometry messages around it. A bag
that cannot be opened or decoded (corrupt, truncated, not a bag) is a
:class:`~homing.errors.UserError` naming the file.
"""

from __future__ import annotations

import bisect
import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from homing.missions.runlog import RunLog, odometry_record, scan_record
from homing.robot.types import Odometry, Pose2, Scan, Twist2

from homing.errors import UserError

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"
TF_TYPE = "tf2_msgs/msg/TFMessage"


@dataclass(frozen=True)
class _OdomSample:
    stamp: float
    pose: Pose2
    twist: Twist2


def stamp_of(header: Any) -> float:
    """A std_msgs/Header's stamp in seconds."""
    return float(header.stamp.sec) + 1e-9 * float(header.stamp.nanosec)


def yaw_of(q: Any) -> float:
    """Yaw [rad] of a geometry_msgs/Quaternion (rotation about z; roll and pitch ignored)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _choose(connections: Sequence[Any], msgtype: str, topic: str | None, flag: str, path: Path) -> str:
    """The topic to read: ``topic`` if given (it must exist with that type), else the only one of ``msgtype``."""
    by_topic = {c.topic: c.msgtype for c in connections}
    if topic is not None:
        if topic not in by_topic:
            raise UserError(f"{flag} {topic}: no such topic (topics: {', '.join(sorted(by_topic)) or 'none'})", path)
        if by_topic[topic] != msgtype:
            raise UserError(f"{flag} {topic}: is {by_topic[topic]}, not {msgtype}", path)
        return topic
    found = sorted(t for t, ty in by_topic.items() if ty == msgtype)
    if not found:
        raise UserError(f"no {msgtype} topic in the bag (topics: {', '.join(sorted(by_topic)) or 'none'})", path)
    if len(found) > 1:
        raise UserError(f"several {msgtype} topics ({', '.join(found)}): choose one with {flag}", path)
    return found[0]


def _scan(msg: Any, laser_pose: Pose2) -> Scan:
    r = np.asarray(msg.ranges, dtype=np.float32)
    ok = np.isfinite(r) & (r >= msg.range_min) & (r <= msg.range_max)
    ranges = np.where(ok, r, np.inf).astype(np.float32)
    return Scan(stamp_of(msg.header), float(msg.angle_min), float(msg.angle_increment), ranges,
                float(msg.range_min), float(msg.range_max), laser_pose)


def _frame(name: str) -> str:
    return name.lstrip("/")


def laser_in_base(tf: dict[str, tuple[str, Pose2]], base: str, laser: str) -> Pose2 | None:
    """The pose of frame ``laser`` in frame ``base`` from child → (parent, pose in parent) edges; None if unlinked."""
    up: list[tuple[str, Pose2]] = []  # laser → root
    frame, pose = laser, Pose2()
    seen = set()
    while True:
        up.append((frame, pose))
        if frame == base:
            return pose
        if frame not in tf or frame in seen:
            break
        seen.add(frame)
        parent, rel = tf[frame]
        frame, pose = parent, rel.compose(pose)
    # base is not above the laser: walk up from base to a common ancestor.
    in_root = dict(up)
    frame, pose, seen = base, Pose2(), set()
    while frame not in in_root:
        if frame not in tf or frame in seen:
            return None
        seen.add(frame)
        parent, rel = tf[frame]
        frame, pose = parent, rel.compose(pose)
    return pose.inverse().compose(in_root[frame])


def read_bag(path: str | Path, scan_topic: str | None = None, odom_topic: str | None = None) -> RunLog:
    """The bag at ``path`` as a :class:`~homing.missions.runlog.RunLog` of odometry and scans (see module doc)."""
    path = Path(path)
    try:
        return _read(path, scan_topic, odom_topic)
    except UserError:
        raise
    except FileNotFoundError as err:
        raise UserError(f"cannot read bag: {err}", path) from None
    except Exception as err:  # rosbags' reader errors and decoding errors of damaged data alike
        if not _is_data_error(err):
            raise
        text = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise UserError(f"corrupt, truncated or unreadable bag: {text}", path) from None


def _is_data_error(err: Exception) -> bool:
    from rosbags.highlevel import AnyReaderError
    from rosbags.rosbag1 import ReaderError as Reader1Error
    from rosbags.rosbag2 import ReaderError as Reader2Error

    return isinstance(err, (AnyReaderError, Reader1Error, Reader2Error, struct.error, EOFError, ValueError,
                            IndexError, KeyError, OSError, UnicodeDecodeError, AssertionError))


def _read(path: Path, scan_topic: str | None, odom_topic: str | None) -> RunLog:
    from rosbags.highlevel import AnyReader

    warnings: list[str] = []
    with AnyReader([path]) as reader:
        scan_t = _choose(reader.connections, SCAN_TYPE, scan_topic, "--scan-topic", path)
        odom_t = _choose(reader.connections, ODOM_TYPE, odom_topic, "--odom-topic", path)
        tf: dict[str, tuple[str, Pose2]] = {}
        odom: list[_OdomSample] = []
        scans: list[Any] = []
        base = laser = None
        wanted = [c for c in reader.connections if c.topic in (scan_t, odom_t) or c.msgtype == TF_TYPE]
        for conn, _t, raw in reader.messages(connections=wanted):
            msg: Any = reader.deserialize(raw, conn.msgtype)
            if conn.msgtype == TF_TYPE:
                for t in msg.transforms:
                    tr = t.transform.translation
                    tf.setdefault(_frame(t.child_frame_id),
                                  (_frame(t.header.frame_id), Pose2(float(tr.x), float(tr.y), yaw_of(t.transform.rotation))))
            elif conn.topic == odom_t:
                p = msg.pose.pose
                base = base or _frame(msg.child_frame_id)
                odom.append(_OdomSample(stamp_of(msg.header), Pose2(float(p.position.x), float(p.position.y),
                                                                     yaw_of(p.orientation)),
                                        Twist2(float(msg.twist.twist.linear.x), float(msg.twist.twist.angular.z))))
            else:
                laser = laser or _frame(msg.header.frame_id)
                scans.append(msg)
    if not scans:
        raise UserError(f"topic {scan_t} holds no messages", path)
    if not odom:
        raise UserError(f"topic {odom_t} holds no messages", path)
    lp = laser_in_base(tf, base or "base_link", laser or "laser")
    if lp is None:
        warnings.append(f"{path}: no transform from {base} to {laser} in /tf or /tf_static: the laser is taken "
                        f"to sit at {base}'s origin")
        lp = Pose2()
    odom.sort(key=lambda o: o.stamp)
    records = _records(odom, [_scan(m, lp) for m in scans])
    meta = {"format": "rosbag", "source": str(path), "scan_topic": scan_t, "odom_topic": odom_t,
            "base_frame": base, "laser_frame": laser, "scans": len(scans)}
    return RunLog.from_records(path, meta, records, warnings)


def _records(odom: list[_OdomSample], scans: list[Scan]) -> list[dict[str, Any]]:
    """obs records for every odometry message and every scan (odometry interpolated at its stamp), in stamp order."""
    stamps = [o.stamp for o in odom]
    timeline: list[tuple[float, int, dict[str, Any]]] = []
    for o in odom:
        timeline.append((o.stamp, 1, odometry_record(o.stamp, Odometry(o.stamp, o.pose, o.twist))))
    for s in sorted(scans, key=lambda s: s.stamp):
        at = odom_at(stamps, odom, s.stamp)
        timeline.append((s.stamp, 0, scan_record(s)))
        timeline.append((s.stamp, 0, odometry_record(s.stamp, Odometry(s.stamp, at.pose, at.twist), s.stamp)))
    timeline.sort(key=lambda e: (e[0], e[1]))
    return [r for _, _, r in timeline]


def odom_at(stamps: list[float], odom: list[_OdomSample], t: float) -> _OdomSample:
    """The odometry at ``t`` [s], linear between the samples around it; the nearest end outside them."""
    i = bisect.bisect_left(stamps, t)
    if i <= 0:
        return odom[0]
    if i >= len(odom):
        return odom[-1]
    a, b = odom[i - 1], odom[i]
    w = (t - a.stamp) / (b.stamp - a.stamp) if b.stamp > a.stamp else 1.0
    d = a.pose.between(b.pose)
    return _OdomSample(t, a.pose.compose(Pose2(w * d.x, w * d.y, w * d.theta)), a.twist)
