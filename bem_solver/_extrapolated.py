"""The dense BEM at two resolutions, extrapolated: ``solve_dense_extrapolated``.

The dense model's F_T and sigma_0 converge at first order in the element side b = d/P (the
square cells resolve the edge singularity of the pressure to O(b)); its constant is large,
so P = 11 alone is off by 2-3 % in sigma_0 and reaching 1 % needs P ~ 27.  Two levels P1 and
P2 remove the first-order term (Richardson, order 1 in h = 1/P):

    f* = f2 + (f2 - f1) P1 / (P2 - P1).

On a flat scene (Hertz) the error is second order, and the extrapolation is too.

The covered-cell pattern changes with P, so the error constant wobbles by a few per cent from
one P to the next; the extrapolation multiplies that wobble by P1 / (P2 - P1).  With
P2 = 2 P1 - 1 (both odd, so both grids have an element centred at r = 0 and sigma_0 is the
pressure of that element at both levels) the factor is P1 / (P1 - 1), 1.25 for (5, 9); for
(9, 11) it would be 4.5.  Measured on a seeded sample of 40 of the 832 scenes behind the
paper's Figs. 4-8 (Phi = 2.3e-3..0.82, E_p/E_l = 1e-3..1e6, zeta = 0.005..0.5 um) against the
FFT BEM at N = 32 and 48 extrapolated (itself within 0.08 % of N = 48, 64): max |error| of
(5, 9) 0.41 % in F_T and 0.36 % in sigma_0; of (9, 11) 0.87 % and 0.69 %; of the plain dense
model at P = 11 2.0 % and 3.1 % (``python -m validation.bench.figures``).

What is extrapolated and what is not
------------------------------------
- sigma_0: the two centre pressures.
- Pillar forces: pillar by pillar where a pillar touches at both levels and the extrapolated
  force stays positive; otherwise the fine level's force (a rim pillar that touches at one
  level only carries a force of the order of the discretisation error).  F_T is their sum,
  so the pillar forces always add up to it.
- The contact radius a, the real contact area A, the pillars in contact, the profile across
  the centre pillar and the element fields (pressure maps) are the fine level's: a staircase
  of cells does not converge smoothly, so extrapolating it would only amplify its jumps.

References
----------
.. [1] L. F. Richardson, Phil. Trans. R. Soc. A 210 (1911) 307-357.
.. [2] I. B. Celik et al., J. Fluids Eng. 130 (2008) 078001 (Richardson extrapolation).
"""

from __future__ import annotations

import time

from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.scenes import Scene

from ._dense import solve_dense
from ._elastic_pillar import operator_records

__all__ = ["MODEL_NAME", "extrapolate", "extrapolation_order", "fine_level", "richardson",
           "solve_dense_extrapolated"]

MODEL_NAME = "bem-richardson"


def fine_level(elements_per_diameter: int) -> int:
    """P2 = 2 P1 - 1: the finer level for a coarse level P1 (odd stays odd)."""
    return 2 * int(elements_per_diameter) - 1


def richardson(coarse: float, fine: float, p_coarse: int, p_fine: int,
               order: float = 1.0) -> float:
    """Richardson extrapolation in h = 1/P, of the given order, of values at P1 < P2."""
    return fine + (fine - coarse) / ((p_fine / p_coarse) ** order - 1.0)


def extrapolation_order(scene: Scene) -> float:
    """1 on pillar tops (the flat-punch edge singularity, resolved to O(b)); 2 on a flat
    scene, whose Hertz pressure vanishes at the edge like a square root (measured: F_T error
    +0.28 %, +0.066 %, +0.011 % at P = 11, 21, 41)."""
    return 2.0 if scene.pillars is None else 1.0


def _level(r: ContactResult) -> dict:
    return {"elements_per_diameter": r.discretisation["elements_per_diameter"],
            "total_force_N": r.total_force_N, "centre_pressure_Pa": r.centre_pressure_Pa,
            "contact_radius_m": r.contact_radius_m,
            "real_contact_area_m2": r.real_contact_area_m2,
            "pillars_in_contact": r.pillars_in_contact, "converged": r.converged,
            "iterations": r.iterations, "wall_time_s": r.wall_time_s,
            "unknowns": r.diagnostics.get("unknowns"),
            "contact_residual": r.diagnostics.get("contact_residual"),
            "message": r.diagnostics.get("message", "")}


def _pillar_forces(coarse: ContactResult, fine: ContactResult, p1: int, p2: int):
    """Fine-level pillar forces, extrapolated where a pillar touches at both levels."""
    before = {(p.n, p.m): p.force_N for p in coarse.pillar_forces}
    out, extrapolated = [], 0
    for p in fine.pillar_forces:
        force = p.force_N
        if (p.n, p.m) in before:
            guess = richardson(before[(p.n, p.m)], p.force_N, p1, p2)
            if guess > 0.0:
                force, extrapolated = guess, extrapolated + 1
        out.append(PillarForce(p.n, p.m, p.x_m, p.y_m, force))
    return out, extrapolated


