"""Shared fixtures: where the public test worlds are, and seeded generators; Hypothesis derandomised."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from hypothesis import settings

# The property tests draw the same examples every run, so a suite that passed passes again (CI lands on
# it). To search fresh examples, as a bug hunt: HYPOTHESIS_PROFILE=explore pytest tests/test_mission_check.py
settings.register_profile("seeded", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "seeded"))

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
