"""A simulated world: a floor plan, the dock, AprilTags, slippery patches, batteries, faults, start pose.

``load_world(spec)`` takes a bundled world's name (``"lab"``), a world YAML,
a bare map_server YAML, or a generated building ``KIND:SEED`` (``office:3``,
``hospital:1``, ``slam_office:2``, ``floor:1``, ``atrium:1``: :mod:`homing.sim.buildings`).
A world file (all lengths in metres, angles in radians, paths relative to the
file)::

    name: lab                      # optional, default: the file's stem
    doc: The thesis's lab …        # optional: one line for 'homing missions'
    map: lab_map.yaml              # map_server YAML (required)
    wall_height: 1.2               # optional, ≥ 1 m (taller than the lidar)
    dock: {x: 0.0, y: -4.9, yaw: 1.5708}   # the dock's back on the wall face, yaw into the room; or "auto"
    dock_tag: {id: 0, height: 0.35, size: 0.16}   # the tag on the wall above the dock
    start: docked                  # or {x: , y: , yaw: }
    tags:                          # a list, or {auto: N, size: 0.16, height: 0.35, first_id: 1}
      - {id: 1, x: 4.99, y: 0.0, z: 0.35, yaw: 3.1416, size: 0.16}
    patches:                       # low-friction floor: rectangles, slip multiplies the odometry noise variance
      - {x0: 1.0, y0: 1.0, x1: 2.0, y1: 3.0, slip: 4.0}
    battery: {base: {percent: 100}, computer: {percent: 90}}   # see homing.sim.battery
    faults: [{name: kidnap, at: 120.0, to: [0.0, 0.0, 0.0]}]   # see homing.sim.faults
    events: [{kind: box, start: 600, end: 4000, x: 3.0, y: 4.0}]   # world changes, see homing.sim.events

A bare map_server YAML becomes a world with the dock placed by
:func:`homing.sim.placement.place_dock`, the robot started docked and no tags.
Every mistake raises :class:`UserError` at ``file:line:col``.

Ground truth lives here and in :class:`homing.sim.robot.SimRobot` only:
evaluation code may read it, the robot's software may not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from homing.robot.types import Pose2
from homing.sim.battery import BASE_DEFAULT, COMPUTER_DEFAULT, BatteryParams, params_from_section
from homing.sim.buildings import KINDS, SPEC, generated
from homing.sim.dock import Dock
from homing.sim.events import Change, change_from_section
from homing.sim.faults import Fault, fault_from_section
from homing.sim.placement import main_component, place_dock, place_tags, reachable_from
from homing.sim.tags import CELLS, TAG_HEIGHT, TAG_IDS, TAG_SIZE, WALL_OFFSET, Tag
from homing.sim.walls import WALL_HEIGHT, solid_mask, world_to_cell

from homing.errors import UserError
from homing.map_server import MapData, load_map
from homing.section import Section, section_at
from homing.yamlfile import LocatedDict, load

WORLDS_DIR = Path(__file__).resolve().parent / "worlds"
_KEYS = ("name", "doc", "map", "wall_height", "dock", "dock_tag", "start", "tags", "patches", "battery", "faults",
         "events")
MIN_WALL_HEIGHT = 1.0  # [m] the lidar at 0.5 m must never graze a wall's top
WALL_REACH = 0.10  # [m] (or 1.5 cells, if more) a dock's back or a tag may stand off its wall's face


@dataclass(frozen=True)
class Patch:
    """A low-friction floor rectangle [x0, x1] × [y0, y1] [m]; ``slip`` multiplies odometry noise variance."""

    x0: float
    y0: float
    x1: float
    y1: float
    slip: float = 4.0

    def contains(self, x: float, y: float) -> bool:
        return self.x0 <= x <= self.x1 and self.y0 <= y <= self.y1


@dataclass(frozen=True)
class World:
    """Everything the simulator needs and evaluation may compare against (ground truth).

    ``dock_pose`` is the **docked robot's** base_link pose (on the contacts,
    facing the dock); ``dock.station`` is the dock itself (its back on the
    wall face, x into the room). ``tags`` include the dock's tag
    (``dock_tag_id``). ``map`` is the true floor plan as loaded.
    """

    name: str
    map: MapData
    dock: Dock
    tags: tuple[Tag, ...]
    dock_tag_id: int
    start: Pose2
    patches: tuple[Patch, ...] = ()
    battery_base: BatteryParams = BASE_DEFAULT
    battery_computer: BatteryParams = COMPUTER_DEFAULT
    faults: tuple[Fault, ...] = ()
    wall_height: float = WALL_HEIGHT
    source: Path | None = None
    events: tuple[Change, ...] = ()
    _cache: dict = field(default_factory=dict, compare=False, repr=False, init=False)

    @property
    def dock_pose(self) -> Pose2:
        """The docked robot's base_link pose in the world."""
        return self.dock.docked

    def staging_pose(self, distance: float = 1.0) -> Pose2:
        """``distance`` [m] straight out from the docked pose, facing the dock."""
        return self.dock.staging(distance)

    @property
    def solid(self) -> np.ndarray:
        """(H, W) bool: cells the simulator treats as walls (everything not free)."""
        return solid_mask(self.map)

    def reachable_free(self) -> np.ndarray:
        """(H, W) bool over ``map.grid``: free cells 4-connected to the start (exploration coverage)."""
        if "reachable" not in self._cache:
            self._cache["reachable"] = reachable_from(self.map, self.start.x, self.start.y)
        return self._cache["reachable"].copy()

    def tag(self, tag_id: int) -> Tag:
        for t in self.tags:
            if t.id == tag_id:
                return t
        raise KeyError(tag_id)

    def is_free(self, x: float, y: float) -> bool:
        """Whether the world point (x, y) [m] lies in a free cell."""
        r, c = world_to_cell(self.map, np.array([[x, y]]))
        h, w = self.map.grid.shape
        return bool(0 <= r[0] < h and 0 <= c[0] < w and not self.solid[r[0], c[0]])


