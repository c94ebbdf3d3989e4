"""Serve a running mission to Groot2: BehaviorTree.CPP v4's monitoring protocol over ZeroMQ, with pyzmq.

The protocol is the one ``include/behaviortree_cpp/loggers/groot2_protocol.h``
and ``src/loggers/groot2_publisher.cpp`` define in BehaviorTree.CPP 4
(``Groot2Publisher``); this is an independent Python implementation of it.

- A REP socket on the server port (1667 by default) answers multipart
  requests. A request's first frame is the 6-byte header: protocol id
  (``uint8``, 2), request type (one ASCII byte) and a unique id
  (``uint32``, little-endian as BT.CPP memcpys it on the machines it runs
  on). The reply starts with the 22-byte header: the request's header
  (protocol id set to 2) and the 16-byte id of the tree (a random UUID per
  server).
- ``T`` (full tree): the mission as BT.CPP v4 XML with ``_uid`` attributes
  and a ``TreeNodesModel`` (:func:`homing.btxml.exporter.export_live`).
- ``S`` (status): 3 bytes a node, ``uint16`` uid then ``uint8`` status,
  every node in uid order: IDLE 0, RUNNING 1, SUCCESS 2, FAILURE 3, and a
  node gone idle as ``10 +`` the status it left (IDLE_FROM_RUNNING 11,
  IDLE_FROM_SUCCESS 12, IDLE_FROM_FAILURE 13), as ``Groot2Publisher::callback``
  writes them. py_trees' INVALID is BT.CPP's IDLE.
- ``B`` (blackboard), two frames, the second the blackboards' names joined
  by ``;``: one msgpack map, each named blackboard's entries as JSON values
  (``ExportBlackboardToJSON``): the main tree's ID names the mission's own
  entries, a subtree instance's ``_fullpath`` its instance's
  (:mod:`homing.live.blackboard`).
- Hooks and breakpoints (``I``, ``R``, ``U``) and recording (``r``, ``t``)
  get the protocol's error reply, two frames ``error`` and a reason: a
  homing tree is not paused from outside. ``A`` (remove all hooks) and
  ``X`` (disable them) are answered with the bare header, ``D`` (dump) with
  ``[]``, as BT.CPP answers them when no hook is set. A request of the
  wrong size gets ``error`` / ``wrong request header``, an unknown type
  ``Request not recognized``; the server goes on serving.
- A PUB socket on the next port (1668) is bound for Groot2 to subscribe
  to; BT.CPP publishes only "breakpoint reached" there, which homing never
  reaches, so it stays silent. Status is polled with ``S``.

The runner's thread feeds the server (``on_change`` for every status change
it reports, ``on_tick`` after every tick, which publishes one snapshot of
the statuses under a lock); the sockets live in the server's own thread,
which never waits on a tick. Nothing binds beyond 127.0.0.1 unless a host
is given.
"""

from __future__ import annotations

import struct
import threading
import uuid
from typing import TYPE_CHECKING

import msgpack
import zmq
from homing.btxml.exporter import LiveTree, export_live
from homing.live.blackboard import blackboard_dump
from py_trees.common import Status

from homing.errors import UserError

if TYPE_CHECKING:
    from homing.missions.compiler import CompiledMission
    from homing.missions.runner import Runner, StatusChange

PROTOCOL_ID = 2  # kProtocolID
DEFAULT_PORT = 1667  # the server's; the publisher's is the next one
REQUEST_HEADER = struct.Struct("<BBI")  # protocol, type, unique id: 6 bytes
TREE_ID_SIZE = 16  # [bytes] the reply header's tree UUID
NODE_STATUS = struct.Struct("<HB")  # uid, status: 3 bytes a node
POLL_MS = 100  # [ms] how often the server thread looks at its stop flag (BT.CPP's receive timeout)

# BT.CPP's NodeStatus numbers, and the idle-after codes of Groot2Publisher::callback
CODES = {Status.INVALID: 0, Status.RUNNING: 1, Status.SUCCESS: 2, Status.FAILURE: 3}
IDLE_AFTER = 10  # a node gone idle is reported as IDLE_AFTER + the code of the status it left

FULLTREE, STATUS, BLACKBOARD = ord("T"), ord("S"), ord("B")
HOOKS_UNSUPPORTED = {ord("I"): "hook_insert", ord("R"): "hook_remove", ord("U"): "breakpoint_unlock",
                     ord("N"): "breakpoint_reached", ord("r"): "toggle_recording", ord("t"): "get_transitions"}
NO_HOOKS = {ord("A"): None, ord("X"): None, ord("D"): b"[]"}  # what BT.CPP answers with no hook set


def status_code(new: Status, old: Status) -> int:
    """The byte BT.CPP reports for a node that went from ``old`` to ``new`` (idle: ``10 +`` what it left)."""
    if new is Status.INVALID:
        return IDLE_AFTER + CODES[old] if old is not Status.INVALID else 0
    return CODES[new]


def request_header(kind: str, unique_id: int, protocol: int = PROTOCOL_ID) -> bytes:
    """The 6-byte header of a request of type ``kind`` (``"T"``, ``"S"``, …): what Groot2 sends."""
    return REQUEST_HEADER.pack(protocol, ord(kind), unique_id)


