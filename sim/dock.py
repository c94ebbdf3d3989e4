"""Kobuki's docking station: its body, three IR emitters seen by three receivers, and the charging contacts.

Geometry (kobuki docs, "Automatic docking", and ``kobuki_dock_drive``): the
dock's three emitters light three regions in front of it, left, centre and
right, each split into a near and a far sub-field; regions may overlap at
their borders. A robot's receivers (right, centre, left) each report the bit
codes of the sub-fields they sit in, provided they face the dock. Left and
right are the **dock's**: standing at the dock looking out, the left region
is on your left (``kobuki_dock_drive``: a robot in the left region rotates
counter-clockwise until its *right* receiver sees the left signal, then
drives across to the centre line).

The emitter frame ``E`` sits at the middle of the dock's front face, x out
of the dock into the room, y to the dock's left. A receiver at (dx, dy) in
``E`` with range r = |(dx, dy)| and bearing φ = atan2(dy, dx) is lit when
0 < dx ≤ ``FIELD_DEPTH`` and |dy| ≤ ``FIELD_HALF_WIDTH`` (the "about
2 m × 5 m" of DESIGN.md), and nothing solid lies between; then

- NEAR (r ≤ ``NEAR_RANGE``) or FAR (beyond) sub-field;
- CENTER if |φ| ≤ ``CENTER_HALF_ANGLE`` or |dy| ≤ ``CENTER_MIN_HALF_WIDTH``;
- LEFT if φ ≥ ``SIDE_INNER_ANGLE`` and dy > 0, RIGHT if φ ≤ −``SIDE_INNER_ANGLE`` and dy < 0

(between 7° and 10° both CENTER and a side code are set). A receiver sees
the dock when the emitter lies within ``RECEIVER_HALF_FOV`` of its axis.
These numbers are this model's, chosen to match the documented picture; the
real dock's beam pattern is not published.

Contacts: the robot charges only within ``CONTACT_TOL_POS`` and
``CONTACT_TOL_YAW`` of the docked pose. The dock's guide funnels a robot
that pushes forward within ``FUNNEL_POS`` / ``FUNNEL_YAW`` of it towards the
docked pose; the body itself is a box that stops the robot.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from homing.robot.frames import wrap_angle
from homing.robot.turtlebot import BASE_RADIUS, DOCK_DEPTH, DOCK_WIDTH
from homing.robot.types import IR, DockIR, Pose2

DOCK_HEIGHT = 0.12  # [m] below the lidar: the lidar does not see the dock
FIELD_DEPTH = 2.0  # [m] IR field depth in front of the emitters
FIELD_HALF_WIDTH = 2.5  # [m] IR field half width
NEAR_RANGE = 0.8  # [m] near/far sub-field boundary
CENTER_HALF_ANGLE = math.radians(10.0)  # [rad] centre beam
CENTER_MIN_HALF_WIDTH = 0.03  # [m] centre beam's width right at the dock
SIDE_INNER_ANGLE = math.radians(7.0)  # [rad] side regions start here (overlap with the centre)
IR_HEIGHT = 0.06  # [m] emitters and receivers above the floor
# Receivers on the bumper rim: (name, bearing of position and axis in base_link [rad])
RECEIVERS = (("right", math.radians(-75.0)), ("centre", 0.0), ("left", math.radians(75.0)))
RECEIVER_RADIUS = BASE_RADIUS - 0.02  # [m] receivers sit just inside the bumper's rim
RECEIVER_HALF_FOV = {"right": math.radians(40.0), "centre": math.radians(20.0), "left": math.radians(40.0)}
CONTACT_TOL_POS = 0.005  # [m] contacts close only this close to the docked pose
CONTACT_TOL_YAW = math.radians(3.0)  # [rad]
FUNNEL_POS = 0.04  # [m] the guide captures a robot pushing in within this lateral offset…
FUNNEL_DEPTH = 0.06  # [m] …and this far from the stop
FUNNEL_YAW = math.radians(12.0)  # [rad] …and this heading error
FUNNEL_TIME = 0.15  # [s] time constant of the guide's centring


@dataclass(frozen=True)
class Dock:
    """The docking station. ``station``: pose of the middle of the dock's back on the wall face,
    x pointing out into the room. ``docked``: base_link of a robot sitting on its contacts."""

    station: Pose2

    @cached_property
    def emitter(self) -> Pose2:
        """Frame E: middle of the front face, x out of the dock."""
        return self.station.compose(Pose2(DOCK_DEPTH, 0.0, 0.0))

    @cached_property
    def _to_emitter(self) -> Pose2:
        """World → frame E."""
        return self.emitter.inverse()

    @cached_property
    def docked(self) -> Pose2:
        """The docked robot's base_link pose (facing the dock)."""
        return self.station.compose(Pose2(DOCK_DEPTH + BASE_RADIUS, 0.0, math.pi))

    def staging(self, distance: float = 1.0) -> Pose2:
        """A pose ``distance`` [m] in front of the docked pose, facing the dock."""
        return self.station.compose(Pose2(DOCK_DEPTH + BASE_RADIUS + distance, 0.0, math.pi))

    # --- IR -----------------------------------------------------------------
    def code_at(self, x: float, y: float) -> int:
        """The IR bit code lit at the world point (x, y), ignoring occlusion and receiver FOV."""
        e = self._to_emitter
        c, s = math.cos(e.theta), math.sin(e.theta)
        dx, dy = e.x + c * x - s * y, e.y + s * x + c * y  # the point in frame E
        if not (0.0 < dx <= FIELD_DEPTH and abs(dy) <= FIELD_HALF_WIDTH):
            return 0
        near = math.hypot(dx, dy) <= NEAR_RANGE
        phi = math.atan2(dy, dx)
        code = 0
        if abs(phi) <= CENTER_HALF_ANGLE or abs(dy) <= CENTER_MIN_HALF_WIDTH:
            code |= IR.NEAR_CENTER if near else IR.FAR_CENTER
        if phi >= SIDE_INNER_ANGLE and dy > 0:
            code |= IR.NEAR_LEFT if near else IR.FAR_LEFT
        if phi <= -SIDE_INNER_ANGLE and dy < 0:
            code |= IR.NEAR_RIGHT if near else IR.FAR_RIGHT
        return int(code)

    def codes_at(self, xy: np.ndarray) -> np.ndarray:
        """(N,) int IR bit codes lit at world points ``xy`` (N, 2) (:meth:`code_at` at each)."""
        pts = np.asarray(xy, dtype=float).reshape(-1, 2)
        return np.array([self.code_at(x, y) for x, y in pts.tolist()], dtype=np.int64)

    def receivers(self, pose: Pose2) -> list[tuple[str, np.ndarray, float]]:
        """(name, world xy, axis yaw) of the robot's three receivers at ``pose``."""
        return [(name, np.array(xy), axis) for name, xy, axis in self._receivers(pose)]

    def _receivers(self, pose: Pose2) -> list[tuple[str, tuple[float, float], float]]:
        out = []
        for name, bearing in RECEIVERS:
            p = pose.compose(Pose2(RECEIVER_RADIUS * math.cos(bearing), RECEIVER_RADIUS * math.sin(bearing), bearing))
            out.append((name, (p.x, p.y), p.theta))
        return out

    def ir(self, pose: Pose2, clear: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> DockIR:
        """What the receivers of a robot at ``pose`` see.

        ``clear(a, b)``: (N,) bool, whether the segments from the emitter
        points ``a`` (N, 2) to receivers ``b`` (N, 2) are unobstructed; None
        assumes they all are.
        """
        e = self.emitter
        # The receivers lie within RECEIVER_RADIUS of the centre: a centre that far outside the lit
        # box leaves every receiver dark (code_at is 0 there), so the robot sees nothing.
        centre = self._to_emitter.compose(pose)
        if (centre.x <= -RECEIVER_RADIUS or centre.x > FIELD_DEPTH + RECEIVER_RADIUS
                or abs(centre.y) > FIELD_HALF_WIDTH + RECEIVER_RADIUS):
            return DockIR()
        seen: dict[str, tuple[tuple[float, float], int]] = {}
        for name, (x, y), axis in self._receivers(pose):
            code = self.code_at(x, y)
            if code and abs(wrap_angle(math.atan2(e.y - y, e.x - x) - axis)) <= RECEIVER_HALF_FOV[name]:
                seen[name] = ((x, y), code)
        if clear is not None and seen:
            pts = np.array([xy for xy, _ in seen.values()])
            ok = np.asarray(clear(np.tile([e.x, e.y], (len(pts), 1)), pts), dtype=bool)
            seen = {name: v for (name, v), k in zip(seen.items(), ok, strict=True) if k}
        vals = {name: IR(code) for name, (_, code) in seen.items()}
        return DockIR(right=vals.get("right", IR.NONE), centre=vals.get("centre", IR.NONE),
                      left=vals.get("left", IR.NONE))

    # --- contacts and body -----------------------------------------------------
    def docked_error(self, pose: Pose2) -> tuple[float, float, float]:
        """(along, across, yaw) error of ``pose`` from the docked pose [m, m, rad]; along > 0 is too far out."""
        d = self.docked.between(pose)
        return -d.x, d.y, d.theta

    def contacts_closed(self, pose: Pose2) -> bool:
        """Whether the charging contacts touch: within a few mm and degrees of the docked pose."""
        d = self.docked
        if abs(pose.x - d.x) > CONTACT_TOL_POS or abs(pose.y - d.y) > CONTACT_TOL_POS:
            return False
        along, across, yaw = self.docked_error(pose)
        return math.hypot(along, across) <= CONTACT_TOL_POS and abs(yaw) <= CONTACT_TOL_YAW

    def funnel(self, pose: Pose2, v: float, dt: float) -> Pose2:
        """The mechanical guide: a robot pushing in (v > 0) near the docked pose is centred on it."""
        if v <= 0.0 or self.docked.distance_to(pose) > FUNNEL_DEPTH + FUNNEL_POS:
            return pose
        along, across, yaw = self.docked_error(pose)
        if not (-0.01 <= along <= FUNNEL_DEPTH and abs(across) <= FUNNEL_POS and abs(yaw) <= FUNNEL_YAW):
            return pose
        k = math.exp(-dt / FUNNEL_TIME)
        d = self.docked
        return d.compose(Pose2(-max(along, 0.0), across * k, yaw * k))

    def push_out(self, pose: Pose2, radius: float = BASE_RADIUS) -> tuple[Pose2, float | None]:
        """Resolve the robot's disc against the dock's box.

        Returns the corrected pose and the contact's bearing in base_link
        [rad] (None if no contact).
        """
        s = self.station
        e = self.emitter
        if math.hypot(pose.x - e.x, pose.y - e.y) > radius + DOCK_DEPTH + DOCK_WIDTH:
            return pose, None
        c, sn = math.cos(s.theta), math.sin(s.theta)
        rx, ry = pose.x - s.x, pose.y - s.y
        lx, ly = c * rx + sn * ry, -sn * rx + c * ry  # robot centre in the station frame
        qx = min(max(lx, 0.0), DOCK_DEPTH)  # closest point of the box
        qy = min(max(ly, -DOCK_WIDTH / 2), DOCK_WIDTH / 2)
        dx, dy = lx - qx, ly - qy
        dist = math.hypot(dx, dy)
        if dist >= radius or dist == 0.0:
            return pose, None
        mx, my = qx + dx / dist * radius, qy + dy / dist * radius
        wx, wy = s.x + c * mx - sn * my, s.y + sn * mx + c * my
        # the contact lies towards (−dx, −dy) from the robot's centre, in the station frame
        bearing = wrap_angle(math.atan2(-(sn * dx + c * dy), -(c * dx - sn * dy)) - pose.theta)
        return Pose2(wx, wy, pose.theta), bearing
