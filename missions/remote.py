"""Follow a running mission from another terminal or machine: ``homing run … --serve PORT``, ``homing view --attach HOST:PORT``.

The runner's side (:class:`TreeServer`) listens on a TCP port and streams
snapshots of the tree as JSON lines, at most ``SERVE_HZ`` a second of wall
time and once more when the run ends. Each snapshot carries the run's state
(adapter time, ticks, root status, the running leaf and its feedback), every
node's name, depth and status, and the live view's frame rendered for the
follower's terminal size: the follower sends ``{"width": W, "height": H}``
when it connects, and sees exactly what :class:`homing.missions.view.LiveView`
draws, ANSI colours included. Followers only read; a slow one misses frames
rather than slowing the robot down (each has its own sender thread and only
the latest frame waits for it).

The follower's side (:func:`attach`) connects, prints frames in place, and
says when the run has ended. Nothing listening is a one-line error. The
server binds ``127.0.0.1`` unless given a host (``--serve 0.0.0.0:8765`` to
be followed from another machine; the stream is read-only and unencrypted,
meant for a lab network).
"""

from __future__ import annotations

import io
import json
import socket
import threading
import time
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, TextIO

from py_trees.behaviour import Behaviour
from py_trees.common import Status
from rich.console import Console

from homing.errors import UserError

if TYPE_CHECKING:
    from homing.missions.runner import Runner

SERVE_HZ = 8.0  # [Hz] wall-clock rate of snapshots
CONNECT_TIMEOUT = 3.0  # [s]
DEFAULT_SIZE = (80, 24)  # a follower's terminal when it does not say


def parse_address(text: str, default_host: str = "127.0.0.1") -> tuple[str, int]:
    """``"8765"`` → (default_host, 8765); ``"HOST:PORT"`` → (HOST, PORT). Raises ValueError for anything else."""
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host, port_text = default_host, text
    host = host.strip("[]") or default_host
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"'{text}' is not a port or HOST:PORT") from None
    if not 0 <= port <= 65535:
        raise ValueError(f"port {port} is not within 0..65535")
    return host, port


def snapshot_nodes(root: Behaviour) -> list[dict[str, Any]]:
    """Every node preorder: name, depth, status (and feedback for the running ones)."""
    out: list[dict[str, Any]] = []

    def walk(node: Behaviour, depth: int) -> None:
        entry: dict[str, Any] = {"name": node.name, "depth": depth, "status": node.status.value}
        if node.status == Status.RUNNING and node.feedback_message:
            entry["feedback"] = node.feedback_message
        out.append(entry)
        for child in node.children:
            walk(child, depth + 1)

    walk(root, 0)
    return out


class _Follower:
    """One connected follower: its terminal size, the latest message for it, and the thread sending it."""

    def __init__(self, conn: socket.socket, size: tuple[int, int]):
        self.conn, self.size = conn, size
        self.latest: bytes | None = None
        self.ready = threading.Condition()
        self.closed = False
        self.thread = threading.Thread(target=self._send, daemon=True)
        self.thread.start()

    def offer(self, message: bytes) -> None:
        with self.ready:
            self.latest = message
            self.ready.notify()

    def _send(self) -> None:
        while True:
            with self.ready:
                while self.latest is None and not self.closed:
                    self.ready.wait()
                message, self.latest = self.latest, None
            if message is None:
                break
            try:
                self.conn.sendall(message)
            except OSError:
                break
        self.closed = True
        self.conn.close()

    def close(self, wait: float = 2.0) -> None:
        """Stop after sending what is waiting (at most ``wait`` seconds)."""
        with self.ready:
            self.closed = True
            self.ready.notify()
        self.thread.join(wait)


