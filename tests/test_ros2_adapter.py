"""Ros2Robot against a ROS 2 robot played by a real Zenoh peer in this process, over loopback TCP.

The peer listens on tcp/127.0.0.1:PORT (as rmw_zenohd would), publishes
LaserScan, Odometry, BatteryState and a latched /tf_static in rmw_zenoh's
format (homing.robot.ros2.node, whose wire format tests/test_ros2_wire.py
checks against rmw_zenoh's documents), and subscribes cmd_vel. The adapter
connects in client mode from a robot file, as ``homing run --robot`` does.
"""

from __future__ import annotations

import math
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("zenoh", reason="eclipse-zenoh (pip install 'homing[ros2]') is not installed")
pytest.importorskip("xxhash", reason="xxhash (pip install 'homing[ros2]') is not installed")

from homing.robot.ros2 import wire  # noqa: E402
from homing.robot.ros2.adapter import Cause, LinkLost, Ros2Robot, open_ros2_robot  # noqa: E402
from homing.robot.ros2.node import Ros2Node, free_port  # noqa: E402
from homing.robot.ros2.robot_file import load_ros2_robot, robot_kind  # noqa: E402
from homing.robot.ros2.wire import LATCHED, SENSOR_DATA, Attachment, Qos, Received  # noqa: E402
from homing.robot.types import ChargingState  # noqa: E402

from homing.errors import UserError  # noqa: E402

m = wire.message
T = "geometry_msgs/msg/"
LASER = (0.1, -0.02, math.pi)  # base_scan in base_link through an intermediate frame: x, y, yaw
WAIT = 10.0  # [s] the longest any condition below may take


