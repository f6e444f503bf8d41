"""Sizes of a solve, known before it runs: what the planner's cost fits are written in.

A cost fit (:class:`.tables.CostFit`, data) names a ``size`` function of this module and the
model option it reads (a model's declaration says which: ``Model.cost``); the function returns
the fit's terms (natural logs of counts) and a memory estimate in bytes.  The dense BEM and
fem-axisym estimate their own memory (``bem_solver.estimate_memory``,
``fem_reference.axisym.estimate_memory``, the same functions that refuse a scene too large for the
machine); the FFT grid's memory is a fitted line in its padded points (``calibrate``); fem-3d
counts its unknowns and memory with ``fem_reference.solid3d.estimate_memory``.  A model
added later names one of these sizes in its cost law, or adds one here.  A one-off set-up
(the elastic pillar's compliance, once per pillar kind) is a :data:`SETUPS` entry: the
planner adds its seconds unless it is already paid (cached).
"""

from __future__ import annotations

import math

from pillar_xval.scenes import Scene

__all__ = ["SETUPS", "SIZES", "compliance_cached", "fft_grid", "size_terms"]

def fft_grid(scene: Scene, cells_per_diameter: int) -> dict:
    """Candidate cells and padded FFT points of the FFT BEM, estimated without building its
    grid (``bem_solver._fft_grid.build_grid``, the solve's own first step; the cost fits are
    written in this estimate): the grid's own cell size and flat candidate radius;
    on pillars, the pillar tops' share Phi of the disk where the lens can touch (at least the
    centre pillar's top); the padded grid doubles the bounding box of the kept cells."""
    from bem_solver._fft_grid import FLAT_CANDIDATE_RATIO, cell_size

    N = int(cells_per_diameter)
    R, zeta = scene.lens.radius_m, scene.indentation_m
    r_geo = math.sqrt(max(2.0 * R * zeta - zeta * zeta, 0.0))
    L = cell_size(scene, N)
    if scene.is_flat:
        r_c = min(r_geo, FLAT_CANDIDATE_RATIO * math.sqrt(R * zeta) + 2.0 * L)
        cells = math.pi * (r_c / L) ** 2
        box = 2.0 * r_c / L
    else:
        d, e, phi = (scene.pillars.diameter_m, scene.pillars.pitch_m,
                     scene.pillars.surface_fraction)
        cells = max(math.pi * N * N / 4.0, phi * math.pi * (r_geo / L) ** 2)
        # Only the centre pillar lies within reach when the nearest one starts beyond it.
        box = N if e - d / 2.0 > r_geo else 2.0 * (r_geo + d / 2.0) / L
    return {"cells": max(cells, 1.0), "points": 4.0 * max(box, 1.0) ** 2}


def _dense(scene, value):
    from bem_solver import estimate_memory

    est = estimate_memory(scene, int(value))
    n = max(est["unknowns"], 1.0)
    return {"log_unknowns": math.log(n)}, est["bytes"]


def _fft(scene, value):
    g = fft_grid(scene, int(value))
    return ({"log_points": math.log(g["points"]), "log_cells": math.log(g["cells"])},
            None)


def _fem(scene, value):
    from fem_reference.axisym import estimate_memory

    est = estimate_memory(scene, float(value))
    return {"log_dofs": math.log(est["dofs"])}, est["bytes"]


def _fem3d(scene, value):
    from fem_reference.solid3d import estimate_memory

    est = estimate_memory(scene, float(value))
    return {"log_dofs": math.log(max(est["dofs"], 1.0))}, est["bytes"]


def _none(scene, value):
    return {}, 0.0


SIZES = {"dense-unknowns": _dense, "fft-grid": _fft, "fem-dofs": _fem, "fem3d-dofs": _fem3d,
         "none": _none}


def compliance_cached(scene: Scene) -> bool:
    """Whether the elastic-pillar BEM finds the scene's pillar compliance in the disk cache,
    valid (``fem_reference._compliance_store.stored`` at the modes and mesh the BEMs ask
    for: a damaged or foreign file there is rebuilt, so its time is charged), or needs none
    (no pillars, or pillars and substrate both rigid: the Hooke and elastic models
    coincide)."""
    if scene.pillars is None or (scene.pillars.material.rigid and scene.substrate.rigid):
        return True
    from fem_reference import PillarKind
    from fem_reference._compliance_store import stored

    return stored(PillarKind.of_scene(scene)) is not None


# One-off set-up costs a candidate may carry (cost_models.json, a "setup" of a scaled cost):
# each returns True when it is already paid for this scene.
SETUPS = {"pillar-compliance": compliance_cached}


def size_terms(size: str, scene: Scene, value) -> tuple[dict, float | None]:
    """(terms, memory bytes or None) of size function ``size`` for the option ``value``."""
    return SIZES[size](scene, value)
