"""Groot2 live (``homing run … --groot``): a pyzmq client plays Groot2's side of BT.CPP v4's monitor protocol.

The reference is BehaviorTree.CPP's ``groot2_protocol.h`` and
``groot2_publisher.cpp``: 6-byte request headers (protocol 2, type, id),
22-byte reply headers, the full tree as XML with ``_uid``s, 3 bytes a node
of status with the idle-after codes, msgpack blackboards, and
``error`` replies that leave the server serving.
"""

from __future__ import annotations

import re
import signal
import socket
import struct
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

zmq = pytest.importorskip("zmq", reason="Groot2 live needs pyzmq (pip install 'homing[groot]')")
msgpack = pytest.importorskip("msgpack", reason="Groot2 live needs msgpack (pip install 'homing[groot]')")

from defusedxml import ElementTree as DET  # noqa: E402
from homing.live.groot2 import CODES, Groot2Server, parse_status, request_header, status_code  # noqa: E402
from homing.missions.compiler import compile_mission  # noqa: E402
from homing.missions.runner import Runner, StatusChange  # noqa: E402
from py_trees.common import Status  # noqa: E402

from tests.conftest import REPO, homing_cli, serving_run  # noqa: E402
from tests.mission_fakes import FakeRobot  # noqa: E402

REPLY_TIMEOUT = 5.0  # [s] a reply later than this is a failure, not a wait
POLL_INTERVAL = 0.05  # [s] between status requests while waiting for a run to start (Groot2 polls too)

SCRIPTED = """\
mission: scripted
rate: 10
services: []
subtrees:
  Mark:
    tree:
      sequence:
        name: Marking
        children:
          - SetBlackboard: {key: seen, value: 1}
          - StatusQueue: {name: Step, statuses: [running, success]}
tree:
  repeat:
    times: 2
    child:
      sequence:
        name: Main
        children:
          - StatusQueue: {name: A, statuses: [running, success]}
          - fallback:
              name: Either
              children:
                - StatusQueue: {name: B, statuses: [failure]}
                - Mark: {name: First}
"""


@pytest.fixture
def client() -> Iterator[Any]:
    context = zmq.Context()
    sockets: list[Any] = []

    def connect(port: int) -> Any:
        sock = context.socket(zmq.REQ)
        sock.setsockopt(zmq.LINGER, 0)
        sock.connect(f"tcp://127.0.0.1:{port}")
        sockets.append(sock)
        return sock

    yield connect
    for sock in sockets:
        sock.close(linger=0)
    context.term()


def ask(sock: Any, *frames: bytes) -> list[bytes]:
    """One request-reply round trip; no reply within REPLY_TIMEOUT fails the test."""
    sock.send_multipart(list(frames))
    assert sock.poll(int(REPLY_TIMEOUT * 1000)), f"no reply to {frames!r}"
    return sock.recv_multipart()


def ask_ok(sock: Any, kind: str, unique_id: int, *body: bytes) -> list[bytes]:
    """A well-formed request; checks the 22-byte reply header echoes it (protocol 2, type, id)."""
    reply = ask(sock, request_header(kind, unique_id), *body)
    assert reply[0] != b"error", reply
    assert len(reply[0]) == 22
    assert struct.unpack("<BBI", reply[0][:6]) == (2, ord(kind), unique_id)
    return reply


class Tracker:
    """The runner's statuses as BT.CPP would report them: a status, or 10 + the status a node left for idle."""

    def __init__(self) -> None:
        self.code: dict[str, int] = {}

    def __call__(self, change: StatusChange) -> None:
        if change.new is Status.INVALID:
            self.code[change.node] = 10 + CODES[change.old] if change.old is not Status.INVALID else 0
        else:
            self.code[change.node] = CODES[change.new]


@dataclass
class Scripted:
    """The scripted mission's runner and server, the tracker of its changes, and a client connected to it."""

    server: Groot2Server
    runner: Runner
    tracker: Tracker
    sock: Any

    def tick(self) -> Status:
        """One tick, its statuses published as ``homing run`` publishes them."""
        status = self.runner.tick()
        self.server.on_tick(self.runner)
        return status


@pytest.fixture
def scripted(tmp_path: Path, client: Any) -> Iterator[Scripted]:
    path = tmp_path / "scripted.yaml"
    path.write_text(SCRIPTED)
    mission = compile_mission(path)
    server = Groot2Server(mission, "127.0.0.1", 0)
    tracker = Tracker()

    def on_change(change: StatusChange) -> None:
        tracker(change)
        server.on_change(change)

    runner = Runner(mission, FakeRobot(), on_change=on_change, on_tick=server.on_tick)
    runner.setup()
    try:
        yield Scripted(server, runner, tracker, client(server.port))
    finally:
        server.close()


