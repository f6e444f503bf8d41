"""The skeleton both FEM drivers share (:mod:`.axisym.driver`, :mod:`.solid3d.driver`).

The verdict: why a solution is not converged (:func:`solve_failures`), and the contact radius
read from a line of pressures and gaps (:func:`contact_radius`).
"""

from __future__ import annotations

import numpy as np

# The linear solve's relative residual below which a solution is taken as exact.
RTOL_LINEAR = 1e-8
# The mortar contact holds the weighted gaps; the pointwise gap at the P2 points beside a
# contact edge dips below zero by a share of zeta: 1-3 % on smooth or well-resolved edges
# (fem-axisym: at most 1.5 % over 838 solves at mesh_size 0.5-4; fem-3d: 2.8 % over the
# lattice study), up to ~9 % beside a flat punch's singular edge at mesh_size 2 (F still
# within 1e-3 of the closed form), 29-53 % where a contact under 1 um spans one or two
# elements.  Beyond this share the mesh does not resolve the contact: not converged.
MAX_POINTWISE_PENETRATION = 0.2


def solve_failures(residual: float, contact, force: float, zeta: float,
                   penetration: float) -> list:
    """Why a FEM solution is not converged (empty: it is): the linear residual, the contact
    solver's own verdict (``contact.converged``, ``contact.message``), no contact force, and a
    pointwise ``penetration`` (over zeta) beyond :data:`MAX_POINTWISE_PENETRATION`."""
    failures = []
    if residual >= RTOL_LINEAR:
        failures.append(f"linear residual {residual:.2e} >= {RTOL_LINEAR:g}")
    if not contact.converged:
        failures.append(f"contact: {contact.message}")
    if force <= 0.0:
        failures.append(f"no contact force (F = {force:g} N): the mesh does not resolve "
                        f"zeta = {zeta:g} m")
    if penetration > MAX_POINTWISE_PENETRATION:
        failures.append(
            f"the contact is under-resolved: the gap at the P2 points dips {penetration:.1%} "
            f"of zeta below zero (at most {MAX_POINTWISE_PENETRATION:.0%} where the mesh "
            "resolves the contact); use a smaller mesh_size")
    return failures


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
