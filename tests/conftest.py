"""Shared fixtures: where the public test worlds are, and seeded generators."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parent.parent
SHARED_WORLDS = REPO.parent / "shared" / "worlds"


@pytest.fixture
def shared_worlds() -> Path:
    """The six public floor plans (map_server YAML + PGM) beside the repository."""
    assert SHARED_WORLDS.is_dir(), f"expected ../shared/worlds beside the repository at {SHARED_WORLDS}"
    return SHARED_WORLDS


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
