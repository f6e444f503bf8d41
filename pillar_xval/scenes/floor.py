"""The floor between the pillars: where the lens can reach it (SI units).

Past the pillar tops the lens may touch the substrate between the pillars (PHYSICS.md, "The
floor between the pillars").  The floor stands h below the plane of the tops, so its
undeformed gap is g(r) + h - zeta, g the lens's own gap (:func:`analytic.lens_gap`).  Every
displacement of the lens and the substrate under contact pressures opens gaps (the half-space
kernel is positive), so the floor can be touched only where that gap is <= 0: within
:func:`floor_reach`, and beyond the rim of the centre pillar (r > d / 2, the nearest floor).
"""

from __future__ import annotations

import math

from ._errors import SceneError, ScopeError
from ._scene import Scene


def _gap(radius: float, r: float) -> float:
    return r * r / (radius + math.sqrt(radius * radius - r * r))


def floor_reach(scene: Scene, indentation_m: float | None = None) -> float:
    """Radius (m) within which the floor's undeformed gap g(r) + h - zeta is <= 0, the floor's
    candidate radius: sqrt(2 R (zeta - h) - (zeta - h)^2); 0 at zeta <= h or on a flat
    scene.  ``indentation_m`` defaults to the scene's own."""
    if scene.pillars is None:
        return 0.0
    zeta = scene.indentation_m if indentation_m is None else indentation_m
    depth = zeta - scene.pillars.height_m
    if depth <= 0.0:
        return 0.0
    R = scene.lens.radius_m
    return math.sqrt(max(2.0 * R * depth - depth * depth, 0.0))


def floor_reachable(scene: Scene, indentation_m: float | None = None) -> bool:
    """Whether the lens can touch the floor at this indentation: its reach passes the rim of
    the centre pillar, zeta > h + g(d / 2)."""
    return floor_reach(scene, indentation_m) > 0.5 * scene.pillars.diameter_m \
        if scene.pillars is not None else False


def floor_onset_bound(scene: Scene) -> float:
    """The indentation (m) below which no model touches the floor, h + g(d / 2): the floor
    next to the centre pillar's rim reached by the undeformed lens (a lower bound of the
    onset, which the lens's deflection over the pillars pushes deeper)."""
    p = scene.pillars
    return p.height_m + _gap(scene.lens.radius_m, 0.5 * p.diameter_m)


def check_floor_scope(scene: Scene, model: str, indentation_m: float | None = None,
                      how: str = "") -> None:
    """Refuse (ScopeError) a scene whose floor ``model`` would have to include and does not:
    the lens reaches the floor between the pillars at this indentation (given, or solved
    under a force: ``how`` says how it was found)."""
    zeta = scene.indentation_m if indentation_m is None else indentation_m
    if zeta is None or not floor_reachable(scene, zeta):
        return
    where = f"load.indentation_um = {zeta * 1e6:.4g}" if not how else (
        f"load.force_uN = {scene.force_N * 1e6:.6g} implies an indentation of "
        f"{zeta * 1e6:.4g} um ({how})")
    raise ScopeError(
        f"{where}: the lens reaches the floor between the pillars (beyond "
        f"h + g(d/2) = {floor_onset_bound(scene) * 1e6:.4g} um), which model {model} does not "
        "include; use bem-fft")


# --- roof collapse -----------------------------------------------------------------------
# sum_{j != 0} e / |c_j| - sum_j e / |m - c_j| over the unit hexagonal lattice, m the centroid
# of a triangle of neighbours (|m| = e / sqrt 3), both sums over the same disk |c_j| < R_c:
# -2.66969 and -2.67045 at R_c = 400 and 800 e, extrapolated in 1 / R_c to -2.671203.
HEX_SAG_CONSTANT = -2.671203
# Pillars within this many pitches of the deepest point take the rigid punch's exact outer
# field (its difference from 1/rho falls like a^2 / rho^3).
NEAR_SHELLS = 12


def roof_collapse_pressure(scene: Scene) -> float:
    """The mean pressure (Pa, force per lattice cell over the cell's area) at which the lens's
    sag between the pillars reaches the floor: the roof-collapse estimate for a hexagonal
    lattice (PHYSICS.md, "The floor between the pillars").

    Each pillar carries F = p A_cell, A_cell = sqrt(3) e^2 / 2, as a rigid flat punch of radius
    a = d/2 on the lens and, through its base, on the substrate ([J] eq. 3.35; outside it the
    surface moves by gamma F asin(a/rho) / (pi a)), plus its Hooke shortening c_s F.  The
    lens's surface at the deepest point m between three pillars (the triangle's centroid)
    then stands above the floor by

        h + g(e/sqrt 3) - F [gamma (1/(2a) + S/pi) + c_s],
        S = sum_{j != 0} f(|c_j|) - sum_j f(|m - c_j|),  f(rho) = asin(a/rho)/a,

    gamma = gamma_l + gamma_s; the roof collapses (the floor is touched) when it reaches 0.  S
    is the lattice constant :data:`HEX_SAG_CONSTANT` / e plus the exact near field's
    correction.  The 2D analogue, periodic punches, is Hui, Jagota, Lin and Kramer, Langmuir
    18 (2002) 1394.  Assumptions: a locally uniform mean pressure over many pillars (a contact
    much wider than the pitch), equal rigid-punch loads superposed without interaction, the
    lens flat but for its gap at m.
    """
    import numpy as np

    from .lattice import pillars_within

    p = scene.pillars
    if p is None:
        raise SceneError("roof collapse needs pillars")
    e, a = p.pitch_m, 0.5 * p.diameter_m
    m = np.array([0.5 * e, e / (2.0 * math.sqrt(3.0))])
    table = pillars_within(NEAR_SHELLS * e, e)
    rho0 = np.hypot(table[:, 2], table[:, 3])
    rhom = np.hypot(table[:, 2] - m[0], table[:, 3] - m[1])
    own = rho0 > 0.5 * e

    def near(rho):  # the exact outer field less the point force's, m^-1
        return np.arcsin(np.minimum(a / rho, 1.0)) / a - 1.0 / rho

    S = HEX_SAG_CONSTANT / e + float(near(rho0[own]).sum() - near(rhom).sum())
    gamma = scene.half_space_compliance
    spring = scene.pillar_spring_compliance
    per_force = gamma * (1.0 / (2.0 * a) + S / math.pi) + spring
    gap = p.height_m + _gap(scene.lens.radius_m, e / math.sqrt(3.0))
    cell = math.sqrt(3.0) * e * e / 2.0
    return gap / (per_force * cell)
