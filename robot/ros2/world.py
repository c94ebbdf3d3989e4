"""homing's world model published back to the robot's ROS 2 graph, so RViz or Foxglove there shows what homing thinks.

:class:`WorldPublisher` declares, on homing's node (:class:`~homing.robot.ros2.node.Ros2Node`):

| topic | type | when |
| --- | --- | --- |
| ``/map`` | ``nav_msgs/msg/OccupancyGrid`` (frame ``map``), latched | every ``MAP_PERIOD`` while the grid changes |
| ``/tf`` | ``tf2_msgs/msg/TFMessage``: ``map → odom`` | every tick |
| ``/plan`` | ``nav_msgs/msg/Path`` (frame ``map``) | when the navigator's path changes |
| ``/explore/goal`` | ``geometry_msgs/msg/PoseStamped`` (frame ``map``) | when the frontier goal changes |
| ``/mission/state`` | ``std_msgs/msg/String``, latched | when the lifecycle state changes |
| ``/slam/landmarks`` | ``visualization_msgs/msg/MarkerArray`` (frame ``map``; a flat cube per tag, marker id = tag id), latched | when the tag landmarks change |
| ``/tree/status`` | ``diagnostic_msgs/msg/DiagnosticArray`` | every tick: one DiagnosticStatus per node, level 0 SUCCESS, 1 RUNNING, 2 FAILURE, 3 INVALID (as the MCAP export writes it) |

Inputs are plain values (a grid with ``data`` (H, W) int8 in ROS's
convention, ``resolution`` [m] and ``origin`` (x, y) [m]; poses; an (N, 2)
path in ``map``), so this module knows nothing of homing's mapping or tree.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from homing.robot.ros2 import wire
from homing.robot.ros2.node import Ros2Node
from homing.robot.ros2.wire import LATCHED, Qos
from homing.robot.types import Pose2

MAP_PERIOD = 2.0  # [s] wall time between two /map messages of a changing grid
STATUS_LEVEL = {"SUCCESS": 0, "RUNNING": 1, "FAILURE": 2, "INVALID": 3}
G = "geometry_msgs/msg/"


def _time(ns: int) -> Any:
    return wire.message("builtin_interfaces/msg/Time", sec=ns // 10**9, nanosec=ns % 10**9)


def _header(frame: str, ns: int) -> Any:
    return wire.message("std_msgs/msg/Header", stamp=_time(ns), frame_id=frame)


def _pose(p: Pose2) -> Any:
    return wire.message(G + "Pose", position=wire.message(G + "Point", x=p.x, y=p.y, z=0.0),
                        orientation=wire.message(G + "Quaternion", x=0.0, y=0.0, z=math.sin(p.theta / 2),
                                                 w=math.cos(p.theta / 2)))  # fmt: skip


class WorldPublisher:
    """Publishes homing's map, map → odom, plan, goal, state and tree status on ``node``."""

    def __init__(self, node: Ros2Node):
        self.map_pub = node.publisher("/map", "nav_msgs/msg/OccupancyGrid", LATCHED)
        self.tf_pub = node.publisher("/tf", "tf2_msgs/msg/TFMessage", Qos(depth=100))
        self.plan_pub = node.publisher("/plan", "nav_msgs/msg/Path", Qos())
        self.goal_pub = node.publisher("/explore/goal", G + "PoseStamped", Qos())
        self.state_pub = node.publisher("/mission/state", "std_msgs/msg/String", LATCHED)
        self.status_pub = node.publisher("/tree/status", "diagnostic_msgs/msg/DiagnosticArray", Qos())
        self.tags_pub = node.publisher("/slam/landmarks", "visualization_msgs/msg/MarkerArray", LATCHED)
        self._next_map = -math.inf
        self._last: dict[str, Any] = {}

    def publish(self, *, grid: Any = None, map_to_odom: Pose2 | None = None, path: np.ndarray | None = None,
                goal: Pose2 | None = None, state: str | None = None, statuses: dict[str, str] | None = None,
                landmarks: dict[int, Pose2] | None = None) -> None:  # fmt: skip
        """Publish what is given (None: nothing of it), each at its own pace (see the module's table)."""
        ns = time.time_ns()
        if grid is not None:
            self._map(grid, ns)
        if map_to_odom is not None:
            t = wire.message(G + "TransformStamped", header=_header("map", ns), child_frame_id="odom",
                             transform=wire.message(G + "Transform", translation=wire.message(
                                 G + "Vector3", x=map_to_odom.x, y=map_to_odom.y, z=0.0),
                                 rotation=_pose(map_to_odom).orientation))  # fmt: skip
            self.tf_pub.publish(wire.message("tf2_msgs/msg/TFMessage", transforms=[t]))
        if path is not None and self._changed("path", np.asarray(path, float).tobytes()):
            poses = [wire.message(G + "PoseStamped", header=_header("map", ns), pose=_pose(Pose2(float(x), float(y))))
                     for x, y in np.asarray(path, float).reshape(-1, 2)]  # fmt: skip
            self.plan_pub.publish(wire.message("nav_msgs/msg/Path", header=_header("map", ns), poses=poses))
        if goal is not None and self._changed("goal", goal):
            self.goal_pub.publish(wire.message(G + "PoseStamped", header=_header("map", ns), pose=_pose(goal)))
        if state is not None and self._changed("state", state):
            self.state_pub.publish(wire.message("std_msgs/msg/String", data=state))
        if landmarks and self._changed("landmarks", sorted(landmarks.items())):
            self.tags_pub.publish(wire.message("visualization_msgs/msg/MarkerArray", markers=[
                wire.zero("visualization_msgs/msg/Marker", header=_header("map", ns), ns="tags", id=int(i), type=1,
                          pose=_pose(p), scale=wire.message(G + "Vector3", x=0.02, y=0.2, z=0.2), text=str(i),
                          color=wire.message("std_msgs/msg/ColorRGBA", r=0.1, g=0.6, b=1.0, a=1.0))
                for i, p in sorted(landmarks.items())]))  # fmt: skip
        if statuses is not None:
            items = [wire.message("diagnostic_msgs/msg/DiagnosticStatus", level=STATUS_LEVEL.get(s, 3), name=name,
                                  message=s, hardware_id="homing", values=[])
                     for name, s in statuses.items()]  # fmt: skip
            self.status_pub.publish(wire.message("diagnostic_msgs/msg/DiagnosticArray", header=_header("", ns),
                                                 status=items))  # fmt: skip

    def _changed(self, what: str, value: Any) -> bool:
        if self._last.get(what) == value:
            return False
        self._last[what] = value
        return True

    def _map(self, grid: Any, ns: int) -> None:
        now = time.monotonic()
        if now < self._next_map:
            return
        data = np.ascontiguousarray(grid.data, dtype=np.int8)
        key = (data.shape, grid.resolution, tuple(grid.origin), hash(data.tobytes()))
        if not self._changed("map", key):
            return
        self._next_map = now + MAP_PERIOD
        h, w = data.shape
        info = wire.message("nav_msgs/msg/MapMetaData", map_load_time=_time(ns), resolution=float(grid.resolution),
                            width=w, height=h, origin=_pose(Pose2(float(grid.origin[0]), float(grid.origin[1]))))  # fmt: skip
        self.map_pub.publish(wire.message("nav_msgs/msg/OccupancyGrid", header=_header("map", ns), info=info,
                                          data=data.reshape(-1)))  # fmt: skip
