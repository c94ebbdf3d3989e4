"""``homing check MISSION.yaml...``: load and check missions, listing every error as file:line:col."""

from __future__ import annotations

import argparse
import sys


def add_set_argument(parser: argparse.ArgumentParser) -> None:
    """``--set NAME=VALUE`` (repeatable): override a mission parameter; VALUE is read as YAML."""
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="NAME=VALUE",
        help="override a mission parameter (repeatable); VALUE is a YAML scalar, e.g. --set low_battery=15",
    )  # fmt: skip


def overrides(args: argparse.Namespace) -> dict[str, object]:
    """The ``--set`` pairs as a dict; a malformed one is a user error."""
    from homing.errors import UserError
    from homing.yamlfile import loads

    out: dict[str, object] = {}
    for item in args.overrides:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise UserError(f"--set needs NAME=VALUE, not '{item}'")
        out[name.strip()] = loads(value, f"--set {name}")
    return out


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "check",
        help="check missions: every error as file:line:col: message (exit 2), or a one-line summary",
        description="Load, check and compile mission files without running them. Lists every error "
        "(unknown nodes and parameters, wrong types and units, missing parameters, unknown subtrees, "
        "includes and services, include cycles, blackboard keys nobody writes, duplicate names).",
    )
    parser.add_argument("missions", nargs="+", metavar="MISSION.yaml")
    add_set_argument(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from homing.missions.compiler import compile_mission

    from homing.errors import EXIT_USAGE, UserError

    status = 0
    for path in args.missions:
        try:
            mission = compile_mission(path, overrides(args))
        except UserError as err:
            print(str(err), file=sys.stderr)
            status = EXIT_USAGE
            continue
        for warning in mission.warnings:
            print(f"warning: {warning}", file=sys.stderr)
        print(mission.summary())
    return status
