"""The robot file of a ROS 2 robot (``kind: ros2``): where its Zenoh router is, its topics, frames and size.

``homing run MISSION --robot robot.yaml`` reads the file's ``kind`` first
(:func:`robot_kind`): ``ros2`` opens a :class:`~homing.robot.ros2.adapter.Ros2Robot`,
anything else (or no ``kind``) the TurtleBot 2 on serial ports. Every mistake
is reported at ``file:line:col``. Example (``robot.example.yaml`` beside this
module has every key; a TurtleBot 4 under its ``/tb4`` namespace would set
``namespace: /tb4`` and keep the relative topic names)::

    kind: ros2
    router: tcp/192.168.1.20:7447   # the robot's rmw_zenohd (Zenoh endpoint; homing is a client of it)
    domain: 0                       # ROS_DOMAIN_ID
    namespace: /                    # relative topic names below resolve under it
    node: homing                    # homing's node name in the ROS graph
    topics:
      scan: scan                    # sensor_msgs/msg/LaserScan
      odom: odom                    # nav_msgs/msg/Odometry
      battery: battery_state        # sensor_msgs/msg/BatteryState, or null if the robot has none
      cmd_vel: cmd_vel              # geometry_msgs/msg/Twist (or TwistStamped, below)
      tf: /tf
      tf_static: /tf_static
      dock_ir: null                 # kobuki_ros_interfaces/msg/DockInfraRed (kobuki_ros: sensors/dock_ir)
      bumper: null                  # kobuki_ros_interfaces/msg/BumperEvent (kobuki_ros: events/bumper)
      image: null                   # sensor_msgs/msg/Image (rgb8, bgr8 or mono8), for tags
      camera_info: null             # sensor_msgs/msg/CameraInfo of that image (rectified: its K is used)
    camera_pose: [0.10, 0.0, 0.30, 0.0]   # optical centre x, y, z [m] in base, and yaw [rad]; looking level
    cmd_vel_type: Twist             # Twist or TwistStamped (Jazzy's Nav2 and ros2_control use the latter)
    frames: {base: base_link, laser: null}   # laser null: the scan's own frame_id
    laser_pose: [0.0, 0.0, 0.0]     # x [m], y [m], yaw [rad] in base: used until /tf_static gives it
    radius: 0.18                    # [m] the footprint's circumscribed radius
    max_v: 0.5                      # [m/s]
    max_omega: 1.9                  # [rad/s]
    timeouts: {scan: 1.0, odom: 0.5, first_data: 5.0}   # [s] silence that counts as a lost topic
    charging_source: dock           # what a CHARGING BatteryState means: dock or adapter
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from homing.robot.turtlebot import BASE_RADIUS, MAX_OMEGA, MAX_V
from homing.robot.types import Pose2

from homing.errors import UserError
from homing.section import Section
from homing.yamlfile import load, where

TOPICS = {"scan": "scan", "odom": "odom", "battery": "battery_state", "cmd_vel": "cmd_vel",
          "tf": "/tf", "tf_static": "/tf_static"}  # fmt: skip
OPTIONAL = ("dock_ir", "bumper", "image", "camera_info")  # topics off unless named
TIMEOUTS = {"scan": 1.0, "odom": 0.5, "first_data": 5.0}  # [s]
KEYS = ("kind", "router", "domain", "namespace", "node", "topics", "cmd_vel_type", "frames",
        "laser_pose", "camera_pose", "radius", "max_v", "max_omega", "timeouts", "charging_source")  # fmt: skip


@dataclass(frozen=True)
class Ros2Config:
    """A parsed ``kind: ros2`` robot file (topic names as written: relative ones resolve under ``namespace``)."""

    file: Path
    router: str
    router_at: tuple[int, int]
    domain: int = 0
    namespace: str = "/"
    node: str = "homing"
    scan: str = TOPICS["scan"]
    odom: str = TOPICS["odom"]
    battery: str | None = TOPICS["battery"]
    cmd_vel: str = TOPICS["cmd_vel"]
    tf: str = TOPICS["tf"]
    tf_static: str = TOPICS["tf_static"]
    stamped: bool = False  # publish TwistStamped instead of Twist
    base_frame: str = "base_link"
    laser_frame: str | None = None  # None: the scan's header.frame_id
    laser_pose: Pose2 = Pose2()
    radius: float = BASE_RADIUS  # [m]
    max_v: float = MAX_V  # [m/s]
    max_omega: float = MAX_OMEGA  # [rad/s]
    scan_timeout: float = TIMEOUTS["scan"]  # [s]
    odom_timeout: float = TIMEOUTS["odom"]  # [s]
    first_data_timeout: float = TIMEOUTS["first_data"]  # [s]
    charging_at_dock: bool = True
    dock_ir: str | None = None
    bumper: str | None = None
    image: str | None = None
    camera_info: str | None = None
    camera_pose: tuple[float, float, float, float] = (0.10, 0.0, 0.30, 0.0)  # x, y, z [m], yaw [rad]


def robot_kind(path: str | Path) -> str:
    """The robot file's ``kind`` (``turtlebot2`` when it names none), read without checking the rest."""
    doc = load(Path(path))
    kind = doc.get("kind", "turtlebot2") if isinstance(doc, dict) else "turtlebot2"
    return kind if isinstance(kind, str) else "turtlebot2"


