"""rmw_zenoh's wire format, as ros2/rmw_zenoh ``docs/design.md`` specifies it: keys, tokens, QoS, attachments, CDR.

A ROS 2 node on ``rmw_zenoh_cpp`` is a Zenoh session that

- puts each message on the data key ``<domain>/<topic>/<dds type>/<RIHS01 hash>``
  (the topic's fully qualified name without its leading slash; the type as
  DDS spells it, ``sensor_msgs::msg::dds_::LaserScan_``; the REP-2011 type
  hash), its payload the message's CDR bytes with their 4-byte
  encapsulation header, its attachment 33 bytes: the sequence number and
  the source timestamp [ns since the epoch] as little-endian int64, then
  the GID's length (one byte, 16) and its 16 bytes (zenoh-cpp's
  ``ext::Serializer`` of ``(int64, int64, std::array<uint8_t, 16>)``, as
  ``attachment_helpers.cpp`` writes it);
- declares a liveliness token per node, publisher and subscription under
  ``@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/
  <namespace>/<node>[/<topic>/<type>/<hash>/<qos>]``, each ``/`` inside a
  name replaced by ``%`` and the QoS written by ``qos_to_keyexpr`` relative to
  rmw_zenoh's defaults (reliable, volatile, keep-last 42, infinite durations).

An entity's GID is XXH3-128 of its token, low 64 bits first, each half
little-endian (``liveliness_utils.cpp``). The CDR goes through ``rosbags``'
typestore (ROS 2 Jazzy's message definitions), which also computes the
RIHS01 hashes. This module holds no Zenoh session: :mod:`homing.robot.ros2.node`
does, so everything here is testable without the network.
"""

from __future__ import annotations

import struct
import threading
from dataclasses import dataclass, field
from enum import IntEnum
from functools import cache
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore

ADMIN_SPACE = "@ros2_lv"  # the hermetic prefix of every liveliness token
GID_SIZE = 16  # [bytes] RMW_GID_STORAGE_SIZE
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE  # [bytes] = 33
DEFAULT_DEPTH = 42  # rmw_zenoh's depth when a profile asks for 0
INFINITE = (9223372036, 854775807)  # RMW_DURATION_INFINITE [s, ns]


class Reliability(IntEnum):
    """rmw_qos_reliability_policy_e."""

    SYSTEM_DEFAULT = 0
    RELIABLE = 1
    BEST_EFFORT = 2


class Durability(IntEnum):
    """rmw_qos_durability_policy_e."""

    SYSTEM_DEFAULT = 0
    TRANSIENT_LOCAL = 1
    VOLATILE = 2


class History(IntEnum):
    """rmw_qos_history_policy_e."""

    SYSTEM_DEFAULT = 0
    KEEP_LAST = 1
    KEEP_ALL = 2


@dataclass(frozen=True)
class Qos:
    """A QoS profile as rmw_zenoh writes it into a token (durations as (s, ns); liveliness AUTOMATIC = 1)."""

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    history: History = History.KEEP_LAST
    depth: int = 10
    deadline: tuple[int, int] = INFINITE
    lifespan: tuple[int, int] = INFINITE
    liveliness: int = 1
    lease: tuple[int, int] = INFINITE

    @property
    def latched(self) -> bool:
        return self.durability is Durability.TRANSIENT_LOCAL


RMW_ZENOH_DEFAULT = Qos(depth=DEFAULT_DEPTH)  # QoS::default_qos() in rmw_zenoh's qos.cpp
SENSOR_DATA = Qos(reliability=Reliability.BEST_EFFORT, depth=5)  # rclcpp's SensorDataQoS
LATCHED = Qos(durability=Durability.TRANSIENT_LOCAL, depth=1)  # /tf_static, /map


def qos_to_keyexpr(qos: Qos) -> str:
    """The token's QoS field: each policy written only where it differs from rmw_zenoh's default.

    ``reliability:durability:history,depth:deadline_s,ns:lifespan_s,ns:liveliness,lease_s,lease_ns``
    (``qos_to_keyexpr`` in ``liveliness_utils.cpp``); a depth of 0 stands for 42, as
    ``best_available_qos`` adapts it before the token is made.
    """
    d = RMW_ZENOH_DEFAULT
    depth = qos.depth or DEFAULT_DEPTH

    def part(value: int, default: int) -> str:
        return "" if value == default else str(int(value))

    return (
        f"{part(qos.reliability, d.reliability)}:{part(qos.durability, d.durability)}:"
        f"{part(qos.history, d.history)},{part(depth, d.depth)}:"
        f"{part(qos.deadline[0], d.deadline[0])},{part(qos.deadline[1], d.deadline[1])}:"
        f"{part(qos.lifespan[0], d.lifespan[0])},{part(qos.lifespan[1], d.lifespan[1])}:"
        f"{part(qos.liveliness, d.liveliness)},{part(qos.lease[0], d.lease[0])},"
        f"{part(qos.lease[1], d.lease[1])}"
    )


