"""Save and load an :class:`~homing.mapping.grid.OccupancyGrid` in the ROS map_server format (YAML + PGM), atomically.

Thin over :mod:`homing.map_server` (which writes each file through
:func:`homing.atomic.atomic_write`): a reader sees the old map or the new
one, never half of one. Saving keeps only the ternary view (free, occupied,
unknown) as map_saver does; loading sets the log-odds to their clamps.
"""

from __future__ import annotations

from pathlib import Path

from homing.mapping.grid import OccupancyGrid

from homing.map_server import load_map, save_map


def save_grid(path: str | Path, grid: OccupancyGrid) -> Path:
    """Write ``grid`` as ``path`` (.yaml) and a .pgm beside it; returns the YAML path."""
    return save_map(path, grid.to_map_data())


def load_grid(path: str | Path, grow: bool = True) -> OccupancyGrid:
    """Read a map_server map into a grid; a bad file raises :class:`homing.errors.UserError` (file:line)."""
    return OccupancyGrid.from_map_data(load_map(path), grow=grow)
