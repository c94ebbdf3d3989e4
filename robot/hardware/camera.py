"""A camera through OpenCV (UVC device, network stream or video file), rectified with a ROS ``camera_info`` YAML file.

``load_calibration(path)`` reads the file ROS's ``camera_calibration`` writes
(``image_width``, ``image_height``, ``camera_matrix``, ``distortion_model``,
``distortion_coefficients``, ``rectification_matrix``,
``projection_matrix``), every mistake reported at ``file:line:col``.
:class:`UvcCamera` grabs frames from ``cv2.VideoCapture(source)`` in a
thread. The source is a device index like ``0`` for ``/dev/video0``, a
device path, a network stream's URL (``http://host:8080/?action=stream``,
MJPEG over HTTP as IP cameras and mjpg-streamer serve it, or ``rtsp://``;
read by OpenCV's FFmpeg backend with open and read timeouts, so a camera
that hangs is lost rather than waited on forever), or a video file (played
at ``rate`` and started again when it ends). Frames are turned RGB and
rectified as ROS's ``image_proc`` does: the undistorted image has the
projection matrix's intrinsics (fx = P[0,0], fy = P[1,1], cx = P[0,2],
cy = P[1,2]), which is what the contract's
:class:`~homing.robot.types.CameraInfo` (no distortion) states. The
distortion models: ``plumb_bob`` and ``rational_polynomial`` (OpenCV's
radial-tangential), ``equidistant`` (OpenCV's fisheye).

A live source streaming faster than ``rate`` has frames dropped, keeping
one whenever at least 0.9 of a period has passed since the last kept one
(so a source at the rate itself, with some jitter, loses none). A frame is
stamped with the adapter's clock when it arrives, less ``delay`` [s], the
source's known capture-to-arrival latency (0 unless measured).

The camera is lost when no frame has come for ``silence`` seconds; the
thread reopens it every second meanwhile.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from homing.robot.types import CameraImage, CameraInfo

from homing.errors import UserError
from homing.section import Section
from homing.yamlfile import load

MODELS = ("plumb_bob", "rational_polynomial", "equidistant")
RETRY = 1.0  # [s] between attempts to reopen a lost camera
KEEP_FRACTION = 0.9  # a live frame is kept once this share of a period has passed since the last kept one
MIN_SILENCE = 2.0  # [s] the shortest silence that counts as a lost camera
STREAM_TIMEOUT = 3.0  # [s] a network stream that opens or sends nothing for this long has failed
FFMPEG_LOG_FATAL = 8  # AV_LOG_FATAL: FFmpeg keeps only its fatal messages
URL_SCHEMES = ("http://", "https://", "rtsp://", "rtp://", "udp://", "tcp://")


@dataclass(frozen=True)
class Calibration:
    """A camera's calibration as ROS states it: K (3 × 3), D (N,), R (3 × 3), P (3 × 4), image size [px]."""

    width: int
    height: int
    K: np.ndarray
    D: np.ndarray
    R: np.ndarray
    P: np.ndarray
    model: str = "plumb_bob"

    def info(self, base_from_optical: np.ndarray) -> CameraInfo:
        """The contract's intrinsics of the *rectified* image (the projection matrix's)."""
        P = self.P
        return CameraInfo(self.width, self.height, float(P[0, 0]), float(P[1, 1]), float(P[0, 2]),
                          float(P[1, 2]), np.asarray(base_from_optical, dtype=float))  # fmt: skip


def _matrix(sec: Section, key: str, rows: int, cols: int | None) -> np.ndarray:
    sub = sec.section(key)
    sub.only(("rows", "cols", "data"))
    data = sub.raw("data")
    n = len(data) if isinstance(data, list) else -1
    want = rows * cols if cols is not None else n
    if not isinstance(data, list) or n != want or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                          for v in data):  # fmt: skip
        raise sub.error("data", f"'{key}.data' must be a list of {want if cols else 'N'} numbers")
    shape = (rows, cols) if cols is not None else (n,)
    if sub.has("rows") and sub.integer("rows") != (rows if cols is not None else 1):
        raise sub.error("rows", f"'{key}.rows' must be {rows if cols is not None else 1}")
    return np.asarray(data, dtype=float).reshape(shape)


