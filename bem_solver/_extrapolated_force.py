"""The extrapolated dense BEM under a given force.

Its force is the extrapolated one, F*(zeta) = F2 + (F2 - F1) / ((P2 / P1)^k - 1), a
combination of the two levels' forces at one indentation; the answer to a given force is the
indentation where F*(zeta) = F, at which both levels are then read and extrapolated as under
a given indentation (so the round trip is exact).  Solving each level under the force alone
would not do: the levels would sit at two indentations, and their extrapolation would miss F
by the product of the levels' force and stiffness errors (~1e-4).

So each level is first solved natively under the force (:mod:`._dense_force`: the approach an
unknown of the exact solver), which builds its operator on a candidate region that holds the
contact; then F*(zeta) = F is closed by a bracketing secant
(:func:`pillar_xval.contact.approach_for_force`) from the levels' extrapolated indentation,
each step solving both levels again at one indentation on their kept operators
(:func:`._dense.resolve`: an active-set solve of a few steps from the last contact set, no
assembly, which is most of a solve's time).  A flat scene's cells follow the indentation, as
in the dense model: the whole is repeated on cells for the solved zeta until they agree
(:data:`._dense_force.FLAT_DESIGN_RTOL`).
"""

from __future__ import annotations

import time

from pillar_xval.contact import approach_for_force
from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import Scene, analytic

from ._dense import (RTOL_COMPLEMENTARITY, _refuse_if_too_large, elastic_setup, level_result,
                     resolve, solve_rounds)
from ._dense_force import FLAT_DESIGN_RTOL, MAX_DESIGN_ROUNDS
from ._extrapolated import extrapolate, extrapolation_order, fine_level, richardson

__all__ = ["solve_under_force"]


def solve_under_force(scene: Scene, p1: int, cells: str, pillars: str, compliance,
                      t0: float) -> ContactResult:
    """:func:`bem_solver.solve_dense_extrapolated` on a force-controlled ``scene``."""
    force = scene.force_N
    resolutions = (p1, fine_level(p1))
    order = extrapolation_order(scene)
    design = analytic.indentation_estimate(scene)
    elastic, rounds = {}, []
    for _ in range(MAX_DESIGN_ROUNDS):
        geometry = scene.designed(design)
        levels = []
        for P in resolutions:
            _refuse_if_too_large(geometry, P, cells, "exact")
            if P not in elastic:
                elastic[P] = elastic_setup(geometry, P, cells, pillars, compliance)
            levels.append(solve_rounds(geometry, P, cells, "exact", elastic[P], force))

        def force_at(zeta, levels=levels):
            again = [resolve(level, zeta) for level in levels]
            carried = richardson(*(_total(level) for level in again), *resolutions, order)
            return carried, again

        guess = richardson(levels[0].zeta, levels[1].zeta, *resolutions, order)
        zeta, levels, met = approach_for_force(force_at, force, guess=guess,
                                               rtol=RTOL_COMPLEMENTARITY)
        rounds.append({"design_indentation_m": geometry.indentation_m, "indentation_m": zeta,
                       "force_met": met})
        if not scene.is_flat or abs(zeta / geometry.indentation_m - 1.0) <= FLAT_DESIGN_RTOL:
            break
        design = zeta
    solved = scene.implied(zeta, f"bem-richardson at P = {p1}, {resolutions[1]}")
    now = time.perf_counter() - t0
    coarse, fine = (level_result(solved, level, now, pillars) for level in levels)
    result = extrapolate(solved, coarse, fine, cells, t0)
    if not met:
        result.converged = False
        result.diagnostics["message"] = (
            f"the extrapolated force {result.total_force_N:.6g} N missed the given "
            f"{force:.6g} N by more than {RTOL_COMPLEMENTARITY:g}")
    return result.for_force(scene.to_dict(), zeta, design_rounds=rounds)


def _total(level) -> float:
    """The force of a level's solution (N): the orbit-weighted sum of its element forces."""
    return float(level.disc.rep_weight @ level.sol.pressure)
