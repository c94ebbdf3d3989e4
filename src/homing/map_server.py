"""Read and write maps in the ROS map_server format (YAML + PGM).

The format (wiki.ros.org/map_server): a YAML file names an ``image``
(relative to the YAML), its ``resolution`` [m/cell], ``origin`` [x, y, yaw]
of the lower-left pixel, ``negate``, ``occupied_thresh`` and ``free_thresh``.
A pixel's occupancy probability is ``(255 − p)/255`` (``p/255`` when
negated); above ``occupied_thresh`` it is occupied, below ``free_thresh``
free, otherwise unknown. Saved maps use 0 = occupied, 254 = free,
205 = unknown, as ``map_saver`` writes them.

This lives in the root package because both the simulator (walls from a
floor plan) and mapping (saving the robot's map) read it, and ``sim`` may not
import ``mapping`` (DESIGN.md, Layout).

Grids are (H, W) int8 with row 0 at the *lowest* y (the image's bottom row),
values ``FREE`` = 0, ``OCCUPIED`` = 100, ``UNKNOWN`` = −1, like ROS's
OccupancyGrid.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from homing.atomic import atomic_write
from homing.errors import UserError
from homing.outputs import map_files
from homing.yamlfile import LocatedDict, load, where

FREE = 0
OCCUPIED = 100
UNKNOWN = -1

MAX_CELLS = 40_000_000  # largest map loaded (e.g. 6300 × 6300 cells: 315 m square at 0.05 m)
MAX_CELLS_ENV = "HOMING_MAX_MAP_CELLS"  # raises (or lowers) MAX_CELLS
BYTES_PER_CELL = 40  # [bytes] about what planning and the simulator hold per cell (costmap, distances, labels)
HEADER_BYTES = 4096  # a PGM header (with its comments) longer than this is not one

_REQUIRED = ("image", "resolution", "origin")
_KNOWN = {"image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode"}


@dataclass(frozen=True)
class MapData:
    """A map_server map: (H, W) int8 grid (row 0 = lowest y), resolution [m], origin (x, y, yaw)."""

    grid: np.ndarray
    resolution: float
    origin: tuple[float, float, float]

    @property
    def width_m(self) -> float:
        return self.grid.shape[1] * self.resolution

    @property
    def height_m(self) -> float:
        return self.grid.shape[0] * self.resolution


def max_cells() -> int:
    """The largest map (cells) homing loads: ``$HOMING_MAX_MAP_CELLS``, else :data:`MAX_CELLS`."""
    text = os.environ.get(MAX_CELLS_ENV, "").strip()
    if not text:
        return MAX_CELLS
    try:
        value = int(float(text))
    except ValueError:
        raise UserError(f"${MAX_CELLS_ENV} must be a number of cells, not '{text}'") from None
    if value < 1:
        raise UserError(f"${MAX_CELLS_ENV} must be a positive number of cells, not '{text}'")
    return value


def check_size(width: int, height: int, path: Path, line: int = 0) -> None:
    """:class:`UserError` if a ``width`` × ``height`` image is more than :func:`max_cells` cells."""
    limit = max_cells()
    if width * height > limit:
        raise UserError(
            f"the map is {width} × {height} = {width * height / 1e6:.3g} M cells, more than the {limit / 1e6:.3g} M "
            f"cells homing loads (planning needs ~{BYTES_PER_CELL} bytes a cell; raise it with {MAX_CELLS_ENV}=N)",
            path, line)


def read_pgm(path: Path) -> np.ndarray:
    """Read a binary (P5) or plain (P2) PGM into an (H, W) uint8 array, top row first, scaled to 0..255.

    The header is read first and the size checked (:func:`check_size`)
    before any pixel is, so an absurd image costs nothing.
    """
    try:
        with open(path, "rb") as f:
            head = f.read(HEADER_BYTES)
            data = _read_pgm_header(head, path)
            width, height, maxval, start, line, magic = data
            check_size(width, height, path, line)
            f.seek(start)
            body = f.read()
    except FileNotFoundError:
        raise UserError("no such image file", path) from None
    except IsADirectoryError:
        raise UserError("is a folder, not an image", path) from None
    except OSError as err:
        raise UserError(f"cannot read image: {err.strerror}", path) from None
    if magic == b"P5":
        dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
        need = width * height * dtype.itemsize
        if len(body) < need:
            raise UserError(f"PGM pixel data is short: {len(body)} of {need} bytes", path)
        img = np.frombuffer(body, dtype=dtype, count=width * height).reshape(height, width)
    else:
        try:
            values = np.array(body.split(), dtype=np.int64)
        except (ValueError, OverflowError):
            raise UserError("plain PGM pixel data is not all integers", path) from None
        if values.size < width * height:
            raise UserError(f"PGM pixel data is short: {values.size} of {width * height} values", path)
        img = np.clip(values[: width * height], 0, maxval).reshape(height, width)
    if maxval == 255 and img.dtype == np.uint8:
        return img
    # Scale to 0..255 by rounding, in integers (no float copy of a large map).
    wide = np.asarray(img, dtype=np.int64)
    return ((wide * 255 + maxval // 2) // maxval).clip(0, 255).astype(np.uint8)


def _read_pgm_header(data: bytes, path: Path) -> tuple[int, int, int, int, int, bytes]:
    """(width, height, maxval, offset of the pixels, line of the width, magic) from a PGM's first bytes."""
    magic = data[:2]
    if magic not in (b"P5", b"P2"):
        raise UserError("not a PGM image (expected 'P5' or 'P2' at the start)", path, 1, 1)
    # Header: magic, width, height, maxval, separated by whitespace, '#' comments to end of line.
    tokens: list[int] = []
    pos = 2
    line = size_line = 1
    token_re = re.compile(rb"\s+|#[^\n]*|\d+")
    while len(tokens) < 3:
        m = token_re.match(data, pos)
        if m is None or (m.end() == len(data) and len(data) == HEADER_BYTES):
            raise UserError("malformed PGM header (expected width, height and maxval)", path, line)
        text = m.group(0)
        line += text.count(b"\n")
        if text[:1].isdigit():
            tokens.append(int(text))
            size_line = line if len(tokens) == 1 else size_line
        pos = m.end()
    width, height, maxval = tokens
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise UserError(f"PGM header has bad size {width}x{height} or maxval {maxval}", path, line)
    if magic == b"P5":
        if pos >= len(data) or not data[pos : pos + 1].isspace():
            raise UserError("malformed PGM header (no whitespace before pixel data)", path, line)
        pos += 1
    return width, height, maxval, pos, size_line, magic


