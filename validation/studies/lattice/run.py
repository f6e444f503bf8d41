"""The lattice study's run on the engine (resumable): its cases, then one row a point."""

from __future__ import annotations

from pillar_xval.scenes import InputError

from ...engine import Engine
from ..targets import TARGET_RULE, TARGETS
from .analysis import compare_point, targets_met
from .points import (
    BEM_LEVELS,
    BEM_MODEL,
    CONVENTIONS,
    DENSE_LEVELS,
    DENSE_MODEL,
    DENSE_OPTIONS,
    E_LENS,
    ELASTIC,
    FEM_LEVELS,
    FEM_MODEL,
    FFT_RUNGS,
    HOOKE,
    PROFILE_POINTS,
    cases,
    default_points,
)


def lattice_study(folder, *, engine: Engine | None = None, points=None, fem_levels=FEM_LEVELS,
                  bem_levels=BEM_LEVELS, dense_levels=DENSE_LEVELS,
                  fft_rungs=FFT_RUNGS) -> dict:
    """Run (or resume) the study into ``folder``/cases; returns the JSON-ready report.
    ``points`` default to :func:`default_points` (the E_s = E_l grid and the E_s = E_p
    scenes); they share one indentation."""
    from pathlib import Path

    points = list(points or default_points())
    zetas = {p.zeta_um for p in points}
    if len(zetas) != 1:
        raise InputError(f"lattice study: the scenes have indentations {sorted(zetas)} um; "
                         "one study runs at one zeta")
    engine = engine or Engine("serial")
    all_cases = [c for p in points
                 for c in cases(p, fem_levels, bem_levels, dense_levels, fft_rungs)]
    # Cheap cases first: the Hooke BEM, then the elastic BEMs (2-3x the Hooke time, and one
    # pillar compliance per kind, cached), then the FEM from coarse to fine: a long run
    # shows its BEM columns early and an interruption loses at most one FEM solve.
    order = sorted(range(len(all_cases)),
                   key=lambda i: (all_cases[i].model == FEM_MODEL,
                                  all_cases[i].options.get("pillars") == "elastic",
                                  -all_cases[i].options.get("mesh_size", 0.0), i))
    outcomes = [None] * len(all_cases)
    ran = engine.run([all_cases[i] for i in order], Path(folder) / "cases", "lattice")
    for i, o in zip(order, ran):
        outcomes[i] = o
    rows, k = [], 0
    sizes = (len(fem_levels), len(bem_levels), len(bem_levels), len(dense_levels),
             len(fft_rungs))
    for p in points:
        parts = []
        for n in sizes:
            parts.append(outcomes[k:k + n])
            k += n
        rows.append(compare_point(p, *parts))
    conventions = [c for c in CONVENTIONS if any(p.substrate == c for p in points)]
    return {"zeta_um": zetas.pop(), "E_lens_Pa": E_LENS,
            "substrate": conventions[0] if len(conventions) == 1
            else "per scene: " + ", ".join(conventions),
            "substrates": conventions,
            "fem": {"model": FEM_MODEL, "mesh_size": list(fem_levels)},
            "bem": {"model": BEM_MODEL, "pillars": HOOKE,
                    "cells_per_diameter": list(bem_levels)},
            "elastic": {"model": BEM_MODEL, "pillars": ELASTIC,
                        "cells_per_diameter": list(bem_levels)},
            "dense_elastic": {"model": DENSE_MODEL, **DENSE_OPTIONS,
                              "elements_per_diameter": list(dense_levels)},
            "targets": {**TARGETS, "rule": TARGET_RULE,
                        "profile_points_over_radius": list(PROFILE_POINTS)},
            "targets_met": targets_met(rows),
            "rows": rows}
