"""``homing schema [MISSION.yaml] [-o PATH]``: the JSON Schema of mission files, for an editor's YAML language server."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file

    parser = sub.add_parser(
        "schema",
        help="write the JSON Schema of the mission language (for editor completion and checking)",
        description="Print (or write with -o) a JSON Schema of mission files covering every registered "
        "node and its parameters. With the YAML language server, add to a mission's first line: "
        "# yaml-language-server: $schema=PATH. With MISSION.yaml, the schema also knows the subtrees that "
        "mission and its includes define, so a misspelt node is flagged there too (without it, a mission "
        "with subtrees or includes accepts any other single-key node as a subtree).",
    )
    parser.add_argument("mission", nargs="?", metavar="MISSION.yaml", help="take the subtrees from this mission")
    parser.add_argument("-o", "--output", metavar="PATH", type=output_file("-o"),
                        help="write the schema here instead of stdout")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import json

    from homing.behaviours import load_nodes
    from homing.missions.schema import json_schema

    from homing.atomic import atomic_write

    load_nodes()
    subtrees = None
    if args.mission:
        from homing.missions.loader import load_source

        subtrees = {name: list(sub.params) for name, sub in load_source(args.mission).subtrees.items()}
    text = json.dumps(json_schema(subtrees), indent=2, sort_keys=False) + "\n"
    if args.output:
        atomic_write(args.output, text)
        print(f"wrote {args.output}")
    else:
        print(text, end="")
    return 0
