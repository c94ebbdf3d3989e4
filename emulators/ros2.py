"""A simulated robot served as a ROS 2 robot over Zenoh, in rmw_zenoh's format, on the wall clock.

:class:`Ros2Emulation` owns a :class:`homing.sim.SimRobot` and a Zenoh peer
listening on ``tcp/127.0.0.1:PORT`` (clients connect to it as to a robot's
``rmw_zenohd``) that plays a node ``turtlebot`` with the topics a TurtleBot 4
publishes (or, given ``router``, a peer that joins that Zenoh router, as
rmw_zenoh's sessions join ``rmw_zenohd``), and every ``PERIOD`` of wall-clock time:

1. applies the last ``/cmd_vel`` (``geometry_msgs/Twist``) to the simulator,
   or zero when none came for ``CMD_TIMEOUT`` (a base's command watchdog);
2. steps the simulator by the wall-clock time that really passed;
3. publishes ``/odom`` (``nav_msgs/Odometry``) and ``odom → base_link`` on
   ``/tf``, each new scan on ``/scan`` (``sensor_msgs/LaserScan``, best
   effort), and once a second ``/battery_state`` (``sensor_msgs/BatteryState``).

``base_link → base_scan`` goes out once on ``/tf_static``, latched (a Zenoh
advanced publisher's cache, as rmw_zenoh's TRANSIENT_LOCAL publishers keep
one). Every sample carries rmw_zenoh's attachment and every endpoint its
liveliness token. The folder gets ``robot.yaml`` (``kind: ros2``, naming the
endpoint) and ``status.json`` (the simulator's truth, for tests only).
Like a Kobuki under ``kobuki_ros``, it also publishes the dock's IR on
``/sensors/dock_ir`` every tick and bumper events on ``/events/bumper``
(``kobuki_ros_interfaces``), and, like an RGB camera driver, each frame the
simulator renders (while a tag can be in view) on ``/camera/color/image_raw``
(``rgb8``) with its ``camera_info``; charging shows in the BatteryState.
"""

from __future__ import annotations

import json
import math
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
from homing.robot.ros2 import wire
from homing.robot.ros2.node import Ros2Node, free_port
from homing.robot.ros2.wire import LATCHED, SENSOR_DATA, Qos, Received
from homing.robot.types import ChargingState, Observation
from homing.sim.world import World

from homing.atomic import atomic_write

PERIOD = 0.02  # [s] odometry at 50 Hz
MAX_STEP = 0.1  # [s] a stall longer than this is not simulated all at once
CMD_TIMEOUT = 0.5  # [s] stop when no cmd_vel came for this long
STATUS_PERIOD = 1.0  # [s] battery and status.json
LASER_FRAME = "base_scan"
T = "geometry_msgs/msg/"

ROBOT_FILE = """\
# Written by 'homing emulate --ros2': the emulated robot's Zenoh endpoint and topics.
kind: ros2
router: {endpoint}
domain: {domain}
node: homing
topics: {{scan: /scan, odom: /odom, battery: /battery_state, cmd_vel: /cmd_vel, dock_ir: /sensors/dock_ir,
          bumper: /events/bumper{camera}}}
frames: {{base: base_link}}
"""
CAMERA_TOPICS = ", image: /camera/color/image_raw, camera_info: /camera/color/camera_info"
CAMERA_POSE = "camera_pose: [{x:g}, {y:g}, {z:g}, 0.0]\n"


