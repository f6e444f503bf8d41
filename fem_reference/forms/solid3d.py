"""3D linear elasticity, mixed displacement-pressure (Taylor-Hood P2/P1 tetrahedra).

Displacement u = (u_x, u_y, u_z), pressure p = lambda div u, so that
sigma = 2 mu eps(u) + p I.  The saddle-point system is::

    [ A     B^T ] [u]   [f]        A = (2 mu eps(u), eps(v)),  B = (q, div u),
    [ B   -C/lam] [p] = [0]        C = (p, q),

exact at nu = 1/2 (1/lambda = 0) and valid for every nu in [0, 1/2].  Solvers rescale the
pressure, p = beta p~ with beta = sqrt(2 nu mu) (:func:`mixed_coefficients`, shared with the
axisymmetric forms), so that no coefficient is infinite at either end of that range.  Pure P2
displacement locks: 30 % too stiff at nu = 0.4999 in 3D (measured while choosing the element).

References
----------
.. [1] T. J. R. Hughes, *The Finite Element Method*, Dover 2000, sec. 4.3 (mixed u-p).
.. [2] C. Taylor, P. Hood, Comput. Fluids 1 (1973) 73 (P2/P1 pair).
"""

from __future__ import annotations

from skfem import BilinearForm
from skfem.helpers import ddot, div, sym_grad

from .axisymmetric import mixed_coefficients

__all__ = ["derivative_coupling", "divergence_coupling", "gradient_product",
           "mixed_coefficients", "pressure_mass", "shear_stiffness", "stress", "von_mises"]


@BilinearForm
def shear_stiffness(u, v, w):
    """A: integral of 2 mu eps(u) : eps(v), with ``w.mu`` the shear modulus (Pa)."""
    return 2.0 * w.mu * ddot(sym_grad(u), sym_grad(v))


@BilinearForm
def divergence_coupling(u, q, w):
    """B: integral of q div u (trial u vector P2, test q scalar P1)."""
    return q * div(u)


@BilinearForm
def pressure_mass(p, q, w):
    """C: integral of p q; the pressure block is -(1/lambda) C."""
    return p * q


# The same operators from scalar P2 pieces (10 x 10 local matrices instead of 30 x 30; the
# assembler interleaves them, see fem_reference.solid3d.system.vector_blocks):
#   A[(t, b), (s, a)] = mu (delta_ab sum_c K_cc + K_ab)[t, s],  K_pq[t, s] = (d_q phi_s, d_p phi_t)
#   B[q, (s, a)] = (psi_q, d_a phi_s).
def gradient_product(p: int, q: int):
    """K_pq: integral of mu d_q(trial) d_p(test), scalar P2."""
    @BilinearForm
    def form(u, v, w):
        return w.mu * u.grad[q] * v.grad[p]

    return form


def derivative_coupling(a: int):
    """B_a: integral of psi d_a(trial), trial scalar P2, test scalar P1."""
    @BilinearForm
    def form(u, q, w):
        return q * u.grad[a]

    return form


def stress(u, p, mu):
    """Stress tensor 2 mu eps(u) + p I as a 3 x 3 nested array of fields (Pa)."""
    e = sym_grad(u)
    return [[2.0 * mu * e[i][j] + (p if i == j else 0.0) for j in range(3)] for i in range(3)]


def von_mises(s):
    """Von Mises equivalent stress of a 3 x 3 stress ``s`` (Pa)."""
    mean = (s[0][0] + s[1][1] + s[2][2]) / 3.0
    dev2 = sum((s[i][j] - (mean if i == j else 0.0)) ** 2 for i in range(3) for j in range(3))
    return (1.5 * dev2) ** 0.5
