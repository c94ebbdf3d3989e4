"""``homing export MISSION.yaml --xml [-o TREE.xml]``: a mission as BehaviorTree.CPP v4 XML that Groot2 opens."""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "export",
        help="write a mission as BehaviorTree.CPP v4 XML with a TreeNodesModel (opens in Groot2)",
        description="Check a mission and write it as BehaviorTree.CPP v4 XML: subtrees as <BehaviorTree>s, homing's "
        "nodes declared in a TreeNodesModel, control nodes under their BT.CPP / Nav2 names where they mean the "
        "same. 'homing import' reads the file back into the same mission.",
    )
    parser.add_argument("mission", metavar="MISSION.yaml")
    parser.add_argument("--xml", action="store_true", required=True, help="BehaviorTree.CPP v4 XML (the one format)")
    parser.add_argument("-o", "--output", metavar="TREE.xml", help="write the XML here (default: stdout)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from homing.btxml.exporter import export_xml
    from homing.missions.loader import resolve_mission

    from homing.atomic import atomic_write
    from homing.errors import UserError

    if args.output and Path(args.output).is_dir():
        raise UserError("is a directory: give the XML file to write", args.output)
    text = export_xml(resolve_mission(args.mission))
    if not args.output:
        sys.stdout.write(text)
        return 0
    try:
        atomic_write(args.output, text)
    except OSError as err:
        raise UserError(f"cannot write: {err.strerror}", args.output) from None
    print(f"wrote {args.output}")
    return 0
