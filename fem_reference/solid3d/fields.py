"""Fields out of a 3D sector solution: element stresses and the VTU file.

The VTU holds the linear tetrahedral mesh of the sector in metres: point data
``displacement_m`` (the P2 vertex values, the lens translation -zeta included) and cell data,
the element averages of ``von_mises_Pa``, ``sigma_zz_Pa``, ``mean_stress_Pa`` and ``body``
(0 lens, 1 pillar, 2 substrate).  Rigid bodies are not meshed and do not appear.  A JSON
sidecar carries the scene and the discretisation (meshio's VTU writer has no field data).
"""

from __future__ import annotations

import json

import numpy as np

from meshes import BODIES
from pillar_xval.scenes import Scene, analytic

from .._floor import side_wall_overlap
from ..forms.solid3d import stress, von_mises


def cell_stresses(system, u: np.ndarray, pressure: dict, E_ref: float) -> dict:
    """Element-average stresses (Pa) of every meshed tetrahedron.

    Parameters
    ----------
    system : SectorSystem
    u : ndarray
        Full P2 displacement dofs (units of the mesh length).
    pressure : dict
        Body -> P1 pressure dofs (units of ``E_ref``).
    E_ref : float
        Modulus unit of the solve (Pa).
    """
    n = system.mesh.t.shape[1]
    out = {k: np.zeros(n) for k in ("von_mises_Pa", "sigma_zz_Pa", "mean_stress_Pa")}
    out["body"] = np.full(n, -1, dtype=int)
    for ps in system.pressures:
        ub = system.basis_u.with_elements(system.mesh.subdomains[ps.body])
        s = stress(ub.interpolate(u), np.asarray(ps.basis.interpolate(pressure[ps.body])),
                   ps.mu)
        dx = ub.dx

        def average(a):
            return np.sum(np.asarray(a) * dx, axis=1) / np.sum(dx, axis=1) * E_ref

        idx = ub.tind
        out["von_mises_Pa"][idx] = average(von_mises(s))
        out["sigma_zz_Pa"][idx] = average(s[2][2])
        out["mean_stress_Pa"][idx] = average((s[0][0] + s[1][1] + s[2][2]) / 3.0)
        out["body"][idx] = BODIES.index(ps.body)
    return out


def write_vtu3d(path, points_m: np.ndarray, tets: np.ndarray, displacement_m: np.ndarray,
                cells: dict, metadata: dict) -> None:
    """Write the VTU atomically, with the JSON sidecar ``path.with_suffix('.json')``."""
    from pathlib import Path

    import meshio

    from pillar_xval.outcome import atomic_path, write_atomic

    path = Path(path)
    out = meshio.Mesh(points_m.T, [("tetra", tets.T)],
                      point_data={"displacement_m": displacement_m.T},
                      cell_data={k: [np.asarray(v, dtype=float)] for k, v in cells.items()})
    with atomic_path(path, ".vtu") as tmp:
        out.write(tmp)
    write_atomic(path.with_suffix(".json"), json.dumps(metadata, indent=2, allow_nan=False))


def lens_in_side_walls(scene: Scene, setup: dict, system, x) -> tuple[float, float]:
    """How deep and how far (m) the deformed lens bottom lies inside a meshed pillar's
    deformed side wall, the largest over the sector's pillars
    (:func:`fem_reference._floor.side_wall_overlap`, on each pillar's lens points within a
    diameter of its rim, radii from its axis).  The lens's bottom point at r is at height
    g(r) - zeta + u_z: its translation and curvature are in the gap.  A rigid pillar's wall
    stays where it is; a rigid lens's bottom is sampled on rings around each pillar."""
    ell, geo, sb = setup["ell"], setup["geometry"], system.basis_s
    H = scene.pillars.height_m / ell
    u, _ = system.full(x)
    bodies = setup["materials"]

    def moved(groups):  # undeformed points (3, n) and displacements (3, n) of face groups
        groups = [g for g in groups if g in sb.mesh.boundaries]
        if not groups:
            return np.zeros((3, 0)), np.zeros((3, 0))
        nodes = np.unique(np.concatenate([sb.get_dofs(g).all() for g in groups]))
        return sb.doflocs[:, nodes], u[3 * nodes + np.arange(3)[:, None]]

    def lens_height(at, uz):
        return (analytic.lens_gap(scene.lens.radius_m, np.hypot(at[0], at[1]) * ell) / ell
                - scene.indentation_m / ell + uz)

    lens_at, lens_u = moved(["contact_lens_floor", "free_lens"])
    wall_at, wall_u = moved(["free_pillar"])
    top_at, top_u = moved(["contact_pillar"])
    depth = width = 0.0
    for p in geo.pillars:
        c = np.array([p.x_m, p.y_m]) / ell
        if "lens" in bodies:
            rho0 = np.hypot(*(lens_at[:2] - c[:, None]))
            near = (rho0 > 1.0) & (rho0 < 3.0)
            at, du = lens_at[:, near], lens_u[:, near]
        else:
            rho, phi = np.meshgrid(np.linspace(1.0, 3.0, 41)[1:], np.linspace(0, 2 * np.pi, 72))
            at = np.vstack([c[0] + rho.ravel() * np.cos(phi.ravel()),
                            c[1] + rho.ravel() * np.sin(phi.ravel()), np.zeros(rho.size)])
            du = np.zeros_like(at)
        lens_rho = np.hypot(*(at[:2] + du[:2] - c[:, None]))
        lens_z = lens_height(at, du[2])
        if "pillar" in bodies:
            mine = np.hypot(*(wall_at[:2] - c[:, None])) < 1.0 + 1e-6
            rim = np.hypot(*(top_at[:2] - c[:, None]))
            on_rim = np.abs(rim - 1.0) < 1e-6
            if not mine.any() or not on_rim.any():
                continue
            wall_rho = np.hypot(*(wall_at[:2, mine] + wall_u[:2, mine] - c[:, None]))
            wall_z = wall_at[2, mine] + wall_u[2, mine]
            top = float(np.max(top_u[2, on_rim]))
        else:
            wall_z, wall_rho, top = np.linspace(-H, 0.0, 33), np.ones(33), 0.0
        d, w = side_wall_overlap(lens_rho, lens_z, top, wall_rho, wall_z)
        depth, width = max(depth, d), max(width, w)
    return depth * ell, width * ell
