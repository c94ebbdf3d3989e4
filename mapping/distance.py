"""Exact Euclidean distance transform, the same bits on every run.

``distance_cells(nonzero)`` is (H, W) float32: the distance in cells from
every cell to the nearest zero of ``nonzero`` (uint8 or bool), as OpenCV's
precise L2 transform (Felzenszwalb & Huttenlocher's exact algorithm) gives
it. That transform's last bits depend on where its buffers fall in memory
(SIMD): the same input gave results 1e-7 apart between two processes (35 of
60 000 cells of a costmap), which made two runs of one seed drift apart
within two simulated minutes. The exact squared distance is an integer, so
it is rounded to that integer and its square root taken again: exactly
rounded, hence identical, on every run.

Where no cell is zero, every distance is ``inf`` (OpenCV would give large
finite numbers).
"""

from __future__ import annotations

import cv2
import numpy as np


def distance_cells(nonzero: np.ndarray) -> np.ndarray:
    """(H, W) float32: the exact distance [cells] from each cell to the nearest zero of ``nonzero``."""
    return np.sqrt(squared_distance_cells(nonzero))


def squared_distance_cells(nonzero: np.ndarray) -> np.ndarray:
    """(H, W) float32: the squared distance [cells²], a whole number, whose square root :func:`distance_cells` is
    (for a caller that wants both, as a cost looked up by squared distance: one transform, one rounding)."""
    src = np.asarray(nonzero).astype(np.uint8, copy=False)
    if src.all():
        return np.full(src.shape, np.inf, np.float32)
    d = cv2.distanceTransform(src, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.rint(d * d)
