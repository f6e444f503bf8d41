"""Exact solution of the contact problem on a dense SPD matrix.

Primal-dual active set on the diagonally scaled problem: each step solves the equality
system on the active set and moves to {p - gap > 0}; when the set repeats, p > 0 on it and
gap >= 0 off it hold exactly.  If the set cycles (rare, for operators far from an M-matrix)
Lawson-Hanson NNLS on the Cholesky form finishes: 1/2 p.A p + b.p = 1/2 |L^T p + L^-1 b|^2
+ const.

Under force control (``force``, ``load``: :mod:`pillar_xval.contact`) the approach zeta is one
more unknown of each equality system, A_II p_I = zeta l_I - b_I with l_I.p_I = F: two solves
with the same matrix (one factorisation), p_I = v + zeta u, zeta = (F - l.v) / (l.u) (the
Schur complement of the bordered system), or for large active sets one conjugate-gradient
sequence projected onto the constraint (:func:`_bordered_solve`).  The steps are those of the
semismooth Newton method on the bordered problem, so the same active-set iteration
converges; a cycle finishes by a safeguarded secant on zeta over indentation-controlled
solves, whose force grows monotonically with zeta.

References
----------
.. [1] M. Hintermueller, K. Ito, K. Kunisch, "The primal-dual active set strategy as a
   semismooth Newton method", SIAM J. Optim. 13 (2002) 865-888.
.. [2] C. L. Lawson, R. J. Hanson, *Solving Least Squares Problems*, SIAM 1995, ch. 23.
.. [3] J. J. Kalker, Y. van Randen, J. Eng. Math. 6 (1972) 193 (minimum principle).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.linalg.blas import dsymv as symv
from scipy.optimize import nnls
from threadpoolctl import threadpool_limits

from ._load import approach_for_force
from ._solution import ContactSolution, min_map_residual

# Below this size one BLAS thread is faster: OpenBLAS's threads spin on small factorisations
# and, on a loaded 2-core machine, made a 370-unknown solve 20x slower (measured).
SINGLE_THREAD_BELOW = 3000
# Above this size the active-set systems are solved by conjugate gradients warm-started from
# the previous iterate (a few dozen products instead of an O(n^3) factorisation).
CHOLESKY_MAX = 1200
CG_RTOL = 1e-14
CG_RTOL_SEARCH = 1e-6  # active sets that are not yet the last one


def solve_active_set(A: np.ndarray, b: np.ndarray, *, scale: float, weights=None,
                groups: np.ndarray | None = None, initial: np.ndarray | None = None,
                tol: float = 1e-8, max_iterations: int = 100, force: float | None = None,
                load: np.ndarray | None = None) -> ContactSolution:
    """Solve gap = A p + b, p >= 0, gap >= 0, p gap = 0 exactly (or, with ``force``, the same
    with gap = A p + b - zeta l and l.p = F, zeta unknown).

    Parameters
    ----------
    A : ndarray (n, n)
        Symmetric positive definite operator (gap per unit p).
    b : ndarray (n,)
        Undeformed gap minus indentation (negative where the bodies overlap).
    scale : float
        Length that normalises the residual (the indentation).
    weights : ndarray, optional
        Positive row weights: gap_i / w_i is a gap in the unit of ``scale``.
    groups : ndarray of int, optional
        Labels of the unknowns of one pillar: large active sets are solved by conjugate
        gradients preconditioned with these blocks (the near field).
    initial : ndarray of bool, optional
        Starting active set (default: where the bodies overlap, b < 0; under force control,
        where b / l is least).
    tol : float
        ``converged`` requires residual <= tol (under force control relative to the approach
        found, not to ``scale``).
    force : float, optional
        The given total load F = l.p (the caller's unit of l times p): force control.
    load : ndarray (n,), optional
        l, the gap's change per unit approach and the unknowns' share of the force (default
        ones).
    """
    b = np.asarray(b, dtype=float)
    if force is not None:
        load = np.ones(len(b)) if load is None else np.asarray(load, dtype=float)
    args = (A, b, scale, weights, groups, initial, tol, max_iterations, force, load)
    if len(b) < SINGLE_THREAD_BELOW:
        with threadpool_limits(limits=1, user_api="blas"):
            return _solve(*args)
    return _solve(*args)


def _solve(A, b, scale, weights, groups, initial, tol, max_iterations, force=None,
           load=None) -> ContactSolution:
    n = len(b)
    if n == 0:
        return ContactSolution(np.zeros(0), np.zeros(0), True, 0, 0.0, "empty", "converged")
    # The diagonally scaled problem S A S, S = diag(A)^-1/2, applied as s * (A @ (s * p)):
    # forming it would cost a fresh n x n array (page faults included) on every solve.
    s = 1.0 / np.sqrt(np.diag(A))
    bs = b * s
    if force is None:
        active = bs < 0 if initial is None else (np.asarray(initial, bool) & (bs < 0))
        ls = None
    else:
        ls = load * s
        touch = b / load
        active = (touch <= touch.min()) if initial is None else np.asarray(initial, bool)
        if not active.any():
            active = touch <= touch.min()
    seen: set = set()
    p = np.zeros(n)
    zeta = None
    method = "active-set"
    # Sets that conjugate gradients solve are first solved to CG_RTOL_SEARCH (the next set
    # needs no more), and to CG_RTOL once a set repeats: the answer is that of the exact
    # iteration.  A cycle met by the loose solves turns them off.
    loose = True
    for it in range(1, max_iterations + 1):
        p_prev, p = p, np.zeros(n)
        rtol = CG_RTOL_SEARCH if loose else CG_RTOL
        while True:
            if active.any():
                idx = np.nonzero(active)[0]
                grp = None if groups is None else groups[idx]
                if ls is None:
                    sub, ok = _spd_solve(A, s, idx, -bs[idx], p_prev[idx], grp, rtol)
                else:  # p_I = v + zeta u with l.p = F: the bordered system
                    sub, zeta, ok = _bordered_solve(A, s, idx, -bs[idx], ls[idx], force,
                                                    p_prev[idx], grp, rtol)
                if not ok:
                    return _finish(A, b, p_prev * s, scale, weights, tol, it, method,
                                   f"conjugate gradients missed {rtol:g} on an active set of "
                                   f"{len(idx)} unknowns", load, zeta)
                p[idx] = sub
            gap = s * _symmetric_product(A, s * p) + bs
            if ls is not None:
                gap -= zeta * ls
            new = p - gap > 0
            if rtol == CG_RTOL or np.count_nonzero(active) <= CHOLESKY_MAX \
                    or not np.array_equal(new, active):
                break
            rtol, p_prev = CG_RTOL, p.copy()  # the set repeats: solve it exactly
        if np.array_equal(new, active):
            return _finish(A, b, p * s, scale, weights, tol, it, method, "", load, zeta)
        key = new.tobytes()
        if key in seen:
            if not loose:
                break
            loose = False
            seen.clear()
        seen.add(key)
        active = new
    if force is not None:
        return _force_by_secant(A, b, scale, weights, groups, tol, max_iterations, force,
                                load, it)
    method = "nnls"
    try:
        L = np.linalg.cholesky(A * s[:, None] * s[None, :])
    except np.linalg.LinAlgError as exc:
        return _finish(A, b, p * s, scale, weights, tol, it, method,
                       f"operator is not positive definite ({exc})")
    ps, _ = nnls(L.T, -solve_triangular(L, bs, lower=True), maxiter=50 * n)
    return _finish(A, b, ps * s, scale, weights, tol, it, method)


def _force_by_secant(A, b, scale, weights, groups, tol, max_iterations, force, load,
                     cycled) -> ContactSolution:
    """Force control after the bordered active set cycled: zeta such that l.p(zeta) = F,
    p(zeta) the indentation-controlled solution at zeta (NNLS finishes those that cycle too),
    by the bracketing secant of :func:`._load.approach_for_force`; no force is carried up to
    zeta = min b/l."""
    def force_at(zeta):
        sol = _solve(A, b - zeta * load, zeta, weights, groups, None, tol, max_iterations)
        return float(load @ sol.pressure), sol

    floor = float((b / load).min())
    zeta, sol, met = approach_for_force(force_at, force, guess=floor + max(abs(floor), scale),
                                        floor=floor, rtol=tol)
    return _finish(A, b, sol.pressure, scale, weights, tol, cycled, f"secant ({sol.method})",
                   "" if met else f"the force was not met within {tol:g}", load, zeta)


def _finish(A, b, p, scale, weights, tol, iterations, method, failure="", load=None,
            zeta=None) -> ContactSolution:
    gap = A @ p + b
    if zeta is not None:
        gap -= zeta * load
        scale = zeta if zeta > 0 else scale
    residual = min_map_residual(p, gap, weights) / scale
    finite = bool(np.all(np.isfinite(p)) and np.isfinite(residual))
    converged = not failure and finite and residual <= tol
    if failure:
        message = failure
    elif not finite:
        message = "non-finite pressures"
    else:
        message = "converged" if converged else f"residual {residual:.3g} > tolerance {tol:g}"
    return ContactSolution(p, gap, converged, iterations, residual if finite else float("inf"),
                           method, message, approach=None if zeta is None else float(zeta))


def _symmetric_product(A, x):
    """A @ x for a symmetric float64 A: BLAS symv on one triangle (half the memory traffic of
    a general product, which bounds these products); A.T is the same matrix in Fortran
    order, the layout symv reads without a copy."""
    At = A.T
    if A.dtype == np.float64 and At.flags.f_contiguous:
        return symv(1.0, At, x)
    return A @ x


def _scaled(A, s, rows, cols):
    """(S A S)[rows, cols] for the diagonal scaling s (the same products, in the same order,
    as scaling the whole matrix first)."""
    return A[np.ix_(rows, cols)] * s[rows][:, None] * s[cols][None, :]


def _spd_solve(A, s, idx, rhs, x0, groups=None, rtol=CG_RTOL) -> tuple[np.ndarray, bool]:
    """Solve (S A S)[idx, idx] x = rhs (SPD): Cholesky when small, else block-preconditioned
    CG whose products use the whole of A (a zero-padded vector) instead of a copy of the
    submatrix."""
    if len(rhs) <= CHOLESKY_MAX:
        return cho_solve(cho_factor(_scaled(A, s, idx, idx)), rhs), True
    product, precondition = _krylov_tools(A, s, idx, groups)
    x = x0.copy()
    r = rhs - product(x)
    z = precondition(r)
    d = z.copy()
    rz = r @ z
    stop = rtol * np.linalg.norm(rhs)
    for _ in range(10 * len(rhs)):
        if np.linalg.norm(r) <= stop:
            return x, True
        Ad = product(d)
        alpha = rz / (d @ Ad)
        x += alpha * d
        r -= alpha * Ad
        z = precondition(r)
        rz, rz_old = r @ z, rz
        d = z + (rz / rz_old) * d
    return x, False


def _bordered_solve(A, s, idx, rhs, load, force, x0, groups=None,
                    rtol=CG_RTOL) -> tuple[np.ndarray, float, bool]:
    """Solve (S A S)[idx, idx] x = rhs + zeta l, l.x = F for x and zeta.

    Small systems: one Cholesky factorisation, two solves (x = v + zeta u).  Large ones:
    conjugate gradients projected onto l.x = F (Gould, Hribar and Nocedal, SIAM J. Sci.
    Comput. 23 (2001) 1376), preconditioned by the same blocks, from ``x0`` moved onto the
    constraint: one Krylov sequence, as many products as one indentation-controlled solve,
    where solving for v and u apart took two; zeta, the constraint's multiplier, is the
    residual's component along l, taken out of it at each step."""
    if len(rhs) <= CHOLESKY_MAX:
        factor = cho_factor(_scaled(A, s, idx, idx))
        v, u = cho_solve(factor, rhs), cho_solve(factor, load)
        zeta = (force - load @ v) / (load @ u)
        return v + zeta * u, zeta, True
    product, precondition = _krylov_tools(A, s, idx, groups)
    m_load = precondition(load)
    norm = load @ m_load
    x = x0 + ((force - load @ x0) / norm) * m_load
    r = product(x) - rhs
    zeta = 0.0

    def shift(r):
        """The residual less its component along l (the multiplier's, accumulated in
        zeta), and its projected preconditioned form: the shift keeps the residual small,
        so the projection's round-off stays small with it (Gould et al.'s residual update;
        without it the iteration stalled near 1e-8 and diverged)."""
        nonlocal zeta
        z = precondition(r)
        lam = (load @ z) / norm
        zeta += lam
        return r - lam * load, z - lam * m_load

    r, g = shift(r)
    d = -g
    rg = r @ g
    stop = rtol * np.linalg.norm(rhs)
    for _ in range(10 * len(rhs)):
        if np.linalg.norm(r) <= stop:
            return x, zeta, True
        Ad = product(d)
        alpha = rg / (d @ Ad)
        x += alpha * d
        r, g = shift(r + alpha * Ad)
        rg, rg_old = r @ g, rg
        d = -g + (rg / rg_old) * d
    return x, zeta, False


def _krylov_tools(A, s, idx, groups):
    """(product, precondition) of conjugate gradients on (S A S)[idx, idx]: the product by
    the whole of A (a zero-padded vector) instead of a copy of the submatrix, and the block
    Jacobi preconditioner of the groups (a pillar's unknowns)."""
    if groups is None:
        groups = np.zeros(len(idx), int)
    si = s[idx]
    diag = A[idx, idx] * si * si
    # Block Jacobi on the groups: the inverses of the blocks that can be factored, padded to
    # the next power of two of their size and applied by one batched product per size
    # (27 blocks a CG iteration on the largest paper scene: one LAPACK call per block cost
    # more than the products); larger blocks are scaled by their diagonal.
    by_width, large = {}, []
    for g in np.unique(groups):
        sel = np.nonzero(groups == g)[0]
        if len(sel) > CHOLESKY_MAX:
            large.append(sel)
        else:
            by_width.setdefault(1 << (len(sel) - 1).bit_length(), []).append(sel)
    jacobi = np.concatenate(large) if large else np.zeros(0, int)
    batches = []
    m = len(idx)
    for width, sels in by_width.items():
        gather = np.full((len(sels), width), m)  # the padding reads a zero
        inverse = np.zeros((len(sels), width, width))
        for k, sel in enumerate(sels):
            gather[k, :len(sel)] = sel
            block = _scaled(A, s, idx[sel], idx[sel])
            inverse[k, :len(sel), :len(sel)] = cho_solve(cho_factor(block), np.eye(len(sel)))
        valid = gather < m
        batches.append((gather, inverse, valid, gather[valid]))
    padded = np.zeros(len(s))
    r_ext = np.zeros(m + 1)

    def product(d):
        padded[idx] = si * d
        return si * _symmetric_product(A, padded)[idx]

    def precondition(r):
        z = np.empty_like(r)
        r_ext[:-1] = r
        for gather, inverse, valid, target in batches:
            z[target] = np.matmul(inverse, r_ext[gather][:, :, None])[:, :, 0][valid]
        z[jacobi] = r[jacobi] / diag[jacobi]
        return z

    return product, precondition
