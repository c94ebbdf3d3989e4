"""ROS 1 and ROS 2 bags in (written by independent writers), and any log out to MCAP read back by an independent reader."""

from __future__ import annotations

import base64
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from homing.logs import open_log
from homing.logs.mcap_export import export_mcap
from homing.missions.runlog import RunLog, odometry_record, scan_record
from homing.robot.types import Odometry, Pose2, Scan, Twist2

from homing.errors import UserError
from tests.log_helpers import ROOM, cast

N_BEAMS, FOV = 683, math.radians(240.0)  # a Hokuyo URG-04LX
LASER_ON_BASE = Pose2(0.12, 0.0, 0.0)


def _poses(n: int) -> list[Pose2]:
    return [Pose2(2.0 + 0.1 * i, 4.0, 0.02 * i) for i in range(n)]


def _write_with_rosbags(path: Path, ros1: bool, storage: str = "sqlite3") -> list[Pose2]:
    """Odometry at 20 Hz and scans at 10 Hz (stamps between odometry messages) with rosbags' writers."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in store.types:  # noetic's store lacks tf2_msgs: its one-line definition
        from rosbags.typesys import get_types_from_msg

        store.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    t = store.types
    poses = _poses(21)

    def header(stamp: float, frame: str) -> Any:
        ns = int(stamp * 1e9)
        kw = {"seq": 0} if ros1 else {}
        return t["std_msgs/msg/Header"](**kw, stamp=t["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9),
                                        frame_id=frame)

    def quat(yaw: float) -> Any:
        return t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def vec(x: float = 0.0) -> Any:
        return t["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0)

    msgs: list[tuple[str, str, float, Any]] = []
    tf = t["geometry_msgs/msg/TransformStamped"](
        header=header(100.0, "base_link"), child_frame_id="laser",
        transform=t["geometry_msgs/msg/Transform"](translation=vec(LASER_ON_BASE.x), rotation=quat(0.0)))
    msgs.append(("/tf_static", "tf2_msgs/msg/TFMessage", 100.0, t["tf2_msgs/msg/TFMessage"](transforms=[tf])))
    for i, p in enumerate(poses):
        stamp = 100.0 + 0.05 * i
        pose = t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=p.x, y=p.y, z=0.0),
                                           orientation=quat(p.theta))
        odom = t["nav_msgs/msg/Odometry"](
            header=header(stamp, "odom"), child_frame_id="base_link",
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=t["geometry_msgs/msg/Twist"](linear=vec(2.0), angular=vec()), covariance=np.zeros(36)))
        msgs.append(("/odom", "nav_msgs/msg/Odometry", stamp, odom))
        if i % 2 == 1 and i < len(poses) - 1:
            at = poses[i]  # the scan is stamped with this odometry message
            angles = -FOV / 2 + FOV / (N_BEAMS - 1) * np.arange(N_BEAMS)
            ranges = cast(at.compose(LASER_ON_BASE), angles, 5.6).astype(np.float32)
            ranges[~np.isfinite(ranges)] = np.nan  # a driver's "no return"
            scan = t["sensor_msgs/msg/LaserScan"](
                header=header(stamp, "laser"), angle_min=-FOV / 2, angle_max=FOV / 2, angle_increment=FOV / (N_BEAMS - 1),
                time_increment=0.0, scan_time=0.1, range_min=0.02, range_max=5.6, ranges=ranges,
                intensities=np.zeros(0, np.float32))
            msgs.append(("/scan", "sensor_msgs/msg/LaserScan", stamp, scan))
    if ros1:
        from rosbags.rosbag1 import Writer as Writer1

        with Writer1(path) as w:
            conns = {topic: w.add_connection(topic, ty, typestore=store) for topic, ty in dict(
                (m[0], m[1]) for m in msgs).items()}
            for topic, ty, stamp, msg in msgs:
                w.write(conns[topic], int(stamp * 1e9), store.serialize_ros1(msg, ty))
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        with Writer(path, version=8, storage_plugin=plugin) as w:
            conns = {topic: w.add_connection(topic, ty, typestore=store) for topic, ty in dict(
                (m[0], m[1]) for m in msgs).items()}
            for topic, ty, stamp, msg in msgs:
                w.write(conns[topic], int(stamp * 1e9), store.serialize_cdr(msg, ty))
    return poses


@pytest.mark.parametrize("kind", ["ros1", "ros2-db3", "ros2-mcap"])
def test_bags_import_scans_odometry_and_laser_pose(tmp_path: Path, kind: str) -> None:
    path = tmp_path / ("run.bag" if kind == "ros1" else "run2")
    poses = _write_with_rosbags(path, kind == "ros1", "mcap" if kind == "ros2-mcap" else "sqlite3")
    if kind == "ros2-mcap":
        path = next(path.glob("*.mcap"))  # a bare .mcap storage file reads too
    log = open_log(path)
    assert log.meta["format"] == "rosbag" and log.meta["scan_topic"] == "/scan"
    ticks = list(log.ticks())
    scans = [t.obs for t in ticks if t.obs.scan is not None]
    assert len(scans) == 10 and len(ticks) == 21 + 10
    s = scans[0].scan
    assert s is not None and len(s.ranges) == N_BEAMS
    assert s.laser_pose.x == pytest.approx(LASER_ON_BASE.x)
    assert s.angle_increment * (N_BEAMS - 1) == pytest.approx(FOV)
    assert not np.isnan(s.ranges).any() and np.isinf(s.ranges).any()  # NaN became "no return"
    pts = s.points(scans[0].odom.pose)
    on_wall = np.min([np.abs(pts[:, 1] - 8.0), np.abs(pts[:, 0] - 12.0), np.abs(pts[:, 0]), np.abs(pts[:, 1]),
                      np.abs(np.maximum(np.abs(pts[:, 0] - 5.5), np.abs(pts[:, 1] - 3.5)) - 0.5),
                      np.abs(pts[:, 0] - 9.0)], axis=0)
    assert np.max(on_wall) < 0.01  # scan, odometry and tf put together give the room
    assert scans[0].odom.pose.distance_to(poses[1]) < 1e-6


def test_topic_flags_and_damaged_bags(tmp_path: Path) -> None:
    path = tmp_path / "run.bag"
    _write_with_rosbags(path, ros1=True)
    with pytest.raises(UserError, match="--scan-topic /laser: no such topic"):
        open_log(path, scan_topic="/laser")
    with pytest.raises(UserError, match="is nav_msgs/msg/Odometry, not sensor_msgs/msg/LaserScan"):
        open_log(path, scan_topic="/odom")
    data = path.read_bytes()
    for cut in (len(data) // 2, 40):
        bad = tmp_path / f"cut{cut}.bag"
        bad.write_bytes(data[:cut])
        with pytest.raises(UserError) as err:
            open_log(bad)
        assert "\n" not in str(err.value) and str(err.value).startswith(f"{bad}: ")


def _homing_run() -> RunLog:
    """A run log with every record kind the exporter knows, 5 ticks."""
    import cv2

    records: list[dict[str, Any]] = []
    for i in range(5):
        stamp = 1.0 + 0.1 * i
        pose = Pose2(0.1 * i, 0.0, 0.0)
        angles = np.radians(np.arange(360.0))
        scan = Scan(stamp, 0.0, math.radians(1.0), cast(pose.compose(Pose2(2, 2)), angles, 6.0).astype(np.float32),
                    0.15, 6.0, Pose2(0.0, 0.0, 0.0))
        records.append(scan_record(scan))
        obs = odometry_record(stamp, Odometry(stamp, pose, Twist2(0.1, 0.0)), stamp)
        obs["bat"] = [15.5, 70.0, "none", "discharging"]
        records.append(obs)
        records.append({"k": "tags", "t": stamp, "m": [[3, stamp, 1.5, 0.2, math.pi, [0.0] * 9, 1.5, 0.1, 0.0,
                                                        50.0, 0, 0.3, "wall"]]})
        if i == 0:
            records.append({"k": "status", "t": stamp, "node": "Explore", "s": "RUNNING"})
        if i == 3:
            records.append({"k": "status", "t": stamp, "node": "Explore", "s": "SUCCESS"})
        if i in (1, 3):
            records.append({"k": "plan", "t": stamp, "path": [[0.0, 0.0], [0.5, 0.1], [1.0, 0.3]],
                            "goal": [1.0, 0.3, 0.2]})
        ok, jpeg = cv2.imencode(".jpg", np.full((24, 32), 128, np.uint8))
        records.append({"k": "img", "t": stamp, "jpeg": base64.b64encode(jpeg.tobytes()).decode(),
                        "K": [30.0, 30.0, 16.0, 12.0], "size": [32, 24]})
        records.append({"k": "cmd", "t": stamp, "v": 0.1, "w": 0.0})
    return RunLog.from_records("run.log", {"format": "homing"}, records)


def test_mcap_round_trip_read_by_an_independent_reader(tmp_path: Path) -> None:
    """Written through rosbags, read back with the mcap library and its ROS 2 decoder: every topic, type, count."""
    from homing.mapping.grid import OccupancyGrid
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    log = _homing_run()
    grid = OccupancyGrid(0.05)
    out = tmp_path / "bag"
    counts = export_mcap(log, out, map_to_odom=lambda t: Pose2(0.5, 0.0, 0.1), grid_at=lambda t: grid)
    expected = {"/scan": ("sensor_msgs/msg/LaserScan", 5), "/odom": ("nav_msgs/msg/Odometry", 5),
                "/tf": ("tf2_msgs/msg/TFMessage", 10), "/tf_static": ("tf2_msgs/msg/TFMessage", 1),
                "/map": ("nav_msgs/msg/OccupancyGrid", 2), "/battery": ("sensor_msgs/msg/BatteryState", 5),
                "/camera/image/compressed": ("sensor_msgs/msg/CompressedImage", 5),
                "/camera/camera_info": ("sensor_msgs/msg/CameraInfo", 5),
                "/tags": ("visualization_msgs/msg/MarkerArray", 5), "/plan": ("nav_msgs/msg/Path", 2),
                "/explore/goal": ("geometry_msgs/msg/PoseStamped", 2), "/cmd_vel": ("geometry_msgs/msg/Twist", 5),
                "/tree/status": ("diagnostic_msgs/msg/DiagnosticArray", 5)}
    assert counts == {k: n for k, (_, n) in expected.items()}
    files = list(out.glob("*.mcap"))
    assert len(files) == 1 and (out / "metadata.yaml").is_file()
    seen: dict[str, list[Any]] = {}
    types: dict[str, str] = {}
    with files[0].open("rb") as f:
        for schema, channel, message, decoded in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            seen.setdefault(channel.topic, []).append((message.log_time, decoded))
            types[channel.topic] = schema.name
    assert {k: (types[k], len(v)) for k, v in seen.items()} == expected
    scan = seen["/scan"][0][1]
    assert scan.header.frame_id == "laser" and len(scan.ranges) == 360 and scan.range_max == pytest.approx(6.0)
    assert seen["/scan"][0][0] == 1_000_000_000  # log time is the log's stamp
    odom = seen["/odom"][2][1]
    assert odom.pose.pose.position.x == pytest.approx(0.2) and odom.child_frame_id == "base_link"
    frames = {(t.header.frame_id, t.child_frame_id) for _, m in seen["/tf"] for t in m.transforms}
    assert frames == {("odom", "base_link"), ("map", "odom")}
    levels = [[(s.name, s.level, s.message) for s in m.status] for _, m in seen["/tree/status"]]
    assert levels[0] == [("Explore", 1, "RUNNING")] and levels[-1] == [("Explore", 0, "SUCCESS")]
    assert [mk.id for mk in seen["/tags"][0][1].markers] == [3]
    assert len(seen["/plan"][0][1].poses) == 3 and seen["/battery"][0][1].percentage == pytest.approx(0.70)
    assert bytes(seen["/camera/image/compressed"][0][1].data[:2]) == b"\xff\xd8"  # JPEG
    assert len(ROOM) == 9


def test_carmen_log_exports_and_reimports(tmp_path: Path) -> None:
    """An imported log goes out to MCAP and comes back in through the bag reader with the same scans."""
    from tests.test_logs_carmen import corrected_log

    path, _, _ = corrected_log(tmp_path)
    log = open_log(path)
    export_mcap(log, tmp_path / "c_bag")
    back = open_log(tmp_path / "c_bag")
    a = [t.obs.scan for t in log.ticks() if t.obs.scan is not None]
    b = [t.obs.scan for t in back.ticks() if t.obs.scan is not None]
    assert len(a) == len(b) == 4
    np.testing.assert_array_equal(a[2].ranges, b[2].ranges)
    assert [s.stamp for s in a] == pytest.approx([s.stamp for s in b])
