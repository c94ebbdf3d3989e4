"""Any log as a ROS 2 bag in MCAP, with standard messages: opens in Foxglove, plays with ``ros2 bag play``.

Written with ``rosbags``' rosbag2 writer (MCAP storage, CDR, the message
definitions of ROS 2 Humble embedded in the file), as a rosbag2 folder
(``metadata.yaml`` and ``<name>_0.mcap``). Topics (those the log has data
for; frames per REP-105):

| topic | type | from |
| --- | --- | --- |
| ``/scan`` | ``sensor_msgs/msg/LaserScan`` (frame ``laser``) | every scan |
| ``/odom`` | ``nav_msgs/msg/Odometry`` (``odom`` → ``base_link``) | every tick |
| ``/tf`` | ``tf2_msgs/msg/TFMessage``: ``odom → base_link`` every tick, ``map → odom`` at every scan | odometry, the SLAM run over the log |
| ``/tf_static`` | ``tf2_msgs/msg/TFMessage``: ``base_link → laser`` (transient local) | the scans' laser pose |
| ``/map`` | ``nav_msgs/msg/OccupancyGrid`` (frame ``map``), every ``MAP_PERIOD`` and at the end | the SLAM run over the log |
| ``/battery`` | ``sensor_msgs/msg/BatteryState`` | a homing run's battery |
| ``/camera/image/compressed`` | ``sensor_msgs/msg/CompressedImage`` (JPEG), and ``/camera/camera_info`` | ``--record-images`` runs |
| ``/tags`` | ``visualization_msgs/msg/MarkerArray`` (frame ``base_link``; marker id = tag id) | tag sightings |
| ``/plan`` | ``nav_msgs/msg/Path`` (frame ``map``) | the navigator's path |
| ``/explore/goal`` | ``geometry_msgs/msg/PoseStamped`` (frame ``map``) | the frontier goal |
| ``/cmd_vel`` | ``geometry_msgs/msg/Twist`` | commands sent |
| ``/tree/status`` | ``diagnostic_msgs/msg/DiagnosticArray``, one per tick | the tree's node statuses |

The tree's status per tick is a DiagnosticArray, which Foxglove's
Diagnostics panels show as they are and its Plot panel plots: one
DiagnosticStatus per node, ``name`` the node's name, ``level`` its status
as a number — 0 SUCCESS, 1 RUNNING, 2 FAILURE, 3 INVALID (plot
``/tree/status.status[:]{name=="Explore"}.level``) — and ``message`` the
status in words.

Messages are stamped with the log's own stamps (receive time = header
stamp). The writer refuses an existing output (rosbags' rule); the caller
checks the path before the SLAM run.
"""

from __future__ import annotations

import base64
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
from homing.mapping.grid import OccupancyGrid
from homing.missions.runlog import RunLog
from homing.robot.types import Pose2

MAP_PERIOD = 5.0  # [s] of log time between two /map messages
STATUS_LEVEL = {"SUCCESS": 0, "RUNNING": 1, "FAILURE": 2, "INVALID": 3}
POWER_STATUS = {"discharging": 2, "docking_charging": 1, "adapter_charging": 1, "docking_charged": 4,
                "adapter_charged": 4}  # sensor_msgs/BatteryState POWER_SUPPLY_STATUS_*
TOPICS = {
    "/scan": "sensor_msgs/msg/LaserScan", "/odom": "nav_msgs/msg/Odometry", "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage", "/map": "nav_msgs/msg/OccupancyGrid",
    "/battery": "sensor_msgs/msg/BatteryState", "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/camera/camera_info": "sensor_msgs/msg/CameraInfo", "/tags": "visualization_msgs/msg/MarkerArray",
    "/plan": "nav_msgs/msg/Path", "/explore/goal": "geometry_msgs/msg/PoseStamped",
    "/cmd_vel": "geometry_msgs/msg/Twist", "/tree/status": "diagnostic_msgs/msg/DiagnosticArray",
}


