"""Foxglove live (``homing run … --foxglove``): a plain WebSocket client speaks the Foxglove WebSocket protocol.

The reference is ``foxglove/ws-protocol``'s ``docs/spec.md``: the client
offers the subprotocol (the SDK's ``foxglove.sdk.v1``, or the original
``foxglove.websocket.v1``), reads ``serverInfo`` and ``advertise`` (JSON
text frames), sends ``subscribe`` with its own subscription ids, and gets
binary message frames: opcode ``0x01``, ``uint32`` subscription id,
``uint64`` log time [ns], payload. Payloads are decoded with the schema the
channel advertised (protobuf from its ``FileDescriptorSet``, JSON checked
against its JSON Schema), and compared with the run's own map and pose.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import re
import signal
import socket
import struct
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("foxglove", reason="Foxglove live needs foxglove-sdk (pip install 'homing[foxglove]')")
websockets_sync = pytest.importorskip("websockets.sync.client", reason="the test's client needs websockets")
pytest.importorskip("google.protobuf", reason="decoding the Foxglove schemas needs protobuf")

import jsonschema  # noqa: E402
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory  # noqa: E402
from homing.behaviours.keys import GRID_KEY, POSE_KEY  # noqa: E402
from homing.live.foxglove import FoxgloveServer  # noqa: E402
from homing.live.foxglove_messages import nanoseconds  # noqa: E402
from homing.missions.compiler import compile_mission  # noqa: E402
from homing.missions.runner import Runner  # noqa: E402
from py_trees.common import Access  # noqa: E402

from tests.conftest import REPO, homing_cli, serving_run  # noqa: E402

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01  # the binary opcode of a message frame
TIME = 0x02  # the binary opcode of the server's time (uint64 ns)
MESSAGE_HEADER = struct.Struct("<BIQ")  # opcode, subscription id, log time [ns]
TIMEOUT = 10.0  # [s] a frame later than this is a failure, not a wait
EXPLORE = REPO / "missions" / "explore.yaml"


class Client:
    """A Foxglove WebSocket client from the spec: handshake, advertisements, subscriptions, decoded frames."""

    def __init__(self, port: int, host: str = "127.0.0.1"):
        self._stack = contextlib.ExitStack()
        self.ws = self._stack.enter_context(websockets_sync.connect(
            f"ws://{host}:{port}", subprotocols=SUBPROTOCOLS, max_size=None, open_timeout=TIMEOUT))  # type: ignore[arg-type]
        self.time: int | None = None  # [ns] the server's last time frame
        self.server_info: dict[str, Any] = {}
        self.channels: dict[str, dict[str, Any]] = {}  # topic → its advertisement
        self.subscriptions: dict[int, str] = {}  # our subscription id → topic
        self.messages: list[tuple[str, int, Any]] = []  # (topic, log time [ns], decoded payload)
        self._decoders: dict[str, Any] = {}

    def read(self, timeout: float) -> bool:
        """Take one frame if one comes within ``timeout`` [s] (0: only one already here); False if none did."""
        try:
            frame = self.ws.recv(timeout=timeout)
        except TimeoutError:
            return False
        if isinstance(frame, str):
            message = json.loads(frame)
            if message["op"] == "serverInfo":
                self.server_info = message
            elif message["op"] == "advertise":
                for channel in message["channels"]:
                    self.channels[channel["topic"]] = channel
            return True
        if frame[0] == TIME:
            (self.time,) = struct.unpack_from("<Q", frame, 1)
        elif frame[0] == MESSAGE_DATA:
            _, sub_id, log_time = MESSAGE_HEADER.unpack_from(frame)
            topic = self.subscriptions[sub_id]
            self.messages.append((topic, log_time, self._decode(topic, frame[MESSAGE_HEADER.size:])))
        return True

    def until(self, done: Any, what: str) -> None:
        """Read frames until ``done()``; a failure after ``TIMEOUT`` of nothing new."""
        deadline = time.monotonic() + TIMEOUT
        while not done():
            assert time.monotonic() < deadline, f"timed out waiting for {what}"
            self.read(0.05)

    def subscribe(self, *topics: str) -> None:
        self.until(lambda: all(t in self.channels for t in topics), f"the advertisement of {topics}")
        subs = [{"id": 100 + len(self.subscriptions) + i, "channelId": self.channels[t]["id"]}
                for i, t in enumerate(topics)]
        for sub, topic in zip(subs, topics, strict=True):
            self.subscriptions[sub["id"]] = topic
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def drain(self) -> None:
        while self.read(0):
            pass

    def last(self, topic: str) -> tuple[int, Any]:
        found = [(t, m) for top, t, m in self.messages if top == topic]
        assert found, f"no {topic} message"
        return found[-1]

    def _decode(self, topic: str, payload: bytes) -> Any:
        channel = self.channels[topic]
        if channel["encoding"] == "json":
            value = json.loads(payload)
            jsonschema.validate(value, json.loads(channel["schema"]))
            return value
        assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
        if topic not in self._decoders:
            files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
            pool = descriptor_pool.DescriptorPool()
            for proto in files.file:
                pool.Add(proto)
            self._decoders[topic] = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
        return self._decoders[topic].FromString(payload)

    def close(self) -> None:
        self._stack.close()


@pytest.fixture
def client() -> Iterator[Any]:
    made: list[Client] = []

    def connect(port: int, host: str = "127.0.0.1") -> Client:
        made.append(Client(port, host))
        return made[-1]

    yield connect
    for c in made:
        c.close()


def _yaw(q: Any) -> float:
    return 2.0 * np.arctan2(q.z, q.w)


def test_the_handshake_advertises_every_channel_with_its_schema(client: Any) -> None:
    server = FoxgloveServer(compile_mission(EXPLORE), "127.0.0.1", 0)
    try:
        c = client(server.port)
        assert c.ws.subprotocol in SUBPROTOCOLS
        c.until(lambda: len(c.channels) == 12, "twelve channels")
        assert c.server_info["name"] == "homing: explore"
        assert "time" in c.server_info["capabilities"]
        schemas = {topic: ch["schemaName"] for topic, ch in c.channels.items()}
        assert schemas == {
            "/map": "foxglove.Grid", "/scan": "foxglove.LaserScan", "/tf": "foxglove.FrameTransforms",
            "/pose": "foxglove.PoseInFrame", "/plan": "foxglove.SceneUpdate", "/goal": "foxglove.SceneUpdate",
            "/frontiers": "foxglove.SceneUpdate", "/landmarks": "foxglove.SceneUpdate",
            "/battery": "homing.Batteries", "/mission/state": "homing.MissionState",
            "/tree/status": "homing.TreeStatus", "/log": "foxglove.Log",
        }
        for topic in ("/battery", "/mission/state", "/tree/status"):
            assert c.channels[topic]["encoding"] == "json" and c.channels[topic]["schemaEncoding"] == "jsonschema"
            jsonschema.Draft202012Validator.check_schema(json.loads(c.channels[topic]["schema"]))
    finally:
        server.close()


@pytest.mark.slow
def test_the_map_and_the_pose_during_a_simulated_explore_are_the_runs_own(client: Any, tmp_path: Path) -> None:
    from homing.sim import SimRobot, load_world

    mission = compile_mission(EXPLORE)
    record = tmp_path / "run.mcap"
    server = FoxgloveServer(mission, "127.0.0.1", 0, record=record)
    robot = SimRobot(load_world("lab"), seed=1)
    runner = Runner(mission, robot, seed=1, on_change=server.on_change, on_tick=server.on_tick)
    for key in (GRID_KEY, POSE_KEY):  # the run's own map and pose, read as `homing run --save-map` reads the map
        runner.bb.register_key(key=key, access=Access.READ)
    try:
        c = client(server.port)
        c.subscribe("/map", "/pose", "/tree/status")
        deadline = time.monotonic() + TIMEOUT  # the server sees the subscriptions (its own thread) before the run
        while not all(server.channels[t].has_sinks() for t in ("/map", "/pose", "/tree/status")):
            assert time.monotonic() < deadline, "the subscriptions never reached the server"
            c.read(0.05)
        runner.setup()
        while runner.now - runner.start < 20.0:  # [s] simulated: undocking, the spin, exploring
            runner.tick()
            server.on_tick(runner)
            c.drain()
            robot.step(runner.next_step())
        server.on_tick(runner, force=True)  # the last tick's snapshot, as `homing run` sends at the end
        final = nanoseconds(runner.now)
        c.until(lambda: any(top == "/tree/status" and t == final for top, t, _ in c.messages),
                "the last tick's snapshot")  # the tree's status is its last message: the map and pose came before
        grid, pose = runner.read(GRID_KEY), runner.read(POSE_KEY)
        h, w = grid.shape

        def last_map_is_the_runs() -> bool:  # the SDK may put a big /map frame on the wire after a small one
            ms = [m for top, _, m in c.messages if top == "/map"]
            return bool(ms) and len(ms[-1].data) == h * w and bool(
                (np.frombuffer(ms[-1].data, np.int8).reshape(h, w) == grid.data).all())

        c.until(last_map_is_the_runs, "the grid's last version")
        maps = [m for top, _, m in c.messages if top == "/map"]
        assert len(maps) >= 2, "the map is sent as it changes"
        known = [int(np.count_nonzero(np.frombuffer(m.data, np.int8) >= 0)) for m in maps]
        assert known[-1] > known[0], "the map grows as the robot explores"
        m = maps[-1]  # the grid's last version
        assert (m.frame_id, m.column_count, m.row_stride, m.cell_stride) == ("map", w, w, 1)
        assert m.cell_size.x == m.cell_size.y == pytest.approx(grid.resolution)
        assert (m.pose.position.x, m.pose.position.y) == pytest.approx(grid.origin)
        assert [(f.name, f.offset) for f in m.fields] == [("occupancy", 0)]
        cells = np.frombuffer(m.data, np.int8).reshape(h, w)
        np.testing.assert_array_equal(cells, grid.data)  # -1 unknown, 0 free, 100 occupied, row 0 at the origin
        assert set(np.unique(cells)) == {-1, 0, 100}

        _, p = c.last("/pose")
        assert p.frame_id == "map"
        assert np.hypot(p.pose.position.x - pose.x, p.pose.position.y - pose.y) <= grid.resolution / 2
        assert abs(np.angle(np.exp(1j * (_yaw(p.pose.orientation) - pose.theta)))) < 1e-6
        assert np.hypot(pose.x - maps[0].pose.position.x, pose.y - maps[0].pose.position.y) > 0  # a real pose
        poses = [(mp.pose.position.x, mp.pose.position.y) for top, _, mp in c.messages if top == "/pose"]
        assert np.ptp(np.array(poses), axis=0).max() > 0.5, "the pose follows the robot"

        _, tree = c.last("/tree/status")
        assert tree["tick"] == runner.ticks and tree["root"] == mission.root.status.value
        assert tree["nodes"][0]["name"] == mission.root.name

        late = client(server.port)  # subscribes once the grid no longer changes: it gets the grid all the same
        late.subscribe("/map")
        deadline = time.monotonic() + TIMEOUT
        while not any(top == "/map" for top, _, _ in late.messages):
            assert time.monotonic() < deadline, "a late subscriber never got the map"
            server.on_tick(runner, force=True)  # snapshots of an unchanged grid: only the new subscriber's wish sends it
            late.read(0.05)
        assert late.last("/map")[1].data == grid.data.tobytes()
    finally:
        runner.shutdown()
        server.close()
        robot.close()
    _check_recording(record, grid)


def _check_recording(record: Path, grid: Any) -> None:
    """The MCAP file holds the same channels, its last /map the run's last grid."""
    from mcap.reader import make_reader

    topics: dict[str, int] = {}
    last_map = None
    with open(record, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            topics[channel.topic] = topics.get(channel.topic, 0) + 1
            if channel.topic == "/map":
                assert schema is not None and schema.name == "foxglove.Grid" and channel.message_encoding == "protobuf"
                last_map = message.data
    assert {"/map", "/scan", "/tf", "/pose", "/plan", "/goal", "/landmarks", "/battery", "/mission/state",
            "/tree/status", "/log"} <= set(topics)
    assert last_map is not None and grid.data.tobytes() in last_map  # the cells, verbatim, inside the protobuf


def _listening(port: int) -> list[str]:
    """The local addresses (hex, as /proc/net/tcp{,6} gives them) of the sockets listening on ``port``."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if not os.path.exists(table):
            continue
        with open(table) as rows:
            next(rows)
            for row in rows:
                local, state = row.split()[1], row.split()[3]
                address, _, hex_port = local.rpartition(":")
                if state == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
                    found.append(address)
    return found


def test_nothing_listens_beyond_loopback_by_default(client: Any) -> None:
    if not os.path.exists("/proc/net/tcp"):
        pytest.skip("needs Linux's /proc/net/tcp to list listening sockets")
    server = FoxgloveServer(compile_mission(EXPLORE), port=0)  # the default host
    try:
        assert server.host == "127.0.0.1"
        assert _listening(server.port) == ["0100007F"]  # 127.0.0.1, and nothing else (no 0.0.0.0, no ::)
        c = client(server.port)
        c.until(lambda: "/map" in c.channels, "the advertisement")
    finally:
        server.close()
    assert _listening(server.port) == []


@pytest.mark.parametrize("value, message", [("nonsense", "not a port"), ("70000", "not within"),
                                            ("nohost.invalid:0", "--foxglove nohost.invalid:0:")])
def test_a_bad_foxglove_value_is_one_line_exit_2(value: str, message: str) -> None:
    code, _, err = homing_cli("run", str(EXPLORE), "--world", "lab", "--no-view", "--foxglove", value)
    assert code == 2
    assert err.count("\n") == 1 and message in err and "Traceback" not in err, err


def test_a_taken_foxglove_port_is_one_line_exit_2() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code, _, err = homing_cli("run", str(EXPLORE), "--world", "lab", "--no-view", "--foxglove", str(port))
    assert code == 2
    assert err.count("\n") == 1 and f"--foxglove 127.0.0.1:{port}" in err and "in use" in err, err


def test_a_recording_into_a_folder_is_one_line_exit_2(tmp_path: Path) -> None:
    code, _, err = homing_cli("run", str(EXPLORE), "--world", "lab", "--no-view", "--foxglove-record", str(tmp_path))
    assert code == 2
    assert err.count("\n") == 1 and "--foxglove-record" in err and "Traceback" not in err, err


@pytest.mark.slow
def test_homing_run_foxglove_serves_until_sigterm_then_closes_its_port(client: Any) -> None:
    with serving_run("--foxglove 0", "serving Foxglove") as (proc, line):
        found = re.search(r"ws://127\.0\.0\.1:(\d+)", line)
        assert found, line
        port = int(found[1])
        c = client(port)
        c.subscribe("/mission/state")
        c.until(lambda: any(top == "/mission/state" for top, _, _ in c.messages), "a mission state")
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM
    assert "stopped: interrupted by SIGTERM" in out
    with socket.socket() as probe:  # the server closed with the run: the port can be listened on again
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # past our own connection's TIME_WAIT
        probe.bind(("127.0.0.1", port))
        probe.listen()


def _panels(node: Any) -> Iterator[str]:
    if isinstance(node, str):
        yield node
    else:
        yield from _panels(node["first"])
        yield from _panels(node["second"])


def test_the_layout_opens_on_the_servers_topics() -> None:
    from importlib.resources import files

    from homing.live.foxglove_messages import BATTERY_SCHEMA, STATE_SCHEMA, TREE_SCHEMA

    layout = json.loads((files("homing.live") / "foxglove_layout.json").read_text())  # shipped as package data
    panels = layout["configById"]
    assert sorted(_panels(layout["layout"])) == sorted(panels), "every panel configured is laid out, and only those"
    assert {p.split("!")[0] for p in panels} == {"3D", "Plot", "StateTransitions", "RosOut", "RawMessages"}
    server = FoxgloveServer(compile_mission(EXPLORE), port=None)  # the channels, served nowhere
    try:
        topics = set(server.channels)
    finally:
        server.close()
    three = next(c for p, c in panels.items() if p.startswith("3D!"))
    assert {"/map", "/scan", "/plan", "/goal", "/frontiers", "/landmarks"} <= set(three["topics"]) <= topics
    schemas = {"/battery": BATTERY_SCHEMA, "/mission/state": STATE_SCHEMA, "/tree/status": TREE_SCHEMA}
    paths = [p["value"] for c in panels.values() for p in c.get("paths", [])]
    assert "/battery.base.percent" in paths and "/battery.computer.percent" in paths and "/mission/state.state" in paths
    for path in paths:  # a message path: the topic, then fields the channel's JSON Schema declares
        topic, *fields = path.split(".")
        schema: Any = schemas[topic]
        for name in fields:
            schema = schema["properties"][name]
    log = next(c for p, c in panels.items() if p.startswith("RosOut!"))
    raw = next(c for p, c in panels.items() if p.startswith("RawMessages!"))
    assert log["topicToRender"] == "/log" and raw["topicPath"] == "/tree/status"


def test_homing_run_foxglove_record_writes_every_channel_as_the_run_goes(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    record = tmp_path / "run.mcap"
    code, out, err = homing_cli("run", str(EXPLORE), "--world", "lab", "--no-view", "--until", "5s",
                                "--foxglove-record", str(record))  # no server: the recording alone
    assert code == 0, err
    assert "serving Foxglove" not in err
    lines = [line for line in out.splitlines() if re.match(r"\[\s*[\d.]+ s\] \S.*: \w+ -> \w+$", line)]
    logged, trees = [], []
    with open(record, "rb") as stream:
        for schema, channel, message in make_reader(stream).iter_messages():
            if channel.topic == "/tree/status":
                assert schema is not None and schema.encoding == "jsonschema"
                tree = json.loads(message.data)
                jsonschema.validate(tree, json.loads(schema.data))
                trees.append(tree)
            elif channel.topic == "/log":
                logged.append(message.data)
    assert trees and trees[-1]["time"] == pytest.approx(5.0) and trees[-1]["nodes"][0]["name"] == "ExploreMission"
    assert len(logged) == len(lines) > 0, "every status-change line of the run is a foxglove.Log"
    assert all(line.encode() in payload for line, payload in zip(lines, logged, strict=True))


def test_the_server_thread_takes_the_newest_snapshot_keeping_an_older_ones_grid_and_scan() -> None:
    import queue

    from homing.live.foxglove import _latest
    from homing.live.foxglove_messages import GridCopy, Snapshot

    grid = GridCopy(3, np.zeros((2, 2), np.int8), 0.05, (0.0, 0.0))
    scan = {"stamp": 1.0}
    waiting: queue.SimpleQueue[Snapshot | None] = queue.SimpleQueue()
    for snap in (Snapshot(1.0, 1, grid=grid), Snapshot(1.1, 2, scan=scan), Snapshot(1.2, 3)):
        waiting.put(snap)
    newest, stop = _latest(waiting)
    assert newest is not None and (newest.ticks, newest.grid, newest.scan, stop) == (3, grid, scan, False)
    waiting.put(Snapshot(1.3, 4))
    waiting.put(None)  # close() after a last snapshot: it is sent, then the thread ends
    newest, stop = _latest(waiting)
    assert newest is not None and newest.ticks == 4 and newest.grid is None and stop


def test_without_the_foxglove_extra_the_option_is_one_line_exit_2(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "homing.live.foxglove", None)  # as if foxglove-sdk were not installed
    code, _, err = homing_cli("run", str(EXPLORE), "--world", "lab", "--no-view", "--foxglove")
    assert code == 2
    assert err.count("\n") == 1 and "pip install 'homing[foxglove]'" in err and "Traceback" not in err, err
