"""A run's state as Foxglove's well-known messages (``foxglove.Grid``, ``LaserScan``, ``FrameTransforms``, …).

The messages are the ``foxglove-sdk`` package's classes (the Foxglove
schemas, sent as protobuf with their ``FileDescriptorSet`` in the channel's
advertisement); the mission state, the batteries and the tree's statuses
are JSON with a JSON Schema, as the Foxglove WebSocket protocol lets a
channel declare (``encoding: json``, ``schemaEncoding: jsonschema``).

Frames follow REP-105 as :mod:`homing.logs.mcap_export` does: the grid,
the path, the goal, the frontiers, the tags and the dock in ``map``; the
scan in ``base_link`` (posed at the laser); ``map → odom → base_link`` in
``/tf``. The grid's cells are the map_server values (FREE 0, OCCUPIED 100,
UNKNOWN −1) as ``int8``, row 0 at the grid's origin, as
``nav_msgs/OccupancyGrid`` lays them out.

Everything here reads a :class:`Snapshot`, never the blackboard: the
snapshot is copied in the tick's thread, the messages are built in the
server's own thread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CubePrimitive,
    FrameTransform,
    FrameTransforms,
    Grid,
    LaserScan,
    LinePrimitive,
    LinePrimitiveLineType,
    PackedElementField,
    PackedElementFieldNumericType,
    Point3,
    Pose,
    PoseInFrame,
    Quaternion,
    SceneEntity,
    SceneUpdate,
    TextPrimitive,
    Timestamp,
    Vector2,
    Vector3,
)
from homing.robot.types import Pose2

MAX_FRONTIER_CELLS = 4000  # cubes drawn for the frontiers at most (a big building's first minutes)
TAG_SIZE = 0.16  # [m] the tag's square drawn in the scene
TAG_HEIGHT = 0.5  # [m] where the tags are drawn above the floor
GREEN = Color(r=0.1, g=0.8, b=0.2, a=1.0)
BLUE = Color(r=0.2, g=0.5, b=1.0, a=1.0)
ORANGE = Color(r=1.0, g=0.55, b=0.0, a=1.0)
MAGENTA = Color(r=0.9, g=0.2, b=0.8, a=0.8)
WHITE = Color(r=1.0, g=1.0, b=1.0, a=1.0)


@dataclass
class GridCopy:
    """The occupancy grid as it was at one tick: ``data`` (H, W) int8, ``resolution`` [m], ``origin`` (x, y) [m]."""

    version: int
    data: np.ndarray
    resolution: float
    origin: tuple[float, float]


@dataclass
class Snapshot:
    """What one tick leaves for the server thread: plain values and copies, nothing the tick will change."""

    time: float  # [s] adapter clock
    ticks: int
    odom: Pose2 | None = None  # base_link in odom
    pose: Pose2 | None = None  # base_link in map
    map_to_odom: Pose2 | None = None
    scan: dict[str, Any] | None = None  # angle_min, angle_increment, ranges (copy), laser_pose, stamp
    grid: GridCopy | None = None  # set only when the grid's version changed since the last snapshot
    path: np.ndarray | None = None  # (N, 2) [m] in map
    goal: Pose2 | None = None
    landmarks: dict[int, Pose2] = field(default_factory=dict)
    dock: Pose2 | None = None
    batteries: dict[str, Any] = field(default_factory=dict)  # the battery JSON message
    state: dict[str, Any] = field(default_factory=dict)  # the mission-state JSON message
    tree: dict[str, Any] = field(default_factory=dict)  # the tree-status JSON message


def stamp(t: float) -> Timestamp:
    """A Foxglove timestamp from seconds (the adapter's clock)."""
    t = max(t, 0.0)
    sec = int(math.floor(t))
    return Timestamp(sec=sec, nsec=min(int(round((t - sec) * 1e9)), 999_999_999))


def nanoseconds(t: float) -> int:
    """The ``log_time`` of a message stamped ``t`` [s]."""
    return int(round(max(t, 0.0) * 1e9))


def quaternion(yaw: float) -> Quaternion:
    """A rotation of ``yaw`` [rad] about z."""
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def pose3(p: Pose2, z: float = 0.0) -> Pose:
    """A planar pose as a 3D one (yaw about z)."""
    return Pose(position=Vector3(x=p.x, y=p.y, z=z), orientation=quaternion(p.theta))


def grid_message(t: float, g: GridCopy) -> Grid:
    """``foxglove.Grid`` of one int8 field ``occupancy`` (−1, 0, 100), row 0 at the origin (``nav_msgs/OccupancyGrid``'s layout)."""
    h, w = g.data.shape
    return Grid(timestamp=stamp(t), frame_id="map", pose=pose3(Pose2(g.origin[0], g.origin[1], 0.0)),
                column_count=int(w), cell_size=Vector2(x=g.resolution, y=g.resolution), row_stride=int(w),
                cell_stride=1,
                fields=[PackedElementField(name="occupancy", offset=0, type=PackedElementFieldNumericType.Int8)],
                data=np.ascontiguousarray(g.data, dtype=np.int8).tobytes())


def scan_message(t: float, scan: dict[str, Any]) -> LaserScan:
    """``foxglove.LaserScan`` in ``base_link``, posed at the laser; a ray with no return is ``inf``."""
    ranges = scan["ranges"]
    n = len(ranges)
    start = float(scan["angle_min"])
    return LaserScan(timestamp=stamp(scan["stamp"]), frame_id="base_link", pose=pose3(scan["laser_pose"]),
                     start_angle=start, end_angle=start + float(scan["angle_increment"]) * max(n - 1, 0),
                     ranges=ranges.tolist())


def transforms_message(s: Snapshot) -> FrameTransforms:
    """``map → odom`` (when the mission localises) and ``odom → base_link``."""
    out = []
    for parent, child, p in (("map", "odom", s.map_to_odom), ("odom", "base_link", s.odom)):
        if p is not None:
            out.append(FrameTransform(timestamp=stamp(s.time), parent_frame_id=parent, child_frame_id=child,
                                      translation=Vector3(x=p.x, y=p.y, z=0.0), rotation=quaternion(p.theta)))
    return FrameTransforms(transforms=out)


def pose_message(s: Snapshot) -> PoseInFrame | None:
    """The robot's pose in ``map`` (``foxglove.PoseInFrame``), or None before the mission localises."""
    if s.pose is None:
        return None
    return PoseInFrame(timestamp=stamp(s.time), frame_id="map", pose=pose3(s.pose))


def path_message(s: Snapshot) -> SceneUpdate:
    """The navigator's planned path as a line strip in ``map`` (an empty entity when there is none)."""
    lines = []
    if s.path is not None and len(s.path) >= 2:
        points = [Point3(x=float(x), y=float(y), z=0.02) for x, y in s.path]
        lines.append(LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.04, points=points, color=BLUE))
    return SceneUpdate(entities=[SceneEntity(timestamp=stamp(s.time), frame_id="map", id="path", lines=lines)])


