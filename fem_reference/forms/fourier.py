"""Linear elasticity of a body of revolution under a load ~ cos(n theta): one Fourier mode.

Coordinates x[0] = r, x[1] = z.  The displacement of mode n >= 0 is

    u = u_r(r, z) cos(n theta) e_r + u_t(r, z) sin(n theta) e_theta + u_z(r, z) cos(n theta) e_z,

with the mixed pressure p(r, z) cos(n theta), p = lambda div u, sigma = 2 mu eps + p I (the
convention of :mod:`.axisymmetric`, which is the case n = 0 without u_t).  The strains are

    eps_rr = d_r u_r,  eps_zz = d_z u_z,  eps_rz = (d_z u_r + d_r u_z) / 2,
    eps_tt = (u_r + n u_t) / r,
    eps_rt = (d_r u_t - (u_t + n u_r) / r) / 2,        (these two carry sin(n theta))
    eps_tz = (d_z u_t - n u_z / r) / 2,

and div u = d_r u_r + (u_r + n u_t) / r + d_z u_z.  Integrated over theta every product of
two cos (or two sin) factors gives pi for n >= 1, so the forms below are the energy divided by
pi: the same 2D integrals (weight r) for cos and sin terms.  For n = 0 the sin factors vanish:
u_t carries no energy and is fixed to zero by the caller, and the integrals are the energy
divided by 2 pi.  The caller divides its loads by the same factor.

Single-valuedness on the axis r = 0 (imposed by the caller): n = 0: u_r = 0; n = 1: u_z = 0
and u_r + u_t = 0 (a rigid translation across the axis); n >= 2: u_r = u_t = u_z = 0.

Reference: O. C. Zienkiewicz, R. L. Taylor, *The Finite Element Method*, vol. 1, 5th ed.,
Butterworth-Heinemann 2000, sec. 10.7 (axisymmetric solids under non-symmetric load).
"""

from __future__ import annotations

from skfem import BilinearForm


def mode_strain(u, r, n):
    """(eps_rr, eps_zz, eps_rz, eps_tt, eps_rt, eps_tz) of a mode-n field u = (u_r, u_t, u_z)."""
    g = u.grad  # g[i][j] = d u_i / d x_j, i over (r, t, z), j over (r, z)
    ur, ut, uz = u[0], u[1], u[2]
    return (g[0][0], g[2][1], 0.5 * (g[0][1] + g[2][0]), (ur + n * ut) / r,
            0.5 * (g[1][0] - (ut + n * ur) / r), 0.5 * (g[1][1] - n * uz / r))


@BilinearForm
def mode_shear_stiffness(u, v, w):
    """Integral of 2 mu eps(u) : eps(v) r dr dz for mode ``w.n``; ``w.mu`` the shear modulus."""
    r, n = w.x[0], w.n
    a = mode_strain(u, r, n)
    b = mode_strain(v, r, n)
    return 2.0 * w.mu * (a[0] * b[0] + a[1] * b[1] + a[3] * b[3]
                         + 2.0 * (a[2] * b[2] + a[4] * b[4] + a[5] * b[5])) * r


@BilinearForm
def mode_divergence_coupling(u, q, w):
    """Integral of q div u r dr dz for mode ``w.n`` (trial u: 3-component P2, test q: P1)."""
    r, n = w.x[0], w.n
    g = u.grad
    ur, ut = u[0], u[1]
    return q * (r * (g[0][0] + g[2][1]) + ur + n * ut)
