"""The camera over a real protocol: MJPEG over HTTP served by the emulator, read by the camera adapter via OpenCV."""

from __future__ import annotations

import http.client
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from homing.emulators.camera_stream import BOUNDARY, MjpegServer
from homing.emulators.emulation import Emulation
from homing.robot.hardware.camera import UvcCamera, calibration_yaml, load_calibration, pinhole
from homing.robot.hardware.robot import open_robot
from homing.robot.hardware.robot_file import load_robot
from homing.sim import load_world
from homing.sim.camera import camera_info

from homing.errors import UserError
from tests.wall_clock import until

W, H = 320, 240
RATE = 5.0  # [Hz] frames published in these tests


def _frame(k: int) -> np.ndarray:
    """A test image: a grey ramp, a bright square whose place depends on ``k``, and ``k`` in 8 blocks on top."""
    img = np.tile(np.linspace(30, 220, W, dtype=np.uint8)[None, :, None], (H, 1, 3))
    x = 40 + 20 * (k % 10)
    img[100:140, x : x + 40] = (250, 40, 40)
    for b in range(8):
        img[:16, b * 40 : (b + 1) * 40] = 255 if k >> b & 1 else 0
    return img


def _number(img: np.ndarray) -> int:
    return sum(1 << b for b in range(8) if img[8, b * 40 + 20].mean() > 128)


@pytest.fixture
def server() -> Iterator[MjpegServer]:
    srv = MjpegServer()
    srv.start()
    yield srv
    srv.stop()


def _camera(url: str) -> UvcCamera:
    return UvcCamera(url, pinhole(W, H, 290.0, 290.0, 160.0, 119.5), np.eye(4), time.monotonic, rate=2 * RATE)


def _open_while_publishing(server: MjpegServer, camera: UvcCamera) -> None:
    """Open the camera (FFmpeg reads two frames before it opens) while frames keep coming."""
    import threading

    opener = threading.Thread(target=camera.open)
    opener.start()
    k = 200
    while opener.is_alive():
        server.publish(_frame(k), time.monotonic())
        k += 1
        opener.join(1.0 / RATE)


def test_every_frame_published_reaches_the_adapter_in_order_and_intact(server: MjpegServer) -> None:
    camera = _camera(server.url)
    _open_while_publishing(server, camera)
    try:
        got: list[int] = []
        due = time.monotonic()
        for k in range(1, 16):
            due += 1.0 / RATE  # a camera sends its frames one period apart
            time.sleep(max(0.0, due - time.monotonic()))
            sent = _frame(k)
            server.publish(sent, time.monotonic())
            assert until(lambda k=k: (im := camera.latest()) is not None and _number(im.image) == k, 2.0), k
            image = camera.latest()
            assert image is not None
            got.append(_number(image.image))
            assert image.image.shape == (H, W, 3)
            assert np.abs(image.image.astype(int) - sent.astype(int)).mean() < 2.0  # JPEG at quality 90
        assert camera.losses == 0 and not camera.lost
    finally:
        server.stop()  # first, so the camera's pending read ends at once
        camera.close()
    assert got == list(range(1, 16))
    assert server.sent >= 15 and server.clients == 1


