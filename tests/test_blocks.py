"""block_any against numpy's reduction over the blocks of a padded mask, on masks of every shape and block size used."""

from __future__ import annotations

import numpy as np
import pytest
from homing.mapping.blocks import block_any


@pytest.mark.parametrize("f", [1, 2, 3, 4, 5, 8, 32])
def test_block_any_is_the_padded_masks_reduction_over_each_block(f: int) -> None:
    rng = np.random.default_rng(f)
    for h, w in ((1, 1), (7, 9), (64, 96), (65, 97), (130, 33)):
        for density in (0.0, 0.002, 0.05, 0.5):
            mask = rng.random((h, w)) < density
            hc, wc = -(-h // f), -(-w // f)
            padded = np.zeros((hc * f, wc * f), bool)
            padded[:h, :w] = mask
            want = padded.reshape(hc, f, wc, f).any(axis=(1, 3))
            got = block_any(mask, f)
            assert got.dtype == bool and got.shape == (hc, wc)
            assert np.array_equal(got, want)
    assert not np.shares_memory(block_any(mask, 1), mask)  # a new array, never a view of the caller's