def keyexpr_to_qos(text: str) -> Qos:
    """Read a token's QoS field back (ValueError if it is not one)."""
    parts = text.split(":")
    if len(parts) < 6:
        raise ValueError(f"not an rmw_zenoh QoS field: {text!r}")
    hist, dead, life, live = (p.split(",") for p in parts[2:6])
    if len(hist) < 2 or len(dead) < 2 or len(life) < 2 or len(live) < 3:
        raise ValueError(f"not an rmw_zenoh QoS field: {text!r}")
    d = RMW_ZENOH_DEFAULT

    def num(s: str, default: int) -> int:
        return int(s) if s else default

    return Qos(
        Reliability(num(parts[0], d.reliability)), Durability(num(parts[1], d.durability)),
        History(num(hist[0], d.history)), num(hist[1], d.depth),
        (num(dead[0], d.deadline[0]), num(dead[1], d.deadline[1])),
        (num(life[0], d.lifespan[0]), num(life[1], d.lifespan[1])),
        num(live[0], d.liveliness), (num(live[1], d.lease[0]), num(live[2], d.lease[1])),
    )  # fmt: skip


def mangle(name: str) -> str:
    """A name inside a token: each ``/`` becomes ``%`` (an empty name becomes ``%``)."""
    return name.replace("/", "%") if name else "%"


def qualified(topic: str, namespace: str = "/") -> str:
    """A topic's fully qualified name: ``scan`` in ``/robot1`` is ``/robot1/scan``; ``/scan`` stays."""
    if topic.startswith("/"):
        return topic
    ns = namespace.rstrip("/")
    return f"{ns}/{topic}"


# kobuki_ros_interfaces (kobuki_ros, the Kobuki's ROS 2 driver): the dock's IR and the bumpers' events.
KOBUKI_MSGS = {
    "kobuki_ros_interfaces/msg/DockInfraRed": """
uint8 NEAR_LEFT   =  1
uint8 NEAR_CENTER =  2
uint8 NEAR_RIGHT  =  4
uint8 FAR_LEFT    = 16
uint8 FAR_CENTER  =  8
uint8 FAR_RIGHT   = 32
std_msgs/Header header
uint8[] data
""",
    "kobuki_ros_interfaces/msg/BumperEvent": """
uint8 LEFT     = 0
uint8 CENTER   = 1
uint8 RIGHT    = 2
uint8 RELEASED = 0
uint8 PRESSED  = 1
uint8 bumper
uint8 state
""",
}


@cache
def typestore() -> Any:
    """rosbags' typestore of ROS 2 Jazzy's message definitions (what a Jazzy or Kilted robot runs), and kobuki_ros'."""
    from rosbags.typesys import get_types_from_msg

    store = get_typestore(Stores.ROS2_JAZZY)
    for name, text in KOBUKI_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store


def type_hash(typename: str) -> str:
    """The RIHS01 hash of a ROS type (``sensor_msgs/msg/LaserScan``): REP-2011's sha256 of its description."""
    return str(typestore().hash_rihs01(typename))


def dds_type(typename: str) -> str:
    """``sensor_msgs/msg/LaserScan`` → ``sensor_msgs::msg::dds_::LaserScan_``, the type in rmw_zenoh's keys."""
    pkg, kind, name = typename.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def ros_type(dds: str) -> str:
    """The inverse of :func:`dds_type`."""
    pkg, kind, _dds, name = dds.split("::")
    return f"{pkg}/{kind}/{name.removesuffix('_')}"


def topic_keyexpr(domain: int, topic: str, typename: str) -> str:
    """The data key: ``<domain>/<topic without slashes at its ends>/<dds type>/<RIHS01 hash>``."""
    return f"{domain}/{topic.strip('/')}/{dds_type(typename)}/{type_hash(typename)}"


@dataclass(frozen=True)
class NodeName:
    """Who a node is in the ROS graph: its domain, the Zenoh session's id (32 hex digits), its id, name, namespace."""

    domain: int
    zid: str
    node_id: int
    name: str
    namespace: str = "/"
    enclave: str = "/"

    def _head(self, entity_id: int, kind: str) -> str:
        return (f"{ADMIN_SPACE}/{self.domain}/{self.zid}/{self.node_id}/{entity_id}/{kind}/"
                f"{mangle(self.enclave)}/{mangle(self.namespace)}/{mangle(self.name)}")  # fmt: skip

    def node_token(self) -> str:
        """The node's token (kind ``NN``; its entity id is its node id)."""
        return self._head(self.node_id, "NN")

    def entity_token(self, entity_id: int, kind: str, topic: str, typename: str, qos: Qos) -> str:
        """A publisher's (``MP``) or subscription's (``MS``) token on ``topic`` (fully qualified)."""
        if kind not in ("MP", "MS", "SS", "SC"):
            raise ValueError(f"entity kind must be MP, MS, SS or SC, not {kind!r}")
        return (f"{self._head(entity_id, kind)}/{mangle(topic)}/{dds_type(typename)}/"
                f"{type_hash(typename)}/{qos_to_keyexpr(qos)}")  # fmt: skip