class TreeServer:
    """Streams tree snapshots of one run to every follower on ``(host, port)``; port 0 picks a free one."""

    def __init__(self, host: str, port: int, view_factory: Callable[[Console], Any]):
        self.view_factory = view_factory
        try:
            self.sock = socket.create_server((host, port), reuse_port=False)
        except OSError as err:
            raise UserError(f"--serve {host}:{port}: {(err.strerror or str(err)).split(' (while')[0]}") from None
        self.host, self.port = self.sock.getsockname()[:2]
        self.followers: list[_Follower] = []
        self.lock = threading.Lock()
        self.last = -1.0
        self.running = True
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while self.running:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                break
            size = DEFAULT_SIZE
            try:
                conn.settimeout(1.0)
                hello = json.loads(conn.makefile("r", encoding="utf-8").readline() or "{}")
                size = (max(20, int(hello.get("width", 80))), max(5, int(hello.get("height", 24))))
                conn.settimeout(None)
            except (OSError, ValueError, TypeError, AttributeError):
                pass
            with self.lock:
                self.followers.append(_Follower(conn, size))

    def publish(self, runner: Runner, *, force: bool = False) -> None:
        """Send a snapshot of ``runner`` to every follower (at most ``SERVE_HZ`` a second unless ``force``)."""
        now = time.monotonic()
        if not force and now - self.last < 1.0 / SERVE_HZ:
            return
        self.last = now
        with self.lock:
            self.followers = [f for f in self.followers if not f.closed]
            followers = list(self.followers)
        if not followers:
            return
        tip = runner.tree.tip()
        base = {
            "mission": runner.mission.name, "time": runner.now - runner.start, "ticks": runner.ticks,
            "root": runner.mission.root.status.value, "tip": tip.name if tip else None,
            "feedback": tip.feedback_message if tip else "", "nodes": snapshot_nodes(runner.mission.root),
            "ended": force and runner.mission.root.status != Status.RUNNING,
        }  # fmt: skip
        frames: dict[tuple[int, int], str] = {}
        for follower in followers:
            if follower.size not in frames:
                frames[follower.size] = self._frame(runner, follower.size)
            message = {**base, "frame": frames[follower.size]}
            follower.offer((json.dumps(message) + "\n").encode("utf-8"))

    def _frame(self, runner: Runner, size: tuple[int, int]) -> str:
        buffer = io.StringIO()
        console = Console(file=buffer, width=size[0], height=size[1], force_terminal=True, color_system="truecolor")
        console.print(self.view_factory(console).render(runner))
        return buffer.getvalue()

    def close(self) -> None:
        self.running = False
        with self.lock:
            for follower in self.followers:
                follower.close()
        self.sock.close()


def messages(host: str, port: int, size: tuple[int, int] = DEFAULT_SIZE) -> Iterator[dict[str, Any]]:
    """Connect to a serving run and yield its snapshots until it ends; nothing listening is a UserError."""
    try:
        sock = socket.create_connection((host, port), timeout=CONNECT_TIMEOUT)
    except ConnectionRefusedError:
        raise UserError(f"--attach {host}:{port}: nothing is listening there "
                        "(start a run with 'homing run MISSION --world W --serve PORT')") from None  # fmt: skip
    except TimeoutError:
        raise UserError(f"--attach {host}:{port}: no answer within {CONNECT_TIMEOUT:g} s") from None
    except OSError as err:
        raise UserError(f"--attach {host}:{port}: {err.strerror or err}") from None
    with sock:
        sock.settimeout(None)
        sock.sendall((json.dumps({"width": size[0], "height": size[1]}) + "\n").encode("utf-8"))
        for line in sock.makefile("r", encoding="utf-8"):
            try:
                message = json.loads(line)
            except json.JSONDecodeError:
                continue
            yield message
            if message.get("ended"):
                return


def attach(host: str, port: int, out: TextIO, size: tuple[int, int]) -> dict[str, Any] | None:
    """Draw the served frames in place on ``out`` until the run ends; the last snapshot (None if there was none)."""
    last = None
    for message in messages(host, port, size):
        out.write("\x1b[H\x1b[J" + message.get("frame", ""))
        out.flush()
        last = message
    if last is not None:
        out.write(f"run ended: root {last.get('root')} at t={last.get('time', 0.0):.1f} s\n"
                  if last.get("ended") else "the run stopped serving\n")  # fmt: skip
    return last
