"""The element matrices of :mod:`.solid3d`'s forms on straight P2/P1 tetrahedra, vectorised.

On an affine tetrahedron with barycentric coordinates lambda_0..3 (skfem's reference vertices
0..3: lambda_0 = 1 - x - y - z, lambda_1 = x, ...), every P2 gradient is a combination of the
constant barycentric gradients with coefficients linear in lambda::

    vertex i:      phi = lambda_i (2 lambda_i - 1),  grad phi = (4 lambda_i - 1) grad lambda_i,
    edge (i, j):   phi = 4 lambda_i lambda_j,        grad phi = 4 (lambda_j grad lambda_i
                                                                 + lambda_i grad lambda_j),

in skfem's ElementTetP2 order (vertices, then the edges (0, 1), (1, 2), (0, 2), (0, 3), (1, 3),
(2, 3)).  Products of two such gradients, or of one with a P1 function, are quadratic, so the
four-point degree-2 rule integrates every matrix here exactly (to round-off, the same values as
skfem's assembly of the forms, tested).  The rule's sums over its points and the functions'
coefficients do not depend on the element: they are summed once into constant tensors, and
an element's matrices are those tensors contracted with its barycentric gradients, one matrix
product over a block of elements (the stiffness: 100 x 16 constants against 16 x 9 products
of gradients per element) instead of one skfem assembly per form and component.
"""

from __future__ import annotations

import numpy as np

EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))
# The four-point rule of degree 2 on the tetrahedron (weights: a quarter of the volume each):
# barycentric coordinates of its points, row g.
_A, _B = 0.5854101966249685, 0.1381966011250105
POINTS = np.full((4, 4), _B) + np.eye(4) * (_A - _B)


def _gradient_coefficients() -> np.ndarray:
    """c[g, a, k]: grad phi_a at point g = sum_k c[g, a, k] grad lambda_k."""
    c = np.zeros((4, 10, 4))
    for g, lam in enumerate(POINTS):
        for i in range(4):
            c[g, i, i] = 4.0 * lam[i] - 1.0
        for e, (i, j) in enumerate(EDGES):
            c[g, 4 + e, i] = 4.0 * lam[j]
            c[g, 4 + e, j] = 4.0 * lam[i]
    return c


COEFFICIENTS = _gradient_coefficients()


def barycentric_gradients(points: np.ndarray, tets: np.ndarray):
    """(grad lambda (E, 3, 4): component p, vertex k; volume (E,)) of the tetrahedra
    ``tets`` (4, E) of ``points`` (3, N)."""
    x = points[:, tets]  # (3, 4, E)
    J = np.transpose(x[:, 1:, :] - x[:, :1, :], (2, 0, 1))  # columns x_k - x_0, k = 1..3
    inv = np.linalg.inv(J)  # rows: grad lambda_1..3
    grad = np.empty((len(J), 3, 4))
    grad[:, :, 1:] = np.transpose(inv, (0, 2, 1))
    grad[:, :, 0] = -grad[:, :, 1:].sum(axis=2)
    return grad, np.abs(np.linalg.det(J)) / 6.0


def _stiffness_coefficients() -> np.ndarray:
    """S[10 t + s, 4 k + l] = (1/4) sum_g c[g, t, k] c[g, s, l]: the integral of
    d_p phi_t d_q phi_s over an element of unit volume is sum_kl S[ts, kl] G[p, k] G[q, l]
    for its barycentric gradients G (component p, vertex k)."""
    c = COEFFICIENTS
    return 0.25 * np.einsum("gtk,gsl->tskl", c, c).reshape(100, 16)


def _divergence_coefficients() -> np.ndarray:
    """R[q, s, k] = (1/4) sum_g lambda_q(x_g) c[g, s, k]: the integral of lambda_q d_a phi_s
    over an element of unit volume is sum_k R[q, s, k] G[a, k]."""
    return 0.25 * np.einsum("gq,gsk->qsk", POINTS, COEFFICIENTS)


STIFFNESS = _stiffness_coefficients()
DIVERGENCE = _divergence_coefficients()


def elasticity_blocks(grad: np.ndarray, volume: np.ndarray, mu: np.ndarray,
                      out: np.ndarray | None = None) -> np.ndarray:
    """The 3 x 3 blocks of the shear stiffness A (:func:`.solid3d.shear_stiffness`) between
    the nodes of each element, V[e, 3 b + a, 10 t + s] = A[(t, b), (s, a)]: the row (test)
    node t, component b, the column (trial) node s, component a,

        A[(t, b), (s, a)] = mu (delta_ab sum_c Q[t, c, s, c] + Q[t, a, s, b]),

    Q[t, p, s, q] the integral of d_p phi_t d_q phi_s; from the barycentric gradients
    ``grad`` (E, 3, 4), ``volume`` and ``mu`` (E,); written into ``out`` (E, 9, 100)
    when given (a buffer the caller reuses across blocks of elements)."""
    E = len(volume)
    # W[e, kl, b, a] = delta_ab (G^T G)[k, l] + G[a, k] G[b, l], times mu and the volume
    W = np.einsum("eak,ebl->eklba", grad, grad)
    gram = np.einsum("eck,ecl->ekl", grad, grad)
    for b in range(3):
        W[:, :, :, b, b] += gram
    W *= (mu * volume)[:, None, None, None, None]
    W = np.ascontiguousarray(np.transpose(W.reshape(E, 16, 9), (0, 2, 1))).reshape(9 * E, 16)
    if out is None:
        return (W @ STIFFNESS.T).reshape(E, 9, 100)
    np.matmul(W, STIFFNESS.T, out=out.reshape(9 * E, 100))
    return out


def divergence_blocks(grad: np.ndarray, volume: np.ndarray) -> np.ndarray:
    """B[e, q, s, a] = integral of lambda_q d_a phi_s (:func:`.solid3d.divergence_coupling`:
    test P1 vertex q, trial P2 node s, component a), from the barycentric gradients ``grad``
    (E, 3, 4) and ``volume`` (E,)."""
    E = len(volume)
    B = (grad.reshape(3 * E, 4) @ DIVERGENCE.reshape(40, 4).T).reshape(E, 3, 40)
    B *= volume[:, None, None]
    return np.transpose(B, (0, 2, 1)).reshape(E, 4, 10, 3)


def pressure_masses(volume: np.ndarray) -> np.ndarray:
    """M[e, q, r] = integral of lambda_q lambda_r = volume (1 + delta_qr) / 20."""
    return (np.ones((4, 4)) + np.eye(4))[None] * (volume / 20.0)[:, None, None]