def _name(sec: Section, key: str, default: str, *, topic: bool = True) -> str:
    text = sec.string(key, default)
    ok = all(c.isalnum() or c in "_/~" for c in text) and "//" not in text
    if not ok or (text.endswith("/") and text != "/"):
        what = "a ROS name" if topic else "a ROS node name"
        raise sec.error(key, f"'{key}' must be {what} (letters, digits, _ and /), not {text!r}")
    return text


def load_ros2_robot(path: str | Path) -> Ros2Config:
    """Read and check a ``kind: ros2`` robot file (nothing is opened here)."""
    path = Path(path)
    top = Section(load(path), path, "robot file")
    top.only(KEYS)
    if top.string("kind", "turtlebot2") != "ros2":
        raise top.error("kind", "robot file: 'kind' must be ros2 here")
    router = top.string("router")
    if "/" not in router or router.split("/", 1)[0] not in ("tcp", "udp", "tls", "quic", "ws", "unixsock-stream"):
        raise top.error("router", f"'router' must be a Zenoh endpoint such as tcp/192.168.1.20:7447, not {router!r}")
    namespace = _name(top, "namespace", "/")
    if not namespace.startswith("/"):
        raise top.error("namespace", f"'namespace' must start with '/', not {namespace!r}")
    node = _name(top, "node", "homing", topic=False)
    if "/" in node:
        raise top.error("node", f"'node' must be a plain name without '/', not {node!r}")

    topics = dict(TOPICS)
    battery: str | None = TOPICS["battery"]
    optional: dict[str, str | None] = dict.fromkeys(OPTIONAL)
    if top.has("topics"):
        t = top.section("topics")
        t.only(tuple(TOPICS) + OPTIONAL)
        for key in OPTIONAL:
            if t.raw(key) is not None:
                optional[key] = _name(t, key, "")
        for key in TOPICS:
            if key == "battery" and t.has(key) and t.raw(key) is None:
                battery = None
                continue
            topics[key] = _name(t, key, TOPICS[key])
        if "battery" in t.doc and t.raw("battery") is not None:
            battery = topics["battery"]

    kind = top.string("cmd_vel_type", "Twist", choices=("Twist", "TwistStamped"))
    base, laser = "base_link", None
    if top.has("frames"):
        f = top.section("frames")
        f.only(("base", "laser"))
        base = _name(f, "base", "base_link")
        laser = None if f.raw("laser") is None else _name(f, "laser", "laser")
    pose = Pose2(*top.vector("laser_pose", 3)) if top.has("laser_pose") else Pose2()

    timeouts = dict(TIMEOUTS)
    if top.has("timeouts"):
        s = top.section("timeouts")
        s.only(tuple(TIMEOUTS))
        timeouts = {k: s.number(k, v, positive=True, hi=120.0) for k, v in TIMEOUTS.items()}
    source = top.string("charging_source", "dock", choices=("dock", "adapter"))
    line, col = where(top.doc, "router")
    config = Ros2Config(
        path, router, (line, col), top.integer("domain", 0, lo=0, hi=232), namespace, node,
        topics["scan"], topics["odom"], battery, topics["cmd_vel"], topics["tf"], topics["tf_static"],
        kind == "TwistStamped", base, laser, pose,
        top.number("radius", BASE_RADIUS, positive=True, hi=2.0),
        top.number("max_v", MAX_V, positive=True, hi=5.0),
        top.number("max_omega", MAX_OMEGA, positive=True, hi=10.0),
        timeouts["scan"], timeouts["odom"], timeouts["first_data"], source == "dock",
        optional["dock_ir"], optional["bumper"], optional["image"], optional["camera_info"],
        top.vector("camera_pose", 4) if top.has("camera_pose") else (0.10, 0.0, 0.30, 0.0),  # type: ignore[arg-type]
    )  # fmt: skip
    if (config.image is None) != (config.camera_info is None):
        key = "image" if config.image is None else "camera_info"
        raise top.error("topics", f"topics: 'image' and 'camera_info' go together: name '{key}' too")
    return config


def router_error(config: Ros2Config, message: str) -> UserError:
    """A one-line error at the robot file's ``router`` entry."""
    return UserError(message, config.file, *config.router_at)
