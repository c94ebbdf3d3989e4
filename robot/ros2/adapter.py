"""Any ROS 2 robot behind the adapter contract, over Zenoh in rmw_zenoh's format, with no ROS install.

``open_ros2_robot("robot.yaml")`` reads a ``kind: ros2`` robot file
(:mod:`homing.robot.ros2.robot_file`), connects to the robot's Zenoh router as
a client, declares homing's node and its endpoints, and returns a
:class:`Ros2Robot` (a :class:`homing.robot.RobotAdapter`) on the wall clock:

- it subscribes ``sensor_msgs/LaserScan``, ``nav_msgs/Odometry``,
  ``sensor_msgs/BatteryState`` and ``tf2_msgs/TFMessage`` on ``/tf`` and
  ``/tf_static`` (latched: the robot's publication cache is queried, so a
  static transform sent long before homing started still arrives); the
  laser's pose in the base frame comes from the transforms, through any
  chain of frames between them;
- each :meth:`Ros2Robot.command` publishes ``geometry_msgs/Twist`` (or
  ``TwistStamped``) on ``cmd_vel`` at once, clipped to the limits; close sends zero;
- a lost router or a topic silent for longer than its timeout is a
  :class:`LinkLost` (typed: :class:`Cause` says which): the robot is sent
  zero, ``Observation.devices_lost`` names it (``router``, ``/scan``…), so
  a mission's ``DevicesOk`` guard takes the tree to Error, and it clears by
  itself when the router and the data are back (Zenoh's client reconnects).

- optional topics a Kobuki under ``kobuki_ros`` and a camera driver give:
  the dock's IR (``kobuki_ros_interfaces/DockInfraRed``; a reading older
  than ``DOCK_IR_TIMEOUT`` reads as nothing seen), the bumpers' events
  (``kobuki_ros_interfaces/BumperEvent``), and camera frames
  (``sensor_msgs/Image`` in rgb8, bgr8 or mono8, with ``CameraInfo``'s K and
  the robot file's ``camera_pose``) for the tags; without them the bumpers
  and the dock IR read nothing and there is no image;
- charging comes from the BatteryState's ``power_supply_status`` (CHARGING,
  FULL: on the dock, or on an adapter if the robot file says so).

Opening fails with a one-line :class:`~homing.errors.UserError` at the
robot file's ``router`` entry if the router cannot be reached or no
odometry, scan (and battery, when named) arrive within ``timeouts.first_data``.
"""

from __future__ import annotations

import enum
import math
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from homing.robot.frames import R_BODY_FROM_OPTICAL, homogeneous, rot_z
from homing.robot.ros2 import wire
from homing.robot.ros2.node import Ros2Node
from homing.robot.ros2.robot_file import Ros2Config, load_ros2_robot, router_error
from homing.robot.ros2.wire import LATCHED, SENSOR_DATA, Qos, Received
from homing.robot.ros2.world import WorldPublisher
from homing.robot.turtlebot import RobotLimits, battery_percent
from homing.robot.types import (
    IR,
    BatteryState,
    Bumpers,
    CameraImage,
    CameraInfo,
    ChargingSource,
    ChargingState,
    DockIR,
    Observation,
    Odometry,
    Pose2,
    Scan,
    Twist2,
)

LINK_CHECK_PERIOD = 0.2  # [s] between looks at the session's router and peers
DOCK_IR_TIMEOUT = 0.2  # [s] a dock IR reading older than this reads as nothing seen
POWER_SUPPLY_CHARGING, POWER_SUPPLY_FULL = 1, 4  # sensor_msgs/BatteryState power_supply_status


class Cause(enum.Enum):
    """Why the link to the robot is lost."""

    ROUTER = "router"  # the Zenoh session has no router (or peer) any more
    SILENT = "silent"  # a topic sent nothing for longer than its timeout


class LinkLost(Exception):
    """The robot cannot be driven safely: ``cause``, and ``what`` (``router`` or the silent topic)."""

    def __init__(self, cause: Cause, what: str, since: float):
        super().__init__(f"{what}: {'no router' if cause is Cause.ROUTER else 'silent'} since {since:.2f} s")
        self.cause, self.what, self.since = cause, what, since


class WallClock:
    """Monotonic seconds since the adapter opened."""

    def __init__(self) -> None:
        self.t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self.t0


