"""``homing nodes [NAME]``: every node a mission may use, with its parameters, keys and semantics."""

from __future__ import annotations

import argparse
import sys


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "nodes",
        help="list every node and service with its parameters (NAME: the full semantics of one)",
        description="List the registered nodes (composites, decorators, actions, conditions) and "
        "services with their parameters (type, unit, default), blackboard keys and one-line "
        "semantics; with NAME, print that node's whole documentation.",
    )
    parser.add_argument("name", nargs="?", help="show one node's full documentation")
    parser.add_argument("--kind", choices=("composite", "decorator", "action", "condition", "service"))
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from homing.behaviours import load_nodes
    from homing.behaviours.registry import NODES, SERVICES
    from homing.missions.commands._args import plain_text
    from homing.missions.schema import describe_param, suggest

    from homing.errors import UserError

    for problem in load_nodes():
        print(f"warning: {problem}", file=sys.stderr)
    if args.name:
        spec = NODES.get(args.name) or SERVICES.get(args.name)
        if spec is None:
            raise UserError(f"unknown node '{args.name}'{suggest(args.name, [*NODES, *SERVICES])}")
        kind = getattr(spec, "kind", "service")
        print(f"{spec.name} ({kind}, from {getattr(spec, 'source', spec.factory.__module__)})\n")
        print(plain_text(spec.factory.__doc__ or spec.doc))
        _details(spec, describe_param)
        return 0
    order = ("composite", "decorator", "action", "condition")
    for kind in order:
        if args.kind and args.kind != kind:
            continue
        names = sorted(n for n, s in NODES.items() if s.kind == kind)
        if names:
            print(f"\n{kind}s:")
        for name in names:
            spec = NODES[name]
            print(f"  {name} — {plain_text(spec.doc)}")
            _details(spec, describe_param, indent="      ")
    if not args.kind or args.kind == "service":
        print("\nservices:" + ("" if SERVICES else " (none registered)"))
        for name in sorted(SERVICES):
            spec = SERVICES[name]
            print(f"  {name} — {plain_text(spec.doc)}")
            _details(spec, describe_param, indent="      ")
    return 0


def _details(spec: object, describe: object, indent: str = "  ") -> None:
    slots = getattr(spec, "child_slots", ())
    optional = getattr(spec, "optional", ())
    if slots:
        print(f"{indent}children: {', '.join(s + (' (optional)' if s in optional else '') for s in slots)}")
    for p in getattr(spec, "params", ()):
        print(f"{indent}{describe(p)}")  # type: ignore[operator]
    for label, keys in (("reads", getattr(spec, "reads", ())), ("writes", getattr(spec, "writes", ()))):
        if keys:
            print(f"{indent}{label}: {', '.join(keys)}")
