"""The pybullet scene of a world: walls, floor, dock, tags, the robot's body and fault obstacles.

One ``pybullet.DIRECT`` client per :class:`Scene` (so several simulations can
live in one process and never see each other). The robot is a kinematic
cylinder (mass > 0 so Bullet computes its contacts; no gravity, never
stepped): :mod:`homing.sim.robot` sets its pose and reads its penetrations
with ``getClosestPoints``. Walls are one static triangle mesh
(:mod:`homing.sim.walls`; a few, for a map larger than one Bullet mesh
holds); tags are visual-only quads; the dock's collision is analytic
(:meth:`homing.sim.dock.Dock.push_out`), its body here only drawn.

Only :mod:`homing.sim` imports pybullet (DESIGN.md, rules of the house).
"""

from __future__ import annotations

import math
import operator

import numpy as np
from homing.robot.turtlebot import BASE_RADIUS
from homing.robot.types import Pose2
from homing.sim.dock import DOCK_DEPTH, DOCK_HEIGHT, DOCK_WIDTH
from homing.sim.quiet import import_pybullet
from homing.sim.tags import add_tag_bodies
from homing.sim.walls import build_mesh
from homing.sim.world import World

p = import_pybullet()

ROBOT_HEIGHT = 0.10  # [m] collision cylinder (the bumper ring)
ROBOT_Z = 0.06  # [m] its centre above the floor
BUMP_DEPTH = 0.0003  # [m] shallower penetrations are numerical, not a bump
OBSTACLE_SIZE = 0.30  # [m] fault obstacles: boxes this wide…
OBSTACLE_HEIGHT = 0.70  # [m] …and this tall (the lidar at 0.5 m sees them)
WALL_RGBA = (0.85, 0.83, 0.78, 1.0)
DOCK_RGBA = (0.15, 0.15, 0.15, 1.0)
OBSTACLE_RGBA = (0.9, 0.45, 0.1, 1.0)
_BODY, _FRACTION = operator.itemgetter(0), operator.itemgetter(2)  # of a rayTestBatch result


