"""The FFT model under a given force: Polonsky and Keer's own, force-controlled CG.

The constrained CG takes the force natively (:func:`pillar_xval.contact.constrained_cg`,
``force=``): the approach is the multiplier of the constraint sum(p L^2) = F, which costs one
preconditioner application more per iteration than a given indentation.  What the force
leaves open is the grid, which an indentation sets:

- on pillars, the candidate region (pillar tops where the undeformed gap is below zeta).  The
  answer does not depend on it once it holds every cell the lens can reach at the solved
  zeta (cells beyond carry no pressure); so the grid is built for a *design* indentation a
  little above the best guess (the coarser level's answer, :data:`DESIGN_MARGIN`), and built
  again, larger, in the rare case the solved zeta exceeds it;
- on a flat scene, the cell size itself, 2 sqrt(R zeta) / N: the grid follows the solved
  zeta (a fixed point: each round builds the grid for the last round's answer, until they
  agree within :data:`FLAT_DESIGN_RTOL`), so the answer is the indentation-controlled
  model's at the solved indentation, whose force is the given one.

The nested warm start solves every coarser level under the same force: each gives the next
its design indentation and its starting pressures.  The coarsest starts from the closed-form
guess (:func:`pillar_xval.scenes.analytic.indentation_estimate`: Hertz's, below the
lattice's indentation) and grows its grid until it holds the answer, a few rounds on a grid
of 8 cells per diameter; a level between it and the finest only starts the next, so it is
solved once, on its own design, however far its answer moves.
"""

from __future__ import annotations

import time

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import Scene, analytic

from ._fft import (WARM_START_MIN_CELLS, _coarser, _initial_pressure, _interpolate, _prepare,
                   finish, run_cg, warm_levels)
from ._fft_operator import TransformWorkspace

__all__ = ["DESIGN_MARGIN", "FLAT_DESIGN_RTOL", "solve_under_force"]

# Design indentation over the best guess on pillars: N/2 and N differ by about 0.2/N in the
# force (the edge cells' first-order error), under 1 % in zeta from N = 16; 3 % more zeta is
# 3 % more candidate cells and leaves the rebuild to guesses off by more than that.
DESIGN_MARGIN = 1.03
# Flat scenes: the grid's zeta and the solved one agree within this; the answer then differs
# from the indentation-controlled one at the solved zeta by this times the sensitivity of the
# discrete force to the cell size (the discretisation error's order times its size, < 1e-2).
FLAT_DESIGN_RTOL = 1e-6
# Rounds of the design (grid rebuilt for the solved zeta) before the solve gives up.
MAX_DESIGN_ROUNDS = 6


def solve_under_force(scene: Scene, cells_per_diameter: int, opts, be, start: float,
                      nested: bool, workspace=None) -> ContactResult:
    """:func:`bem_solver.solve_fft` on a force-controlled ``scene`` (module docstring);
    ``workspace``: the transforms' work arrays, shared by the levels (coarsest first)."""
    force = scene.force_N
    workspace = workspace if workspace is not None else TransformWorkspace()
    coarse = cells_per_diameter // 2
    rough, levels = None, []
    lap = time.perf_counter()
    if opts.warm_start and coarse >= WARM_START_MIN_CELLS:
        rough = _coarser(scene, coarse, opts, be, workspace)
        levels = warm_levels(rough, coarse)
        guess = rough.indentation_m
    else:
        guess = analytic.indentation_estimate(scene)
    warm = time.perf_counter() - lap
    design = guess if scene.is_flat else guess * DESIGN_MARGIN
    only_starts = nested and rough is not None  # a level between the coarsest and the finest
    rounds = []
    for _ in range(MAX_DESIGN_ROUNDS):
        geometry = scene.designed(design)
        setup = _prepare(geometry, cells_per_diameter, opts, be, workspace, start)
        grid = setup.grid
        b = be.asarray(grid.gap0, dtype=be.xp.float64) + geometry.indentation_m
        q0 = (_initial_pressure(setup.plan, b - geometry.indentation_m, be) if rough is None
              else _interpolate(rough, grid, be, slivers=opts.edge_correction))
        setup.timings["warm_start"] = warm
        outcome = run_cg(setup, b, q0, geometry.indentation_m, opts, be,
                         force=force / grid.cell_size**2)
        zeta = outcome.approach
        rounds.append({"design_indentation_m": geometry.indentation_m,
                       "indentation_m": zeta, "iterations": outcome.iterations})
        # A coarser level only starts the next: it is solved once on its design, unless it
        # is the coarsest, whose design, from the closed-form guess, may be far off.
        if only_starts or _designed_for(scene, geometry.indentation_m, zeta):
            break
        design = zeta if scene.is_flat else zeta * DESIGN_MARGIN
        rough = finish(geometry, setup, outcome, cells_per_diameter, opts, be, levels, start)
    else:
        outcome.converged = False
        outcome.message = (f"the grid's design indentation did not settle in "
                           f"{MAX_DESIGN_ROUNDS} rounds ({rounds[-2]['indentation_m']:.6g} "
                           f"then {zeta:.6g} m)")
    solved = (scene.designed(zeta) if nested else
              scene.implied(zeta, f"bem-fft at N = {cells_per_diameter}"))
    result = finish(solved, setup, outcome, cells_per_diameter, opts, be, levels, start)
    return result.for_force(scene.to_dict(), zeta, design_rounds=rounds)


def _designed_for(scene: Scene, design: float, zeta: float) -> bool:
    """Whether a grid built for ``design`` is the grid of the solved ``zeta``: on pillars,
    when it holds every cell the lens can reach (zeta <= design); on a flat scene, when the
    cell size agrees (module docstring)."""
    if scene.is_flat:
        return abs(zeta / design - 1.0) <= FLAT_DESIGN_RTOL
    return zeta <= design
