"""A ROS 2 node without ROS: one Zenoh session speaking rmw_zenoh's wire format (:mod:`homing.robot.ros2.wire`).

:class:`Ros2Node` opens a session (client mode to a robot's ``rmw_zenohd``
router, or a peer listening on an endpoint when it plays the robot itself),
declares the node's liveliness token, and makes publishers and subscriptions
that declare theirs, so ``ros2 node list`` and ``ros2 topic info -v`` on the
robot see it. A publisher puts CDR with the 33-byte attachment (sequence from
1, source time, its GID) on the data key; a latched one (TRANSIENT_LOCAL)
keeps its last samples in a Zenoh advanced-publisher cache that late
subscribers query, as rmw_zenoh's do. A subscription listens on
``<domain>/<topic>/*/*`` so that a sample of another type or hash is seen,
counted and skipped rather than silently missed; each accepted sample is
decoded in Zenoh's thread and handed to a callback.

Needs the ``ros2`` extra (``eclipse-zenoh``, ``xxhash``). Not thread-safe to
declare from several threads at once; publishing is.
"""

from __future__ import annotations

import itertools
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh
import zenoh.ext
from homing.robot.ros2.wire import (
    Attachment,
    Counters,
    NodeName,
    Qos,
    Received,
    encode,
    gid,
    parse_sample,
    qualified,
    topic_keyexpr,
)


def free_port() -> int:
    """A TCP port on 127.0.0.1 free at the time of asking (for a peer's listening endpoint)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def session_config(mode: str, connect: list[str] | None = None, listen: list[str] | None = None) -> Any:
    """A Zenoh config: ``mode`` (client or peer), endpoints, timestamps, no multicast scouting (rmw_zenoh's default)."""
    import json

    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("timestamping/enabled", "true")  # advanced publishers' caches need it (rmw_zenoh sets it too)
    if connect:
        c.insert_json5("connect/endpoints", json.dumps(connect))
    if listen is not None:
        c.insert_json5("listen/endpoints", json.dumps(listen))
    return c


class Publisher:
    """One ROS publisher: its token, its Zenoh publisher, its sequence number."""

    def __init__(self, node: Ros2Node, topic: str, typename: str, qos: Qos):
        self.topic, self.typename, self.qos = topic, typename, qos
        self.key = topic_keyexpr(node.name.domain, topic, typename)
        self.token_key = node.name.entity_token(node.next_id(), "MP", topic, typename, qos)
        self.gid = gid(self.token_key)
        self._seq = itertools.count(1)
        self._lock = threading.Lock()
        s = node.session
        if qos.latched:
            self._pub: Any = zenoh.ext.declare_advanced_publisher(
                s, self.key, cache=zenoh.ext.CacheConfig(max_samples=max(1, qos.depth)),
                publisher_detection=True)  # fmt: skip
        else:
            self._pub = s.declare_publisher(self.key)
        self._token = s.liveliness().declare_token(self.token_key)
        self.sent = 0

    def publish(self, msg: Any) -> None:
        """Encode and put ``msg`` with its attachment."""
        self.publish_raw(encode(msg, self.typename))

    def publish_raw(self, cdr: bytes) -> None:
        with self._lock:
            att = Attachment(next(self._seq), time.time_ns(), self.gid).encode()
            self._pub.put(cdr, attachment=att)
            self.sent += 1

    def close(self) -> None:
        for handle in (self._token, self._pub):
            try:
                handle.undeclare()
            except Exception:  # already gone with the session
                pass


class Subscription:
    """One ROS subscription: its token, a Zenoh subscriber, counters, and the callback for accepted samples."""

    def __init__(self, node: Ros2Node, topic: str, typename: str, qos: Qos,
                 callback: Callable[[Received], None]):  # fmt: skip
        self.topic, self.typename, self.qos = topic, typename, qos
        self.key = topic_keyexpr(node.name.domain, topic, typename)
        self.token_key = node.name.entity_token(node.next_id(), "MS", topic, typename, qos)
        self.counters = Counters()
        self._callback = callback
        wildcard = f"{node.name.domain}/{topic.strip('/')}/*/*"
        s = node.session
        if qos.latched:
            self._sub: Any = zenoh.ext.declare_advanced_subscriber(
                s, wildcard, self._on_sample,
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True))  # fmt: skip
        else:
            self._sub = s.declare_subscriber(wildcard, self._on_sample)
        self._token = s.liveliness().declare_token(self.token_key)

    def _on_sample(self, sample: Any) -> None:
        att = sample.attachment
        got = parse_sample(str(sample.key_expr), sample.payload.to_bytes(),
                           att.to_bytes() if att is not None else None, self.typename,
                           self.counters, time.monotonic())  # fmt: skip
        if got is not None:
            self._callback(got)

    def close(self) -> None:
        for handle in (self._token, self._sub):
            try:
                handle.undeclare()
            except Exception:
                pass


class Ros2Node:
    """A named ROS 2 node on one Zenoh session (``mode`` client or peer; endpoints as Zenoh writes them)."""

    def __init__(self, name: str, *, domain: int = 0, namespace: str = "/", mode: str = "client",
                 connect: list[str] | None = None, listen: list[str] | None = None):  # fmt: skip
        self.session = zenoh.open(session_config(mode, connect, listen))
        self._ids = itertools.count(0)
        self.name = NodeName(domain, str(self.session.zid()), next(self._ids), name, namespace)
        self._token = self.session.liveliness().declare_token(self.name.node_token())
        self.entities: list[Publisher | Subscription] = []

    def next_id(self) -> int:
        return next(self._ids)

    def publisher(self, topic: str, typename: str, qos: Qos) -> Publisher:
        pub = Publisher(self, qualified(topic, self.name.namespace), typename, qos)
        self.entities.append(pub)
        return pub

    def subscribe(self, topic: str, typename: str, qos: Qos,
                  callback: Callable[[Received], None]) -> Subscription:  # fmt: skip
        sub = Subscription(self, qualified(topic, self.name.namespace), typename, qos, callback)
        self.entities.append(sub)
        return sub

    def linked(self) -> bool:
        """True while the session has a router or a peer to talk to."""
        info = self.session.info
        return bool(list(info.routers_zid()) or list(info.peers_zid()))

    def close(self) -> None:
        """Undeclare every entity and the node's token, close the session."""
        for e in reversed(self.entities):
            e.close()
        self.entities.clear()
        try:
            self._token.undeclare()
        except Exception:
            pass
        if not self.session.is_closed():
            self.session.close()