def load_calibration(path: str | Path) -> Calibration:
    """Read a ROS ``camera_info`` YAML file; UserError at ``file:line:col`` when it is wrong."""
    path = Path(path)
    sec = Section(load(path), path, "camera info")
    sec.only(("image_width", "image_height", "camera_name", "camera_matrix", "distortion_model",
              "distortion_coefficients", "rectification_matrix", "projection_matrix"))  # fmt: skip
    width, height = sec.integer("image_width", lo=1), sec.integer("image_height", lo=1)
    K = _matrix(sec, "camera_matrix", 3, 3)
    model = sec.string("distortion_model", "plumb_bob", choices=MODELS)
    D = _matrix(sec, "distortion_coefficients", 1, None) if sec.has("distortion_coefficients") else np.zeros(5)
    R = _matrix(sec, "rectification_matrix", 3, 3) if sec.has("rectification_matrix") else np.eye(3)
    if sec.has("projection_matrix"):
        P = _matrix(sec, "projection_matrix", 3, 4)
    else:
        P = np.hstack([K, np.zeros((3, 1))])
    if not (K[0, 0] > 0 and K[1, 1] > 0 and P[0, 0] > 0 and P[1, 1] > 0):
        raise sec.error("camera_matrix", "focal lengths must be positive")
    if model == "equidistant" and len(D) != 4:
        raise sec.error("distortion_coefficients", "the equidistant model takes 4 coefficients")
    return Calibration(width, height, K, D, R, P, model)


def pinhole(width: int, height: int, fx: float, fy: float, cx: float, cy: float) -> Calibration:
    """The calibration of an ideal pinhole camera (no distortion): K = P's left 3 × 3."""
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    return Calibration(width, height, K, np.zeros(5), np.eye(3), np.hstack([K, np.zeros((3, 1))]))


def calibration_yaml(cal: Calibration, name: str = "camera") -> str:
    """``cal`` as the ROS ``camera_info`` YAML that :func:`load_calibration` reads (and camera_calibration writes)."""

    def matrix(key: str, m: np.ndarray, rows: int) -> str:
        data = ", ".join(repr(float(v)) for v in m.ravel())
        return f"{key}:\n  rows: {rows}\n  cols: {m.size // rows}\n  data: [{data}]\n"

    return (f"image_width: {cal.width}\nimage_height: {cal.height}\ncamera_name: {name}\n"
            + matrix("camera_matrix", cal.K, 3) + f"distortion_model: {cal.model}\n"
            + matrix("distortion_coefficients", cal.D, 1) + matrix("rectification_matrix", cal.R, 3)
            + matrix("projection_matrix", cal.P, 3))  # fmt: skip


class Rectifier:
    """Undistorts (H, W, 3) images of one calibration onto its projection matrix's pinhole camera."""

    def __init__(self, cal: Calibration):
        import cv2

        size = (cal.width, cal.height)
        newK = cal.P[:, :3]
        if cal.model == "equidistant":
            self.maps = cv2.fisheye.initUndistortRectifyMap(cal.K, cal.D, cal.R, newK, size, cv2.CV_16SC2)
        else:
            self.maps = cv2.initUndistortRectifyMap(cal.K, cal.D, cal.R, newK, size, cv2.CV_16SC2)
        self.size = size

    def __call__(self, image: np.ndarray) -> np.ndarray:
        import cv2

        if (image.shape[1], image.shape[0]) != self.size:
            image = cv2.resize(image, self.size, interpolation=cv2.INTER_AREA)
        return cv2.remap(image, self.maps[0], self.maps[1], cv2.INTER_LINEAR)


def is_url(source: int | str) -> bool:
    """Whether a camera source is a network stream's URL (not a device index or a path)."""
    return isinstance(source, str) and source.lower().startswith(URL_SCHEMES)


