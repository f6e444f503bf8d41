"""Exact solvers of the contact complementarity problem on a dense symmetric operator.

Find forces q >= 0 with gap y = M q - c >= 0 and q * y = 0 on every element (Kalker's
variational principle: the minimiser of 1/2 q^T M q - c^T q over q >= 0).

References
----------
.. [1] M. Hintermueller, K. Ito, K. Kunisch, "The primal-dual active set strategy as a
   semismooth Newton method", SIAM J. Optim. 13 (2002) 865-888.
.. [2] C. L. Lawson, R. J. Hanson, *Solving Least Squares Problems*, Prentice-Hall, 1974
   (NNLS, used as the fallback).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import nnls
from threadpoolctl import threadpool_limits


class NoConvergenceError(RuntimeError):
    """A contact solver did not reach its tolerance; the message says how far it got."""


@dataclass
class LCPSolution:
    q: np.ndarray
    gap: np.ndarray
    iterations: int
    method: str
    complementarity: float   # max |q_i y_i| / (max q * max |c|)
    min_gap: float           # most negative gap, relative to max |c|


# Below this size one BLAS thread is faster: OpenBLAS's threads spin on small factorisations
# and, on a loaded 2-core machine, made a 370-unknown solve 20x slower (measured).
SINGLE_THREAD_BELOW = 3000


def solve_lcp(M: np.ndarray, c: np.ndarray, groups: np.ndarray | None = None,
              initial: np.ndarray | None = None, max_iterations: int = 100) -> LCPSolution:
    """See :func:`_solve_lcp`; runs with one BLAS thread on small systems."""
    if len(c) < SINGLE_THREAD_BELOW:
        with threadpool_limits(limits=1, user_api="blas"):
            return _solve_lcp(M, c, groups, initial, max_iterations)
    return _solve_lcp(M, c, groups, initial, max_iterations)


def _solve_lcp(M: np.ndarray, c: np.ndarray, groups: np.ndarray | None = None,
               initial: np.ndarray | None = None, max_iterations: int = 100) -> LCPSolution:
    """Primal-dual active set on the diagonally scaled problem, NNLS if it cycles.

    The active set starts at ``initial`` (a guess; default {c > 0}, where the undeformed bodies
    overlap); each step solves
    the equality system on the active set and moves to {q - y > 0}.  It stops when the set
    repeats: then q > 0 on the set and y >= 0 off it hold exactly.  ``groups`` labels the
    unknowns of one pillar: large systems are solved by conjugate gradients preconditioned
    with the pillars' own blocks (the near field), which leaves only the smooth far-field
    coupling to the iteration.
    """
    n = len(c)
    if n == 0:
        return LCPSolution(np.zeros(0), np.zeros(0), 0, "empty", 0.0, 0.0)
    s = 1.0 / np.sqrt(np.diag(M))
    Ms = M * s[:, None] * s[None, :]
    cs = c * s
    active = cs > 0 if initial is None else (np.asarray(initial, bool) & (cs > 0))
    seen = set()
    q = np.zeros(n)
    for it in range(1, max_iterations + 1):
        q_prev, q = q, np.zeros(n)
        if active.any():
            idx = np.nonzero(active)[0]
            q[idx] = _spd_solve(Ms[np.ix_(idx, idx)], cs[idx], q_prev[idx],
                                None if groups is None else groups[idx])
        y = Ms @ q - cs
        new = q - y > 0
        if np.array_equal(new, active):
            return summarise(M, c, q * s, it, "active-set")
        key = new.tobytes()
        if key in seen:
            break
        seen.add(key)
        active = new
    # Cycling (rare, for operators far from an M-matrix): Lawson-Hanson on the Cholesky form,
    # 1/2 q^T M q - c^T q = 1/2 |L^T q - L^-1 c|^2 + const.
    L = np.linalg.cholesky(Ms)
    qs, _ = nnls(L.T, solve_triangular(L, cs, lower=True), maxiter=50 * n)
    return summarise(M, c, qs * s, it, "nnls")


# Above this size the active-set systems are solved by conjugate gradients warm-started from
# the previous iterate (a few dozen products instead of an O(n^3) factorisation).
CHOLESKY_MAX = 1200
CG_RTOL = 1e-14


def _spd_solve(A, b, x0, groups=None):
    if len(b) <= CHOLESKY_MAX:
        return cho_solve(cho_factor(A), b)
    if groups is None:
        groups = np.zeros(len(b), int)
    blocks = []
    for g in np.unique(groups):
        idx = np.nonzero(groups == g)[0]
        if len(idx) > CHOLESKY_MAX:  # a block too large to factor: Jacobi on its diagonal
            blocks.append((idx, None))
        else:
            blocks.append((idx, cho_factor(A[np.ix_(idx, idx)])))

    diag = np.diag(A)

    def precondition(r):
        z = np.empty_like(r)
        for idx, factor in blocks:
            z[idx] = r[idx] / diag[idx] if factor is None else cho_solve(factor, r[idx])
        return z

    x = x0.copy()
    r = b - A @ x
    z = precondition(r)
    p = z.copy()
    rz = r @ z
    stop = CG_RTOL * np.linalg.norm(b)
    for _ in range(10 * len(b)):
        if np.linalg.norm(r) <= stop:
            return x
        Ap = A @ p
        alpha = rz / (p @ Ap)
        x += alpha * p
        r -= alpha * Ap
        z = precondition(r)
        rz, rz_old = r @ z, rz
        p = z + (rz / rz_old) * p
    raise NoConvergenceError(f"conjugate gradients did not reach {CG_RTOL:g} in {10 * len(b)} steps")


def summarise(M, c, q, iterations, method) -> LCPSolution:
    """Gap, complementarity and worst gap of forces ``q`` (also for solutions made
    elsewhere, such as the paper's radius search)."""
    y = M @ q - c
    scale_c = max(np.max(np.abs(c)), 1e-300)
    scale_q = max(np.max(np.abs(q)), 1e-300)
    comp = float(np.max(np.abs(q * y)) / (scale_q * scale_c))
    return LCPSolution(q, y, iterations, method, comp, float(min(0.0, y.min()) / scale_c))


def check_solution(sol: LCPSolution, rtol: float = 1e-8) -> None:
    """Raise :class:`NoConvergenceError` unless q >= 0, y >= 0, q y = 0 hold to ``rtol``."""
    if not np.all(np.isfinite(sol.q)):
        raise NoConvergenceError("contact solver produced non-finite forces")
    if sol.q.min(initial=0.0) < 0 or sol.min_gap < -rtol or sol.complementarity > rtol:
        raise NoConvergenceError(
            f"contact solver ({sol.method}) missed its tolerance {rtol:g}: min gap "
            f"{sol.min_gap:.3g}, complementarity {sol.complementarity:.3g}")
