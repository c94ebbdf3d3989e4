"""The Asus Xtion's RGB camera, rendered by pybullet's tiny renderer only when a tag can be in view.

Rendering a frame costs milliseconds, far more than a scan, so the camera
renders only when at least one tag is in front of it, facing it, within
``MAX_TAG_RANGE``, inside the field of view (with a margin of the tag's own
size) and not hidden behind a wall (one ray per candidate tag). Otherwise
the frame is skipped and the adapter reports no image, which a tag detector
treats exactly like an image without tags.

Intrinsics: pybullet's projection takes the *vertical* field of view
(DESIGN.md), and pixels are square, so fy = fx = (H/2)/tan(vfov/2) and
the horizontal FOV follows from the aspect (57.8° for 45° at 4:3).
Principal point: the image centre in OpenCV's convention (pixel centres
at integer coordinates), ((W − 1)/2, (H − 1)/2). The optical frame follows
OpenCV: z forward, x right, y down; ``CAMERA_POSE_XYZ`` puts it on the
TurtleBot's plate, looking straight ahead.

The floor is not a body: a floor plane spanning the map costs the tiny
renderer ~5 ms a frame (it fills the triangles' screen bounding boxes),
about half of the frame. As the camera looks level and everything else
stands on the floor, every pixel below the horizon that the renderer left
empty (depth 1) sees the floor, so those pixels get ``FLOOR_GREY``.

Pixel noise: Gaussian, σ = ``PIXEL_SIGMA`` grey levels, the same on the three
channels, seeded.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from homing.robot.frames import R_BODY_FROM_OPTICAL, homogeneous
from homing.robot.turtlebot import CAMERA_VFOV
from homing.robot.types import CameraImage, CameraInfo, Pose2
from homing.sim.quiet import import_pybullet
from homing.sim.scene import Scene
from homing.sim.tags import Tag

p = import_pybullet()

CAMERA_POSE_XYZ = (0.10, 0.0, 0.30)  # [m] optical centre in base_link
WIDTH, HEIGHT = 320, 240  # [px] enough for tags up to ~3 m (DESIGN.md)
CAMERA_RATE = 3.0  # [Hz]
NEAR, FAR = 0.05, 10.0  # [m] clipping planes
MAX_TAG_RANGE = 5.0  # [m] beyond this a tag is too small to decode: do not render for it
PIXEL_SIGMA = 2.0  # [grey levels]
FLOOR_GREY = 105  # [0..255] the lit floor
FAR_GREY = 200  # [0..255] above the horizon and beyond FAR (rare indoors)
EMPTY_DEPTH = 0.9999995  # the depth buffer holds 1 (as float32: 0.99999994) where nothing was drawn
LIGHT = dict(lightAmbientCoeff=0.75, lightDiffuseCoeff=0.35, lightSpecularCoeff=0.0, shadow=0)


def camera_info(width: int = WIDTH, height: int = HEIGHT) -> CameraInfo:
    """Intrinsics of a ``width`` × ``height`` frame with the Xtion's vertical FOV, and its mount."""
    f = (height / 2) / math.tan(CAMERA_VFOV / 2)
    return CameraInfo(width, height, f, f, width / 2, (height - 1) / 2,
                      homogeneous(R_BODY_FROM_OPTICAL, np.array(CAMERA_POSE_XYZ)))


class RenderedOnDemand(CameraImage):
    """A frame the simulator renders only when its pixels are first read (``.image``), then keeps.

    A real camera's frames cost nothing to ignore; a rendered one costs
    15–20 ms, so a frame nobody reads (the tag service skips most of them,
    the explore mission reads none) is never rendered. The pose, the time and
    the pixel noise are fixed when the frame is taken, so the pixels are the
    same whenever (and whether) they are read; the rest of the scene is
    rendered as it stands when they are read — within the tick, as services
    read frames right after the step that took them. Pickles as a plain
    :class:`~homing.robot.types.CameraImage`.
    """

    _pixels: np.ndarray | None
    _render: Callable[[], np.ndarray] | None

    def __init__(self, stamp: float, info: CameraInfo, render: Callable[[], np.ndarray]) -> None:
        object.__setattr__(self, "stamp", stamp)
        object.__setattr__(self, "info", info)
        object.__setattr__(self, "_render", render)
        object.__setattr__(self, "_pixels", None)

    @property  # type: ignore[override]
    def image(self) -> np.ndarray:
        if self._pixels is None:
            assert self._render is not None
            object.__setattr__(self, "_pixels", self._render())
            object.__setattr__(self, "_render", None)
        assert self._pixels is not None
        return self._pixels

    @property
    def rendered(self) -> bool:
        """Whether the pixels have been rendered yet."""
        return self._pixels is not None

    def __reduce__(self) -> tuple[type, tuple[float, np.ndarray, CameraInfo]]:
        return (CameraImage, (self.stamp, self.image, self.info))