def parse_status(frame: bytes) -> dict[int, int]:
    """A status answer's body → {uid: status byte}."""
    return {uid: code for uid, code in NODE_STATUS.iter_unpack(frame)}


class Groot2Server:
    """Serves one run's tree to Groot2 on ``(host, port)`` (REP) and ``port + 1`` (PUB).

    ``port`` 0 binds both sockets to free ports (tests); :attr:`port` and
    :attr:`publisher_port` say which. A port that is taken, or a host that
    cannot be bound, is a :class:`UserError` raised here, before the run.
    """

    def __init__(self, mission: CompiledMission, host: str = "127.0.0.1", port: int = DEFAULT_PORT):
        self.live: LiveTree = export_live(mission)
        self.tree_id = uuid.uuid4().bytes
        self.host = host
        # status bytes: the tick thread writes `_work`; `_snapshot` is what the server thread answers with
        self._work = bytearray(b"".join(NODE_STATUS.pack(uid, 0) for uid, _ in self.live.nodes))
        self._snapshot = bytes(self._work)
        self._slots: dict[str, list[int]] = {}  # node name → offsets of its status bytes (a SubTree shares its root's)
        for index, (_, node) in enumerate(self.live.nodes):
            self._slots.setdefault(node.name, []).append(3 * index + 2)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._context = zmq.Context()
        self._server = self._context.socket(zmq.REP)
        self._publisher = self._context.socket(zmq.PUB)
        for sock in (self._server, self._publisher):
            sock.setsockopt(zmq.LINGER, 0)
            sock.setsockopt(zmq.SNDTIMEO, 1000)
        try:
            self.port = self._bind(self._server, port)
            self.publisher_port = self._bind(self._publisher, port + 1 if port else 0)
        except UserError:
            self._context.destroy(linger=0)
            raise
        self.requests = 0
        self._thread = threading.Thread(target=self._serve, name="groot2", daemon=True)
        self._thread.start()

    def _bind(self, sock: zmq.Socket, port: int) -> int:
        host = f"[{self.host}]" if ":" in self.host else self.host
        if ":" in self.host:
            sock.setsockopt(zmq.IPV6, 1)
        try:
            sock.bind(f"tcp://{host}:{port if port else '*'}")
        except zmq.ZMQError as err:
            why = zmq.strerror(err.errno) if err.errno is not None else str(err)  # strerror without the address
            raise UserError(f"--groot {self.host}:{port}: {why}") from None
        return int(sock.getsockopt_string(zmq.LAST_ENDPOINT).rsplit(":", 1)[1])

    # --- the runner's thread ---------------------------------------------------------------------------------

    def on_change(self, change: StatusChange) -> None:
        """Write one status change into the working buffer (the runner's ``on_change``)."""
        code = status_code(change.new, change.old)
        for offset in self._slots.get(change.node, ()):
            self._work[offset] = code

    def on_tick(self, runner: Runner | None = None) -> None:
        """Publish the statuses as they are after this tick, for the server thread (the runner's ``on_tick``)."""
        snapshot = bytes(self._work)
        with self._lock:
            self._snapshot = snapshot

    def close(self) -> None:
        """Stop serving; the server thread closes the sockets (within ``POLL_MS``)."""
        self._stop.set()
        self._thread.join(2.0)
        self._context.destroy(linger=0)

    # --- the server's thread ---------------------------------------------------------------------------------

    def status(self) -> bytes:
        """The last published status frame."""
        with self._lock:
            return self._snapshot

    def answer(self, frames: list[bytes]) -> list[bytes]:
        """The reply to one request (its frames): always a reply, never an exception (REP must answer)."""
        if len(frames[0]) != REQUEST_HEADER.size:
            return [b"error", b"wrong request header"]
        _, kind, unique_id = REQUEST_HEADER.unpack(frames[0])
        header = REQUEST_HEADER.pack(PROTOCOL_ID, kind, unique_id) + self.tree_id
        if kind == FULLTREE:
            return [header, self.live.xml.encode("utf-8")]
        if kind == STATUS:
            return [header, self.status()]
        if kind == BLACKBOARD:
            if len(frames) != 2:
                return [b"error", b"must be 2 parts message"]
            names = frames[1].decode("utf-8", "replace").split(";")
            return [header, msgpack.packb(blackboard_dump(names, self.live.blackboards))]
        if kind in NO_HOOKS:
            body = NO_HOOKS[kind]
            return [header] if body is None else [header, body]
        if kind in HOOKS_UNSUPPORTED:
            return [b"error", f"not supported: {HOOKS_UNSUPPORTED[kind]} (homing does not pause its tree)".encode()]
        return [b"error", b"Request not recognized"]

    def _serve(self) -> None:
        poller = zmq.Poller()
        poller.register(self._server, zmq.POLLIN)
        try:
            while not self._stop.is_set():
                if not poller.poll(POLL_MS):
                    continue
                frames = self._server.recv_multipart()
                self.requests += 1
                try:
                    reply = self.answer(frames)
                except Exception as err:  # a REP socket must answer, whatever went wrong
                    reply = [b"error", f"{type(err).__name__}: {err}".encode()]
                self._server.send_multipart(reply)
        except zmq.ZMQError:
            pass  # the context was destroyed under us: closing
        finally:
            self._server.close(linger=0)
            self._publisher.close(linger=0)