def wait_until(predicate: Callable[[], object], timeout: float = WAIT) -> bool:
    """Poll ``predicate`` every 10 ms until it holds or ``timeout`` [s] passes."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return bool(predicate())


def _header(frame: str) -> object:
    ns = time.time_ns()
    return m("std_msgs/msg/Header", stamp=m("builtin_interfaces/msg/Time", sec=ns // 10**9, nanosec=ns % 10**9),
             frame_id=frame)  # fmt: skip


def _tf(parent: str, child: str, x: float, y: float, yaw: float) -> object:
    return m(T + "TransformStamped", header=_header(parent), child_frame_id=child,
             transform=m(T + "Transform", translation=m(T + "Vector3", x=x, y=y, z=0.2),
                         rotation=m(T + "Quaternion", x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))))  # fmt: skip


class RobotPeer:
    """A ROS 2 robot on a listening Zenoh peer: scan 10 Hz, odom 50 Hz, battery 1 Hz, static TF, cmd_vel in."""

    def __init__(self, port: int, cmd_type: str = "geometry_msgs/msg/Twist", *, via_router: bool = False):
        if via_router:  # rmw_zenoh's default session: a peer connected to the router, listening on loopback
            self.node = Ros2Node("turtlebot", mode="peer", connect=[f"tcp/127.0.0.1:{port}"],
                                 listen=["tcp/127.0.0.1:0"])  # fmt: skip
        else:  # the robot's session is itself the endpoint homing connects to
            self.node = Ros2Node("turtlebot", mode="peer", listen=[f"tcp/127.0.0.1:{port}"])
        n = self.node
        self.scan_pub = n.publisher("/scan", "sensor_msgs/msg/LaserScan", SENSOR_DATA)
        self.odom_pub = n.publisher("/odom", "nav_msgs/msg/Odometry", Qos())
        self.battery_pub = n.publisher("/battery_state", "sensor_msgs/msg/BatteryState", SENSOR_DATA)
        static = n.publisher("/tf_static", "tf2_msgs/msg/TFMessage", LATCHED)
        x, y, yaw = LASER
        static.publish(m("tf2_msgs/msg/TFMessage", transforms=[
            _tf("base_link", "shell_link", x, 0.0, 0.0), _tf("shell_link", "base_scan", 0.0, y, yaw)]))  # fmt: skip
        self.commands: list[Received] = []
        self.cond = threading.Condition()
        n.subscribe("/cmd_vel", cmd_type, Qos(), self._on_cmd)
        self.send = {"scan": True, "odom": True}
        self.stop = threading.Event()
        self.x = 0.0
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _on_cmd(self, r: Received) -> None:
        with self.cond:
            self.commands.append(r)
            self.cond.notify_all()

    def wait_commands(self, n: int) -> list[Received]:
        with self.cond:
            assert self.cond.wait_for(lambda: len(self.commands) >= n, WAIT), f"{len(self.commands)} < {n}"
            return list(self.commands)

    def _run(self) -> None:
        i = 0
        while not self.stop.wait(0.02):  # the robot's 50 Hz loop
            i += 1
            self.x += 0.001
            if self.send["odom"]:
                self.odom_pub.publish(self.odom())
            if i % 5 == 0 and self.send["scan"]:
                self.scan_pub.publish(self.scan())
            if i % 50 == 1:
                self.battery_pub.publish(self.battery())

    def odom(self) -> object:
        yaw = 0.5
        pose = m(T + "PoseWithCovariance", covariance=np.zeros(36), pose=m(T + "Pose",
                 position=m(T + "Point", x=self.x, y=-1.0, z=0.0),
                 orientation=m(T + "Quaternion", x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))))  # fmt: skip
        twist = m(T + "TwistWithCovariance", covariance=np.zeros(36), twist=m(T + "Twist",
                  linear=m(T + "Vector3", x=0.05, y=0.0, z=0.0), angular=m(T + "Vector3", x=0.0, y=0.0, z=-0.2)))  # fmt: skip
        return m("nav_msgs/msg/Odometry", header=_header("odom"), child_frame_id="base_link", pose=pose, twist=twist)

    @staticmethod
    def scan() -> object:
        ranges = np.full(360, 2.0, dtype=np.float32)
        ranges[10], ranges[11], ranges[12] = np.nan, 0.01, 50.0  # no return, under min, over max
        return m("sensor_msgs/msg/LaserScan", header=_header("base_scan"), angle_min=-math.pi,
                 angle_max=math.pi, angle_increment=2 * math.pi / 360, time_increment=0.0, scan_time=0.1,
                 range_min=0.12, range_max=12.0, ranges=ranges, intensities=np.zeros(0, np.float32))  # fmt: skip

    @staticmethod
    def battery() -> object:
        return m("sensor_msgs/msg/BatteryState", header=_header(""), voltage=15.5, temperature=20.0, current=1.0,
                 charge=1.0, capacity=2.0, design_capacity=2.0, percentage=0.61, power_supply_status=1,
                 power_supply_health=1, power_supply_technology=2, present=True,
                 cell_voltage=np.zeros(0, np.float32), cell_temperature=np.zeros(0, np.float32),
                 location="", serial_number="")  # fmt: skip

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.node.close()


def robot_file(tmp_path: Path, port: int, extra: str = "") -> Path:
    path = tmp_path / "robot.yaml"
    path.write_text(f"kind: ros2\nrouter: tcp/127.0.0.1:{port}\ntimeouts: {{scan: 1.0, odom: 0.6}}\n"
                    f"radius: 0.2\nmax_v: 0.5\n{extra}")  # fmt: skip
    return path


@pytest.fixture
def port() -> int:
    return free_port()


@pytest.fixture
def peer(port):
    p = RobotPeer(port)
    yield p
    p.close()


@pytest.fixture
def robot(tmp_path, port, peer):
    r = open_ros2_robot(robot_file(tmp_path, port))
    yield r
    r.close()


def test_observation_holds_the_robots_scan_odometry_battery_and_laser_pose(robot, peer):
    assert robot_kind(robot.config.file) == "ros2"
    assert wait_until(lambda: robot.frames.pose("base_link", "base_scan") is not None), "no /tf_static"
    obs = robot.observe()
    assert obs.devices_lost == ()
    assert obs.odom.pose.y == -1.0 and obs.odom.pose.theta == pytest.approx(0.5)
    assert obs.odom.twist.v == pytest.approx(0.05) and obs.odom.twist.omega == pytest.approx(-0.2)
    assert obs.scan is not None and len(obs.scan.ranges) == 360
    assert np.isinf(obs.scan.ranges[10:13]).all() and (obs.scan.ranges[13:] == 2.0).all()
    lp = obs.scan.laser_pose
    assert (lp.x, lp.y, abs(lp.theta)) == pytest.approx((LASER[0], LASER[1], math.pi))
    # ray 180 (angle 0 in the laser frame; 3 invalid rays before it) ends behind the base: the laser looks back
    assert obs.scan.points()[180 - 3][0] == pytest.approx(0.1 - 2.0, abs=1e-6)
    assert wait_until(lambda: robot.observe().battery.percent == pytest.approx(61.0, abs=1e-4))
    b = robot.observe().battery
    assert b.state is ChargingState.DOCKING_CHARGING and b.on_dock and b.voltage == pytest.approx(15.5)
    assert robot.limits.radius == 0.2 and robot.command(2.0, 0.0).v == 0.5


def test_homing_is_in_the_ros_graph_with_rmw_zenoh_tokens(robot, peer):
    zid = robot.node.name.zid
    tokens = {str(r.ok.key_expr) for r in peer.node.session.liveliness().get(f"@ros2_lv/0/{zid}/**")}
    scan_hash = wire.type_hash("sensor_msgs/msg/LaserScan")
    twist_hash = wire.type_hash("geometry_msgs/msg/Twist")
    assert f"@ros2_lv/0/{zid}/0/0/NN/%/%/homing" in tokens
    assert (f"@ros2_lv/0/{zid}/0/1/MS/%/%/homing/%scan/sensor_msgs::msg::dds_::LaserScan_/{scan_hash}/"
            "2::,5:,:,:,,") in tokens  # fmt: skip
    assert (f"@ros2_lv/0/{zid}/0/6/MP/%/%/homing/%cmd_vel/geometry_msgs::msg::dds_::Twist_/{twist_hash}/"
            "::,10:,:,:,,") in tokens  # fmt: skip
    assert any("/MS/%/%/homing/%tf_static/" in t and t.endswith("/:1:,1:,:,:,,") for t in tokens)
    # homing's world model is declared with the node, before the first tick publishes on it
    assert any("/MP/%/%/homing/%mission%state/std_msgs::msg::dds_::String_/" in t and t.endswith("/:1:,1:,:,:,,")
               for t in tokens)  # fmt: skip
    assert len(tokens) == 14  # node, scan, odom, battery, tf, tf_static, cmd_vel; map, tf, plan, goal, state, status, tags


def test_commands_reach_the_robot_as_twists_with_attachments_and_close_sends_zero(robot, peer):
    t0 = time.monotonic()
    robot.command(0.3, 0.5)
    first = peer.wait_commands(1)[0]
    latency = time.monotonic() - t0
    assert (first.message.linear.x, first.message.angular.z) == (0.3, 0.5)
    assert first.attachment.sequence == 1 and first.attachment.gid == wire.gid(robot.cmd_pub.token_key)
    assert abs(first.attachment.timestamp_ns / 1e9 - time.time()) < 5.0
    assert latency < 1.0
    robot.command(-3.0, 0.0)
    assert peer.wait_commands(2)[1].message.linear.x == -0.5  # clipped to max_v
    robot.close()
    last = peer.wait_commands(3)[-1]
    assert (last.message.linear.x, last.message.angular.z, last.attachment.sequence) == (0.0, 0.0, 3)


def test_twist_stamped_when_the_robot_file_asks(tmp_path, port):
    peer = RobotPeer(port, cmd_type="geometry_msgs/msg/TwistStamped")
    try:
        robot = open_ros2_robot(robot_file(tmp_path, port, "cmd_vel_type: TwistStamped\n"))
        try:
            robot.command(0.2, -0.1)
            got = peer.wait_commands(1)[0].message
            assert got.header.frame_id == "base_link"
            assert (got.twist.linear.x, got.twist.angular.z) == (0.2, -0.1)
        finally:
            robot.close()
    finally:
        peer.close()


def test_bad_samples_are_counted_and_skipped(robot, peer):
    scan_sub = next(e for e in robot.node.entities if getattr(e, "topic", "") == "/scan" and hasattr(e, "counters"))
    c = scan_sub.counters
    s = peer.node.session
    good = wire.encode(peer.scan(), "sensor_msgs/msg/LaserScan")
    att = Attachment(99, time.time_ns(), bytes(16)).encode()
    key = scan_sub.key
    before = (c.no_attachment, c.wrong_type, c.bad_cdr)
    s.put(key, good)  # no attachment
    s.put(key.rsplit("/", 1)[0] + "/RIHS01_" + "0" * 64, good, attachment=att)  # another type hash
    s.put(key, good[: len(good) // 3], attachment=att)  # truncated CDR
    assert wait_until(lambda: (c.no_attachment, c.wrong_type, c.bad_cdr) == tuple(b + 1 for b in before))
    assert robot.observe().devices_lost == () and c.taken > 0


def test_a_silent_topic_stops_the_robot_until_it_speaks_again(robot, peer):
    peer.send["scan"] = False
    assert wait_until(lambda: robot.observe().devices_lost == ("/scan",))
    assert robot.failure is not None and robot.failure.cause is Cause.SILENT
    with pytest.raises(LinkLost):
        robot.require_link()
    assert robot.command(0.4, 0.2).v == 0.0
    assert peer.wait_commands(2)[-1].message.linear.x == 0.0  # the stop on losing it, then the zeroed command
    peer.send["scan"] = True
    assert wait_until(lambda: robot.observe().devices_lost == ())
    assert robot.command(0.4, 0.0).v == 0.4


def test_a_lost_router_stops_the_robot_and_it_reconnects_when_the_router_is_back(tmp_path, port):
    peer = RobotPeer(port)
    robot = open_ros2_robot(robot_file(tmp_path, port))
    try:
        peer.close()
        assert wait_until(lambda: robot.observe().devices_lost == ("router",))
        assert robot.failure is not None and robot.failure.cause is Cause.ROUTER
        assert robot.command(0.3, 0.0) == robot.command(0.3, 0.0) and robot.command(0.3, 0.0).v == 0.0
        peer = RobotPeer(port)  # the router is back on the same endpoint
        assert wait_until(lambda: robot.observe().devices_lost == (), timeout=30.0), robot.failure
        assert robot.command(0.3, 0.0).v == 0.3
        assert peer.wait_commands(1)[-1].message.linear.x == 0.3
    finally:
        robot.close()
        peer.close()


def test_through_a_zenoh_router_as_rmw_zenohd_runs_it_and_when_it_restarts(tmp_path, port):
    import zenoh
    from homing.robot.ros2.node import session_config

    router = zenoh.open(session_config("router", listen=[f"tcp/127.0.0.1:{port}"]))
    peer = RobotPeer(port, via_router=True)
    robot = None
    try:
        robot = open_ros2_robot(robot_file(tmp_path, port))
        assert list(robot.node.session.info.routers_zid())  # homing talks to the router, not to the robot directly
        assert robot.observe().scan is not None
        robot.command(0.25, 0.0)
        assert peer.wait_commands(1)[-1].message.linear.x == 0.25
        router.close()
        assert wait_until(lambda: robot.observe().devices_lost == ("router",))
        router = zenoh.open(session_config("router", listen=[f"tcp/127.0.0.1:{port}"]))
        assert wait_until(lambda: robot.observe().devices_lost == (), timeout=30.0), robot.failure
        robot.command(0.2, 0.0)
        assert wait_until(lambda: any(c.message.linear.x == 0.2 for c in peer.wait_commands(1)))
    finally:
        if robot is not None:
            robot.close()
        peer.close()
        router.close()


def test_an_unreachable_router_is_a_one_line_error_at_the_robot_files_router(tmp_path):
    path = robot_file(tmp_path, free_port())
    with pytest.raises(UserError) as err:
        Ros2Robot(load_ros2_robot(path))
    assert str(err.value).startswith(f"{path}:2:9: cannot reach the Zenoh router tcp/127.0.0.1:")
    assert "\n" not in str(err.value)


def test_a_router_without_the_robots_topics_is_a_one_line_error(tmp_path, port):
    quiet = Ros2Node("empty", mode="peer", listen=[f"tcp/127.0.0.1:{port}"])
    try:
        path = tmp_path / "robot.yaml"
        path.write_text(f"kind: ros2\nrouter: tcp/127.0.0.1:{port}\ntimeouts: {{first_data: 0.5}}\n")
        with pytest.raises(UserError, match=r"robot.yaml:2:9: no /odom and no /scan and no /battery_state from tcp/127.0.0.1:\d+ within 0.5 s"):
            open_ros2_robot(path)
    finally:
        quiet.close()


@pytest.mark.parametrize("text, where, message", [
    ("kind: ros2\n", "1:1", "missing required key 'router'"),
    ("kind: ros2\nrouter: 192.168.1.2:7447\n", "2:9", "'router' must be a Zenoh endpoint"),
    ("kind: ros2\nrouter: tcp/a:1\ntopix: {}\n", "3:1", "unknown key 'topix' in robot file (did you mean 'topics'?)"),
    ("kind: ros2\nrouter: tcp/a:1\ncmd_vel_type: Twits\n", "3:15", "'cmd_vel_type' must be one of Twist, TwistStamped"),
    ("kind: ros2\nrouter: tcp/a:1\ntopics: {scan: 'sc an'}\n", "3:16", "'scan' must be a ROS name"),
    ("kind: ros2\nrouter: tcp/a:1\nnamespace: tb4\n", "3:12", "'namespace' must start with '/'"),
])  # fmt: skip
def test_robot_file_mistakes_are_one_line_errors(tmp_path, text, where, message):
    path = tmp_path / "robot.yaml"
    path.write_text(text)
    with pytest.raises(UserError) as err:
        load_ros2_robot(path)
    assert str(err.value).startswith(f"{path}:{where}: ") and message in str(err.value)


def test_the_cli_reports_a_bad_ros2_robot_file_in_one_line_and_exits_2(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text("kind: ros2\nrouter: tcp/127.0.0.1:1\ndomian: 3\n")
    done = subprocess.run([sys.executable, "-m", "homing.missions.cli", "run", "explore", "--robot", str(path)],
                          capture_output=True, text=True, timeout=120)  # fmt: skip
    assert done.returncode == 2
    assert done.stderr.strip() == f"{path}:3:1: unknown key 'domian' in robot file (did you mean 'domain'?)"


class _Grid:
    """A grid as homing.mapping's OccupancyGrid offers it: data (H, W) int8, resolution [m], origin (x, y) [m]."""

    def __init__(self) -> None:
        self.data = np.full((4, 6), -1, dtype=np.int8)
        self.data[1:3, 1:5] = 0
        self.data[0, 0] = 100
        self.resolution = 0.05
        self.origin = (-1.5, 2.0)