def expected(server: Groot2Server, tracker: Tracker) -> dict[int, int]:
    """What the status frame must say now, from the runner's own statuses and changes."""
    out = {}
    for uid, node in server.live.nodes:
        if node.status is not Status.INVALID:
            out[uid] = CODES[node.status]
        else:
            out[uid] = tracker.code.get(node.name, 0)
            assert out[uid] in (0, 11, 12, 13)
    return out


def test_request_header_and_status_codes_are_bt_cpps() -> None:
    assert request_header("S", 0x01020304) == bytes([2, ord("S"), 4, 3, 2, 1])
    assert [status_code(s, Status.INVALID) for s in (Status.RUNNING, Status.SUCCESS, Status.FAILURE)] == [1, 2, 3]
    assert [status_code(Status.INVALID, s) for s in (Status.INVALID, Status.RUNNING, Status.SUCCESS, Status.FAILURE)] == [0, 11, 12, 13]


def test_blackboard_values_become_small_json() -> None:
    import numpy as np
    from homing.live.blackboard import json_value
    from homing.robot import Pose2, Twist2

    assert json_value(Pose2(1.0, 2.0, 0.5)) == {"x": 1.0, "y": 2.0, "theta": 0.5}
    assert json_value([Twist2(0.1, 0.0), None, "s", True]) == [{"v": 0.1, "omega": 0.0}, None, "s", True]
    assert json_value(np.float32(0.5)) == 0.5 and json_value(np.int64(3)) == 3
    assert json_value(np.arange(3)) == [0, 1, 2]
    assert json_value(np.zeros((100, 2))) == "<ndarray 100x2 float64>"
    assert json_value(float("nan")) == "nan"
    assert json_value({i: i for i in range(40)}) == "<dict of 40>"
    assert json_value(object()) == "<object>"
    msgpack.packb(json_value({"a": [[[[1]]]]}))  # deep nesting ends in a string msgpack packs


@pytest.mark.parametrize("name", ["missions/explore.yaml", "missions/persistent.yaml", "missions/examples/wander.yaml"])
def test_full_tree_parses_with_a_unique_uid_on_every_node(name: str, client: Any) -> None:
    mission = compile_mission(REPO / name)
    server = Groot2Server(mission, "127.0.0.1", 0)
    try:
        sock = client(server.port)
        header, xml = ask_ok(sock, "T", 1)
        root = DET.fromstring(xml)
        assert root.tag == "root" and root.get("BTCPP_format") == "4"
        trees = root.findall("BehaviorTree")
        assert trees[0].get("_fullpath") == ""
        nodes = [e for tree in trees for e in tree.iter() if e is not tree]
        uids = [int(e.get("_uid", "-1")) for e in nodes]
        assert sorted(uids) == list(range(1, len(nodes) + 1)), "every node has a _uid, each once"
        # every SubTree names a tree instance of its own, and the status frame covers exactly the uids
        calls = {e.get("_fullpath") for e in nodes if e.tag == "SubTree"}
        assert calls == {t.get("_fullpath") for t in trees[1:]}
        _, status = ask_ok(sock, "S", 2)
        assert len(status) == 3 * len(uids)
        by_tree = [int(e.get("_uid", "-1")) for tree in trees for e in tree.iter() if e is not tree]
        assert list(parse_status(status)) == by_tree, "laid out as Groot2Publisher does: tree by tree"
        # every node that is neither BT.CPP's own nor a SubTree is declared in the TreeNodesModel
        models = {m.get("ID") for m in root.find("TreeNodesModel")}  # type: ignore[union-attr]
        builtin = {"Sequence", "Fallback", "ReactiveSequence", "ReactiveFallback", "Repeat", "RetryUntilSuccessful",
                   "Timeout", "Delay", "Inverter", "ForceSuccess", "ForceFailure", "RunOnce", "ParallelNode",
                   "KeepRunningUntilFailure", "SequenceWithMemory", "IfThenElse", "WhileDoElse", "SubTree"}
        assert {e.tag for e in nodes} - builtin <= models
        assert len(mission.info) + len(calls) == len(nodes)
    finally:
        server.close()


