"""``homing bench NAME``: run one of the benchmarks in :mod:`homing.benchmarks`."""

from __future__ import annotations

import argparse
import importlib
import pkgutil


def register(sub: argparse._SubParsersAction) -> None:
    from homing.missions.commands._args import output_file, plain_text

    from homing import benchmarks

    parser = sub.add_parser(
        "bench",
        help="run a benchmark and print its table (--json PATH writes its figures)",
        description="Benchmarks print a table and, with --json PATH, write their figures.",
    )
    names = parser.add_subparsers(dest="bench", metavar="NAME", parser_class=type(parser))
    for info in sorted(pkgutil.iter_modules(benchmarks.__path__), key=lambda m: m.name):
        if info.name.startswith("_") or info.name == "common":
            continue
        module = importlib.import_module(f"{benchmarks.__name__}.{info.name}")
        if not (hasattr(module, "add_arguments") and hasattr(module, "run")):
            continue
        doc = plain_text(module.__doc__)
        name = info.name.replace("_", "-")  # slam_logs.py is `homing bench slam-logs` (slam_logs works too)
        aliases = [info.name] if name != info.name else []
        bench = names.add_parser(name, aliases=aliases, help=doc.split(". ")[0].split("\n\n")[0] if doc else None,
                                 description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(bench)
        bench.add_argument("--json", metavar="PATH", type=output_file("--json"), help="write the figures as JSON to PATH")
        bench.set_defaults(func=module.run)
    parser.set_defaults(func=lambda args: (parser.print_help(), 2)[1])
