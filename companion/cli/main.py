"""The ``companion`` command: ``main(argv) -> int`` and the console entry point.

Each sub-command lives in its own module exposing ``register(subparsers)``; the parser it adds
sets ``func=run`` where ``run(args) -> int``. This module is the one place that maps domain
errors (:class:`companion.errors.CompanionError`) to a one-line message and an exit code.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from companion import __version__
from companion.errors import CompanionError

# Sub-command modules, in the order ``companion --help`` lists them.
COMMAND_MODULES = (
    "companion.cli.sim",
    "companion.cli.fly",
    "companion.cli.demo",
    "companion.cli.mission",
    "companion.cli.replay",
    "companion.cli.log",
    "companion.cli.bench",
    "companion.cli.identify",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="companion",
        description="Offboard path-following guidance for PX4 and ArduPilot over MAVLink.",
    )
    parser.add_argument("--version", action="version", version=f"companion {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except CompanionError as err:
        for line in str(err).splitlines() or [type(err).__name__]:
            print(f"companion: error: {line}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print("companion: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return 1


def entry_point() -> None:
    sys.exit(main())