def test_the_stream_speaks_multipart_mjpeg_as_mjpg_streamer(server: MjpegServer) -> None:
    frame = server.publish(_frame(7), 12.5)
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    conn.request("GET", "/?action=stream")  # mjpg-streamer's URL works too
    reply = conn.getresponse()
    assert reply.status == 200
    assert reply.getheader("Content-Type") == f"multipart/x-mixed-replace;boundary={BOUNDARY}"
    assert reply.readline() == f"--{BOUNDARY}\r\n".encode()
    headers = {}
    while (line := reply.readline()) != b"\r\n":
        name, _, value = line.decode().strip().partition(": ")
        headers[name] = value
    assert headers["Content-Type"] == "image/jpeg" and headers["X-Timestamp"] == "12.500000"
    jpeg = reply.read(int(headers["Content-Length"]))
    assert jpeg == frame.jpeg and reply.read(2) == b"\r\n"
    decoded = cv2.cvtColor(cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    assert _number(decoded) == 7
    conn.close()
    with urllib.request.urlopen(f"http://127.0.0.1:{server.port}/snapshot.jpg", timeout=5) as snap:
        assert snap.headers["Content-Type"] == "image/jpeg" and snap.read() == frame.jpeg
    with pytest.raises(urllib.error.HTTPError) as err:
        urllib.request.urlopen(f"http://127.0.0.1:{server.port}/video", timeout=5)
    assert err.value.code == 404


def test_a_stream_that_stops_loses_the_camera_and_one_that_restarts_is_picked_up(server: MjpegServer) -> None:
    camera = _camera(server.url)
    _open_while_publishing(server, camera)
    port = server.port
    try:
        server.stop()  # as pulling an IP camera's cable: the connection is cut, the port refuses
        assert until(lambda: camera.lost, camera.silence + 2.0) and camera.losses == 1
        server.start()
        assert server.port == port
        k = 1

        def back() -> bool:
            nonlocal k
            server.publish(_frame(k), time.monotonic())
            k += 1
            time.sleep(1.0 / RATE)
            return not camera.lost and camera.reconnects >= 1

        assert until(back, 10.0)
    finally:
        server.stop()
        camera.close()


def test_camera_info_written_for_a_pinhole_reads_back_as_ros_camera_info(tmp_path: Path) -> None:
    info = camera_info()
    cal = pinhole(info.width, info.height, info.fx, info.fy, info.cx, info.cy)
    (tmp_path / "cam.yaml").write_text(calibration_yaml(cal, "xtion"))
    back = load_calibration(tmp_path / "cam.yaml")
    assert (back.width, back.height, back.model) == (320, 240, "plumb_bob")
    for a, b in ((back.K, cal.K), (back.D, cal.D), (back.R, cal.R), (back.P, cal.P)):
        assert np.array_equal(a, b)
    got = back.info(np.eye(4))
    assert (got.fx, got.fy, got.cx, got.cy) == (info.fx, info.fy, info.cx, info.cy)


def test_the_emulated_camera_is_the_simulators_behind_a_url(tmp_path: Path) -> None:
    emu = Emulation(load_world("lab"), tmp_path / "emu", seed=3)
    emu.start()
    try:
        config = load_robot(emu.robot_file)
        assert config.camera is not None and config.camera.source == emu.camera_url
        robot = open_robot(emu.robot_file)
        try:
            assert robot.camera is not None
            assert until(lambda: robot.camera is not None and robot.camera.frames >= 2, 5.0)
            image = robot.observe().image
            assert image is not None
            sim = camera_info()
            assert (image.info.fx, image.info.cx, image.info.cy) == (sim.fx, sim.cx, sim.cy)
            assert np.allclose(image.info.base_from_optical, sim.base_from_optical)
            with emu.lock:  # the robot sits still on its dock: the view now is the view then
                truth = emu.robot.render().image
            diff = np.abs(image.image.astype(int) - truth.astype(int))
            assert diff.mean() < 4.0  # pixel noise (σ 2) and JPEG; a wrong image differs by tens
        finally:
            robot.close()
    finally:
        emu.stop()
    assert emu.status()["frames"] >= 2


def test_a_camera_url_in_the_robot_file_is_kept_as_a_url(tmp_path: Path) -> None:
    path = tmp_path / "robot.yaml"
    path.write_text("base: {port: a}\nlidar: {port: b}\n"
                    "camera: {source: 'http://cam.local:8080/?action=stream', info: c.yaml, delay: 0.08}\n")  # fmt: skip
    config = load_robot(path)
    assert config.camera is not None
    assert config.camera.source == "http://cam.local:8080/?action=stream" and config.camera.delay == 0.08
    path.write_text("base: {port: a}\nlidar: {port: b}\ncamera: {source: 0, info: c.yaml, delay: -0.1}\n")
    with pytest.raises(UserError) as err:
        load_robot(path)
    assert str(err.value).startswith(f"{path}:3:") and "'delay'" in str(err.value)
