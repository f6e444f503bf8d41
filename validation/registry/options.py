"""The options a model takes, with their allowed values: one table for the CLI
(:mod:`validation.cli._args`) and for sweep specs (:mod:`validation.studies.sweep_grid`).

Which model takes which option is the registry's business (:data:`validation.models.MODELS`);
this table says what a value of each option may be.  The refinement option of a model family
(``family=True``) is a solve's resolution, or the coarsest level of a ladder.  The ranges are
the models' own (``bem_solver._dense``, ``bem_solver._fft_grid``, ``meshes._geometry``), so an
option is refused here, before any solve, with the name the user wrote.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scenes import InputError

__all__ = ["MODEL_OPTIONS", "OptionSpec", "check_option", "family_options"]


@dataclass(frozen=True)
class OptionSpec:
    """An option: its kind (int, float or str), its range [lo, hi] (hi None: unbounded) or its
    choices, whether it is a family's refinement option, and its help text."""

    kind: type
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    family: bool = False
    metavar: str = ""
    help: str = ""

    def allowed(self) -> str:
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.hi is None:
            return f">= {self.lo:g}"
        return f"[{self.lo:g}, {self.hi:g}]"


MODEL_OPTIONS: dict[str, OptionSpec] = {
    "elements_per_diameter": OptionSpec(
        int, 2, 400, family=True, metavar="P",
        help="bem: square elements across a pillar diameter (flat scenes: across the Hertz "
             "contact diameter 2 sqrt(R zeta))"),
    "cells_per_diameter": OptionSpec(
        int, 2, None, family=True, metavar="N",
        help="bem-fft: square grid cells across a pillar diameter (flat scenes: across "
             "2 sqrt(R zeta))"),
    "mesh_size": OptionSpec(
        float, 0.02, 4.0, family=True, metavar="S",
        help="fem-axisym, fem-3d: mesh refinement factor, 0.5 halves every element"),
    "cells": OptionSpec(
        str, choices=("covered", "centre"),
        help="bem: 'covered' adds edge cells weighted by their covered area (smooth "
             "convergence; default); 'centre' keeps the paper's cells whose centre lies on "
             "the pillar top"),
    "contact": OptionSpec(
        str, choices=("exact", "paper"),
        help="bem: exact complementarity (default) or the paper's contact-radius search"),
    "max_iterations": OptionSpec(
        int, 1, None, metavar="K",
        help="bem-fft: iteration limit of the contact CG (default 20 sqrt(cells) + 500)"),
    "device": OptionSpec(
        str, choices=("cpu", "gpu", "auto"),
        help="bem-fft: where the FFTs run (cpu: numpy, the default; gpu: cupy)"),
}


def family_options() -> list[str]:
    """The refinement options, one per model family."""
    return [name for name, spec in MODEL_OPTIONS.items() if spec.family]


def flag(name: str) -> str:
    """The command-line spelling: mesh_size -> --mesh-size."""
    return "--" + name.replace("_", "-")


def check_option(name: str, value, where: str = ""):
    """``value`` if it is allowed for option ``name``; InputError otherwise, one line that
    starts with ``where`` (default: the option's command-line spelling) and gives the value
    and the allowed range.  Options without an entry in :data:`MODEL_OPTIONS` pass."""
    spec = MODEL_OPTIONS.get(name)
    if spec is None:
        return value
    shown = where or flag(name)
    if spec.choices:
        if value not in spec.choices:
            raise InputError(f"{shown} {value!r}: allowed: {spec.allowed()}")
        return value
    if spec.kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) \
            and math.isfinite(value)
    if not ok:
        kind = "an integer" if spec.kind is int else "a finite number"
        raise InputError(f"{shown} {value!r}: expected {kind}, allowed {spec.allowed()}")
    if value < spec.lo or (spec.hi is not None and value > spec.hi):
        raise InputError(f"{shown} {value!r}: allowed range is {spec.allowed()}")
    return value