# uid order: repeat, Main, A, Either, B, SubTree First, Marking, SetBlackboard, Step
SCRIPTED_FRAMES = [
    [1, 1, 1, 0, 0, 0, 0, 0, 0],  # A runs
    [1, 1, 2, 1, 3, 1, 1, 2, 1],  # A succeeded, B failed, the fallback goes into the subtree, Step runs
    [1, 2, 2, 2, 13, 2, 2, 2, 2],  # Step succeeds: Main succeeds, repeat goes on; B was halted after its failure
    [1, 1, 1, 12, 13, 12, 12, 12, 12],  # the second cycle: Main restarts, what had succeeded is idle after success
    [1, 1, 2, 1, 3, 1, 1, 2, 1],
    [2, 2, 2, 2, 13, 2, 2, 2, 2],  # both cycles done: the root succeeds
]


def test_status_frames_follow_a_scripted_tree_tick_by_tick(scripted: Scripted) -> None:
    sock = scripted.sock
    _, xml = ask_ok(sock, "T", 1)
    names = [e.get("name") or e.get("_fullpath") for e in DET.fromstring(xml).iter() if e.get("_uid")]
    assert names == ["repeat", "Main", "A", "Either", "B", "First", "Marking", "SetBlackboard", "Step"]
    _, before = ask_ok(sock, "S", 2)
    assert set(parse_status(before).values()) == {0}, "nothing ticked yet: all idle"
    for n, frame in enumerate(SCRIPTED_FRAMES, start=1):
        root = scripted.tick()
        got = parse_status(ask_ok(sock, "S", 100 + n)[1])
        assert got == expected(scripted.server, scripted.tracker), f"tick {n}: the frame is not the runner's statuses"
        assert [got[uid] for uid in sorted(got)] == frame, f"tick {n}"
    assert root is Status.SUCCESS


def test_a_halt_shows_the_halted_nodes_idle_after_running(scripted: Scripted) -> None:
    scripted.tick()
    scripted.tick()
    scripted.runner.shutdown()  # as Ctrl-C ends a run: the tree halted, on_tick called once more
    got = parse_status(ask_ok(scripted.sock, "S", 1)[1])
    assert got == expected(scripted.server, scripted.tracker)
    assert [got[uid] for uid in sorted(got)] == [11, 11, 12, 11, 13, 11, 11, 12, 11]


def test_blackboards_are_msgpack_json_per_tree_instance(scripted: Scripted) -> None:
    scripted.tick()
    scripted.runner.robot.step(scripted.runner.period)
    scripted.tick()  # the subtree instance 'First' wrote its own entry 'seen'
    _, body = ask_ok(scripted.sock, "B", 1, b"MainTree;First;NoSuchTree")
    boards = msgpack.unpackb(body)
    assert set(boards) == {"MainTree", "First"}
    assert boards["First"] == {"seen": 1.0}
    main = boards["MainTree"]
    assert main["robot/time"] == pytest.approx(0.1)
    assert main["robot/observation"]["battery"]["percent"] == pytest.approx(90.0)
    assert not any(key.startswith("First") for key in main), "an instance's entries are its own blackboard's"


def test_malformed_requests_get_the_error_reply_and_the_server_goes_on(scripted: Scripted) -> None:
    sock = scripted.sock
    assert ask(sock, b"") == [b"error", b"wrong request header"]
    assert ask(sock, b"\x02S\x00\x00\x00") == [b"error", b"wrong request header"]  # 5 bytes
    assert ask(sock, request_header("S", 1) + b"\x00") == [b"error", b"wrong request header"]
    assert ask(sock, request_header("Z", 2)) == [b"error", b"Request not recognized"]
    assert ask(sock, request_header("B", 3)) == [b"error", b"must be 2 parts message"]
    for kind in "IRUrt":  # hooks, breakpoints and recording
        reply = ask(sock, request_header(kind, 4), b"{}")
        assert reply[0] == b"error" and reply[1].startswith(b"not supported"), reply
    assert ask_ok(sock, "D", 5)[1] == b"[]"  # no hooks to dump
    assert len(ask_ok(sock, "A", 6)) == 1  # removing all hooks: nothing to do, the bare header
    scripted.tick()
    assert DET.fromstring(ask_ok(sock, "T", 7)[1]).tag == "root"
    assert parse_status(ask_ok(sock, "S", 8)[1])[1] == 1
    assert scripted.server.requests == 14


