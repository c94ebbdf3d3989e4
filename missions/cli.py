"""The ``homing`` command line: one entry point, one module per subcommand.

Subcommands live in :mod:`homing.missions.commands`, one module each, found
at start-up: a module there that defines ``register(subparsers)`` adds its
parser and sets ``func`` (``args -> int``). Modules import their heavy
dependencies inside ``func`` so that ``homing --help`` stays fast.

A user's mistake (:class:`homing.errors.UserError`, or a bad argument) is
printed as one line on stderr with exit status 2, never a traceback.
Ctrl-C, SIGTERM and SIGHUP all raise ``KeyboardInterrupt``
(:mod:`homing.signals`): a command that owns a robot stops it cleanly and
finishes its outputs; one stopped before that ends with one line and the
shell's status for the signal (130, 143, 129).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import pkgutil
import re
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

from homing import __version__
from homing.errors import EXIT_USAGE, UserError
from homing.signals import exit_status, received, signal_name, stop_on_signals

# What argparse should take as a (negative) value rather than an option: "-1", "-0.5", "-5s", "-2 min", "-inf".
NEGATIVE_VALUE = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(\s*[A-Za-z%/]+)?$|^-(inf|nan)$", re.IGNORECASE)


class ArgumentParser(argparse.ArgumentParser):
    """argparse that reports a bad argument as one line, exit 2.

    A negative value with a unit (``--until -5s``) is read as the option's
    value, so the option's own check says what is wrong with it, instead of
    argparse's "expected one argument".
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_VALUE

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> ArgumentParser:
    parser = ArgumentParser(
        prog="homing",
        description="Behaviour-tree missions for persistent autonomous mobile robots.",
    )
    parser.add_argument("--version", action="version", version=f"homing {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=ArgumentParser)
    from homing.missions import commands

    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (also used as the console script)."""
    command = "homing"
    try:
        with stop_on_signals():
            parser = build_parser()
            args = parser.parse_args(argv)
            command = f"homing {args.command}" if getattr(args, "command", None) else command
            func = getattr(args, "func", None)
            if func is None:
                parser.print_help()
                return EXIT_USAGE
            return int(func(args) or 0)
    except UserError as err:
        print(str(err), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"{command}: interrupted by {signal_name(received())} before it finished", file=sys.stderr)
        return exit_status(received())
    except BrokenPipeError:
        return 0
    except OSError as err:
        if err.errno != errno.EIO:
            raise
        return exit_status(received()) if received() is not None else 1  # the terminal hung up under us


if __name__ == "__main__":
    sys.exit(main())