def resolve(spec: str | Path) -> Path:
    """The YAML file a world spec names: a bundled world's name or a path (a generated plan has none: see
    :func:`check_spec`)."""
    text = str(spec)
    bundled = WORLDS_DIR / f"{text}.yaml"
    if "/" not in text and not text.endswith((".yaml", ".yml")) and bundled.is_file():
        return bundled
    path = Path(text)
    kind, colon, seed = text.partition(":")
    if colon and kind in KINDS and not path.exists():
        raise UserError(f"'{text}': a generated {kind}'s seed is a whole number of up to 9 digits "
                        f"({kind}:SEED, e.g. {kind}:1), not '{seed}'")
    if not path.exists():
        names = sorted(p.stem for p in WORLDS_DIR.glob("*.yaml") if not p.stem.endswith("_map"))
        raise UserError(f"no world named '{text}' (bundled: {', '.join(names)}; generated: "
                        f"{', '.join(k + ':SEED' for k in KINDS)}) and no such file")
    return path


def check_spec(spec: str | Path) -> None:
    """Raise :class:`UserError` unless ``spec`` names a world: bundled, a file, or a generated plan (``office:3``)."""
    if SPEC.match(str(spec)) is None:
        resolve(spec)


def load_world(spec: str | Path) -> World:
    """Load a world by bundled name, world YAML path, bare map_server YAML path, or generated plan ``KIND:SEED``
    (:mod:`homing.sim.buildings`: the dock placed as on a bare map)."""
    made = generated(str(spec))
    if made is not None:
        name, data = made
        return _from_map_data(name, data, None)
    path = resolve(spec)
    doc = load(path)
    if not isinstance(doc, LocatedDict):
        raise UserError("a world file must be a YAML mapping", path, 1, 1)
    if "image" in doc and "map" not in doc:
        return _from_bare_map(path)
    return _from_world_file(path, doc)


