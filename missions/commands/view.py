"""``homing view MISSION.yaml``: draw a mission's tree (kinds, names, parameters) without running it."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "view",
        help="draw a mission's static tree with each node's kind and parameters",
        description="Check a mission and draw its tree as the runner will build it.",
    )
    parser.add_argument("mission", metavar="MISSION.yaml", nargs="?")
    parser.add_argument(
        "--attach", metavar="HOST:PORT",
        help="follow a run started with --serve instead (live, from another terminal or machine)",
    )  # fmt: skip
    from homing.missions.commands.check import add_set_argument

    add_set_argument(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.attach:
        return follow(args)
    from homing.errors import UserError

    if not args.mission:
        raise UserError("homing view needs MISSION.yaml (or --attach HOST:PORT)")
    from homing.missions.commands.check import overrides
    from homing.missions.compiler import compile_mission
    from homing.missions.view import static_tree
    from rich.console import Console

    mission = compile_mission(args.mission, overrides(args))
    console = Console()
    console.print(static_tree(mission))
    console.print(mission.summary(), style="grey50", highlight=False)
    return 0


def follow(args: argparse.Namespace) -> int:
    """``--attach HOST:PORT``: draw a serving run's live view until it ends."""
    import shutil
    import sys

    from homing.missions.remote import attach, parse_address

    from homing.errors import UserError

    if args.mission:
        raise UserError("homing view: give MISSION.yaml or --attach HOST:PORT, not both")
    try:
        host, port = parse_address(args.attach)
    except ValueError as err:
        raise UserError(f"--attach: {err}") from None
    size = shutil.get_terminal_size((80, 24))
    attach(host, port, sys.stdout, (size.columns, size.lines))
    return 0