def test_the_world_model_is_published_in_the_robots_graph(robot, peer):
    from homing.robot.types import Pose2

    got: dict[str, list[Received]] = {"status": [], "tf": [], "map": []}
    cond = threading.Condition()

    def keep(what: str) -> Callable[[Received], None]:
        def on(r: Received) -> None:
            with cond:
                got[what].append(r)
                cond.notify_all()
        return on

    n = peer.node
    n.subscribe("/tree/status", "diagnostic_msgs/msg/DiagnosticArray", Qos(), keep("status"))
    n.subscribe("/tf", "tf2_msgs/msg/TFMessage", Qos(), keep("tf"))
    path = np.array([[0.0, 0.0], [0.5, 0.25], [1.0, 0.5]])
    with cond:  # the status and tf subscriptions are declared; publish until they hear it (discovery is async)
        for _ in range(200):
            robot.publish_world(grid=_Grid(), map_to_odom=Pose2(1.0, -2.0, 0.3), path=path, goal=Pose2(1.0, 0.5),
                                state="Exploring", statuses={"Explore": "RUNNING", "Undock": "SUCCESS"},
                                landmarks={7: Pose2(3.0, 1.0, math.pi), 0: Pose2(0.2, -0.1, 0.0)})  # fmt: skip
            if cond.wait_for(lambda: got["status"] and got["tf"], 0.05):
                break
    status = got["status"][-1].message.status
    assert [(s.name, s.level, s.message) for s in status] == [("Explore", 1, "RUNNING"), ("Undock", 0, "SUCCESS")]
    tf = got["tf"][-1].message.transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id, tf.transform.translation.x) == ("map", "odom", 1.0)
    # the map is latched: a subscription made after it was sent still gets it, from homing's cache
    n.subscribe("/map", "nav_msgs/msg/OccupancyGrid", LATCHED, keep("map"))
    with cond:
        assert cond.wait_for(lambda: got["map"], WAIT)
    got["tags"] = []
    n.subscribe("/slam/landmarks", "visualization_msgs/msg/MarkerArray", LATCHED, keep("tags"))
    with cond:
        assert cond.wait_for(lambda: got["tags"], WAIT)
    markers = got["tags"][0].message.markers
    assert [(mk.id, mk.header.frame_id, mk.pose.position.x, mk.text) for mk in markers] == [
        (0, "map", 0.2, "0"), (7, "map", 3.0, "7")]
    grid = got["map"][0].message
    assert (grid.info.width, grid.info.height, grid.info.resolution) == (6, 4, pytest.approx(0.05))
    assert grid.info.origin.position.x == -1.5 and grid.data.tolist() == _Grid().data.reshape(-1).tolist()


