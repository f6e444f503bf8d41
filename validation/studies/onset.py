"""The transition from suspended to mixed contact: the indentation and the force at which the
lens first touches the floor between the pillars, by bisection on a model's solves.

Below h + g(d/2) the floor is out of the lens's reach (:func:`pillar_xval.scenes.floor.
floor_onset_bound`): that indentation is suspended without a solve, and its solve gives the
bracket's lower force.  The upper end doubles the depth past the pillar tops until a solve
touches the floor (from a quarter of h, up to the small-slope limit), then bisection halves the
bracket until it is within ``rtol`` of the indentation.  The force follows: F(zeta) never
falls, so the forces at the bracket's ends bracket the onset force (PHYSICS.md, "Force
control").  Each solve is a case on the study engine (cached, resumable).

The onset is where the model's discrete floor carries a positive force: on a grid, the
first floor cell in contact.  Its discretisation error is the model's (a ladder of
resolutions gives it; the bracket is only the bisection's).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import InputError, Scene
from pillar_xval.scenes._checks import small_slope_indentation
from pillar_xval.scenes.floor import floor_onset_bound, roof_collapse_pressure

from ..engine import Case, Engine
from ..registry import get_model

__all__ = ["DEFAULT_RTOL", "MAX_SOLVES", "OUTPUTS", "onset_study", "write_outputs"]

# The bracket's width relative to the indentation; a solve costs seconds at N = 16.
DEFAULT_RTOL = 1e-3
MAX_SOLVES = 60
OUTPUTS = ("onset.json",)


def onset_study(scene: Scene, model: str, cache_dir, *, options: dict | None = None,
                engine: Engine | None = None, rtol: float = DEFAULT_RTOL) -> dict:
    """The onset of floor contact of ``model`` (with ``options``) on ``scene`` (its load is
    replaced by each bisection's indentation); a JSON-ready dict (module docstring)."""
    declared = get_model(model)
    if not declared.floor:
        raise InputError(f"--model {model}: does not include the floor between the pillars; "
                         "choose a model that does (bem-fft)")
    if scene.pillars is None:
        raise InputError(f"--scene {scene.name}: a flat substrate has no floor between pillars")
    if not 0.0 < rtol < 0.5:
        raise InputError(f"--rtol {rtol!r}: allowed range is (0, 0.5)")
    options = dict(options or {})
    own = engine is None
    engine = engine or Engine("serial", label="onset")
    solves = []

    def touches(zeta: float) -> bool:
        case = Case(model, scene.at_indentation(zeta), options,
                    tag=f"onset {len(solves) + 1}: zeta = {zeta * 1e6:.6g} um")
        result = engine.run([case], cache_dir, label="onset")[0].unwrap()
        centre = [f.force_N for f in result.pillar_forces if (f.n, f.m) == (0, 0)]
        solves.append({"indentation_m": zeta, "total_force_N": result.total_force_N,
                       "floor_force_N": result.floor_force_N, "regime": result.regime,
                       "centre_pillar_force_N": centre[0] if centre else 0.0,
                       "converged": bool(result.converged)})
        return result.floor_force_N > 0.0

    try:
        top = small_slope_indentation(scene.lens.radius_m) * (1.0 - 1e-9)
        lo = floor_onset_bound(scene)
        if touches(lo):  # a grid's floor cell may touch a hair before the continuum's bound
            raise InputError(f"--model {model}: touches the floor at h + g(d/2) = "
                             f"{lo * 1e6:.6g} um already (a coarse grid's floor cell)")
        lo_solve = solves[-1]
        h = scene.pillars.height_m
        # The depth past the tops doubles from a quarter of h (the grids grow like zeta).
        hi = h + max(2.0 * (lo - h), 0.25 * h)
        while not touches(min(hi, top)):
            if hi >= top or len(solves) >= MAX_SOLVES:
                raise InputError(f"--model {model}: the lens does not reach the floor below "
                                 f"the small-slope limit, zeta = {top * 1e6:.6g} um")
            lo, lo_solve = hi, solves[-1]
            hi = h + 2.0 * (lo - h)
        hi = min(hi, top)
        hi_solve = solves[-1]
        while hi - lo > rtol * hi and len(solves) < MAX_SOLVES:
            mid = 0.5 * (lo + hi)
            if touches(mid):
                hi, hi_solve = mid, solves[-1]
            else:
                lo, lo_solve = mid, solves[-1]
    finally:
        if own:
            engine.close()
    return {"model": model, "options": options, "scene": scene.to_dict(),
            "onset_indentation_m": 0.5 * (lo + hi),
            "onset_force_N": 0.5 * (lo_solve["total_force_N"] + hi_solve["total_force_N"]),
            "bracket_indentation_m": [lo, hi],
            "bracket_force_N": [lo_solve["total_force_N"], hi_solve["total_force_N"]],
            "tolerance": rtol, "bracketed": hi - lo <= rtol * hi,
            "onset_over_height": 0.5 * (lo + hi) / scene.pillars.height_m,
            "geometric_bound_m": floor_onset_bound(scene),
            # The roof-collapse estimate against the centre pillar's load at the onset (its
            # force over its lattice cell, the local mean pressure there).
            "roof_collapse_pressure_Pa": roof_collapse_pressure(scene),
            "onset_centre_mean_pressure_Pa": 0.5 * (lo_solve["centre_pillar_force_N"]
                                                    + hi_solve["centre_pillar_force_N"])
            / (math.sqrt(3.0) / 2.0 * scene.pillars.pitch_m ** 2),
            "converged": all(s["converged"] for s in solves), "solves": solves}


def write_outputs(doc: dict, out: Path) -> list[str]:
    """``onset.json`` in ``out``; its name."""
    write_atomic(Path(out) / "onset.json", json.dumps(doc, indent=2, allow_nan=False))
    return list(OUTPUTS)
