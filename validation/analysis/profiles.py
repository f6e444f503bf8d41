"""Shape of a pressure profile across a pillar top (or a Hertz contact): pure functions of
``{"r_m": [...], "pressure_Pa": [...]}`` dicts, SI units.

The centre plateau sigma(d/4)/sigma_0, the exponent lambda of an edge singularity
sigma ~ (d/2 - r)^(-lambda) (a rigid punch gives 1/2), the share of a pillar's force carried
by the outer part of its radius, and the profile sampled at given radii.

References
----------
.. [J] K. L. Johnson, *Contact Mechanics*, 1985, eq. 3.35 (rigid punch: lambda = 1/2, outer
   10 % of the radius carries sqrt(1 - 0.9^2) = 43.6 % of the force).
"""

from __future__ import annotations

import numpy as np

# Edge-exponent fit range, rho = d/2 - r relative to d/2, and the profile nodes next to the
# edge left out (four P2 elements); edge_exponent gives the measurements behind them.
EDGE_WINDOW = (0.004, 0.03)
EDGE_SKIP = 8


def _sorted_profile(profile: dict) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(profile.get("r_m", []), dtype=float)
    p = np.asarray(profile.get("pressure_Pa", []), dtype=float)
    order = np.argsort(r)
    return r[order], p[order]


def plateau_ratio(profile: dict, radius_m: float, sigma0_Pa: float) -> float | None:
    """sigma(r = radius/2) / sigma_0 (for a pillar of radius d/2: the pressure at r = d/4)."""
    r, p = _sorted_profile(profile)
    x = 0.5 * radius_m
    if r.size < 2 or not r[0] <= x <= r[-1] or sigma0_Pa == 0:
        return None
    return float(np.interp(x, r, p)) / sigma0_Pa


def _load_inside(r: np.ndarray, p: np.ndarray, rho: float) -> float:
    """int_0^rho sigma 2 pi r dr by the trapezoid rule on the profile nodes (N)."""
    rr = np.concatenate([r[r < rho], [rho]])
    pp = np.concatenate([p[r < rho], [np.interp(rho, r, p)]])
    if rr[0] > 0:
        rr, pp = np.concatenate([[0.0], rr]), np.concatenate([[pp[0]], pp])
    return float(np.trapezoid(2.0 * np.pi * rr * pp, rr))


def outer_load_fraction(profile: dict, radius_m: float, force_N: float,
                        outer: float = 0.1) -> dict:
    """Share of ``force_N`` carried by radius_m (1 - outer) < r < radius_m.

    The inner part is integrated from the profile, where it is smooth; the remainder of the
    model's own force is the outer share (the nodal profile cannot integrate an edge
    singularity).  ``profile_integral_ratio`` = (trapezoid integral of the whole profile) / F
    tells how far the profile alone is from the force.
    """
    r, p = _sorted_profile(profile)
    if r.size < 2 or force_N <= 0 or r[-1] < (1.0 - outer) * radius_m:
        return {"outer_load_fraction": None, "profile_integral_ratio": None}
    inner = _load_inside(r, p, (1.0 - outer) * radius_m)
    whole = _load_inside(r, p, min(radius_m, r[-1]))
    return {"outer_load_fraction": 1.0 - inner / force_N,
            "profile_integral_ratio": whole / force_N}


def edge_exponent(profile: dict, radius_m: float, window: tuple[float, float] | None = EDGE_WINDOW,
                  points: int = 6, skip: int = EDGE_SKIP) -> dict:
    """Fit log sigma = c - lambda log(radius - r) near the edge of the pillar top.

    The ``skip`` profile nodes nearest the edge (and the edge node itself) are never used;
    of the others, those whose distance to the edge rho = radius - r lies in ``window``
    (relative to the radius) are fitted, or, with ``window=None``, the ``points`` nearest.

    Returns ``lambda`` (0.5 for a rigid punch), the fit range ``rho_min_m``..``rho_max_m`` (also
    relative to the radius), the node count ``n``, ``r_squared`` and ``drift``: lambda fitted on
    the half of the nodes nearest the edge minus lambda on the other half (0 for a pure power
    law).  ``status`` says why a field is None (too few nodes: the mesh is too coarse for the
    window).

    Why these defaults (FEM P2 profiles, two nodes per element, single-pillar scene,
    E_p/E_l = 1e6): over the last four elements the nodal pressures alternate between vertex
    and mid-side nodes (local slopes 0.25..0.65 at every mesh_size), so ``skip`` = 8 nodes.
    Outside that zone the vertex-to-vertex slope rises towards 1/2 as rho falls (mesh_size
    0.5: 0.485 at rho/radius = 0.05, 0.494..0.497 over 0.01..0.02); beyond rho/radius ~ 0.03
    the far field bends it (0.44 at 0.2).  Hence the window [0.004, 0.03]: at mesh_size 0.5
    it keeps 6 nodes (0.0085..0.027) and gives lambda = 0.49-0.50; at mesh_size 1 no node is
    left and the fit is refused instead of returning the biased 0.46 that a fit reaching
    into the alternating zone gave.
    """
    r, p = _sorted_profile(profile)
    rho = radius_m - r
    interior = rho > 1e-9 * radius_m
    rho, p = rho[interior], p[interior]
    order = np.argsort(rho)[skip:]
    rho, p = rho[order], p[order]
    keep = p > 0
    if window is not None:
        keep &= (rho >= window[0] * radius_m) & (rho <= window[1] * radius_m)
    rho, p = rho[keep], p[keep]
    order = np.arange(rho.size) if window is not None else np.arange(min(points, rho.size))
    out = {"lambda": None, "r_squared": None, "drift": None, "n": int(order.size),
           "rho_min_m": None, "rho_max_m": None, "rho_min_rel": None, "rho_max_rel": None,
           "window": None if window is None else list(window), "status": "ok"}
    if order.size < 3:
        out["status"] = (f"too few nodes with positive pressure in the fit range "
                         f"({order.size} < 3): refine the mesh or widen --edge-window")
        return out
    x, y = np.log(rho[order]), np.log(p[order])
    slope, c = np.polyfit(x, y, 1)
    ss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum((y - slope * x - c) ** 2)) / ss if ss > 0 else 1.0
    half = max(2, order.size // 2)
    inner = np.polyfit(x[:half], y[:half], 1)[0]
    outer_ = np.polyfit(x[-half:], y[-half:], 1)[0]
    out.update({"lambda": float(-slope), "r_squared": float(r2),
                "drift": float(-(inner - outer_)),
                "rho_min_m": float(rho[order].min()), "rho_max_m": float(rho[order].max())})
    out["rho_min_rel"] = out["rho_min_m"] / radius_m
    out["rho_max_rel"] = out["rho_max_m"] / radius_m
    return out



def profile_at(profile: dict, radius_m: float, points) -> list[float | None]:
    """Pressure (Pa) interpolated at r = x radius_m for each x in ``points``; None outside
    the profile's range."""
    r, p = _sorted_profile(profile)
    if r.size < 2:
        return [None] * len(points)
    out = []
    for x in points:
        rx = x * radius_m
        out.append(float(np.interp(rx, r, p)) if r[0] <= rx <= r[-1] else None)
    return out