class SimCamera:
    """Renders frames of a :class:`Scene` from the robot's camera."""

    def __init__(self, scene: Scene, width: int = WIDTH, height: int = HEIGHT,
                 pixel_sigma: float = PIXEL_SIGMA):
        self.scene = scene
        self.info = camera_info(width, height)
        self.pixel_sigma = pixel_sigma
        self._proj = p.computeProjectionMatrixFOV(math.degrees(CAMERA_VFOV), width / height, NEAR, FAR)
        self.half_h = math.atan((width / 2) / self.info.fx)  # [rad] horizontal half FOV
        self.half_v = CAMERA_VFOV / 2

    def eye(self, pose: Pose2) -> np.ndarray:
        """Optical centre in the world (3,) [m]."""
        x, y, z = CAMERA_POSE_XYZ
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        return np.array([pose.x + c * x - s * y, pose.y + s * x + c * y, z])

    def visible_tags(self, pose: Pose2, tags: tuple[Tag, ...] | list[Tag]) -> list[Tag]:
        """Tags that may appear in a frame taken at ``pose`` (cheap geometric test plus one ray each)."""
        if not tags:
            return []
        eye = self.eye(pose)
        c, s = math.cos(pose.theta), math.sin(pose.theta)
        cand = []
        for tag in tags:
            d = np.array([tag.x, tag.y, tag.z]) - eye
            fwd = c * d[0] + s * d[1]
            dist = float(np.linalg.norm(d))
            if fwd <= NEAR or dist > MAX_TAG_RANGE:
                continue
            if math.cos(tag.yaw) * d[0] + math.sin(tag.yaw) * d[1] >= 0.0:  # seen from behind
                continue
            margin = math.atan2(tag.quad_width / 2, fwd)
            lat = -s * d[0] + c * d[1]
            if abs(math.atan2(lat, fwd)) > self.half_h + margin or abs(math.atan2(d[2], fwd)) > self.half_v + margin:
                continue
            cand.append(tag)
        if not cand:
            return []
        ends = np.array([[t.x, t.y, t.z] for t in cand])
        starts = np.tile(eye, (len(cand), 1))
        # stop a little short of the tag so the wall it hangs on does not count as an occluder
        direction = ends - starts
        ends = starts + direction * (1.0 - 0.02 / np.linalg.norm(direction, axis=1, keepdims=True))
        frac, ids = self.scene.rays(starts, ends)
        return [t for t, f, i in zip(cand, frac, ids, strict=True) if i < 0 or f >= 1.0]

    def render(self, pose: Pose2, stamp: float, rng: np.random.Generator | None = None) -> CameraImage:
        """Render one RGB frame (H, W, 3) uint8 at the true ``pose``, with seeded pixel noise if ``rng``."""
        eye = self.eye(pose)
        fwd = np.array([math.cos(pose.theta), math.sin(pose.theta), 0.0])
        view = p.computeViewMatrix(eye.tolist(), (eye + fwd).tolist(), [0, 0, 1])
        w, h = self.info.width, self.info.height
        light = (eye - fwd * 2.0 + np.array([0.0, 0.0, 2.0])).tolist()
        out = p.getCameraImage(w, h, view, self._proj, renderer=p.ER_TINY_RENDERER,
                               flags=p.ER_NO_SEGMENTATION_MASK, lightDirection=light,
                               physicsClientId=self.scene.client, **LIGHT)
        rgb = np.asarray(out[2], dtype=np.uint8).reshape(h, w, 4)[:, :, :3].copy()
        empty = np.asarray(out[3], dtype=np.float32).reshape(h, w) >= EMPTY_DEPTH
        below = np.arange(h)[:, None] > self.info.cy
        rgb[empty & below] = FLOOR_GREY
        rgb[empty & ~below] = FAR_GREY
        if rng is not None and self.pixel_sigma > 0:
            noise = rng.standard_normal((h, w, 1), dtype=np.float32) * self.pixel_sigma
            rgb = np.clip(rgb.astype(np.float32) + noise, 0, 255).astype(np.uint8)
        return CameraImage(stamp, rgb, self.info)


def main(argv: list[str] | None = None) -> int:
    """Render what the robot's camera sees from a world's staging pose: ``python -m homing.sim.camera``."""
    import argparse

    import cv2
    from homing.sim.robot import SimRobot
    from homing.sim.world import load_world

    from homing.atomic import atomic_write

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument("world", nargs="?", default="lab", help="world name or YAML (default: lab)")
    parser.add_argument("--distance", type=float, default=1.0, help="metres out from the docked pose")
    parser.add_argument("--size", type=int, nargs=2, default=(WIDTH, HEIGHT), metavar=("W", "H"))
    parser.add_argument("--out", default="frame.png", help="PNG to write")
    args = parser.parse_args(argv)
    world = load_world(args.world)
    robot = SimRobot(world, seed=0, start=world.staging_pose(args.distance), image_size=tuple(args.size))
    frame = robot.render()
    ok, png = cv2.imencode(".png", cv2.cvtColor(frame.image, cv2.COLOR_RGB2BGR))
    atomic_write(args.out, png.tobytes())
    robot.close()
    print(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