def gid(token: str) -> bytes:
    """An entity's 16-byte GID: XXH3-128 of its token, low 64 bits then high, each little-endian."""
    import xxhash  # the ros2 extra; only senders need it

    return xxhash.xxh3_128_intdigest(token.encode()).to_bytes(GID_SIZE, "little")


@dataclass(frozen=True)
class Attachment:
    """What rides with each sample: sequence number, source timestamp [ns since the epoch], publisher GID."""

    sequence: int
    timestamp_ns: int
    gid: bytes

    def encode(self) -> bytes:
        """The 33 bytes: int64 LE, int64 LE, length byte 16, the GID."""
        if len(self.gid) != GID_SIZE:
            raise ValueError(f"a GID has {GID_SIZE} bytes, not {len(self.gid)}")
        return struct.pack("<qqB", self.sequence, self.timestamp_ns, GID_SIZE) + self.gid

    @staticmethod
    def decode(data: bytes) -> Attachment:
        """Read an attachment (ValueError if it is not 33 bytes with a 16-byte GID)."""
        if len(data) != ATTACHMENT_SIZE or data[16] != GID_SIZE:
            raise ValueError(f"not an rmw_zenoh attachment ({len(data)} bytes)")
        seq, stamp, _n = struct.unpack_from("<qqB", data)
        return Attachment(seq, stamp, bytes(data[17:]))


def encode(message: Any, typename: str) -> bytes:
    """A message's CDR bytes (little-endian, with the encapsulation header), via rosbags."""
    return bytes(typestore().serialize_cdr(message, typename))


def decode(data: bytes, typename: str) -> Any:
    """A message from CDR bytes (any rosbags or struct error propagates: callers count and skip)."""
    return typestore().deserialize_cdr(bytes(data), typename)


def message(typename: str, **fields: Any) -> Any:
    """A rosbags message object of ``typename`` built from keyword fields."""
    return typestore().types[typename](**fields)


NUMPY = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
         "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
         "uint64": np.uint64, "float32": np.float32, "float64": np.float64}  # fmt: skip


def zero(typename: str, **fields: Any) -> Any:
    """A message of ``typename`` with every field not given zero, empty or its nested type's zero."""
    values = {}
    for name, (kind, spec) in typestore().fielddefs[typename][1]:
        if name in fields:
            values[name] = fields[name]
        elif kind == 1:  # a base type: (type, string bound)
            values[name] = "" if spec[0] in ("string", "wstring") else (False if spec[0] == "bool" else 0)
        elif kind == 2:  # a nested message
            values[name] = zero(spec)
        else:  # 3: a fixed array, 4: a sequence: ((kind, spec), length)
            (inner_kind, inner), n = spec
            n = n if kind == 3 else 0
            if inner_kind == 1 and inner[0] in NUMPY:
                values[name] = np.zeros(n, dtype=NUMPY[inner[0]])
            else:
                values[name] = [zero(inner) if inner_kind == 2 else "" for _ in range(n)]
    return typestore().types[typename](**values)


@dataclass
class Counters:
    """Samples a subscription received, took, and skipped by cause (thread-safe increments)."""

    received: int = 0
    taken: int = 0
    no_attachment: int = 0
    bad_attachment: int = 0
    wrong_type: int = 0
    bad_cdr: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock, repr=False, compare=False)

    def add(self, name: str) -> None:
        with self.lock:
            setattr(self, name, getattr(self, name) + 1)

    @property
    def skipped(self) -> int:
        return self.no_attachment + self.bad_attachment + self.wrong_type + self.bad_cdr


@dataclass(frozen=True)
class Received:
    """A decoded sample: the message, its attachment, and when it arrived [s, time.monotonic()]."""

    message: Any
    attachment: Attachment
    arrived: float


def parse_sample(key: str, payload: bytes, attachment: bytes | None, typename: str,
                 counters: Counters, arrived: float) -> Received | None:
    """Check and decode one sample as an rmw_zenoh subscription would; None (and counted) if it is not one.

    Skipped: no attachment, an attachment that is not 33 bytes, a key whose
    type or hash is not ``typename``'s, a CDR body that does not decode.
    """  # fmt: skip
    counters.add("received")
    if attachment is None:
        counters.add("no_attachment")
        return None
    try:
        att = Attachment.decode(attachment)
    except ValueError:
        counters.add("bad_attachment")
        return None
    parts = key.rsplit("/", 2)
    if len(parts) != 3 or parts[1] != dds_type(typename) or parts[2] != type_hash(typename):
        counters.add("wrong_type")
        return None
    try:
        msg = decode(payload, typename)
    except Exception:  # rosbags raises struct.error, IndexError, ValueError…: all mean a bad body
        counters.add("bad_cdr")
        return None
    counters.add("taken")
    return Received(msg, att, arrived)