class _Msgs:
    """Builders of the standard messages from homing's values (the typestore's classes)."""

    def __init__(self, typestore: Any) -> None:
        self.t = typestore.types

    def time(self, stamp: float) -> Any:
        ns = int(round(stamp * 1e9))
        return self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def header(self, stamp: float, frame: str) -> Any:
        return self.t["std_msgs/msg/Header"](stamp=self.time(stamp), frame_id=frame)

    def quat(self, yaw: float) -> Any:
        return self.t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def pose(self, p: Pose2) -> Any:
        return self.t["geometry_msgs/msg/Pose"](position=self.t["geometry_msgs/msg/Point"](x=p.x, y=p.y, z=0.0),
                                                 orientation=self.quat(p.theta))

    def tf(self, stamp: float, parent: str, child: str, p: Pose2) -> Any:
        t = self.t
        return t["geometry_msgs/msg/TransformStamped"](
            header=self.header(stamp, parent), child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](translation=t["geometry_msgs/msg/Vector3"](x=p.x, y=p.y, z=0.0),
                                                       rotation=self.quat(p.theta)))

    def tf_message(self, transforms: list[Any]) -> Any:
        return self.t["tf2_msgs/msg/TFMessage"](transforms=transforms)

    def vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
        return self.t["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)

    def grid(self, stamp: float, g: OccupancyGrid) -> Any:
        t = self.t
        h, w = g.shape
        origin = Pose2(g.origin[0], g.origin[1], 0.0)
        info = t["nav_msgs/msg/MapMetaData"](map_load_time=self.time(stamp), resolution=float(g.resolution),
                                            width=w, height=h, origin=self.pose(origin))
        return t["nav_msgs/msg/OccupancyGrid"](header=self.header(stamp, "map"), info=info,
                                              data=np.ascontiguousarray(g.data, dtype=np.int8).reshape(-1))


def _covariance36(diag: float) -> np.ndarray:
    return (np.eye(6) * diag).reshape(-1)


def export_mcap(log: RunLog, out: str | Path, map_to_odom: Callable[[float], Pose2] | None = None,
                grid_at: Callable[[float], OccupancyGrid | None] | None = None) -> dict[str, int]:
    """Write ``log`` as a rosbag2 folder ``out`` in MCAP; returns the message count per topic.

    ``map_to_odom(t)`` [map] and ``grid_at(t)`` come from a SLAM run over
    the log (None: no ``map`` frame and no ``/map``).
    """
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    m = _Msgs(typestore)
    counts: dict[str, int] = {}
    zero = QosTime(0, 0)
    latched = Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, zero, zero,
                  QosLiveliness.AUTOMATIC, zero, False)
    with Writer(Path(out), version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        conns: dict[str, Any] = {}

        def write(topic: str, stamp: float, msg: Any) -> None:
            if topic not in conns:
                qos = [latched] if topic in ("/tf_static", "/map") else []
                conns[topic] = writer.add_connection(topic, TOPICS[topic], typestore=typestore,
                                                     offered_qos_profiles=qos)
            data = typestore.serialize_cdr(msg, TOPICS[topic])
            writer.write(conns[topic], int(round(max(stamp, 0.0) * 1e9)), data)
            counts[topic] = counts.get(topic, 0) + 1

        for topic, stamp, msg in _messages(log, m, map_to_odom, grid_at):
            write(topic, stamp, msg)
    return counts


def _messages(log: RunLog, m: _Msgs, map_to_odom: Callable[[float], Pose2] | None,
              grid_at: Callable[[float], OccupancyGrid | None] | None) -> Iterator[tuple[str, float, Any]]:
    """(topic, stamp [s], message) for everything in the log, in the log's order."""
    t = m.t
    laser_sent = False
    next_map = -math.inf
    statuses: dict[str, str] = {}
    last_t = 0.0
    for r in log.records:
        k, stamp = r["k"], float(r["t"])
        last_t = max(last_t, stamp)
        if k == "scan":
            if not laser_sent:
                laser_sent = True
                yield "/tf_static", stamp, m.tf_message([m.tf(stamp, "base_link", "laser", Pose2(*r["lp"]))])
            ranges = np.frombuffer(base64.b64decode(r["r"]), dtype="<f4").astype(np.float32)
            n = len(ranges)
            yield "/scan", stamp, t["sensor_msgs/msg/LaserScan"](
                header=m.header(stamp, "laser"), angle_min=float(r["amin"]),
                angle_max=float(r["amin"] + r["ainc"] * max(n - 1, 0)), angle_increment=float(r["ainc"]),
                time_increment=0.0, scan_time=0.0, range_min=float(r["rmin"]), range_max=float(r["rmax"]),
                ranges=ranges, intensities=np.zeros(0, dtype=np.float32))
            if map_to_odom is not None:
                yield "/tf", stamp, m.tf_message([m.tf(stamp, "map", "odom", map_to_odom(stamp))])
            if grid_at is not None and stamp >= next_map:
                g = grid_at(stamp)
                if g is not None:
                    next_map = stamp + MAP_PERIOD
                    yield "/map", stamp, m.grid(stamp, g)
        elif k == "obs":
            od = r["odom"]
            pose = Pose2(od[1], od[2], od[3])
            twist = t["geometry_msgs/msg/Twist"](linear=m.vector(od[4]), angular=m.vector(0.0, 0.0, od[5]))
            yield "/odom", stamp, t["nav_msgs/msg/Odometry"](
                header=m.header(stamp, "odom"), child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=m.pose(pose), covariance=_covariance36(1e-3)),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=_covariance36(1e-3)))
            yield "/tf", stamp, m.tf_message([m.tf(stamp, "odom", "base_link", pose)])
            if r.get("bat"):
                yield "/battery", stamp, _battery(m, stamp, r["bat"])
        elif k == "cmd":
            yield "/cmd_vel", stamp, t["geometry_msgs/msg/Twist"](linear=m.vector(r["v"]),
                                                                   angular=m.vector(0.0, 0.0, r["w"]))
            yield "/tree/status", stamp, _status_array(m, stamp, statuses)
        elif k == "status":
            statuses[r["node"]] = r["s"]
        elif k == "tags":
            yield "/tags", stamp, _markers(m, stamp, r["m"])
        elif k == "plan":
            if r["path"] is not None:
                poses = [t["geometry_msgs/msg/PoseStamped"](header=m.header(stamp, "map"), pose=m.pose(Pose2(x, y)))
                         for x, y in r["path"]]
                yield "/plan", stamp, t["nav_msgs/msg/Path"](header=m.header(stamp, "map"), poses=poses)
            if r["goal"] is not None:
                yield "/explore/goal", stamp, t["geometry_msgs/msg/PoseStamped"](header=m.header(stamp, "map"),
                                                                                 pose=m.pose(Pose2(*r["goal"])))
        elif k == "img":
            yield from _image(m, stamp, r)
    if grid_at is not None:
        g = grid_at(math.inf)
        if g is not None:
            yield "/map", last_t, m.grid(last_t, g)


