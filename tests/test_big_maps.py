"""An absurd map is refused before it is read, with the limit and how to raise it; a large one is drawn in megabytes."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from homing.errors import UserError
from homing.map_server import FREE, OCCUPIED, MapData, load_map, save_map

YAML = "image: {image}\nresolution: 0.05\norigin: [0, 0, 0]\n"


def test_a_20000_square_map_is_refused_from_its_header(tmp_path: Path) -> None:
    header = b"P5\n# 400 M cells\n20000 20000\n255\n"
    with open(tmp_path / "huge.pgm", "wb") as f:  # sparse: 400 MB on paper, nothing on disk
        f.write(header)
        f.truncate(len(header) + 20000 * 20000)
    (tmp_path / "huge.yaml").write_text(YAML.format(image="huge.pgm"))
    with pytest.raises(UserError) as info:
        load_map(tmp_path / "huge.yaml")
    message = str(info.value)
    assert message.startswith(f"{tmp_path / 'huge.pgm'}:3: the map is 20000 × 20000 = 400 M cells, more than the 40 M")
    assert "HOMING_MAX_MAP_CELLS" in message


def test_a_huge_png_is_refused_from_its_header(tmp_path: Path) -> None:
    import zlib

    ihdr = (30000).to_bytes(4, "big") * 2 + bytes([8, 0, 0, 0, 0])
    chunk = b"IHDR" + ihdr
    png = b"\x89PNG\r\n\x1a\n" + len(ihdr).to_bytes(4, "big") + chunk + zlib.crc32(chunk).to_bytes(4, "big")
    (tmp_path / "huge.png").write_bytes(png)
    (tmp_path / "huge.yaml").write_text(YAML.format(image="huge.png"))
    with pytest.raises(UserError, match=r"huge.png: the map is 30000 × 30000 = 900 M cells"):
        load_map(tmp_path / "huge.yaml")


def test_the_limit_is_configurable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    grid = np.full((30, 40), FREE, np.int8)
    path = save_map(tmp_path / "m.yaml", MapData(grid, 0.05, (0.0, 0.0, 0.0)))
    monkeypatch.setenv("HOMING_MAX_MAP_CELLS", "1000")
    with pytest.raises(UserError, match=r"40 × 30 = 0.0012 M cells, more than the 0.001 M cells"):
        load_map(path)
    monkeypatch.setenv("HOMING_MAX_MAP_CELLS", "1200")
    assert load_map(path).grid.shape == (30, 40)
    monkeypatch.setenv("HOMING_MAX_MAP_CELLS", "lots")
    with pytest.raises(UserError, match=r"HOMING_MAX_MAP_CELLS must be a number of cells, not 'lots'"):
        load_map(path)


@pytest.mark.slow
def test_world_show_on_a_5000_square_map_needs_megabytes_not_gigabytes(tmp_path: Path) -> None:
    n = 5000
    grid = np.full((n, n), FREE, np.int8)
    grid[[0, -1], :] = OCCUPIED
    grid[:, [0, -1]] = OCCUPIED
    grid[2000:2100, 1000:4000] = OCCUPIED  # a long block in the middle
    save_map(tmp_path / "big.yaml", MapData(grid, 0.05, (0.0, 0.0, 0.0)))
    del grid
    script = ("import resource, sys\nfrom homing.missions.cli import main\n"
              f"code = main(['world', 'show', {str(tmp_path / 'big.yaml')!r}, '--out', {str(tmp_path / 'big.png')!r}])\n"
              "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\nsys.exit(code)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    peak_mb = int(out.stdout.splitlines()[-1]) / 1024  # ru_maxrss is in kB on Linux
    assert peak_mb < 1024, f"peak {peak_mb:.0f} MB"
    import cv2

    img = cv2.imread(str(tmp_path / "big.png"), cv2.IMREAD_GRAYSCALE)
    assert img is not None and min(img.shape) > 400
    assert (img < 40).mean() > 0.005, "the walls are drawn"
