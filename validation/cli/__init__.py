"""Command line: ``pillar-xval COMMAND --scene PRESET|FILE [--set table.key=value ...]``.

Each command lives in its own module of this package, listed in ``COMMANDS``: a thin layer
that parses options, calls a study (:mod:`validation.studies`) and prints.  A module provides
``add_parser(subparsers)`` (which sets ``func``) and the function it names.  Bad input ends
the program with one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from scenes import EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_TOOL_FAILURE, InputError, ToolError

from ._args import add_scene_arguments

__all__ = ["COMMANDS", "UserError", "add_scene_arguments", "build_parser", "main"]

COMMANDS = ("validation.cli.solve", "validation.cli.compare", "validation.cli.converge",
            "validation.cli.gecit", "validation.cli.tradeoff", "validation.cli.sweep",
            "validation.cli.figures")


class UserError(Exception):
    """An error in what the user asked for; printed as one line."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pillar-xval",
        description="Contact of a spherical lens on a hexagonal lattice of pillars: "
                    "BEM solver and FEM references.  SI units in results.")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMANDS:
        importlib.import_module(name).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (InputError, UserError, ValueError) as exc:
        print(f"pillar-xval {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except ToolError as exc:
        print(f"pillar-xval {args.command}: failure: {exc}", file=sys.stderr)
        return EXIT_TOOL_FAILURE
    except KeyboardInterrupt:
        print(f"pillar-xval {args.command}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
