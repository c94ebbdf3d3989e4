"""Block reductions of a grid: which f × f blocks of a mask hold a set cell (a coarse grid's open cells, a tile's change).

``block_any(mask, f)`` is ``mask.reshape(H/f, f, W/f, f).any(axis=(1, 3))``
(padded with False to whole blocks), the same booleans without numpy's
reduction over two strided axes, which on a floor of a few hundred thousand
cells costs milliseconds: the f rows of each block are OR-ed as whole rows,
then each block's f bytes of the result are read as one integer (f = 2, 4,
8) or reduced along one contiguous axis.
"""

from __future__ import annotations

import numpy as np

_WORDS = {2: np.uint16, 4: np.uint32, 8: np.uint64}  # f bytes (a block's row of bools) read as one integer


def block_any(mask: np.ndarray, f: int) -> np.ndarray:
    """(ceil(H/f), ceil(W/f)) bool: whether any cell of each f × f block of ``mask`` (H, W) bool is set; the blocks
    start at cell (0, 0), and those past the last row or column count the missing cells as unset."""
    mask = np.asarray(mask, dtype=bool)
    h, w = mask.shape
    if f <= 1:
        return mask.copy()
    hc, wc = -(-h // f), -(-w // f)
    rows = np.zeros((hc, wc * f), bool)  # each block row's f rows OR-ed, padded to whole blocks
    whole = h // f
    stacked = mask[:whole * f].reshape(whole, f, w)
    out = rows[:whole, :w]
    np.copyto(out, stacked[:, 0])
    for k in range(1, f):
        out |= stacked[:, k]
    if h % f:
        rows[whole, :w] = mask[whole * f:].any(axis=0)
    blocks = rows.reshape(hc, wc, f)
    word = _WORDS.get(f)
    if word is not None:
        return np.asarray(blocks.view(word)[..., 0] != 0)
    return np.asarray(blocks.any(axis=2))
