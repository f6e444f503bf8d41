"""Options shared by the commands."""

from __future__ import annotations

import argparse

from scenes import preset_names

from ..engine import add_engine_arguments, engine_from_args

__all__ = ["add_engine_arguments", "add_scene_arguments", "engine_from_args"]


def add_scene_arguments(parser: argparse.ArgumentParser, required: bool = True,
                        default: str | None = None) -> None:
    parser.add_argument(
        "--scene", required=required, default=default,
        help=f"preset ({', '.join(preset_names())}) or a TOML scene file"
             + (f" (default {default})" if default else ""))
    parser.add_argument(
        "--set", dest="overrides", action="append", default=[], metavar="TABLE.KEY=VALUE",
        help="override a scene value in file units, e.g. --set pillars.E_Pa=1e9 (repeatable); "
             "--set pillars=none removes the pillars")
