"""The dense BEM under a given force: the approach as one more unknown of the exact solver.

The exact active set takes the force natively (:func:`pillar_xval.contact.solve_active_set`,
``force=``): each of its equality systems gains the approach as an unknown and the force as
an equation, two solves with one factorisation instead of one, and the same few active-set
steps.  The operator, whose assembly is most of a solve's time, is built once per candidate
region, as under a given indentation.

What an indentation sets besides the gap is the discretisation:

- on pillars, only the first candidate region (1.15 Hertz radii): the region grows, as under
  a given indentation, until a lower bound of the deflection rules contact out beyond it,
  now at the solved indentation, so the answer does not depend on the first guess
  (:func:`pillar_xval.scenes.analytic.indentation_estimate`);
- on a flat scene, the cell size, 2 sqrt(R zeta) / P: the cells follow the solved zeta (a
  fixed point, each round discretised for the last round's answer, until they agree within
  :data:`FLAT_DESIGN_RTOL`), so the answer is the indentation-controlled model's at the
  solved indentation.

The paper's radius search (``contact = "paper"``) is displacement-controlled: under a force
it runs at the approaches of a bracketing secant (:func:`pillar_xval.contact
.approach_for_force`), a whole search each.
"""

from __future__ import annotations

import time

from pillar_xval.contact import solve_at_force
from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import Scene, analytic
from pillar_xval.scenes.floor import check_floor_scope

from ._dense import (RTOL_COMPLEMENTARITY, _refuse_if_too_large, elastic_setup, level_result,
                     solve_dense, solve_rounds)

__all__ = ["FLAT_DESIGN_RTOL", "solve_under_force"]

# Flat scenes: the cells' indentation and the solved one agree within this; the answer then
# differs from the indentation-controlled one at the solved zeta by this times the discrete
# force's sensitivity to the cell size (its error's order times its size, < 1e-2).
FLAT_DESIGN_RTOL = 1e-6
MAX_DESIGN_ROUNDS = 6
# The paper's search under a force: whole searches of the secant.
MAX_SEARCHES = 60


def solve_under_force(scene: Scene, P: int, cells: str, contact: str, pillars: str,
                      compliance, progress, t0: float) -> ContactResult:
    """:func:`bem_solver.solve_dense` on a force-controlled ``scene`` (module docstring)."""
    if contact == "paper":
        return _paper_search(scene, P, cells, pillars, compliance, progress, t0)
    force = scene.force_N
    design = analytic.indentation_estimate(scene)
    elastic, rounds = None, []
    for _ in range(MAX_DESIGN_ROUNDS):
        geometry = scene.designed(design)
        _refuse_if_too_large(geometry, P, cells, contact)
        if elastic is None:
            elastic = elastic_setup(geometry, P, cells, pillars, compliance, progress)
        level = solve_rounds(geometry, P, cells, contact, elastic, force)
        zeta = level.zeta
        rounds.append({"design_indentation_m": geometry.indentation_m,
                       "indentation_m": zeta, "candidate_rounds": level.rounds})
        if not scene.is_flat or not level.sol.converged \
                or abs(zeta / geometry.indentation_m - 1.0) <= FLAT_DESIGN_RTOL:
            break
        design = zeta
    else:
        level.sol.converged = False
        level.sol.message = (f"the cells' design indentation did not settle in "
                             f"{MAX_DESIGN_ROUNDS} rounds ({rounds[-2]['indentation_m']:.6g} "
                             f"then {zeta:.6g} m)")
    check_floor_scope(scene, "bem", zeta, f"bem at P = {P}")
    solved = scene.implied(zeta, f"bem at P = {P}")
    result = level_result(solved, level, time.perf_counter() - t0, pillars)
    return result.for_force(scene.to_dict(), zeta, design_rounds=rounds)


def _paper_search(scene: Scene, P: int, cells: str, pillars: str, compliance, progress,
                  t0: float) -> ContactResult:
    """The paper's radius search at the approach where it carries the force."""
    result = solve_at_force(
        lambda at: solve_dense(at, P, cells, "paper", pillars=pillars, compliance=compliance,
                               progress=progress),
        scene, guess=analytic.indentation_estimate(scene), how=f"bem at P = {P}, the paper's "
        "search", rtol=RTOL_COMPLEMENTARITY, max_solves=MAX_SEARCHES)
    result.wall_time_s = time.perf_counter() - t0
    return result
