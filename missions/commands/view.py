"""``homing view MISSION.yaml``: draw a mission's tree (kinds, names, parameters) without running it."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "view",
        help="draw a mission's static tree with each node's kind and parameters",
        description="Check a mission and draw its tree as the runner will build it.",
    )
    parser.add_argument("mission", metavar="MISSION.yaml")
    from homing.missions.commands.check import add_set_argument

    add_set_argument(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from homing.missions.commands.check import overrides
    from homing.missions.compiler import compile_mission
    from homing.missions.view import static_tree
    from rich.console import Console

    mission = compile_mission(args.mission, overrides(args))
    console = Console()
    console.print(static_tree(mission))
    console.print(mission.summary(), style="grey50", highlight=False)
    return 0
