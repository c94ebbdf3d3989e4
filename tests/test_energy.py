"""The energy policy: thresholds, the measured drain, the reserve for the way home."""

from __future__ import annotations

import math

import pytest
from homing.lifecycle.energy import MIN_DRAIN, Drain, Thresholds, charged, must_go_home, reserve


def test_thresholds_refuse_what_makes_no_sense() -> None:
    Thresholds(90.0, 20.0)
    for undock, home in [(90.0, 95.0), (90.0, 90.0), (120.0, 20.0), (90.0, -5.0), (math.nan, 20.0)]:
        with pytest.raises(ValueError):
            Thresholds(undock, home)


def test_drain_is_the_slope_of_the_readings_and_never_below_the_prior() -> None:
    d = Drain(window=300.0, floor=0.001)
    assert d.rate == 0.001  # nothing measured yet: the prior
    for k in range(61):
        d.add(10.0 * k, 80.0 - 0.02 * 10.0 * k, on_dock=False)  # 0.02 %/s
    assert d.rate == pytest.approx(0.02, rel=1e-9)
    assert d.samples[0][0] >= 600.0 - 300.0 - 10.0  # the window slides
    d.add(700.0, 70.0, on_dock=True)  # docked: a new window
    assert len(d.samples) == 0 and d.rate == 0.001
    rising = Drain(floor=0.003)
    for k in range(30):
        rising.add(float(k), 50.0 + k, on_dock=False)  # charging off the dock cannot happen; clamp to the prior
    assert rising.rate == 0.003


def test_reserve_grows_with_the_way_home() -> None:
    near = reserve(MIN_DRAIN, 2.0, speed=0.25, docking=180.0, margin=1.5)
    far = reserve(MIN_DRAIN, 30.0, speed=0.25, docking=180.0, margin=1.5)
    assert near == pytest.approx(1.5 * MIN_DRAIN * (8.0 + 180.0))
    assert far - near == pytest.approx(1.5 * MIN_DRAIN * 28.0 / 0.25)
    with pytest.raises(ValueError):
        reserve(MIN_DRAIN, math.inf)


def test_go_home_and_leave_levels() -> None:
    t = Thresholds(90.0, 20.0)
    assert must_go_home(23.0, t, reserve_pct=3.5) and not must_go_home(24.0, t, reserve_pct=3.5)
    assert charged(90.0, t) and not charged(89.9, t) and charged(50.0, t, full=True)
