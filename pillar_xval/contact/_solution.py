"""The result every contact solver returns, and the one residual they all report."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class ContactSolution:
    """Solution of gap = A p + b, p >= 0, gap >= 0, p gap = 0 (see :mod:`pillar_xval.contact`).

    ``pressure`` is p (the unit of the caller's unknowns), ``gap`` = A p + b (the caller's
    gap unit: m, or m times a weight), ``residual`` the min-map residual over ``scale``,
    ``history`` the residual after each iteration (iterative solvers), ``reentries`` the
    iterations in which unknowns re-entered the contact set and ``halvings`` the truncated
    steps shortened to lower the energy (constrained CG).  ``approach`` is the indentation a
    force-controlled solve found (the multiplier of the force constraint, in the unit of the
    caller's gaps), None under indentation control.
    """

    pressure: np.ndarray
    gap: np.ndarray
    converged: bool
    iterations: int
    residual: float
    method: str
    message: str = ""
    history: list = field(default_factory=list)
    reentries: int = 0
    halvings: int = 0
    approach: float | None = None


def min_map_residual(pressure, gap, weights=None) -> float:
    """max_i of |gap_i| on {p > 0} and max(-gap_i, 0) elsewhere (gaps divided by ``weights``).

    max(|gap| on the set, -gap anywhere) equals it, since -gap <= |gap| on the set."""
    gap = np.asarray(gap, dtype=float)
    if gap.size == 0:
        return 0.0
    if weights is not None:
        gap = gap / weights
    on_set = np.abs(gap) * (np.asarray(pressure) > 0.0)
    return float(max(on_set.max(), -gap.min(), 0.0))


def evaluate(A, b, pressure, *, scale: float, weights=None, tol: float = 1e-8,
             method: str = "given", iterations: int = 0, message: str = "") -> ContactSolution:
    """The :class:`ContactSolution` of pressures found by other means (the paper's radius
    search, say): gap, residual, and ``converged`` when p >= 0 and the residual is within
    ``tol``."""
    p = np.asarray(pressure, dtype=float)
    gap = A @ p + b
    residual = min_map_residual(p, gap, weights) / scale
    ok = bool(np.all(np.isfinite(p)) and p.min(initial=0.0) >= 0.0 and residual <= tol)
    return ContactSolution(p, gap, ok, iterations, residual, method,
                           message or ("converged" if ok else
                                       f"residual {residual:.3g} > tolerance {tol:g}"))
