"""``homing missions [NAME]``: the bundled missions and worlds with their one-line docs; one mission's parameters."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

LINE_WIDTH = 80  # [characters] a listing line, name and doc


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "missions",
        help="list the bundled missions and worlds (NAME: one mission's parameters and tree size)",
        description="List the missions bundled with homing (run them by name: homing run NAME --world WORLD) and "
        "the worlds (--world NAME), each with its one-line doc, and the public floor plans when they are found. "
        "With NAME, show that mission's doc, file and parameters (override them with --set NAME=VALUE).",
    )
    parser.add_argument("name", nargs="?", help="a bundled mission's name (or any mission file)")
    parser.set_defaults(func=run)


def _doc(path: Path, width: int) -> str:
    """The ``doc:`` of a mission or world file, cut to ``width`` characters ('' if none)."""
    from homing.errors import UserError
    from homing.yamlfile import load

    try:
        doc = load(path)
    except UserError:
        return "(cannot be read: run 'homing check' on it)"
    text = " ".join(str(doc.get("doc", "") or "").split()) if isinstance(doc, dict) else ""
    return text if len(text) <= width else text[: width - 1] + "…"


def bundled_missions() -> dict[str, Path]:
    """Bundled missions by the name ``homing run`` takes: the package's own, then its examples."""
    from homing.missions.loader import BUNDLED

    out: dict[str, Path] = {}
    for folder in (BUNDLED, BUNDLED / "examples"):
        for path in sorted(folder.glob("*.yaml")):
            out.setdefault(path.stem, path)
    return out


def bundled_worlds() -> dict[str, Path]:
    """Bundled worlds by the name ``--world`` takes (their floor plans, ``*_map.yaml``, left out)."""
    from homing.sim.world import WORLDS_DIR

    return {p.stem: p for p in sorted(WORLDS_DIR.glob("*.yaml")) if not p.stem.endswith("_map")}


def run(args: argparse.Namespace) -> int:
    if args.name:
        return _one(args.name)
    from homing.benchmarks.common import find_plans

    missions, worlds = bundled_missions(), bundled_worlds()
    width = max(map(len, [*missions, *worlds]), default=8) + 2
    print("missions (homing run NAME --world WORLD; parameters: homing missions NAME):")
    for name, path in missions.items():
        print(f"  {name:<{width}}{_doc(path, LINE_WIDTH - 2 - width)}")
    print("\nworlds (--world NAME):")
    for name, path in worlds.items():
        print(f"  {name:<{width}}{_doc(path, LINE_WIDTH - 2 - width)}")
    plans = find_plans(quiet=True)
    if plans:
        folder = next(iter(plans.values())).parent
        print(f"\npublic floor plans (--world {folder}/NAME.yaml):")
        print("  " + ", ".join(plans))
    return 0


def _one(name: str) -> int:
    from homing.missions.compiler import compile_mission

    mission = compile_mission(name)
    source = mission.source
    print(f"{mission.name}: {' '.join(source.doc.split()) or '(no doc)'}")
    print(f"file: {source.path}")
    print(f"{len(mission.info)} nodes, services: {', '.join(s.name for s, _ in mission.services) or 'none'}, "
          f"{mission.rate:g} Hz")
    if source.params:
        print("parameters (--set NAME=VALUE):")
        for key, value in source.params.items():
            print(f"  {key} = {_value(value)}")
    else:
        print("parameters: none")
    return 0


def _value(value: Any) -> str:
    return "(required)" if value is None else str(value) if not isinstance(value, str) else value
