"""AprilTags (tag36h11) in the simulated world: their poses, textures and one-sided quads.

A tag is printed with a one-cell white border around its 8 × 8-cell black
square; ``size`` is the black square's edge (what pose estimation takes as
``tag_size``), so the printed quad is ``size · 10/8`` wide. The texture is
OpenCV's ``aruco`` DICT_APRILTAG_36h11 marker rotated by 180°, which is the
official AprilTag image (DESIGN.md, pybullet lessons). It is drawn on a
one-sided square mesh with UVs (``assets/tag_quad.obj``), not on a box face,
whose texture mapping the tiny renderer mirrors.

Frames: a tag stands upright on a wall at centre (x, y, z) [m] facing
``yaw`` [rad] (its outward normal, into the room). :meth:`Tag.world_from_tag`
gives its pose in the AprilTag detector's convention: x to the right and y
down as seen from the front, z into the wall.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from homing.atomic import atomic_write

TAG_FAMILY = "tag36h11"
TAG_IDS = 587  # tag36h11 has ids 0..586
TAG_SIZE = 0.16  # [m] default black-square edge
TAG_HEIGHT = 0.35  # [m] default centre height above the floor
BORDER_CELLS = 1  # white cells around the 8-cell black square
CELLS = 8 + 2 * BORDER_CELLS
TEXTURE_CELL_PX = 16  # [px] texture pixels per tag cell
WALL_OFFSET = 0.002  # [m] a tag's centre stands this far off its wall so the two never z-fight
QUAD_OBJ = Path(__file__).resolve().parent / "assets" / "tag_quad.obj"


@dataclass(frozen=True)
class Tag:
    """One AprilTag: id, centre (x, y, z) [m] in the world, facing ``yaw`` [rad], black edge ``size`` [m]."""

    id: int
    x: float
    y: float
    z: float
    yaw: float
    size: float = TAG_SIZE

    @property
    def quad_width(self) -> float:
        """Printed width including the white border [m]."""
        return self.size * CELLS / 8.0

    def world_from_quad(self) -> np.ndarray:
        """3 × 3 rotation of the quad frame (x right, y up, z out of the wall) in the world."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[-s, 0.0, c], [c, 0.0, s], [0.0, 1.0, 0.0]])

    def world_from_tag(self) -> np.ndarray:
        """4 × 4 pose of the tag in the detector's convention (x right, y down, z into the wall)."""
        q = self.world_from_quad()
        T = np.eye(4)
        T[:3, :3] = np.column_stack([q[:, 0], -q[:, 1], -q[:, 2]])
        T[:3, 3] = (self.x, self.y, self.z)
        return T

    def corners(self) -> np.ndarray:
        """(4, 3) world corners of the black square: lower-left, lower-right, upper-right, upper-left (seen from the front)."""
        q = self.world_from_quad()
        h = self.size / 2
        local = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
        return local @ q.T + np.array([self.x, self.y, self.z])


def tag_image(tag_id: int, cell_px: int = TEXTURE_CELL_PX) -> np.ndarray:
    """(CELLS·cell_px, CELLS·cell_px) uint8: the official tag36h11 image with its white border."""
    import cv2

    if not 0 <= tag_id < TAG_IDS:
        raise ValueError(f"tag36h11 ids are 0..{TAG_IDS - 1}, not {tag_id}")
    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    marker = dictionary.generateImageMarker(tag_id, 8 * cell_px, borderBits=1)
    official = np.rot90(marker, 2)  # OpenCV's aruco image is the official tag turned by 180°
    pad = BORDER_CELLS * cell_px
    return np.pad(official, pad, constant_values=255).copy()


def texture_file(tag_id: int, cache: Path | None = None) -> Path:
    """A PNG of :func:`tag_image` in a cache directory (written once, atomically)."""
    import cv2

    folder = cache or Path(tempfile.gettempdir()) / "homing-sim-tags"
    path = folder / f"{TAG_FAMILY}_{tag_id:03d}_{TEXTURE_CELL_PX}.png"
    if not path.is_file():
        rgb = cv2.cvtColor(tag_image(tag_id), cv2.COLOR_GRAY2BGR)
        ok, buf = cv2.imencode(".png", rgb)
        if not ok:
            raise RuntimeError("cannot encode a tag texture")
        atomic_write(path, buf.tobytes())
    return path


def quaternion_from_matrix(R: np.ndarray) -> tuple[float, float, float, float]:
    """(x, y, z, w) unit quaternion of a 3 × 3 rotation (pybullet's order)."""
    m = np.asarray(R, dtype=float)
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.sqrt(max(0.0, 1.0 + m[0, 0] - m[1, 1] - m[2, 2])) / 2
    y = math.sqrt(max(0.0, 1.0 - m[0, 0] + m[1, 1] - m[2, 2])) / 2
    z = math.sqrt(max(0.0, 1.0 - m[0, 0] - m[1, 1] + m[2, 2])) / 2
    x = math.copysign(x, m[2, 1] - m[1, 2])
    y = math.copysign(y, m[0, 2] - m[2, 0])
    z = math.copysign(z, m[1, 0] - m[0, 1])
    return x, y, z, w


def add_tag_bodies(client: int, tags: list[Tag] | tuple[Tag, ...]) -> list[int]:
    """Create one visual-only textured quad per tag in pybullet ``client``; returns body ids.

    The quads have no collision shape: the lidar and the robot pass through
    them (they are 2 mm off the wall anyway).
    """
    import pybullet as p

    bodies = []
    shapes: dict[float, int] = {}
    for tag in tags:
        w = tag.quad_width
        if w not in shapes:
            shapes[w] = p.createVisualShape(
                p.GEOM_MESH, fileName=str(QUAD_OBJ), meshScale=[w, w, 1.0], physicsClientId=client
            )
        pos = np.array([tag.x, tag.y, tag.z])
        body = p.createMultiBody(
            baseMass=0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=shapes[w],
            basePosition=pos.tolist(), baseOrientation=quaternion_from_matrix(tag.world_from_quad()),
            physicsClientId=client,
        )
        tex = p.loadTexture(str(texture_file(tag.id)), physicsClientId=client)
        p.changeVisualShape(body, -1, textureUniqueId=tex, rgbaColor=[1, 1, 1, 1], physicsClientId=client)
        bodies.append(body)
    return bodies
