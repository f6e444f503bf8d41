"""What a model option may be: :class:`OptionSpec`, and the specs the models declare.

A model's declaration (:mod:`.models`) names its options with these specs; the CLI's flags
(:mod:`validation.cli._args`) and sweep specs (:mod:`validation.studies.sweep`) check values
against them, before any solve, with the name the user wrote.  The ranges and choices are read
from the solvers' own constants (``bem_solver._limits``, ``bem_solver._cells``,
``bem_solver._xp``, ``meshes.MESH_SIZE_RANGE`` and ``MESH_SIZE_RANGE_3D``), which the solvers check
again.  The refinement option of a model family (``family=True``) is a solve's resolution, or
the coarsest level of a ladder.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bem_solver._cells import VARIANTS
from bem_solver._limits import (CONTACT_METHODS, DEVICES, ELEMENTS_PER_DIAMETER_RANGE,
                                MIN_CELLS_PER_DIAMETER, PILLAR_MODELS, PRECISIONS)
from meshes import MESH_SIZE_RANGE, MESH_SIZE_RANGE_3D
from pillar_xval.scenes import InputError

__all__ = ["CELLS", "CELLS_PER_DIAMETER", "CONTACT", "DEVICE", "ELEMENTS_PER_DIAMETER",
           "MAX_ITERATIONS", "MESH_SIZE", "MESH_SIZE_3D", "OptionSpec", "PILLARS", "PLANNED",
           "BOTH", "check_option", "flag", "pillar_models"]


@dataclass(frozen=True)
class OptionSpec:
    """An option: its kind (int, float or str; ``object``: any value, checked by the solver),
    its range [lo, hi] (hi None: unbounded) or its choices, whether it is a family's refinement
    option, its metavar, its short label in candidate names (``P=11``) and its help text."""

    kind: type
    lo: float | None = None
    hi: float | None = None
    choices: tuple = ()
    family: bool = False
    metavar: str = ""
    short: str = ""
    help: str = ""
    # Choices that change what a model solves: {choice: physics} (a model's ``physics``, the
    # reference group of ``tradeoff``; :meth:`validation.registry.Model.physics_of`).
    physics: tuple = ()

    def allowed(self) -> str:
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.lo is None:
            return "any"
        if self.hi is None:
            return f">= {self.lo:g}"
        return f"[{self.lo:g}, {self.hi:g}]"

    def hull(self, other: OptionSpec) -> OptionSpec:
        """One spec for a flag that several models share: the widest range (each model's
        solver still refuses a value outside its own)."""
        if other == self or self.choices or self.kind is object:
            return self
        lo = None if self.lo is None or other.lo is None else min(self.lo, other.lo)
        hi = None if self.hi is None or other.hi is None else max(self.hi, other.hi)
        return OptionSpec(self.kind, lo, hi, self.choices, self.family,
                          self.metavar, self.short, self.help)


ELEMENTS_PER_DIAMETER = OptionSpec(
    int, *ELEMENTS_PER_DIAMETER_RANGE, family=True, metavar="P", short="P",
    help="bem: square elements across a pillar diameter (flat scenes: across the Hertz "
         "contact diameter 2 sqrt(R zeta))")
CELLS_PER_DIAMETER = OptionSpec(
    int, MIN_CELLS_PER_DIAMETER, None, family=True, metavar="N", short="N",
    help="bem-fft: square grid cells across a pillar diameter (flat scenes: across "
         "2 sqrt(R zeta))")
_MESH_SIZE_HELP = "fem-axisym, fem-3d: mesh refinement factor, 0.5 halves every element"
MESH_SIZE = OptionSpec(float, *MESH_SIZE_RANGE, family=True, metavar="S", short="mesh",
                       help=_MESH_SIZE_HELP)
MESH_SIZE_3D = OptionSpec(float, *MESH_SIZE_RANGE_3D, family=True, metavar="S", short="mesh",
                          help=_MESH_SIZE_HELP)
CELLS = OptionSpec(
    str, choices=tuple(sorted(VARIANTS, reverse=True)),  # covered (the default) first
    help="bem: 'covered' adds edge cells weighted by their covered area (smooth "
         "convergence; default); 'centre' keeps the paper's cells whose centre lies on "
         "the pillar top")
CONTACT = OptionSpec(
    str, choices=CONTACT_METHODS,
    help="bem: exact complementarity (default) or the paper's contact-radius search")
MAX_ITERATIONS = OptionSpec(
    int, 1, None, metavar="K",
    help="bem-fft: iteration limit of the contact CG (default 20 sqrt(cells) + 500)")
DEVICE = OptionSpec(
    str, choices=DEVICES,
    help="bem-fft: where the FFTs run (cpu: numpy, the default; gpu: cupy)")
PRECISION = OptionSpec(
    str, choices=PRECISIONS,
    help="bem-fft: 'mixed' (default): the CG's FFTs in float32 with float64 gap refreshes, the "
         "same tolerance met in float64; 'double': float64 throughout")
PILLARS = OptionSpec(
    str, choices=PILLAR_MODELS,
    # The elastic pillar is the FEMs' physics: its tradeoff needs its own reference.
    physics=(("hooke", "hooke-pillar"), ("elastic", "elastic-pillar")),
    help="bem, bem-fft, bem-richardson: the pillar model: 'hooke', the paper's uniformly "
         "shortening spring (default), or 'elastic', the whole pillar's top compliance from "
         "a Fourier-mode FEM of one pillar on the substrate (computed once per pillar kind, "
         "cached)")
# The planner's request (auto): checked by the planner itself (validation.planner.check_request).
PLANNED = OptionSpec(object, help="auto: the planner's request (tolerance, quantities, budget)")


def flag(name: str) -> str:
    """The command-line spelling: mesh_size -> --mesh-size."""
    return "--" + name.replace("_", "-")


def check_option(name: str, value, where: str = "", spec: OptionSpec | None = None):
    """``value`` if it is allowed for option ``name``; InputError otherwise, one line that
    starts with ``where`` (default: the option's command-line spelling) and gives the value
    and the allowed range.  ``spec`` defaults to the flag's spec of every registered model
    (:func:`validation.registry.option_vocabulary`); options without one pass."""
    if spec is None:
        from . import option_vocabulary

        spec = option_vocabulary().get(name)
    if spec is None or spec.kind is object:
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
    if (spec.lo is not None and value < spec.lo) or (spec.hi is not None and value > spec.hi):
        raise InputError(f"{shown} {value!r}: allowed range is {spec.allowed()}")
    return value


# What --pillars takes beyond the BEM's own choices: every one of them, for a three-way table.
BOTH = "both"


def pillar_models(pillars) -> tuple[str, ...]:
    """The BEMs' pillar models a compare runs, in the declaration's order: ``pillars`` is one
    of the BEM's choices, ``"both"``, a comma list (``"hooke,elastic"``) or a sequence.
    InputError (one line naming --pillars, the value and the allowed values) otherwise."""
    allowed = tuple(PILLARS.choices)
    if isinstance(pillars, str):
        names = list(allowed) if pillars.strip() == BOTH else \
            [p.strip() for p in pillars.split(",")]
    else:
        names = list(pillars)
    if not names or any(p not in allowed for p in names) or len(set(names)) != len(names):
        shown = pillars if isinstance(pillars, str) else ",".join(map(str, pillars))
        twice = len(set(names)) != len(names) and all(p in allowed for p in names)
        raise InputError(f"--pillars {shown!r}: allowed: {', '.join(allowed)}, {BOTH}, or a "
                         f"comma list of {', '.join(allowed)}"
                         + (" (each once)" if twice else ""))
    return tuple(p for p in allowed if p in names)
