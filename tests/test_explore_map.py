"""``homing map show``: every strategy's goal and path drawn on a saved map; a user's mistake is one line, exit 2."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest
from homing.mapping.map_io import save_grid
from homing.mapping.strategies import SETBACK
from homing.missions.cli import main

from tests.test_explore import _two_openings


def test_map_show_draws_each_strategy_choice(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = save_grid(tmp_path / "partial.yaml", _two_openings())
    out = tmp_path / "map.png"
    code = main(["map", "show", str(path), "--out", str(out), "--robot", "1.0", "1.5", "0.0",
                 "--strategy", "nearest", "--strategy", "gain_rate", "--scale", "2"])
    assert code == 0
    img = cv2.imread(str(out))
    assert img is not None
    # two panels side by side, each 120 × 100 cells at 2 px plus a title band
    assert img.shape[1] >= 2 * 240 and img.shape[0] >= 200
    lines = capsys.readouterr().out.splitlines()
    goals = [ln for ln in lines if ln.strip().startswith(("nearest:", "gain_rate:"))]
    assert len(goals) == 2
    # Both goals lie at one of the room's two openings (x ≈ 0 or 4 m); gain_rate's may be a viewpoint standing
    # back from it by up to SETBACK.
    for ln in goals:
        x = float(ln.split("goal (")[1].split(",")[0])
        slack = SETBACK if ln.strip().startswith("gain_rate") else 0.0  # [m]
        assert min(abs(x), abs(x - 4.0)) < 0.4 + slack
    # The goal (green) and the robot (red) are drawn.
    assert ((img[:, :, 1] > 150) & (img[:, :, 0] < 60) & (img[:, :, 2] < 60)).any()
    assert ((img[:, :, 2] > 200) & (img[:, :, 0] < 60) & (img[:, :, 1] < 60)).any()


def test_map_show_rejects_an_unknown_strategy(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = save_grid(tmp_path / "partial.yaml", _two_openings())
    code = main(["map", "show", str(path), "--out", str(tmp_path / "x.png"), "--strategy", "gain_rat"])
    err = capsys.readouterr().err
    assert code == 2 and "unknown strategy 'gain_rat'" in err and "Traceback" not in err
    assert not (tmp_path / "x.png").exists()