def _from_bare_map(path: Path) -> World:
    return _from_map_data(path.stem, load_map(path), path)


def _from_map_data(name: str, data: MapData, path: Path | None) -> World:
    try:
        station = place_dock(data)
    except ValueError as err:
        raise UserError(f"cannot place a dock: {err}", path) from None
    dock = Dock(station)
    tag = _dock_tag(dock, 0, TAG_HEIGHT, TAG_SIZE)
    return World(name, data, dock, (tag,), 0, dock.docked, source=path)


def _dock_tag(dock: Dock, tag_id: int, height: float, size: float) -> Tag:
    s = dock.station.compose(Pose2(WALL_OFFSET, 0.0, 0.0))
    return Tag(tag_id, s.x, s.y, height, s.theta, size)


def _pose(sec: Section) -> Pose2:
    sec.only(("x", "y", "yaw"))
    return Pose2(sec.number("x"), sec.number("y"), sec.number("yaw", 0.0))


def _from_world_file(path: Path, doc: LocatedDict) -> World:
    top = Section(doc, path, "a world file")
    top.only(_KEYS)
    name = top.string("name", path.stem)
    map_ref = top.string("map")
    map_path = Path(map_ref) if Path(map_ref).is_absolute() else path.parent / map_ref
    if not map_path.is_file():
        raise top.error("map", f"map file '{map_ref}' not found (paths are relative to the world file)")
    data = load_map(map_path)
    wall_height = top.number("wall_height", WALL_HEIGHT, lo=MIN_WALL_HEIGHT)

    # Dock: explicit pose or auto-placed.
    if top.has("dock") and top.raw("dock") != "auto":
        dsec = top.section("dock")
        station = _pose(dsec)
        if not _on_floor(data, station.compose(Pose2(0.3, 0.0, 0.0))) or not _against_wall(data, station):
            raise top.error("dock", f"the dock at ({station.x:g}, {station.y:g}) must stand on free floor with its "
                            f"back against a wall (within {_reach(data):g} m), facing into the room")
    else:
        try:
            station = place_dock(data)
        except ValueError as err:
            raise top.error("dock", f"cannot place a dock: {err}") from None
    dock = Dock(station)

    tag_id, tag_height, tag_size = 0, TAG_HEIGHT, TAG_SIZE
    if top.has("dock_tag"):
        ts = top.section("dock_tag")
        ts.only(("id", "height", "size"))
        tag_id = ts.integer("id", 0, lo=0, hi=TAG_IDS - 1)
        tag_height = ts.number("height", TAG_HEIGHT, lo=0.0, hi=wall_height)
        tag_size = ts.number("size", TAG_SIZE, positive=True, hi=1.0)
    tags = [_dock_tag(dock, tag_id, tag_height, tag_size)]
    if top.has("tags"):
        tags += _tags(top, data, dock, tag_id, wall_height)

    start = dock.docked
    if top.has("start") and top.raw("start") != "docked":
        start = _pose(top.section("start"))
        if not _on_floor(data, start):
            raise top.error("start", f"start ({start.x:.2f}, {start.y:.2f}) is not on free floor")

    patches = []
    if top.has("patches"):
        for item, loc in top.items("patches"):
            ps = section_at(item, loc, path, "a patch")
            ps.only(("x0", "y0", "x1", "y1", "slip"))
            x0, y0, x1, y1 = (ps.number(k) for k in ("x0", "y0", "x1", "y1"))
            if x1 <= x0 or y1 <= y0:
                raise UserError("a patch needs x0 < x1 and y0 < y1", path, *loc)
            patches.append(Patch(x0, y0, x1, y1, ps.number("slip", 4.0, lo=1.0)))

    base, computer = BASE_DEFAULT, COMPUTER_DEFAULT
    if top.has("battery"):
        bs = top.section("battery")
        bs.only(("base", "computer"))
        if bs.has("base"):
            base = params_from_section(bs.section("base"), BASE_DEFAULT)
        if bs.has("computer"):
            computer = params_from_section(bs.section("computer"), COMPUTER_DEFAULT)

    faults = []
    if top.has("faults"):
        for item, loc in top.items("faults"):
            faults.append(fault_from_section(section_at(item, loc, path, "a fault")))

    events = []
    if top.has("events"):
        for item, loc in top.items("events"):
            events.append(change_from_section(section_at(item, loc, path, "a world change")))

    return World(name, data, dock, tuple(tags), tag_id, start, tuple(patches), base, computer,
                 tuple(faults), wall_height, path, tuple(events))


