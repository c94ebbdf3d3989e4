"""``homing import TREE.xml [-o MISSION.yaml]``: a BehaviorTree.CPP v3/v4 or Nav2 tree as a homing mission."""

from __future__ import annotations

import argparse
import sys

from homing.missions.commands._args import output_folder


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "import",
        help="convert a BehaviorTree.CPP / Nav2 XML tree into a mission (every node mapped, or an error naming it)",
        description="Read BehaviorTree.CPP v3 or v4 XML (Nav2's navigators, Groot2 files) and write the equivalent "
        "homing mission: control nodes and decorators with their semantics (memory, retry counts, milliseconds "
        "as seconds), <SubTree> as subtrees with their port remapping, {key} as blackboard ports, Nav2's leaves "
        "as homing's. A node with no equivalent is a file:line:col error; attributes homing does not use are "
        "listed as notes in the mission's header.",
    )
    parser.add_argument("tree", metavar="TREE.xml", help="the file to import; its <include path> files are read too, "
                        "relative to the including file as BehaviorTree.CPP does")
    parser.add_argument("-o", "--output", metavar="MISSION.yaml", help="write the mission here (default: stdout)")
    parser.add_argument("--tree", metavar="ID", dest="main_tree", help="the main tree, for a file of several trees without "
                        "main_tree_to_execute (or to run another one)")
    parser.add_argument("--scaffold", metavar="DIR", type=output_folder("--scaffold"),
                        help="write a Python package of placeholder plugin nodes for the custom nodes homing does not "
                        "know (ports from <TreeNodesModel> or the uses); after 'pip install DIR' the mission checks and "
                        "runs, and you fill the nodes in")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from homing.btxml.importer import import_xml
    from homing.missions.compiler import compile_mission

    from homing.atomic import atomic_write
    from homing.errors import UserError

    if args.output and Path(args.output).is_dir():
        raise UserError("is a directory: give the mission file to write", args.output)
    if args.scaffold is not None:
        from homing.btxml.scaffold import scaffold

        module, nodes = scaffold(Path(args.tree), args.main_tree, args.scaffold)
        print(f"scaffolded {len(nodes)} custom nodes in {args.scaffold} ({module}): {', '.join(nodes) or 'none needed'}"
              + (f"; install them with: pip install {args.scaffold}" if nodes else ""), file=sys.stderr)
    imported = import_xml(args.tree, args.main_tree)
    if not args.output:
        sys.stdout.write(imported.text)
        return 0
    try:
        atomic_write(args.output, imported.text)
    except OSError as err:
        raise UserError(f"cannot write: {err.strerror}", args.output) from None
    print(f"wrote {args.output} ({len(imported.notes)} notes in its header)")
    print(compile_mission(args.output).summary())
    return 0