def _battery(m: _Msgs, stamp: float, bat: list[Any]) -> Any:
    volt, pct, _source, state = bat
    nan = float("nan")
    return m.t["sensor_msgs/msg/BatteryState"](
        header=m.header(stamp, "base_link"), voltage=float(volt), temperature=nan, current=nan, charge=nan,
        capacity=nan, design_capacity=2.2, percentage=float(pct) / 100.0, power_supply_status=POWER_STATUS.get(state, 0),
        power_supply_health=0, power_supply_technology=2, present=True, cell_voltage=np.zeros(0, np.float32),
        cell_temperature=np.zeros(0, np.float32), location="kobuki", serial_number="")


def _status_array(m: _Msgs, stamp: float, statuses: dict[str, str]) -> Any:
    t = m.t
    items = [t["diagnostic_msgs/msg/DiagnosticStatus"](level=STATUS_LEVEL.get(s, 3), name=name, message=s,
                                                       hardware_id="homing", values=[])
             for name, s in statuses.items()]
    return t["diagnostic_msgs/msg/DiagnosticArray"](header=m.header(stamp, ""), status=items)


def _markers(m: _Msgs, stamp: float, sightings: list[list[Any]]) -> Any:
    t = m.t
    out = []
    for a in sightings:
        tag_id, x, y, th, h = int(a[0]), float(a[2]), float(a[3]), float(a[4]), float(a[11])
        pose = m.pose(Pose2(x, y, th))
        pose.position.z = h
        out.append(t["visualization_msgs/msg/Marker"](
            header=m.header(stamp, "base_link"), ns="tags", id=tag_id, type=1, action=0, pose=pose,
            scale=m.vector(0.02, 0.16, 0.16), color=t["std_msgs/msg/ColorRGBA"](r=0.1, g=0.8, b=0.2, a=1.0),
            lifetime=t["builtin_interfaces/msg/Duration"](sec=1, nanosec=0), frame_locked=False, points=[],
            colors=[], texture_resource="", texture=t["sensor_msgs/msg/CompressedImage"](
                header=m.header(stamp, ""), format="", data=np.zeros(0, np.uint8)),
            uv_coordinates=[], text=str(tag_id), mesh_resource="",
            mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
            mesh_use_embedded_materials=False))
    return t["visualization_msgs/msg/MarkerArray"](markers=out)


def _image(m: _Msgs, stamp: float, r: dict[str, Any]) -> Iterator[tuple[str, float, Any]]:
    t = m.t
    data = np.frombuffer(base64.b64decode(r["jpeg"]), dtype=np.uint8)
    yield "/camera/image/compressed", stamp, t["sensor_msgs/msg/CompressedImage"](
        header=m.header(stamp, "camera"), format="jpeg", data=data)
    fx, fy, cx, cy = r["K"]
    w, h = r["size"]
    roi = t["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
    yield "/camera/camera_info", stamp, t["sensor_msgs/msg/CameraInfo"](
        header=m.header(stamp, "camera"), height=int(h), width=int(w), distortion_model="plumb_bob",
        d=np.zeros(5), k=np.array([fx, 0, cx, 0, fy, cy, 0, 0, 1], float),
        r=np.eye(3).reshape(-1), p=np.array([fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0], float),
        binning_x=0, binning_y=0, roi=roi)