def _quat_yaw(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


class Scene:
    """A world's bodies in their own pybullet client."""

    def __init__(self, world: World, visuals: bool = True):
        self.world = world
        self.client = p.connect(p.DIRECT)
        c = self.client
        p.setGravity(0, 0, 0, physicsClientId=c)
        mesh = build_mesh(world.map, world.wall_height)
        self.n_wall_triangles = len(mesh.indices) // 3
        bodies = []
        for piece in mesh.pieces():
            verts = piece.vertices.tolist()
            idx = piece.indices.tolist()
            col = p.createCollisionShape(p.GEOM_MESH, vertices=verts, indices=idx, physicsClientId=c)
            vis = -1
            if visuals:
                vis = p.createVisualShape(p.GEOM_MESH, vertices=verts, indices=idx, normals=piece.normals.tolist(),
                                          rgbaColor=WALL_RGBA, physicsClientId=c)
            bodies.append(p.createMultiBody(0, col, vis, physicsClientId=c))
        self.wall_bodies = tuple(bodies)  # the walls' bodies: one, unless the map is larger than a mesh holds
        self.walls = bodies[0]
        rob = p.createCollisionShape(p.GEOM_CYLINDER, radius=BASE_RADIUS, height=ROBOT_HEIGHT, physicsClientId=c)
        self.robot = p.createMultiBody(1.0, rob, -1, [0, 0, ROBOT_Z], physicsClientId=c)
        self.tag_bodies: list[int] = []
        if visuals:  # no floor body: the camera paints it (homing.sim.camera), 5 ms cheaper a frame
            self._add_dock()
            self.tag_bodies = add_tag_bodies(c, world.tags)
        self.obstacles: dict[str, int] = {}
        # Bullet keeps a shape when its body is removed (and will not remove one it thinks in use), so boxes of
        # one size share one collision and one visual shape: a long run's faults and changes make no new ones.
        self._box_shapes: dict[tuple[float, float], tuple[int, int]] = {}

    # --- static decoration ---------------------------------------------------------
    def _add_dock(self) -> None:
        s = self.world.dock.station
        centre = s.compose(Pose2(DOCK_DEPTH / 2, 0.0, 0.0))
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[DOCK_DEPTH / 2, DOCK_WIDTH / 2, DOCK_HEIGHT / 2],
                                  rgbaColor=DOCK_RGBA, physicsClientId=self.client)
        p.createMultiBody(0, -1, vis, [centre.x, centre.y, DOCK_HEIGHT / 2], _quat_yaw(s.theta),
                          physicsClientId=self.client)

    # --- obstacles (faults) ----------------------------------------------------------
    def add_obstacle(self, key: str, x: float, y: float, yaw: float = 0.0,
                     size: tuple[float, float] = (OBSTACLE_SIZE, OBSTACLE_SIZE)) -> None:
        """A lidar-visible box of ``size`` (sx, sy) [m] (faults, world changes); replaces any under ``key``."""
        self.remove_obstacle(key)
        shapes = self._box_shapes.get((size[0], size[1]))
        if shapes is None:
            half = [size[0] / 2, size[1] / 2, OBSTACLE_HEIGHT / 2]
            shapes = (p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=self.client),
                      p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=OBSTACLE_RGBA,
                                          physicsClientId=self.client))
            self._box_shapes[(size[0], size[1])] = shapes
        col, vis = shapes
        self.obstacles[key] = p.createMultiBody(0, col, vis, [x, y, OBSTACLE_HEIGHT / 2], _quat_yaw(yaw),
                                                physicsClientId=self.client)

    def move_obstacle(self, key: str, x: float, y: float, yaw: float = 0.0) -> None:
        p.resetBasePositionAndOrientation(self.obstacles[key], [x, y, OBSTACLE_HEIGHT / 2], _quat_yaw(yaw),
                                          physicsClientId=self.client)

    def remove_obstacle(self, key: str) -> None:
        body = self.obstacles.pop(key, None)
        if body is not None:
            p.removeBody(body, physicsClientId=self.client)

    # --- queries ------------------------------------------------------------------------
    def penetrations(self, pose: Pose2) -> list[tuple[np.ndarray, float, float, int]]:
        """Penetrations of the robot's cylinder at ``pose``: (push xy unit vector, depth [m], bearing [rad], body).

        ``bearing`` is the contact's direction in base_link; push the robot by
        ``depth`` along the vector to resolve it. The geometry is taken from
        the contact point on the other body (Bullet's normals against a
        triangle mesh's diagonal edges are sometimes wrong; its points are not).
        """
        c = self.client
        p.resetBasePositionAndOrientation(self.robot, [pose.x, pose.y, ROBOT_Z], _quat_yaw(pose.theta),
                                          physicsClientId=c)
        out = []
        for body in (*self.wall_bodies, *self.obstacles.values()):
            for pt in p.getClosestPoints(self.robot, body, 0.0, physicsClientId=c):
                if pt[8] >= 0.0:
                    continue
                d = np.array([pose.x - pt[6][0], pose.y - pt[6][1]])  # from the contact towards the centre
                dist = float(np.hypot(*d))
                if dist > 1e-6:
                    n, depth = d / dist, BASE_RADIUS - dist
                else:
                    n, depth = np.array(pt[7][:2], dtype=float), -pt[8]
                if depth <= 0.0:
                    continue
                bearing = math.atan2(-n[1], -n[0]) - pose.theta
                out.append((n, depth, math.atan2(math.sin(bearing), math.cos(bearing)), body))
        return out

    def rays(self, starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Cast rays (N, 3) → (N, 3); returns hit fraction (N,) (1 = no hit) and hit body ids (N,)."""
        res = p.rayTestBatch(starts, ends, numThreads=1, physicsClientId=self.client)
        ids = np.fromiter(map(_BODY, res), dtype=np.int64, count=len(res))
        frac = np.fromiter(map(_FRACTION, res), dtype=float, count=len(res))
        return np.where(ids >= 0, frac, 1.0), ids

    def close(self) -> None:
        if self.client is not None and p.isConnected(self.client):
            p.disconnect(self.client)
        self.client = None  # type: ignore[assignment]
