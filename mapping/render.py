"""Pictures of a grid with its frontier segments, goal, path and robot, in the manner of the thesis's figures 2-3 to 2-6.

Drawn with OpenCV into a BGR uint8 image, north up (the grid's row 0, the
lowest y, at the bottom). Unknown is grey, free white, walls black; each
frontier segment gets its own colour, the chosen goal a filled circle, the
robot a red disc with a heading tick, the path a blue polyline.
"""

from __future__ import annotations

import colorsys

import cv2
import numpy as np
from homing.mapping.frontier import FrontierSegment

from homing.map_server import FREE, UNKNOWN

UNKNOWN_BGR = (160, 160, 160)
FREE_BGR = (255, 255, 255)
WALL_BGR = (0, 0, 0)
ROBOT_BGR = (0, 0, 230)
GOAL_BGR = (0, 170, 0)
PATH_BGR = (220, 120, 0)
BLACKLIST_BGR = (0, 0, 120)


def segment_colour(label: int) -> tuple[int, int, int]:
    """A distinct saturated BGR colour per segment label (golden-ratio hues)."""
    h = (label * 0.618033988749895) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.9, 0.85)
    return (int(b * 255), int(g * 255), int(r * 255))


def render_grid(
    grid: np.ndarray,
    segments: list[FrontierSegment] | None = None,
    goal: tuple[int, int] | None = None,
    robot: tuple[float, float, float] | None = None,
    path: np.ndarray | None = None,
    blacklist: list[tuple[int, int]] | None = None,
    scale: int = 2,
    highlight: int | None = None,
) -> np.ndarray:
    """BGR image of ``grid`` (H, W) int8 map_server view, ``scale`` pixels per cell.

    ``goal`` (row, col); ``robot`` (row, col, heading [rad]) in fractional
    cells; ``path`` (N, 2) (row, col); ``blacklist`` cells; ``highlight``:
    the label of the segment the goal came from (drawn thicker).
    """
    h, w = grid.shape
    img = np.empty((h, w, 3), np.uint8)
    img[:] = UNKNOWN_BGR
    img[grid == FREE] = FREE_BGR
    img[(grid != FREE) & (grid != UNKNOWN)] = WALL_BGR
    for seg in segments or []:
        img[seg.cells[:, 0], seg.cells[:, 1]] = segment_colour(seg.label)
    img = np.ascontiguousarray(cv2.resize(img, (w * scale, h * scale), interpolation=cv2.INTER_NEAREST)[::-1])  # row 0 = lowest y at the bottom

    def px(r: float, c: float) -> tuple[int, int]:
        return int(round((c + 0.5) * scale)), int(round((h - r - 0.5) * scale))

    if highlight is not None:
        for seg in segments or []:
            if seg.label == highlight:
                for r, c in seg.cells[:: max(1, len(seg.cells) // 200)]:
                    cv2.circle(img, px(r, c), max(2, scale), segment_colour(seg.label), -1)
    if path is not None and len(path) > 1:
        pts = np.array([px(r, c) for r, c in np.asarray(path)], np.int32)
        cv2.polylines(img, [pts], False, PATH_BGR, max(1, scale // 2))
    for r, c in blacklist or []:
        cv2.drawMarker(img, px(r, c), BLACKLIST_BGR, cv2.MARKER_TILTED_CROSS, 4 * scale, max(1, scale // 2))
    if goal is not None:
        cv2.circle(img, px(*goal), 3 * scale, GOAL_BGR, -1)
        cv2.circle(img, px(*goal), 3 * scale, (0, 0, 0), 1)
    if robot is not None:
        r, c, th = robot
        centre = px(r, c)
        cv2.circle(img, centre, 3 * scale, ROBOT_BGR, -1)
        tip = (int(centre[0] + 6 * scale * np.cos(th)), int(centre[1] - 6 * scale * np.sin(th)))
        cv2.line(img, centre, tip, ROBOT_BGR, max(1, scale // 2))
    return img
