"""Frictionless unilateral contact on condensed unknowns, and what is read from it.

The contact pressure is a P1 field lam on the vertices of the contact line (a mortar
multiplier); the nodal forces on the P2 points are f = D lam (:func:`mortar_matrix`).  The
condensed problem is the linear complementarity problem (LCP)::

    w~ = D^T C D lam + D^T q >= 0,   lam >= 0,   lam . w~ = 0,

with C the symmetric positive definite compliance of the two bodies at the contact points,
q = g(r) - zeta the initial gap minus the indentation and w~ the r-weighted gaps (Kalker's
variational principle).  It is the minimisation of 1/2 lam^T (D^T C D) lam + (D^T q)^T lam
over lam >= 0,
solved exactly by :func:`pillar_xval.contact.solve_active_set` with the vertex weights (integral of psi_j r dr)
that turn weighted gaps into mean gaps for the residual.

References
----------
.. [1] J. J. Kalker, Y. van Randen, J. Eng. Math. 6 (1972) 193 (minimum principle).
.. [2] B. I. Wohlmuth, Acta Numerica 20 (2011) 569 (mortar contact).
"""

from __future__ import annotations

import numpy as np

from .._reduced import SolveError

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
