"""Path smoothing by gradient descent between the original points and their neighbours (Nav2's ``SimpleSmoother``).

Nav2's default smoother plugin (``nav2_smoother/src/simple_smoother.cpp``,
after the smoothing of Thrun's "AI for Robotics" course): every inner point
``y_i`` moves by ``w_data·(x_i − y_i) + w_smooth·(y_{i+1} + y_{i−1} − 2·y_i)``,
``x`` the original path, the end points fixed, until the summed change of a
sweep falls under ``tolerance``; then the result is smoothed again with
itself as data, up to ``refinements`` times. A sweep that would put a point
on an inscribed or lethal cell (cost above ``MAX_NON_OBSTACLE`` and not
unknown) is undone and the smoothing stops there: the path is the last
admissible one. Paths of 10 points or fewer are left as they are, as Nav2
leaves such segments.

Each sweep updates every point from the previous sweep's neighbours (Jacobi)
where Nav2 updates in place along the path: the fixed point, and so the
converged path, is the same, and a sweep is one numpy expression. Paths are
(N, 2) float64 [m] in ``map``; do not use it on paths that reverse (homing's
planners never make one; Nav2 smooths each direction apart).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

W_DATA = 0.2  # weight pulling a point back to the original path (Nav2 default)
W_SMOOTH = 0.3  # weight pulling a point towards its neighbours' mid-point (Nav2 default)
TOLERANCE = 1e-10  # [m] summed change of a sweep under which it has converged
MAX_ITS = 1000  # sweeps before giving up (Nav2 default)
REFINEMENTS = 4  # further rounds on the smoothed path (Nav2's do_refinement)
MIN_POINTS = 11  # shorter paths are not smoothed (Nav2: segments of more than 9 steps)
MAX_NON_OBSTACLE = 252  # Nav2's highest cost that is not a collision
NO_INFORMATION = 255


def _round(path: np.ndarray, cost: Callable[[np.ndarray], np.ndarray] | None, w_data: float, w_smooth: float,
           tolerance: float, max_its: int) -> tuple[np.ndarray, bool]:  # fmt: skip
    """One smoothing round with ``path`` as data: (the converged or last admissible path, whether it converged)."""
    data = path
    current = path.copy()
    its = 0
    change = tolerance
    while change >= tolerance:
        its += 1
        if its >= max_its:
            return current, False
        new = current.copy()
        inner = current[1:-1]
        new[1:-1] = inner + w_data * (data[1:-1] - inner) + w_smooth * (current[2:] + current[:-2] - 2.0 * inner)
        change = float(np.abs(new - current).sum())
        if cost is not None:
            c = cost(new[1:-1])
            if np.any((c > MAX_NON_OBSTACLE) & (c != NO_INFORMATION)):
                return current, False
        current = new
    return current, True


def smooth_path(path: np.ndarray, cost: Callable[[np.ndarray], np.ndarray] | None = None, *,
                w_data: float = W_DATA, w_smooth: float = W_SMOOTH, tolerance: float = TOLERANCE,
                max_its: int = MAX_ITS, refinements: int = REFINEMENTS) -> tuple[np.ndarray, bool]:  # fmt: skip
    """Smooth an (N, 2) path [m]; returns (the smoothed (N, 2) path, whether the first round converged in time).

    ``cost`` maps (M, 2) points [m] to their (M,) costmap costs (Nav2's 0..255);
    without it no point is checked. A first round that does not converge
    within ``max_its`` sweeps, or would enter a costly cell, returns its last
    admissible path and False (Nav2's ``was_completed``); a refinement round
    that fails keeps its last admissible path and ends the refinement.
    """
    xy = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(xy) < MIN_POINTS:
        return xy.copy(), True
    out, done = _round(xy, cost, w_data, w_smooth, tolerance, max_its)
    if not done:
        return out, False
    for _ in range(refinements):
        out, done = _round(out, cost, w_data, w_smooth, tolerance, max_its)
        if not done:
            break
    return out, True