def _stamp(t_ns: int) -> Any:
    return wire.message("builtin_interfaces/msg/Time", sec=t_ns // 10**9, nanosec=t_ns % 10**9)


def _header(frame: str, t_ns: int) -> Any:
    return wire.message("std_msgs/msg/Header", stamp=_stamp(t_ns), frame_id=frame)


def _quaternion(yaw: float) -> Any:
    return wire.message(T + "Quaternion", x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def _vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
    return wire.message(T + "Vector3", x=x, y=y, z=z)


def _transform(parent: str, child: str, x: float, y: float, z: float, yaw: float, t_ns: int) -> Any:
    return wire.message(T + "TransformStamped", header=_header(parent, t_ns), child_frame_id=child,
                        transform=wire.message(T + "Transform", translation=_vector(x, y, z),
                                               rotation=_quaternion(yaw)))  # fmt: skip


class Ros2Emulation:
    """The simulated robot behind a Zenoh peer on 127.0.0.1 (``port`` 0: a free one)."""

    def __init__(self, world: World, folder: str | Path, seed: int = 0, port: int = 0, domain: int = 0,
                 camera: bool = True, router: str | None = None):  # fmt: skip
        from homing.sim.robot import SimRobot

        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.robot = SimRobot(world, seed=seed, camera=camera)
        self.camera = camera
        self._frame_stamp: float | None = None
        self._bumpers: tuple[bool, bool, bool] = (False, False, False)
        self.frames = 0
        self.router = router  # join this Zenoh router (as rmw_zenoh's sessions do) instead of listening
        self.port = port or free_port()
        self.domain = domain
        self.node: Ros2Node | None = None
        self.lock = threading.Lock()
        self._cmd: tuple[float, float, float] = (0.0, 0.0, -math.inf)  # v, ω, wall time received
        self.commands = 0
        self.distance = 0.0  # [m] travelled (truth)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_scan = -math.inf
        self._next_status = 0.0

    @property
    def endpoint(self) -> str:
        """What a client connects to: the router joined, or this peer's own listening endpoint."""
        return self.router or f"tcp/127.0.0.1:{self.port}"

    @property
    def robot_file(self) -> Path:
        return self.folder / "robot.yaml"

    def start(self) -> None:
        """Open the peer (a zenoh error if the port cannot be had), declare the topics, write the files, run."""
        if self.router is not None:  # rmw_zenoh's default session: connect to the router, listen on loopback
            n = Ros2Node("turtlebot", domain=self.domain, mode="peer", connect=[self.router],
                         listen=["tcp/127.0.0.1:0"])  # fmt: skip
        else:
            n = Ros2Node("turtlebot", domain=self.domain, mode="peer", listen=[self.endpoint])
        self.node = n
        self.odom_pub = n.publisher("/odom", "nav_msgs/msg/Odometry", Qos())
        self.scan_pub = n.publisher("/scan", "sensor_msgs/msg/LaserScan", SENSOR_DATA)
        self.battery_pub = n.publisher("/battery_state", "sensor_msgs/msg/BatteryState", SENSOR_DATA)
        self.tf_pub = n.publisher("/tf", "tf2_msgs/msg/TFMessage", Qos(depth=100))
        static = n.publisher("/tf_static", "tf2_msgs/msg/TFMessage", LATCHED)
        lp = self.robot.observe().scan
        pose = lp.laser_pose if lp is not None else None
        x, y, yaw = (pose.x, pose.y, pose.theta) if pose is not None else (0.0, 0.0, 0.0)
        static.publish(wire.message("tf2_msgs/msg/TFMessage", transforms=[
            _transform("base_link", LASER_FRAME, x, y, 0.5, yaw, time.time_ns())]))  # fmt: skip
        self.ir_pub = n.publisher("/sensors/dock_ir", "kobuki_ros_interfaces/msg/DockInfraRed", SENSOR_DATA)
        self.bumper_pub = n.publisher("/events/bumper", "kobuki_ros_interfaces/msg/BumperEvent", Qos())
        text = ROBOT_FILE.format(endpoint=self.endpoint, domain=self.domain, camera=CAMERA_TOPICS if self.camera else "")
        if self.camera:
            self.image_pub = n.publisher("/camera/color/image_raw", "sensor_msgs/msg/Image", SENSOR_DATA)
            self.info_pub = n.publisher("/camera/color/camera_info", "sensor_msgs/msg/CameraInfo", SENSOR_DATA)
            assert self.robot.camera is not None
            x, y, z = (float(v) for v in self.robot.camera.info.base_from_optical[:3, 3])
            text += CAMERA_POSE.format(x=x, y=y, z=z)
        n.subscribe("/cmd_vel", "geometry_msgs/msg/Twist", Qos(), self._on_cmd)
        atomic_write(self.robot_file, text)
        self._write_status()
        self._thread = threading.Thread(target=self._run, name="homing-ros2-emulation", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self.node is not None:
            self.node.close()
        self._write_status()
        self.robot.close()

    def _on_cmd(self, r: Received) -> None:
        with self.lock:
            self._cmd = (float(r.message.linear.x), float(r.message.angular.z), time.monotonic())
            self.commands += 1

    def _run(self) -> None:
        last = deadline = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            with self.lock:
                v, omega, at = self._cmd
            if now - at > CMD_TIMEOUT:
                v, omega = 0.0, 0.0
            self._tick(v, omega, min(now - last, MAX_STEP), now)
            last = now
            deadline = max(deadline + PERIOD, time.monotonic() - MAX_STEP)
            time.sleep(max(0.0, deadline - time.monotonic()))

    def _tick(self, v: float, omega: float, dt: float, wall: float) -> None:
        before = self.robot.truth_pose()
        self.robot.command(v, omega)
        self.robot.step(dt)
        self.distance += before.distance_to(self.robot.truth_pose())
        obs = self.robot.observe()
        t_ns = time.time_ns()
        self._publish_odom(obs, t_ns)
        if obs.scan is not None and obs.scan.stamp != self._last_scan:
            self._last_scan = obs.scan.stamp
            self._publish_scan(obs, t_ns)
        ir = obs.dock_ir
        self.ir_pub.publish(wire.message("kobuki_ros_interfaces/msg/DockInfraRed", header=_header("dock_ir", t_ns),
                                         data=np.array([ir.right, ir.centre, ir.left], dtype=np.uint8)))  # fmt: skip
        b = obs.bumpers
        for i, (was, now) in enumerate(zip(self._bumpers, (b.left, b.centre, b.right), strict=True)):
            if was != now:
                self.bumper_pub.publish(wire.message("kobuki_ros_interfaces/msg/BumperEvent", bumper=i, state=int(now)))
        self._bumpers = (b.left, b.centre, b.right)
        if obs.image is not None and obs.image.stamp != self._frame_stamp:
            self._frame_stamp = obs.image.stamp
            self._publish_image(obs, t_ns)
        if wall >= self._next_status:
            self._next_status = wall + STATUS_PERIOD
            self._publish_battery(obs, t_ns)
            self._write_status()

    def _publish_odom(self, obs: Observation, t_ns: int) -> None:
        p, tw = obs.odom.pose, obs.odom.twist
        pose = wire.message(T + "PoseWithCovariance", covariance=np.zeros(36), pose=wire.message(
            T + "Pose", position=wire.message(T + "Point", x=p.x, y=p.y, z=0.0), orientation=_quaternion(p.theta)))  # fmt: skip
        twist = wire.message(T + "TwistWithCovariance", covariance=np.zeros(36), twist=wire.message(
            T + "Twist", linear=_vector(tw.v), angular=_vector(z=tw.omega)))  # fmt: skip
        self.odom_pub.publish(wire.message("nav_msgs/msg/Odometry", header=_header("odom", t_ns),
                                           child_frame_id="base_link", pose=pose, twist=twist))  # fmt: skip
        self.tf_pub.publish(wire.message("tf2_msgs/msg/TFMessage", transforms=[
            _transform("odom", "base_link", p.x, p.y, 0.0, p.theta, t_ns)]))  # fmt: skip

    def _publish_scan(self, obs: Observation, t_ns: int) -> None:
        s = obs.scan
        assert s is not None
        ranges = np.asarray(s.ranges, dtype=np.float32)
        n = len(ranges)
        self.scan_pub.publish(wire.message(
            "sensor_msgs/msg/LaserScan", header=_header(LASER_FRAME, t_ns), angle_min=float(s.angle_min),
            angle_max=float(s.angle_min + s.angle_increment * (n - 1)), angle_increment=float(s.angle_increment),
            time_increment=0.0, scan_time=0.0, range_min=float(s.range_min), range_max=float(s.range_max),
            ranges=ranges, intensities=np.zeros(0, np.float32)))  # fmt: skip

    def _publish_image(self, obs: Observation, t_ns: int) -> None:
        img = obs.image
        assert img is not None
        pixels = np.ascontiguousarray(img.image, dtype=np.uint8)
        h, w = pixels.shape[:2]
        mono = pixels.ndim == 2
        i = img.info
        header = _header("camera_color_optical_frame", t_ns)
        self.info_pub.publish(wire.zero("sensor_msgs/msg/CameraInfo", header=header, width=w, height=h,
                                        distortion_model="plumb_bob", d=np.zeros(5),
                                        k=np.array([i.fx, 0.0, i.cx, 0.0, i.fy, i.cy, 0.0, 0.0, 1.0]),
                                        r=np.eye(3).reshape(-1),
                                        p=np.array([i.fx, 0.0, i.cx, 0.0, 0.0, i.fy, i.cy, 0.0, 0.0, 0.0, 1.0, 0.0])))  # fmt: skip
        self.image_pub.publish(wire.message("sensor_msgs/msg/Image", header=header, height=h, width=w,
                                            encoding="mono8" if mono else "rgb8", is_bigendian=0,
                                            step=w if mono else 3 * w, data=pixels.reshape(-1)))  # fmt: skip
        self.frames += 1

    def _publish_battery(self, obs: Observation, t_ns: int) -> None:
        b = obs.battery
        status = {ChargingState.DOCKING_CHARGING: 1, ChargingState.ADAPTER_CHARGING: 1,
                  ChargingState.DOCKING_CHARGED: 4, ChargingState.ADAPTER_CHARGED: 4}.get(b.state, 2)  # fmt: skip
        nan = float("nan")
        self.battery_pub.publish(wire.message(
            "sensor_msgs/msg/BatteryState", header=_header("base_link", t_ns), voltage=b.voltage, temperature=nan,
            current=nan, charge=nan, capacity=nan, design_capacity=2.2, percentage=b.percent / 100.0,
            power_supply_status=status, power_supply_health=1, power_supply_technology=2, present=True,
            cell_voltage=np.zeros(0, np.float32), cell_temperature=np.zeros(0, np.float32),
            location="base", serial_number=""))  # fmt: skip

    def status(self) -> dict[str, Any]:
        """The simulator's truth and the link's counters (evaluation only)."""
        pose = self.robot.truth_pose()
        return {"time": self.robot.clock.now(), "truth": [pose.x, pose.y, pose.theta], "distance": self.distance,
                "commands": self.commands, "frames": self.frames, "charging": self.robot.charging,
                "from_dock": pose.distance_to(self.robot.world.dock_pose), "endpoint": self.endpoint}  # fmt: skip

    def _write_status(self) -> None:
        atomic_write(self.folder / "status.json", json.dumps(self.status(), indent=1) + "\n")
