"""Draws the floor plan of the bundled ``lab`` world, modelled on the thesis's lab (Mata 2017, §5.1).

The thesis's robot lived in a lab in MIT's Stata Center: desks, chairs,
boxes and filing cabinets, a corridor narrowed by kayaks leading to the
other side of the lab, and the dock on a wide strip of bare floor. This
module draws a 10 m × 10 m version of it at 5 cm per cell:

- outer walls 15 cm thick; a partition wall splits the lab into a west room
  (0–6 m) and an east room (6.15–10 m), joined by a 3 m gap in the north…
- …which two kayaks lying in it narrow to a ~1 m corridor;
- desks along the west and north walls, filing cabinets on the south wall,
  a table and a stack of boxes in the east room.

Run ``python -m homing.sim.labmap`` to rewrite ``worlds/lab_map.{yaml,pgm}``;
the world file ``worlds/lab.yaml`` places the dock and tags on it. Solid
furniture is drawn as walls (the lidar at 0.5 m sees desk fronts, not legs).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from homing.map_server import FREE, OCCUPIED, UNKNOWN, MapData, save_map

RESOLUTION = 0.05  # [m/cell]
ORIGIN = (-0.5, -0.5, 0.0)  # lower-left corner of the image [m, m, rad]
SIZE = 11.0  # [m] image side: the 10 m lab and a 0.5 m margin around it
WALL = 0.15  # [m] wall thickness
# Solid rectangles inside the lab (x0, y0, x1, y1) [m], in the world frame.
FURNITURE = (
    (6.0, 0.0, 6.15, 7.0),  # partition wall between the west and east rooms
    (0.0, 2.0, 0.75, 3.5),  # desks along the west wall
    (0.0, 5.0, 0.75, 6.5),
    (1.0, 9.25, 2.5, 10.0),  # desks along the north wall
    (3.0, 9.25, 4.5, 10.0),
    (4.0, 0.0, 4.9, 0.5),  # filing cabinets
    (5.0, 8.2, 7.6, 8.55),  # kayaks lying across the passage to the east room
    (5.4, 8.7, 8.0, 9.05),
    (7.6, 3.0, 9.2, 3.8),  # table in the east room
    (9.4, 1.0, 10.0, 1.6),  # boxes
)


def draw() -> MapData:
    """The lab's occupancy grid (row 0 = lowest y)."""
    n = round(SIZE / RESOLUTION)
    grid = np.full((n, n), UNKNOWN, dtype=np.int8)

    def cells(x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice]:
        c0 = round((x0 - ORIGIN[0]) / RESOLUTION)
        c1 = round((x1 - ORIGIN[0]) / RESOLUTION)
        r0 = round((y0 - ORIGIN[1]) / RESOLUTION)
        r1 = round((y1 - ORIGIN[1]) / RESOLUTION)
        return slice(r0, r1), slice(c0, c1)

    grid[cells(-WALL, -WALL, 10.0 + WALL, 10.0 + WALL)] = OCCUPIED
    grid[cells(0.0, 0.0, 10.0, 10.0)] = FREE
    for rect in FURNITURE:
        grid[cells(*rect)] = OCCUPIED
    return MapData(grid, RESOLUTION, ORIGIN)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).resolve().parent / "worlds" / "lab_map.yaml"),
                        help="map_server YAML to write (the PGM goes beside it)")
    args = parser.parse_args(argv)
    print(save_map(args.out, draw()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
