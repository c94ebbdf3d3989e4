"""map_server maps load with their geometry, round-trip, and fail with file:line on bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from homing.errors import UserError
from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData, load_map, save_map

WORLDS = ["room", "corner", "corridor", "loop", "loop_with_corridor", "room_with_corner"]


@pytest.mark.parametrize("name", WORLDS)
def test_shared_worlds_load(shared_worlds: Path, name: str) -> None:
    m = load_map(shared_worlds / f"{name}.yaml")
    assert m.grid.shape == (250, 250)
    assert m.resolution == pytest.approx(0.1)
    assert m.origin == (-12.5, -12.5, 0.0)
    values = set(np.unique(m.grid).tolist())
    assert values <= {FREE, OCCUPIED, UNKNOWN} and OCCUPIED in values and FREE in values


def test_row_zero_is_the_bottom_of_the_image(tmp_path: Path) -> None:
    # A 3 x 2 image whose top row is black (occupied): that row has the largest y.
    (tmp_path / "m.pgm").write_bytes(b"P5\n2 3\n255\n" + bytes([0, 0, 254, 254, 254, 254]))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [1.0, 2.0, 0.0]\n")
    m = load_map(tmp_path / "m.yaml")
    assert m.grid[2].tolist() == [OCCUPIED, OCCUPIED]
    assert m.grid[0].tolist() == [FREE, FREE]


def test_save_then_load_round_trips(tmp_path: Path, rng: np.random.Generator) -> None:
    grid = rng.choice(np.array([FREE, OCCUPIED, UNKNOWN], dtype=np.int8), size=(40, 30))
    path = save_map(tmp_path / "out.yaml", MapData(grid, 0.05, (-1.0, 2.5, 0.0)))
    back = load_map(path)
    assert np.array_equal(back.grid, grid)
    assert back.resolution == pytest.approx(0.05) and back.origin == (-1.0, 2.5, 0.0)


def test_plain_pgm_with_comments(tmp_path: Path) -> None:
    (tmp_path / "p.pgm").write_text("P2\n# a comment\n2 1\n# another\n15\n0 15\n")
    (tmp_path / "p.yaml").write_text("image: p.pgm\nresolution: 1\norigin: [0, 0, 0]\n")
    assert load_map(tmp_path / "p.yaml").grid.tolist() == [[OCCUPIED, FREE]]


@pytest.mark.parametrize(
    ("yaml_text", "image", "expect"),
    [
        ("image: missing.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", None, "m.yaml:1:8: image file"),
        ("image: m.pgm\nresolution: fine\norigin: [0, 0, 0]\n", b"P5\n1 1\n255\n\xfe", "m.yaml:2:13: 'resolution' must be a number"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0]\n", b"P5\n1 1\n255\n\xfe", "m.yaml:3:9: 'origin'"),
        ("image: m.pgm\nresolution: 0.1\n", b"P5\n1 1\n255\n\xfe", "missing required key 'origin'"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", b"GIF89a", "m.pgm:1:1: not a PGM"),
        ("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n", b"P5\n4 4\n255\n\x00", "pixel data is short"),
        ("image: m.pgm\nresolution: [0.1\n", None, "m.yaml:2:13: invalid YAML: this '[' is never closed"),
    ],
)
def test_bad_maps_name_the_file_and_line(tmp_path: Path, yaml_text: str, image: bytes | None, expect: str) -> None:
    (tmp_path / "m.yaml").write_text(yaml_text)
    if image is not None:
        (tmp_path / "m.pgm").write_bytes(image)
    with pytest.raises(UserError) as info:
        load_map(tmp_path / "m.yaml")
    assert expect in str(info.value)
    assert "\n" not in str(info.value)