def goal_message(s: Snapshot) -> SceneUpdate:
    """The current exploration goal as an arrow in ``map`` (an empty entity when there is none)."""
    arrows = []
    if s.goal is not None:
        arrows.append(ArrowPrimitive(pose=pose3(s.goal, 0.05), shaft_length=0.3, shaft_diameter=0.05,
                                     head_length=0.15, head_diameter=0.12, color=ORANGE))
    return SceneUpdate(entities=[SceneEntity(timestamp=stamp(s.time), frame_id="map", id="goal", arrows=arrows)])


def frontiers_message(t: float, cells: np.ndarray, g: GridCopy) -> SceneUpdate:
    """Frontier cells ((N, 2) row, col of ``g``) as flat cubes in ``map``, at most ``MAX_FRONTIER_CELLS``."""
    cells = cells[:MAX_FRONTIER_CELLS]
    r = g.resolution
    size = Vector3(x=r, y=r, z=0.01)
    cubes = [CubePrimitive(pose=pose3(Pose2(g.origin[0] + (c + 0.5) * r, g.origin[1] + (row + 0.5) * r), 0.01),
                           size=size, color=MAGENTA) for row, c in cells.tolist()]
    return SceneUpdate(entities=[SceneEntity(timestamp=stamp(t), frame_id="map", id="frontiers", cubes=cubes)])


