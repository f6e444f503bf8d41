"""Command line: ``pillar-xval COMMAND --scene PRESET|FILE [--set table.key=value ...]``.

Each command lives in its own module of this package, listed in ``COMMANDS``; a module
provides ``add_parser(subparsers)`` (which sets ``func``) and the function it names.
Bad input ends the program with one line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from scenes import (EXIT_BAD_INPUT, EXIT_INTERRUPTED, EXIT_TOOL_FAILURE, InputError, ToolError,
                    preset_names)

COMMANDS = ("validation.cmd_solve", "validation.cmd_compare", "validation.cmd_converge",
            "validation.cmd_gecit", "validation.cmd_tradeoff")


class UserError(Exception):
    """An error in what the user asked for; printed as one line."""


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--scene", required=True,
        help=f"preset ({', '.join(preset_names())}) or a TOML scene file")
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="TABLE.KEY=VALUE",
        help="override a scene value in file units, e.g. --set pillars.E_Pa=1e9 (repeatable); "
             "--set pillars=none removes the pillars")


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
