"""Axisymmetric linear elasticity, mixed displacement-pressure (Taylor-Hood P2/P1).

Coordinates x[0] = r, x[1] = z; displacement u = (u_r, u_z); pressure p = lambda div u, so
that sigma = 2 mu eps(u) + p I.  Every integral carries the weight r (the factor 2 pi is left
out: assembled forces are per radian).  The hoop strain is u_r / r; quadrature points lie
inside the elements, so r > 0 wherever a form is evaluated.

The saddle-point system is::

    [ A     B^T ] [u]   [f]        A = (2 mu eps(u), eps(v))_r,  B = (q, div u)_r,
    [ B   -C/lam] [p] = [0]        C = (p, q)_r,

exact at nu = 1/2 (1/lambda = 0) and valid for every nu in [0, 1/2].  Solvers rescale the
pressure, p = beta p~ with beta = sqrt(2 nu mu) (see :func:`mixed_coefficients`), so that
no coefficient is infinite at either end of that range.

References
----------
.. [1] T. J. R. Hughes, *The Finite Element Method*, Dover 2000, sec. 4.3 (mixed u-p).
.. [2] C. Taylor, P. Hood, Comput. Fluids 1 (1973) 73 (P2/P1 pair).
"""

from __future__ import annotations

import math

from skfem import BilinearForm
from skfem.helpers import grad


def strain(u, r):
    """Strain components (eps_rr, eps_zz, eps_rz, eps_tt) of an axisymmetric field (1)."""
    g = grad(u)  # g[i][j] = d u_i / d x_j
    return g[0][0], g[1][1], 0.5 * (g[0][1] + g[1][0]), u[0] / r


def r_divergence(u, r):
    """r div u = r (d u_r/dr + d u_z/dz) + u_r (m): the divergence times the weight r."""
    g = grad(u)
    return r * (g[0][0] + g[1][1]) + u[0]


@BilinearForm
def shear_stiffness(u, v, w):
    """A: integral of 2 mu eps(u) : eps(v) r dr dz, with ``w.mu`` the shear modulus (Pa)."""
    r = w.x[0]
    urr, uzz, urz, utt = strain(u, r)
    vrr, vzz, vrz, vtt = strain(v, r)
    return 2.0 * w.mu * (urr * vrr + uzz * vzz + 2.0 * urz * vrz + utt * vtt) * r


@BilinearForm
def divergence_coupling(u, q, w):
    """B: integral of q div u r dr dz (trial u vector P2, test q scalar P1)."""
    return q * r_divergence(u, w.x[0])


@BilinearForm
def pressure_mass(p, q, w):
    """C: integral of p q r dr dz; the pressure block is -(1/lambda) C."""
    return p * q * w.x[0]


def mixed_coefficients(E: float, nu: float) -> tuple[float, float, float]:
    """(mu, beta, c) for the rescaled pressure p = beta p~.

    With beta = sqrt(2 nu mu) the blocks become beta B and -beta^2/lambda C = -(1 - 2 nu) C:
    finite for every nu in [0, 1/2] (nu = 0 gives beta = 0 and p~ = 0, the decoupled limit).
    """
    mu = E / (2.0 * (1.0 + nu))
    return mu, math.sqrt(2.0 * nu * mu), 1.0 - 2.0 * nu


def stress(u, p, mu, r):
    """Stress components (sigma_rr, sigma_zz, sigma_rz, sigma_tt) = 2 mu eps + p I (Pa)."""
    err, ezz, erz, ett = strain(u, r)
    return 2 * mu * err + p, 2 * mu * ezz + p, 2 * mu * erz, 2 * mu * ett + p


def von_mises(srr, szz, srz, stt):
    """Von Mises equivalent stress of the axisymmetric stress state (Pa)."""
    return ((0.5 * ((srr - szz) ** 2 + (szz - stt) ** 2 + (stt - srr) ** 2)
             + 3.0 * srz**2) ** 0.5)
