"""Waiting on the wall clock in hardware tests: poll a condition until it holds or a deadline passes."""

from __future__ import annotations

import time
from collections.abc import Callable


def until(cond: Callable[[], bool], timeout: float, poll: float = 0.005) -> bool:
    """Whether ``cond()`` came true within ``timeout`` [s], checked every ``poll`` [s] (and once more at the end)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(poll)
    return cond()