def _number(doc: LocatedDict, key: str, file: Path) -> float:
    value = doc[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        line, col = where(doc, key)
        raise UserError(f"'{key}' must be a number, not {value!r}", file, line, col)
    return float(value)


def load_map(path: str | Path) -> MapData:
    """Load a map_server YAML and its image; any mistake raises :class:`UserError` with file:line."""
    yaml_path = Path(path)
    doc = load(yaml_path)
    if not isinstance(doc, LocatedDict):
        raise UserError("a map file must be a YAML mapping with image, resolution and origin", yaml_path, 1, 1)
    for key in _REQUIRED:
        if key not in doc:
            raise UserError(f"missing required key '{key}'", yaml_path, *doc.loc)
    for key in doc:
        if key not in _KNOWN:
            line, col = where(doc, key, value=False)
            raise UserError(f"unknown key '{key}' in a map_server map", yaml_path, line, col)
    image = doc["image"]
    if not isinstance(image, str) or not image:
        raise UserError(f"'image' must be a file name, not {image!r}", yaml_path, *where(doc, "image"))
    resolution = _number(doc, "resolution", yaml_path)
    if resolution <= 0:
        raise UserError(f"'resolution' must be positive, not {resolution}", yaml_path, *where(doc, "resolution"))
    origin = doc["origin"]
    if (
        not isinstance(origin, list)
        or len(origin) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in origin)
    ):
        raise UserError(f"'origin' must be [x, y, yaw], not {origin!r}", yaml_path, *where(doc, "origin"))
    negate = doc.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise UserError(f"'negate' must be 0 or 1, not {negate!r}", yaml_path, *where(doc, "negate"))
    occ = _number(doc, "occupied_thresh", yaml_path) if "occupied_thresh" in doc else 0.65
    free = _number(doc, "free_thresh", yaml_path) if "free_thresh" in doc else 0.196
    if not 0.0 <= free < occ <= 1.0:
        raise UserError(
            f"thresholds must satisfy 0 <= free_thresh ({free}) < occupied_thresh ({occ}) <= 1",
            yaml_path, *where(doc, "free_thresh" if "free_thresh" in doc else "occupied_thresh"),
        )
    img_path = Path(image) if Path(image).is_absolute() else yaml_path.parent / image
    if not img_path.is_file():
        raise UserError(f"image file '{image}' not found", yaml_path, *where(doc, "image"))
    pixels = _read_image(img_path)
    # Each of the 256 grey levels maps to one cell value: a table, not a float copy of the map.
    p = np.arange(256, dtype=np.float64) / 255.0
    occupancy = p if negate else 1.0 - p
    table = np.full(256, UNKNOWN, dtype=np.int8)
    table[occupancy > occ] = OCCUPIED
    table[occupancy < free] = FREE
    grid = table[pixels[::-1]]  # row 0 = the image's bottom row
    return MapData(grid, resolution, (float(origin[0]), float(origin[1]), float(origin[2])))


def _read_image(path: Path) -> np.ndarray:
    """(H, W) uint8 grey levels of a map image: PGM by hand, anything else through OpenCV, size checked first."""
    try:
        with open(path, "rb") as f:
            head = f.read(32)
    except OSError as err:
        raise UserError(f"cannot read image: {err.strerror}", path) from None
    if path.suffix.lower() in (".pgm", ".pnm") or head[:1] == b"P":
        return read_pgm(path)
    if head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) >= 24:  # IHDR: width, height (big-endian) at bytes 16..24
        check_size(int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big"), path)
    import cv2

    decoded = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if decoded is None:
        raise UserError("cannot decode the map image", path)
    check_size(decoded.shape[1], decoded.shape[0], path)
    return np.asarray(decoded, dtype=np.uint8)


def save_map(path: str | Path, data: MapData, image_name: str | None = None) -> Path:
    """Write ``data`` as YAML + PGM next to each other, each file atomically. Returns the YAML path."""
    yaml_path, pgm_path = map_files(path)
    name = image_name or pgm_path.name
    grid = np.flipud(np.asarray(data.grid))
    pixels = np.full(grid.shape, 205, dtype=np.uint8)
    pixels[grid == FREE] = 254
    pixels[grid >= 65] = 0
    h, w = map(int, pixels.shape)
    header = f"P5\n# CREATOR: homing {data.resolution:.3f} m/pix\n{w} {h}\n255\n".encode("ascii")
    atomic_write(yaml_path.parent / name, header + pixels.tobytes())
    ox, oy, oyaw = data.origin
    text = (
        f"image: {name}\n"
        f"resolution: {data.resolution:.6f}\n"
        f"origin: [{ox:.6f}, {oy:.6f}, {oyaw:.6f}]\n"
        "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
    )
    atomic_write(yaml_path, text)
    return yaml_path