class UvcCamera:
    """A camera read by OpenCV in a thread; :meth:`latest` gives the newest rectified RGB frame."""

    def __init__(self, source: int | str, calibration: Calibration, base_from_optical: np.ndarray,
                 now: Callable[[], float], rate: float = 5.0, silence: float | None = None, delay: float = 0.0):
        self.name = "camera"
        self.source = source
        self.info = calibration.info(base_from_optical)
        self.rectify = Rectifier(calibration)
        self.now = now
        self.rate = rate  # [Hz] frames kept per second (a file is paced to it)
        self.silence = silence if silence is not None else max(MIN_SILENCE, 5.0 / rate)
        self.delay = delay  # [s] subtracted from the arrival time to stamp a frame
        self.lock = threading.Lock()
        self.image: CameraImage | None = None
        self.frames = 0
        self.last_frame = -float("inf")
        self.connected = False
        self.losses = 0
        self.reconnects = 0
        self._cap: Any = None  # a cv2.VideoCapture
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._is_file = isinstance(source, str) and not is_url(source) and Path(source).is_file()

    def open(self) -> None:
        """Open the source and start grabbing; UserError-free :class:`CameraError` if it cannot."""
        if not self._open():
            raise CameraError(f"cannot open video source {self.source!r}")
        self._thread = threading.Thread(target=self._run, name="homing-camera", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the thread and release the source (the thread releases it if a read outlasts the wait)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=STREAM_TIMEOUT + 1.0)
            if self._thread.is_alive():
                return
        if self._cap is not None:
            self._cap.release()
            self._cap = None

    @property
    def lost(self) -> bool:
        return not self.connected or self.now() - self.last_frame > self.silence

    def latest(self) -> CameraImage | None:
        with self.lock:
            return self.image

    def _open(self) -> bool:
        import cv2

        if is_url(self.source):
            # FFmpeg prints "Stream ends prematurely" to stderr, over the live view, whenever a stream stops; the
            # adapter reports a lost camera itself (``lost``, ``reconnects``). Read once, at the backend's first use.
            os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", str(FFMPEG_LOG_FATAL))
            ms = round(STREAM_TIMEOUT * 1000)
            cap = cv2.VideoCapture(self.source, cv2.CAP_FFMPEG,
                                   [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, ms, cv2.CAP_PROP_READ_TIMEOUT_MSEC, ms])
        else:
            cap = cv2.VideoCapture(self.source)
        if not cap.isOpened():
            cap.release()
            return False
        self._cap = cap
        self.connected = True
        self.last_frame = self.now()
        return True

    def _run(self) -> None:
        period = 1.0 / self.rate
        next_keep, last_kept = time.monotonic(), -math.inf
        while not self._stop.is_set():
            cap = self._cap
            if cap is None:
                if self._stop.wait(RETRY):
                    break
                if self._open():
                    self.reconnects += 1
                continue
            ok, frame = cap.read()
            if not ok or frame is None:
                cap.release()
                self._cap = None
                if self._is_file:
                    self._open()  # a file starts again: a test source, not a camera that died
                    continue
                self.connected = False
                self.losses += 1
                continue
            wall = time.monotonic()
            if self._is_file:
                if wall < next_keep:
                    self._stop.wait(next_keep - wall)  # a file has no rate of its own: play it at `rate`
                next_keep = max(next_keep + period, time.monotonic() - period)
            elif wall - last_kept < KEEP_FRACTION * period:
                continue  # a live camera streams faster than we keep frames: drop this one
            last_kept = wall
            self._keep(frame)
        if self._cap is not None:  # stopped: the thread that reads releases
            self._cap.release()
            self._cap = None

    def _keep(self, frame: np.ndarray) -> None:
        import cv2

        rgb = cv2.cvtColor(frame, cv2.COLOR_BGR2RGB) if frame.ndim == 3 else frame
        arrived = self.now()
        image = CameraImage(arrived - self.delay, self.rectify(rgb), self.info)
        with self.lock:
            self.image = image
            self.frames += 1
            self.last_frame = arrived


class CameraError(Exception):
    """The camera's source cannot be opened."""


def check_calibration(path: str | Path, file: str | Path, line: int, col: int) -> Calibration:
    """:func:`load_calibration`, with a missing file reported where the robot file names it."""
    if not Path(path).is_file():
        raise UserError(f"camera info file {path} does not exist", file, line, col)
    return load_calibration(path)