def landmarks_message(s: Snapshot) -> SceneUpdate:
    """The tags' estimates (green squares with their id) and the dock (a white box labelled ``dock``) in ``map``."""
    cubes, texts = [], []
    for tag_id, p in sorted(s.landmarks.items()):
        cubes.append(CubePrimitive(pose=pose3(p, TAG_HEIGHT), size=Vector3(x=0.02, y=TAG_SIZE, z=TAG_SIZE),
                                   color=GREEN))
        texts.append(TextPrimitive(pose=pose3(p, TAG_HEIGHT + 0.15), billboard=True, font_size=14.0,
                                   scale_invariant=True, color=GREEN, text=f"tag {tag_id}"))
    if s.dock is not None:
        cubes.append(CubePrimitive(pose=pose3(s.dock, 0.05), size=Vector3(x=0.1, y=0.4, z=0.1), color=WHITE))
        texts.append(TextPrimitive(pose=pose3(s.dock, 0.3), billboard=True, font_size=14.0, scale_invariant=True,
                                   color=WHITE, text="dock"))
    return SceneUpdate(entities=[SceneEntity(timestamp=stamp(s.time), frame_id="map", id="landmarks", cubes=cubes,
                                             texts=texts)])


# --- JSON channels: their schemas -----------------------------------------------------------------------------

_BATTERY = {
    "type": "object",
    "properties": {
        "voltage": {"type": "number", "description": "[V]"},
        "percent": {"type": "number", "description": "[%]"},
        "state": {"type": "string", "description": "discharging, docking_charging, docking_charged, …"},
        "source": {"type": "string"},
        "home": {"type": ["number", "null"], "description": "[%] go-home level with the reserve (the energy policy)"},
        "undock": {"type": ["number", "null"], "description": "[%] charged enough to undock"},
    },
}
BATTERY_SCHEMA = {
    "title": "homing.Batteries", "type": "object",
    "properties": {"base": _BATTERY, "computer": _BATTERY},
}
STATE_SCHEMA = {
    "title": "homing.MissionState", "type": "object",
    "properties": {
        "time": {"type": "number", "description": "[s] adapter clock"},
        "ticks": {"type": "integer"},
        "state": {"type": "string", "description": "/mission/state (Docked, Undocking, Exploring, …)"},
        "cycles": {"type": "integer", "description": "dock cycles completed"},
        "localized": {"type": ["boolean", "null"]},
    },
}
TREE_SCHEMA = {
    "title": "homing.TreeStatus", "type": "object",
    "properties": {
        "time": {"type": "number", "description": "[s] adapter clock of the tick"},
        "tick": {"type": "integer"},
        "root": {"type": "string", "enum": ["RUNNING", "SUCCESS", "FAILURE", "INVALID"]},
        "running": {"type": "array", "items": {"type": "string"}, "description": "the running leaves"},
        "nodes": {
            "type": "array", "description": "every node in preorder",
            "items": {"type": "object", "properties": {
                "name": {"type": "string"}, "depth": {"type": "integer"},
                "status": {"type": "string", "enum": ["RUNNING", "SUCCESS", "FAILURE", "INVALID"]},
            }},
        },
    },
}


def battery_json(battery: Any, policy: dict[str, Any] | None) -> dict[str, Any]:
    """One battery (:class:`homing.robot.types.BatteryState`) with its thresholds from ``/energy/policy``."""
    levels = policy or {}
    home = levels.get("home")
    if home is not None and levels.get("reserve") is not None:
        home = float(home) + float(levels["reserve"])
    return {"voltage": float(battery.voltage), "percent": float(battery.percent), "state": battery.state.value,
            "source": getattr(battery.source, "value", str(battery.source)),
            "home": None if home is None else float(home),
            "undock": None if levels.get("undock") is None else float(levels["undock"])}