def test_a_kobuki_under_kobuki_ros_gives_dock_ir_bumpers_and_camera_frames(tmp_path, port, peer):
    from homing.robot.types import IR

    n = peer.node
    ir_pub = n.publisher("/sensors/dock_ir", "kobuki_ros_interfaces/msg/DockInfraRed", SENSOR_DATA)
    bumper_pub = n.publisher("/events/bumper", "kobuki_ros_interfaces/msg/BumperEvent", Qos())
    image_pub = n.publisher("/camera/image_raw", "sensor_msgs/msg/Image", SENSOR_DATA)
    info_pub = n.publisher("/camera/camera_info", "sensor_msgs/msg/CameraInfo", SENSOR_DATA)
    robot = open_ros2_robot(robot_file(tmp_path, port, "topics: {dock_ir: /sensors/dock_ir, bumper: /events/bumper, "
                                       "image: /camera/image_raw, camera_info: /camera/camera_info}\n"
                                       "camera_pose: [0.12, 0.0, 0.35, 0.0]\n"))  # fmt: skip
    try:
        pixels = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
        bgr = np.zeros((4, 8, 3), dtype=np.uint8)  # a row padded to 24 bytes, as drivers may send
        bgr[:, :5] = pixels[..., ::-1]
        info = wire.zero("sensor_msgs/msg/CameraInfo", width=5, height=4,
                         k=np.array([200.0, 0.0, 2.5, 0.0, 210.0, 1.5, 0.0, 0.0, 1.0]))  # fmt: skip
        image = m("sensor_msgs/msg/Image", header=_header("camera"), height=4, width=5, encoding="bgr8",
                  is_bigendian=0, step=24, data=bgr.reshape(-1))  # fmt: skip

        def send() -> None:
            ir_pub.publish(m("kobuki_ros_interfaces/msg/DockInfraRed", header=_header("dock_ir"),
                             data=np.array([IR.NEAR_LEFT, IR.FAR_CENTER | IR.NEAR_CENTER, 0], dtype=np.uint8)))  # fmt: skip
            info_pub.publish(info)
            image_pub.publish(image)
            bumper_pub.publish(m("kobuki_ros_interfaces/msg/BumperEvent", bumper=1, state=1))

        heard: list = []

        def seen() -> bool:  # the robot's subscriptions are discovered asynchronously: send until all of them hear
            send()
            heard[:] = [robot.observe()]  # checked below as observed (a dock IR reading goes stale on a busy machine)
            obs = heard[0]
            return obs.image is not None and obs.bumpers.centre and obs.dock_ir.any()

        assert wait_until(seen)
        obs = heard[0]
        assert obs.dock_ir.right == IR.NEAR_LEFT and obs.dock_ir.centre == IR.FAR_CENTER | IR.NEAR_CENTER
        assert obs.dock_ir.left == IR.NONE and obs.bumpers.any() and not obs.bumpers.left
        assert obs.image is not None and np.array_equal(obs.image.image, pixels)  # bgr8 with padding read as RGB
        cam = obs.image.info
        assert (cam.width, cam.height, cam.fx, cam.fy, cam.cx, cam.cy) == (5, 4, 200.0, 210.0, 2.5, 1.5)
        assert cam.base_from_optical[:3, 3] == pytest.approx([0.12, 0.0, 0.35])
        assert cam.base_from_optical[:3, 2] == pytest.approx([1.0, 0.0, 0.0])  # the optical z looks forward
        bumper_pub.publish(m("kobuki_ros_interfaces/msg/BumperEvent", bumper=1, state=0))
        assert wait_until(lambda: not robot.observe().bumpers.any())
        assert wait_until(lambda: not robot.observe().dock_ir.any())  # a dock IR reading goes stale
    finally:
        robot.close()


def test_the_example_robot_file_is_a_valid_ros2_robot_file():
    import homing.robot.ros2 as pkg

    config = load_ros2_robot(Path(pkg.__file__).parent / "robot.example.yaml")
    assert (config.router, config.scan, config.battery, config.stamped, config.dock_ir) == (
        "tcp/192.168.1.20:7447", "scan", "battery_state", False, None)
    assert config.odom_timeout == 0.5 and config.radius == 0.18
