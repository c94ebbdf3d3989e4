"""A camera served as an MJPEG stream over HTTP, as IP cameras and mjpg-streamer serve one.

The protocol (``multipart/x-mixed-replace``, RFC 2046 §5.1): the client asks
``GET /stream.mjpg`` (or mjpg-streamer's ``GET /?action=stream``); the
answer is one endless HTTP/1.0 body of parts, each a boundary line,
headers (``Content-Type: image/jpeg``, ``Content-Length``, and
mjpg-streamer's ``X-Timestamp``: the capture time [s]) and one JPEG.
``GET /snapshot.jpg`` (or ``/?action=snapshot``) answers the latest frame
alone. Anything else is a 404. OpenCV's ``VideoCapture`` reads the stream
by URL through its FFmpeg backend (the ``mpjpeg`` demuxer), as it reads a
real network camera.

:class:`MjpegServer` holds the latest frame; :meth:`MjpegServer.publish`
encodes a new one (RGB, (H, W, 3) uint8) and wakes every client, which
is sent it at once (a client that connects is sent the latest frame first,
so it never waits a whole frame period to start). A client slower than the
frames skips to the newest, as a live camera's does. :meth:`stop` closes
the listening socket and every client's connection, as unplugging the
camera's network cable does; :meth:`start` again listens on the same port.
"""

from __future__ import annotations

import socket
import threading
from dataclasses import dataclass
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, urlsplit

import numpy as np

BOUNDARY = "homingframe"
STREAM_PATH = "/stream.mjpg"
SNAPSHOT_PATH = "/snapshot.jpg"
JPEG_QUALITY = 90  # [0..100] mjpg-streamer's input_uvc defaults to 80; tags want sharp edges
WAIT = 0.5  # [s] a client re-checks for a stopped server this often while no frame comes


@dataclass(frozen=True)
class Frame:
    """One encoded frame: its number, JPEG bytes and capture time [s]."""

    seq: int
    jpeg: bytes
    stamp: float


def encode_jpeg(rgb: np.ndarray, quality: int = JPEG_QUALITY) -> bytes:
    """JPEG bytes of an RGB (H, W, 3) uint8 image."""
    import cv2

    ok, buf = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        raise ValueError(f"cannot encode a {rgb.shape} image as JPEG")
    return buf.tobytes()


def part(frame: Frame) -> bytes:
    """One part of the multipart stream: boundary, headers, JPEG."""
    head = (f"--{BOUNDARY}\r\nContent-Type: image/jpeg\r\nContent-Length: {len(frame.jpeg)}\r\n"
            f"X-Timestamp: {frame.stamp:.6f}\r\n\r\n")  # fmt: skip
    return head.encode("ascii") + frame.jpeg + b"\r\n"


class MjpegServer:
    """The latest frame of a camera, served to any number of HTTP clients on ``host:port``."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0, quality: int = JPEG_QUALITY):
        self.host = host
        self.port = port  # 0: a free port, chosen when first started and kept from then on
        self.quality = quality
        self.frames = 0  # frames published
        self.sent = 0  # frames written to clients (all clients)
        self.clients = 0  # clients served so far
        self._frame: Frame | None = None
        self._cond = threading.Condition()
        self._server: ThreadingHTTPServer | None = None
        self._thread: threading.Thread | None = None
        self._connections: set[socket.socket] = set()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}{STREAM_PATH}"

    @property
    def running(self) -> bool:
        return self._server is not None

    def start(self) -> None:
        """Listen (OSError if the port cannot be had) and serve in a thread."""
        if self._server is not None:
            return
        server = ThreadingHTTPServer((self.host, self.port), _handler(self))
        server.daemon_threads = True
        self.port = server.server_address[1]
        self._server = server
        self._thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.1},
                                        name="homing-mjpeg", daemon=True)  # fmt: skip
        self._thread.start()

    def stop(self) -> None:
        """Stop listening and cut every client off."""
        server, self._server = self._server, None
        if server is None:
            return
        server.shutdown()
        server.server_close()
        with self._cond:
            for conn in list(self._connections):
                try:
                    conn.shutdown(socket.SHUT_RDWR)
                except OSError:
                    pass
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=2.0)

    def publish(self, rgb: np.ndarray, stamp: float) -> Frame:
        """Encode ``rgb`` (captured at ``stamp`` [s]) and hand it to every client."""
        jpeg = encode_jpeg(rgb, self.quality)
        with self._cond:
            self._frame = Frame(self.frames, jpeg, stamp)
            self.frames += 1
            self._cond.notify_all()
            return self._frame

    def latest(self) -> Frame | None:
        with self._cond:
            return self._frame

    def next_frame(self, after: int) -> Frame | None:
        """The newest frame numbered above ``after``, waiting up to ``WAIT`` [s] (None if none came)."""
        with self._cond:
            if self._frame is None or self._frame.seq <= after:
                self._cond.wait(WAIT)
            frame = self._frame
            return frame if frame is not None and frame.seq > after else None

    def _serve(self, handler: BaseHTTPRequestHandler) -> None:
        """Stream frames to one client until it goes or the server stops."""
        with self._cond:
            self._connections.add(handler.connection)
            self.clients += 1
        try:
            handler.send_response(200)
            handler.send_header("Content-Type", f"multipart/x-mixed-replace;boundary={BOUNDARY}")
            handler.send_header("Cache-Control", "no-store, no-cache, must-revalidate, max-age=0")
            handler.send_header("Pragma", "no-cache")
            handler.send_header("Connection", "close")
            handler.end_headers()
            seq = -1
            while self._server is not None:
                frame = self.next_frame(seq)
                if frame is None:
                    continue
                handler.wfile.write(part(frame))
                handler.wfile.flush()
                seq = frame.seq
                with self._cond:
                    self.sent += 1
        except OSError:  # the client went, or stop() cut it off
            pass
        finally:
            with self._cond:
                self._connections.discard(handler.connection)

    def _snapshot(self, handler: BaseHTTPRequestHandler) -> None:
        frame = self.latest()
        if frame is None:
            handler.send_error(503, "no frame yet")
            return
        handler.send_response(200)
        handler.send_header("Content-Type", "image/jpeg")
        handler.send_header("Content-Length", str(len(frame.jpeg)))
        handler.send_header("X-Timestamp", f"{frame.stamp:.6f}")
        handler.end_headers()
        handler.wfile.write(frame.jpeg)


def _handler(camera: MjpegServer) -> Any:
    class Handler(BaseHTTPRequestHandler):
        server_version = "homing-emulate/1"

        def do_GET(self) -> None:  # noqa: N802 - http.server's name
            url = urlsplit(self.path)
            action = parse_qs(url.query).get("action", [""])[0]
            if url.path == STREAM_PATH or (url.path == "/" and action == "stream"):
                camera._serve(self)
            elif url.path == SNAPSHOT_PATH or (url.path == "/" and action == "snapshot"):
                camera._snapshot(self)
            else:
                self.send_error(404, f"no such stream: {url.path} (try {STREAM_PATH})")

        def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 - http.server's signature
            pass  # no access log on stderr

    return Handler
