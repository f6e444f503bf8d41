"""Frictionless unilateral contact on condensed unknowns, and what is read from it.

The contact pressure is a P1 field lam on the vertices of the contact line (a mortar
multiplier); the nodal forces on the P2 points are f = D lam (:func:`mortar_matrix`).  The
condensed problem is the linear complementarity problem (LCP)::

    w~ = D^T C D lam + D^T q >= 0,   lam >= 0,   lam . w~ = 0,

with C the symmetric positive definite compliance of the two bodies at the contact points,
q = g(r) - zeta the initial gap minus the indentation and w~ the r-weighted gaps (Kalker's
variational principle).  It is the minimisation of 1/2 lam^T (D^T C D) lam + (D^T q)^T lam
over lam >= 0,
solved exactly by :func:`contact.solve_dense` with the vertex weights (integral of psi_j r dr)
that turn weighted gaps into mean gaps for the residual.

References
----------
.. [1] J. J. Kalker, Y. van Randen, J. Eng. Math. 6 (1972) 193 (minimum principle).
.. [2] B. I. Wohlmuth, Acta Numerica 20 (2011) 569 (mortar contact).
"""

from __future__ import annotations

import numpy as np

from ._system import SolveError


def mortar_matrix(r: np.ndarray) -> np.ndarray:
    """D[i, j] = integral of phi_i psi_j r dr on the contact line (dense, small).

    phi_i are the P2 functions at the points ``r`` (vertices at even, edge midpoints at odd
    indices), psi_j the P1 functions at the vertices.  The contact pressure is a P1 field
    with vertex values lam (a mortar multiplier): nodal forces f = D lam, weighted gaps
    D^T w.  Node-to-node contact on the P2 points instead makes the pressure alternate by
    +-5 % between vertices and midpoints and leaves the axis point without force (its
    r-weighted P2 function integrates to zero against a constant).
    """
    n = len(r)
    if n < 3 or n % 2 == 0 or not np.allclose(r[1::2], 0.5 * (r[0:-2:2] + r[2::2]), rtol=0,
                                              atol=1e-9 * r[-1]):
        raise SolveError("contact points are not the P2 points of a straight line")
    t, wq = np.polynomial.legendre.leggauss(4)  # exact for the degree-4 integrand
    t, wq = 0.5 * (t + 1.0), 0.5 * wq
    phi = np.array([(1 - t) * (1 - 2 * t), 4 * t * (1 - t), t * (2 * t - 1)])
    psi = np.array([1 - t, t])
    D = np.zeros((n, n // 2 + 1))
    for k in range(0, n - 2, 2):
        ra, rb = r[k], r[k + 2]
        rq = ra + (rb - ra) * t
        D[k:k + 3, k // 2:k // 2 + 2] += (phi * (wq * rq * (rb - ra))) @ psi.T
    return D


def contact_radius(r: np.ndarray, lam: np.ndarray, w: np.ndarray,
                   band: float = 0.1) -> tuple[float, bool]:
    """Radius of the outermost point of contact, and whether it is the last point.

    The edge lies between the last vertex with positive pressure, r_k, and the next vertex.
    Outside a smooth contact edge the gap opens as (r - a)^(3/2) (Johnson 1985, sec. 4.2),
    so w^(2/3) is fitted by a straight line over the points in [r_k+1, (1 + band) r_k] and
    its root is a, kept in [r_k, r_k+1].  (The pointwise gaps of a mortar solution wobble
    by ~1e-5 zeta at the first points outside; a least-squares fit over ~10 % of the radius
    measured +-2e-4 a on Hertz, against +-3e-3 from the first two points alone.)

    Parameters
    ----------
    r : ndarray
        P2 points of the contact line (vertices at even indices).
    lam : ndarray
        Pressure at the vertices.
    w : ndarray
        Pointwise gaps at the P2 points.
    """
    active = np.nonzero(lam > 0)[0]
    if len(active) == 0:
        return 0.0, False
    k = 2 * active[-1]
    if k == len(r) - 1:
        return float(r[k]), True
    outside = np.nonzero((r >= r[k + 2]) & (w > 0))[0]
    sel = outside[r[outside] <= (1.0 + band) * r[k]]
    if len(sel) < 3:
        sel = outside[:3]
    if len(sel) < 2:
        return float(0.5 * (r[k] + r[k + 2])), False
    slope, intercept = np.polyfit(r[sel], w[sel] ** (2.0 / 3.0), 1)
    a = -intercept / slope if slope > 0 else 0.5 * (r[k] + r[k + 2])
    return float(np.clip(a, r[k], r[k + 2])), False