def solve_dense_extrapolated(scene: Scene, elements_per_diameter: int = 5,
                             cells: str = "covered", *, pillars: str = "hooke",
                             compliance=None) -> ContactResult:
    """Solve ``scene`` with the dense BEM at P1 and P2 = 2 P1 - 1 and extrapolate F_T and
    sigma_0 to zero element size (module docstring: what is extrapolated and why this P2).

    Parameters
    ----------
    scene : Scene
    elements_per_diameter : int
        P1, square elements across a pillar diameter on the coarse level (b = d/P1); the fine
        level has 2 P1 - 1.  For a flat scene: across the Hertz contact diameter 2 sqrt(R zeta).
    cells : {"covered", "centre"}
        Cell variant of both levels (see :func:`bem_solver.solve_dense`); only ``covered``
        converges smoothly enough to extrapolate.
    pillars, compliance
        The pillar model of both levels (see :func:`bem_solver.solve_dense`).

    Returns
    -------
    ContactResult
        ``model = "bem-richardson"``; ``discretisation`` names both levels;
        ``diagnostics["levels"]`` holds each level's F_T (N), sigma_0 (Pa), a (m), A (m^2),
        pillars, convergence and wall time (s), and ``diagnostics["richardson_change"]`` the
        relative change of F_T and sigma_0 from the fine level to the extrapolated value (an
        estimate of the fine level's error).  ``converged`` holds when both levels converged.

    References
    ----------
    .. [1] I. B. Celik et al., J. Fluids Eng. 130 (2008) 078001.
    """
    t0 = time.perf_counter()
    p1 = elements_per_diameter
    if scene.force_N is not None:
        from ._extrapolated_force import solve_under_force

        return solve_under_force(scene, p1, cells, pillars, compliance, t0)
    coarse = solve_dense(scene, p1, cells=cells, pillars=pillars, compliance=compliance)
    fine = solve_dense(scene, fine_level(p1), cells=cells, pillars=pillars,
                       compliance=compliance)
    return extrapolate(scene, coarse, fine, cells, t0)


def extrapolate(scene: Scene, coarse: ContactResult, fine: ContactResult, cells: str,
                t0: float) -> ContactResult:
    """The extrapolated result of the two levels on ``scene`` (module docstring); ``t0``: the
    start of the solve (s, ``time.perf_counter``)."""
    p1 = coarse.discretisation["elements_per_diameter"]
    p2 = fine.discretisation["elements_per_diameter"]
    order = extrapolation_order(scene)
    sigma0 = richardson(coarse.centre_pressure_Pa, fine.centre_pressure_Pa, p1, p2, order)
    if scene.pillars is None:
        pillar_forces, extrapolated = [], 0
        total = richardson(coarse.total_force_N, fine.total_force_N, p1, p2, order)
    else:
        pillar_forces, extrapolated = _pillar_forces(coarse, fine, p1, p2)
        total = sum(p.force_N for p in pillar_forces)
    converged = coarse.converged and fine.converged
    messages = [f"P = {r.discretisation['elements_per_diameter']}: "
                f"{r.diagnostics.get('message', '')}" for r in (coarse, fine)
                if not r.converged]
    diagnostics = {
        **fine.diagnostics,
        "message": "; ".join(messages) if messages else "both levels converged",
        "extrapolation": f"Richardson, order {order:g} in h = 1/P",
        "levels": [_level(coarse), _level(fine)],
        "pillars_extrapolated": extrapolated,
        "operators": operator_records(coarse.diagnostics, fine.diagnostics),
        "richardson_change": {
            "total_force": (total - fine.total_force_N) / fine.total_force_N
            if fine.total_force_N else 0.0,
            "centre_pressure": (sigma0 - fine.centre_pressure_Pa) / fine.centre_pressure_Pa
            if fine.centre_pressure_Pa else 0.0},
    }
    return ContactResult(
        model=MODEL_NAME,
        scene=scene.to_dict(),
        discretisation={"elements_per_diameter": p1, "fine_elements_per_diameter": p2,
                        "cells": cells, "contact": "exact",
                        "element_side_m": fine.discretisation["element_side_m"]},
        total_force_N=float(total),
        centre_pressure_Pa=float(sigma0),
        contact_radius_m=fine.contact_radius_m,
        real_contact_area_m2=fine.real_contact_area_m2,
        pillars_in_contact=fine.pillars_in_contact,
        pillar_forces=pillar_forces,
        converged=bool(converged),
        iterations=coarse.iterations + fine.iterations,
        wall_time_s=time.perf_counter() - t0,
        pillar_top_profile=fine.pillar_top_profile,
        diagnostics=diagnostics,
        fields=fine.fields,
    )
