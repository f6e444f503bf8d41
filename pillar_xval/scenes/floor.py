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

from ._errors import ScopeError
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
