"""Contact solvers shared by every model: one sign convention, one residual.

The discrete frictionless contact problem, displacement-controlled, for an SPD operator A
(the compliance of the bodies at the contact unknowns) and b the undeformed gap minus the
indentation (negative where the undeformed bodies overlap)::

    gap = A p + b,   p >= 0,   gap >= 0,   p_i gap_i = 0 for every i.

It is Kalker's minimum principle: p minimises 1/2 p.A p + b.p over p >= 0.

Force control.  With a given total load F instead of the indentation, b is the undeformed
gap alone and the indentation zeta is one more unknown: the gap is A p + b - zeta l, with l
the gap's change per unit approach (1 on a BEM's cells, the hat functions' integrals of a
mortar FEM, the orbit sizes of a symmetry-reduced operator), and l.p = F.  Each model's
force is such a sum (its unknowns times their areas), so zeta is exactly the multiplier of
the constraint l.p = F in the same minimum principle, and both solvers take it natively
(``force=``, ``load=``): the exact active set with zeta one more unknown of each equality
system, the constrained CG as Polonsky and Keer wrote it (directions projected onto l.p = 0,
the approach the mean gap over the contact set, pressures rescaled to F after a truncated
step).  ``ContactSolution.approach`` returns zeta.  Every solver
returns a :class:`ContactSolution` whose ``residual`` is the max-norm min-map residual
relative to a length ``scale`` (the indentation):

    e_i = |gap_i / w_i|  where p_i > 0,   max(-gap_i / w_i, 0)  where p_i = 0,

with w the optional positive ``weights`` that turn a weighted gap (a row of a
symmetry-reduced or mortar operator) into a gap in metres.  It is zero exactly at the
solution and bounds both the interpenetration and the gap on the contact set.  A solver that
misses its tolerance returns ``converged = False`` and a message; it never raises for that.

- :func:`solve_active_set`: exact primal-dual active set on a dense matrix (NNLS if it cycles).
- :func:`constrained_cg`: Polonsky-Keer constrained conjugate gradients on an operator given
  as a function (FFT half-space, or an FEM compliance applied by back-substitution).
- :func:`approach_for_force`: the approach at which a solver under a given indentation
  carries a given force (a bracketing secant over whole solves), where force control cannot
  be native; :func:`solve_at_force`: a model's answer to a force-controlled scene that way.
"""

from ._active_set import solve_active_set
from ._cg import (FewCellUpdates, MixedPrecision, Operator, constrained_cg,
                  diagonal_preconditioner)
from ._load import approach_for_force, solve_at_force
from ._solution import ContactSolution, evaluate, min_map_residual

__all__ = [
    "ContactSolution",
    "FewCellUpdates",
    "MixedPrecision",
    "Operator",
    "approach_for_force",
    "constrained_cg",
    "diagonal_preconditioner",
    "evaluate",
    "min_map_residual",
    "solve_active_set",
    "solve_at_force",
]