def _on_floor(data: MapData, pose: Pose2) -> bool:
    r, c = world_to_cell(data, np.array([[pose.x, pose.y]]))
    h, w = data.grid.shape
    return bool(0 <= r[0] < h and 0 <= c[0] < w and not solid_mask(data)[r[0], c[0]])


def _reach(data: MapData) -> float:
    return max(WALL_REACH, 1.5 * data.resolution)


def _against_wall(data: MapData, pose: Pose2) -> bool:
    """Whether a wall is right behind ``pose`` (within :func:`_reach`) and free floor right in front of it."""
    step = data.resolution / 2
    behind = [pose.compose(Pose2(-d, 0.0, 0.0)) for d in np.arange(step / 2, _reach(data) + 1e-9, step)]
    front = pose.compose(Pose2(step, 0.0, 0.0))
    return any(not _on_floor(data, q) for q in behind) and _on_floor(data, front)


def _tags(top: Section, data: MapData, dock: Dock, dock_tag_id: int, wall_height: float) -> list[Tag]:
    value = top.raw("tags")
    path = top.file
    if isinstance(value, dict):
        auto = top.section("tags")
        auto.only(("auto", "size", "height", "first_id"))
        n = auto.integer("auto", lo=0, hi=TAG_IDS - 1)
        size = auto.number("size", TAG_SIZE, positive=True, hi=1.0)
        height = auto.number("height", TAG_HEIGHT, lo=0.0, hi=wall_height)
        first = auto.integer("first_id", 1 if dock_tag_id == 0 else 0, lo=0, hi=TAG_IDS - 1)
        ids = [i for i in range(first, TAG_IDS) if i != dock_tag_id][:n]
        if len(ids) < n:
            raise auto.error("auto", f"not enough tag36h11 ids from {first} for {n} tags")
        region = main_component(~solid_mask(data))
        spots = place_tags(data, n, size * CELLS / 8.0, dock.station, region)
        out = []
        for tid, spot in zip(ids, spots, strict=False):
            p = spot.compose(Pose2(WALL_OFFSET, 0.0, 0.0))
            out.append(Tag(tid, p.x, p.y, height, p.theta, size))
        return out
    seen = {dock_tag_id}
    out = []
    for item, loc in top.items("tags"):
        ts = section_at(item, loc, path, "a tag")
        ts.only(("id", "x", "y", "z", "yaw", "size"))
        tid = ts.integer("id", lo=0, hi=TAG_IDS - 1)
        if tid in seen:
            raise ts.error("id", f"tag id {tid} is used twice (ids are unique; the dock's tag is {dock_tag_id})")
        seen.add(tid)
        out.append(Tag(tid, ts.number("x"), ts.number("y"), ts.number("z", TAG_HEIGHT, lo=0.0, hi=wall_height),
                       ts.number("yaw"), ts.number("size", TAG_SIZE, positive=True, hi=1.0)))
        tag = out[-1]
        if not math.isfinite(tag.yaw):
            raise ts.error("yaw", "yaw must be finite")
        if not _against_wall(data, Pose2(tag.x, tag.y, tag.yaw)):
            raise UserError(f"tag {tid} at ({tag.x:g}, {tag.y:g}) must hang on a wall (within {_reach(data):g} m of "
                            "its face) and face free floor (yaw points into the room)", path, *loc)
    return out