def yaw_of(q: Any) -> float:
    """The yaw [rad] of a geometry_msgs/Quaternion."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class FrameTree:
    """Planar transforms parent → child from /tf and /tf_static; ``pose(base, frame)`` walks the chain."""

    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, Pose2]] = {}
        self._lock = threading.Lock()

    def add(self, msg: Any, skip_child: str | None = None) -> None:
        with self._lock:
            for t in msg.transforms:
                child = t.child_frame_id.lstrip("/")
                if child == skip_child:
                    continue  # odom → base moves every tick; the laser hangs below base
                tr, q = t.transform.translation, t.transform.rotation
                self._parent[child] = (t.header.frame_id.lstrip("/"), Pose2(tr.x, tr.y, yaw_of(q)))

    def pose(self, base: str, frame: str) -> Pose2 | None:
        """``frame``'s pose in ``base`` (None if the transforms do not connect them)."""
        with self._lock:
            pose, at = Pose2(), frame.lstrip("/")
            for _ in range(32):
                if at == base:
                    return pose
                if at not in self._parent:
                    return None
                parent, step = self._parent[at]
                pose, at = step.compose(pose), parent
        return None


class Ros2Robot:
    """A ROS 2 robot over Zenoh (implements :class:`homing.robot.RobotAdapter`)."""

    def __init__(self, config: Ros2Config):
        self.config = c = config
        self._clock = WallClock()
        self._limits = RobotLimits(c.max_v, c.max_omega, c.radius)
        self._deadline: float | None = None
        self._lock = threading.Lock()
        self._scan: Received | None = None
        self._odom: Received | None = None
        self._battery: Received | None = None
        self._dock_ir: Received | None = None
        self._image: Received | None = None
        self._info: Received | None = None
        self._bumpers = Bumpers()
        self._camera: tuple[Received, Received, CameraImage] | None = None  # the last image made, and from what
        self._arrived: dict[str, float] = {}  # [s, adapter clock] last sample per topic
        self._got_data = threading.Event()
        self.frames = FrameTree()
        self.failure: LinkLost | None = None
        self._link_ok, self._link_checked = True, -math.inf
        self._cmd = Twist2()
        try:
            self.node = Ros2Node(c.node, domain=c.domain, namespace=c.namespace, mode="client", connect=[c.router])
        except Exception as err:  # zenoh.ZError: unreachable endpoint, refused…
            raise router_error(c, f"cannot reach the Zenoh router {c.router}: {str(err).split(' at /')[0]}") from None
        try:
            self._declare()
            self._wait_for_data()
        except BaseException:
            self.node.close()
            raise

    def _declare(self) -> None:
        c, n = self.config, self.node
        self.topics = {"odom": wire.qualified(c.odom, c.namespace), "scan": wire.qualified(c.scan, c.namespace)}
        if c.battery is not None:
            self.topics["battery"] = wire.qualified(c.battery, c.namespace)
        n.subscribe(c.scan, "sensor_msgs/msg/LaserScan", SENSOR_DATA, lambda r: self._take("scan", r))
        n.subscribe(c.odom, "nav_msgs/msg/Odometry", Qos(), lambda r: self._take("odom", r))
        if c.battery is not None:
            n.subscribe(c.battery, "sensor_msgs/msg/BatteryState", SENSOR_DATA, lambda r: self._take("battery", r))
        n.subscribe(c.tf, "tf2_msgs/msg/TFMessage", Qos(depth=100), self._take_tf)
        n.subscribe(c.tf_static, "tf2_msgs/msg/TFMessage", LATCHED, lambda r: self.frames.add(r.message))
        if c.dock_ir is not None:
            n.subscribe(c.dock_ir, "kobuki_ros_interfaces/msg/DockInfraRed", SENSOR_DATA,
                        lambda r: self._take("dock_ir", r))  # fmt: skip
        if c.bumper is not None:
            n.subscribe(c.bumper, "kobuki_ros_interfaces/msg/BumperEvent", Qos(), self._take_bumper)
        if c.image is not None and c.camera_info is not None:
            n.subscribe(c.image, "sensor_msgs/msg/Image", SENSOR_DATA, lambda r: self._take("image", r))
            n.subscribe(c.camera_info, "sensor_msgs/msg/CameraInfo", SENSOR_DATA, lambda r: self._take("info", r))
        self.cmd_type = "geometry_msgs/msg/TwistStamped" if c.stamped else "geometry_msgs/msg/Twist"
        self.cmd_pub = n.publisher(c.cmd_vel, self.cmd_type, Qos())
        # declared before the sensors are awaited, not at the first tick: a subscriber already on the graph
        # (RViz, a probe) has matched homing's publishers by the time the first state is published
        self._world = WorldPublisher(n)

    def _take(self, what: str, r: Received) -> None:
        with self._lock:
            setattr(self, f"_{what}", r)
            self._arrived[what] = r.arrived - self._clock.t0
            if self._odom is not None and self._scan is not None and (
                    self._battery is not None or self.config.battery is None):  # docked or not: ask the battery
                self._got_data.set()

    def _take_bumper(self, r: Received) -> None:
        which = ("left", "centre", "right")[min(int(r.message.bumper), 2)]
        with self._lock:
            self._bumpers = replace(self._bumpers, **{which: bool(r.message.state)})

    def _take_tf(self, r: Received) -> None:
        self.frames.add(r.message, skip_child=self.config.base_frame)

    def _wait_for_data(self) -> None:
        c = self.config
        if not self._got_data.wait(c.first_data_timeout):
            missing = [self.topics[k] for k in self.topics if k not in self._arrived]
            raise router_error(c, f"no {' and no '.join(missing)} from {c.router} within "
                                  f"{c.first_data_timeout:g} s (wrong router, domain, namespace or topic?)")  # fmt: skip

    # --- the adapter contract ----------------------------------------------------------------
    @property
    def clock(self) -> WallClock:
        return self._clock

    @property
    def limits(self) -> RobotLimits:
        return self._limits

    def link_failure(self) -> LinkLost | None:
        """The link's state now: None, or why the robot may not be driven."""
        t = self._clock.now()
        if t - self._link_checked >= LINK_CHECK_PERIOD:
            self._link_checked, self._link_ok = t, self.node.linked()
        if not self._link_ok:
            since = self.failure.since if self.failure is not None and self.failure.cause is Cause.ROUTER else t
            return LinkLost(Cause.ROUTER, "router", since)
        c = self.config
        with self._lock:
            for what, timeout in (("scan", c.scan_timeout), ("odom", c.odom_timeout)):  # the battery may be slow
                last = self._arrived.get(what, 0.0)
                if t - last > timeout:
                    return LinkLost(Cause.SILENT, self.topics[what], last)
        return None

    def require_link(self) -> None:
        """Raise :class:`LinkLost` if the robot may not be driven now."""
        failure = self.link_failure()
        if failure is not None:
            raise failure

    def observe(self) -> Observation:
        t = self._clock.now()
        failure = self.link_failure()
        if failure is not None and self.failure is None:
            self._send(0.0, 0.0)
            print(f"[{t:8.2f} s] lost: {failure}; robot stopped", file=sys.stderr)
        elif failure is None and self.failure is not None:
            print(f"[{t:8.2f} s] back: {self.failure.what}", file=sys.stderr)
        self.failure = failure
        with self._lock:
            scan, odom, battery, ir = self._scan, self._odom, self._battery, self._dock_ir
            image, info, bumpers = self._image, self._info, self._bumpers
            arrived = dict(self._arrived)
        fresh_ir = ir is not None and t - arrived.get("dock_ir", -math.inf) <= DOCK_IR_TIMEOUT
        return Observation(
            stamp=t, odom=self._odometry(odom, arrived.get("odom", 0.0)),
            scan=self._to_scan(scan, arrived.get("scan", 0.0)) if scan is not None else None,
            image=self._to_image(image, info, arrived.get("image", 0.0)), bumpers=bumpers,
            dock_ir=self._to_dock_ir(ir) if fresh_ir and ir is not None else DockIR(),
            battery=self._to_battery(battery), devices_lost=(failure.what,) if failure is not None else (),
        )  # fmt: skip

    def command(self, v: float, omega: float) -> Twist2:
        """Clip and publish (v [m/s], ω [rad/s]) now; zero while the link is lost."""
        cv, cw = self._limits.clip(v, omega)
        if self.failure is not None:
            cv, cw = 0.0, 0.0
        self._send(cv, cw)
        self._cmd = Twist2(cv, cw)
        return self._cmd

    def step(self, dt: float) -> None:
        """Sleep until ``dt`` [s] after the last step's deadline (no drift; never sleeps to catch up)."""
        now = time.monotonic()
        deadline = (self._deadline if self._deadline is not None else now) + dt
        deadline = max(deadline, now)
        time.sleep(deadline - now)
        self._deadline = deadline

    def publish_world(self, **world: Any) -> None:
        """Publish homing's world model on the robot's graph (:class:`~homing.robot.ros2.world.WorldPublisher`)."""
        self._world.publish(**world)

    def close(self) -> None:
        """Send zero, undeclare homing's node and endpoints, close the session (again: nothing)."""
        if self.node.session.is_closed():
            return
        try:
            self._send(0.0, 0.0)
        finally:
            self.node.close()

    # --- conversions -------------------------------------------------------------------------
    def _send(self, v: float, omega: float) -> None:
        V = "geometry_msgs/msg/Vector3"
        twist = wire.message("geometry_msgs/msg/Twist", linear=wire.message(V, x=float(v), y=0.0, z=0.0),
                             angular=wire.message(V, x=0.0, y=0.0, z=float(omega)))  # fmt: skip
        if self.config.stamped:
            ns = time.time_ns()
            header = wire.message("std_msgs/msg/Header", frame_id=self.config.base_frame,
                                  stamp=wire.message("builtin_interfaces/msg/Time", sec=ns // 10**9,
                                                     nanosec=ns % 10**9))  # fmt: skip
            twist = wire.message(self.cmd_type, header=header, twist=twist)
        self.cmd_pub.publish(twist)

    def _odometry(self, r: Received | None, stamp: float) -> Odometry:
        if r is None:
            return Odometry(stamp, Pose2(), Twist2())
        m = r.message
        p = m.pose.pose
        return Odometry(stamp, Pose2(p.position.x, p.position.y, yaw_of(p.orientation)),
                        Twist2(m.twist.twist.linear.x, m.twist.twist.angular.z))  # fmt: skip

    def _to_scan(self, r: Received, stamp: float) -> Scan:
        m = r.message
        frame = self.config.laser_frame or m.header.frame_id
        pose = self.frames.pose(self.config.base_frame, frame) or self.config.laser_pose
        ranges = np.asarray(m.ranges, dtype=np.float32).copy()
        bad = ~np.isfinite(ranges) | (ranges < m.range_min) | (ranges > m.range_max)
        ranges[bad] = np.inf
        return Scan(stamp, float(m.angle_min), float(m.angle_increment), ranges,
                    float(m.range_min), float(m.range_max), pose)  # fmt: skip

    @staticmethod
    def _to_dock_ir(r: Received) -> DockIR:
        d = [int(v) for v in r.message.data]
        if len(d) < 3:
            return DockIR()
        return DockIR(IR(d[0] & 63), IR(d[1] & 63), IR(d[2] & 63))  # kobuki's order: right, centre, left

    def _to_image(self, image: Received | None, info: Received | None, stamp: float) -> CameraImage | None:
        """The latest Image as a CameraImage with the latest CameraInfo's K (None before both came)."""
        if image is None or info is None:
            return None
        if self._camera is not None and self._camera[0] is image and self._camera[1] is info:
            return self._camera[2]
        m, k = image.message, info.message.k
        channels = {"rgb8": 3, "bgr8": 3, "mono8": 1}.get(m.encoding)
        if channels is None or m.step < m.width * channels or len(m.data) < m.step * m.height:
            return None  # an encoding homing does not read: no image rather than a wrong one
        rows = np.asarray(m.data, dtype=np.uint8)[: m.step * m.height].reshape(m.height, m.step)
        pixels = rows[:, : m.width * channels].reshape(m.height, m.width, channels)
        pixels = pixels[..., ::-1] if m.encoding == "bgr8" else pixels
        x, y, z, yaw = self.config.camera_pose
        cam = CameraInfo(int(m.width), int(m.height), float(k[0]), float(k[4]), float(k[2]), float(k[5]),
                         homogeneous(rot_z(yaw) @ R_BODY_FROM_OPTICAL, np.array([x, y, z])))  # fmt: skip
        made = CameraImage(stamp, np.ascontiguousarray(pixels[..., 0] if channels == 1 else pixels), cam)
        self._camera = (image, info, made)
        return made

    def _to_battery(self, r: Received | None) -> BatteryState:
        if r is None:
            return BatteryState(0.0, 100.0)  # no battery topic: never a reason to go home
        m = r.message
        percent = 100.0 * m.percentage if math.isfinite(m.percentage) else battery_percent(m.voltage)
        dock = self.config.charging_at_dock
        if m.power_supply_status == POWER_SUPPLY_CHARGING:
            source = ChargingSource.DOCK if dock else ChargingSource.ADAPTER
            state = ChargingState.DOCKING_CHARGING if dock else ChargingState.ADAPTER_CHARGING
        elif m.power_supply_status == POWER_SUPPLY_FULL:
            source = ChargingSource.DOCK if dock else ChargingSource.ADAPTER
            state = ChargingState.DOCKING_CHARGED if dock else ChargingState.ADAPTER_CHARGED
        else:
            source, state = ChargingSource.NONE, ChargingState.DISCHARGING
        return BatteryState(float(m.voltage), min(100.0, max(0.0, percent)), source, state)


def open_ros2_robot(path: str | Path) -> Ros2Robot:
    """Read a ``kind: ros2`` robot file and connect (UserError, one line, if it cannot)."""
    return Ros2Robot(load_ros2_robot(path))