@pytest.mark.slow
def test_status_frames_match_the_runner_during_a_simulated_explore(client: Any) -> None:
    from homing.sim import SimRobot, load_world

    mission = compile_mission(REPO / "missions" / "explore.yaml")
    server = Groot2Server(mission, "127.0.0.1", 0)
    tracker = Tracker()

    def on_change(change: StatusChange) -> None:
        tracker(change)
        server.on_change(change)

    robot = SimRobot(load_world("lab"), seed=1)
    runner = Runner(mission, robot, seed=1, on_change=on_change, on_tick=server.on_tick)
    try:
        sock = client(server.port)
        runner.setup()
        frames = []
        while runner.now - runner.start < 15.0:  # [s] of simulated time: undocking, the spin, exploring
            runner.tick()
            server.on_tick(runner)
            status = parse_status(ask_ok(sock, "S", runner.ticks)[1])
            assert status == expected(server, tracker), f"tick {runner.ticks}"
            frames.append(status)
            robot.step(runner.next_step())
        assert len({tuple(sorted(f.items())) for f in frames}) >= 3, "the frames change as the tree ticks"
        assert frames[-1][1] == 1, "the mission is running"
    finally:
        runner.shutdown()
        server.close()
        robot.close()


def _free_port_pair() -> int:
    """A port P with P + 1 also free just now (the server's and the publisher's)."""
    for _ in range(50):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        if port >= 65535:
            continue
        try:
            with socket.socket() as a, socket.socket() as b:
                a.bind(("127.0.0.1", port))
                b.bind(("127.0.0.1", port + 1))
            return port
        except OSError:
            continue
    pytest.skip("no two free consecutive ports")


def _outside_address() -> str | None:
    """This machine's address on its default route (no packet is sent), or None when it has only loopback."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("10.255.255.255", 1))
        except OSError:
            return None
        address = probe.getsockname()[0]
    return None if address.startswith("127.") else address


def test_the_publisher_is_on_the_next_port_and_loopback_only(client: Any) -> None:
    mission = compile_mission(REPO / "missions" / "explore.yaml")
    port = _free_port_pair()
    server = Groot2Server(mission, "127.0.0.1", port)
    try:
        assert (server.port, server.publisher_port) == (port, port + 1)
        for bound in (port, port + 1):  # taken on loopback
            with socket.socket() as probe, pytest.raises(OSError):
                probe.bind(("127.0.0.1", bound))
        assert ask_ok(client(port), "S", 1)
        outside = _outside_address()
        if outside is not None:  # nothing listens on the machine's other addresses
            for bound in (port, port + 1):
                with socket.socket() as probe, pytest.raises(ConnectionRefusedError):
                    probe.settimeout(REPLY_TIMEOUT)
                    probe.connect((outside, bound))
    finally:
        server.close()


@pytest.mark.parametrize("value, message", [("nonsense", "not a port"), ("70000", "not within"),
                                            ("65535", "no port for the publisher")])
def test_a_bad_groot_value_is_one_line_exit_2(value: str, message: str) -> None:
    code, _, err = homing_cli("run", str(REPO / "missions" / "explore.yaml"), "--world", "lab", "--no-view",
                              "--groot", value)
    assert code == 2
    assert err.count("\n") == 1 and message in err and "Traceback" not in err, err


def test_a_taken_groot_port_is_one_line_exit_2() -> None:
    context = zmq.Context()
    taken = context.socket(zmq.REP)
    port = taken.bind_to_random_port("tcp://127.0.0.1")
    try:
        code, _, err = homing_cli("run", str(REPO / "missions" / "explore.yaml"), "--world", "lab", "--no-view",
                                  "--groot", str(port))
    finally:
        taken.close(linger=0)
        context.term()
    assert code == 2
    assert err.count("\n") == 1 and f"--groot 127.0.0.1:{port}" in err and "in use" in err, err


@pytest.mark.slow
def test_homing_run_groot_serves_until_sigterm_then_closes_its_ports(client: Any) -> None:
    with serving_run("--groot 0", "serving Groot2") as (proc, line):
        found = re.search(r"on 127\.0\.0\.1:(\d+) \(publisher (\d+)\)", line)
        assert found, line
        port, publisher = int(found[1]), int(found[2])
        sock = client(port)
        assert DET.fromstring(ask_ok(sock, "T", 1)[1]).tag == "root"
        deadline = time.monotonic() + 60.0
        while 1 not in parse_status(ask_ok(sock, "S", 2)[1]).values():  # polls until the first tick is published
            assert time.monotonic() < deadline, "no node ever ran"
            time.sleep(POLL_INTERVAL)  # as Groot2 polls: not waiting for anything in particular
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 128 + signal.SIGTERM
    assert "stopped: interrupted by SIGTERM" in out
    for bound in (port, publisher):  # both sockets closed with the run: the ports can be listened on again
        with socket.socket() as probe:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # past our own connection's TIME_WAIT
            probe.bind(("127.0.0.1", bound))
            probe.listen()
