"""Fields out of an axisymmetric solution: element stresses and the VTU file.

The VTU holds the linear mesh in metres (z = 0 plane for the (r, z) coordinates): point data
``displacement_m`` (u_r, u_z, 0) at the vertices (the P2 vertex values), and cell data, the
element averages of ``sigma_zz_Pa``, ``von_mises_Pa``, ``mean_stress_Pa``
((sigma_rr + sigma_zz + sigma_tt) / 3) and the ``mixed_pressure_Pa`` unknown, plus ``body``
(0 lens, 1 pillar, 2 substrate).  Rigid bodies are not meshed and do not appear.  And the
lens's overlap with the pillar's side wall (:func:`lens_in_side_wall`).
"""

from __future__ import annotations

import json

import numpy as np

from meshes import BODIES
from pillar_xval.scenes import Scene, analytic

from .._floor import side_wall_overlap
from ..forms.axisymmetric import stress, von_mises


def cell_stresses(system, u: np.ndarray, pressure: dict, E_ref: float) -> dict:
    """Element-average stresses (Pa) of every meshed element.

    Parameters
    ----------
    system : AxisymmetricSystem
    u : ndarray
        Full P2 displacement dofs (units of the mesh length).
    pressure : dict
        Body -> P1 pressure dofs (units of ``E_ref``).
    E_ref : float
        Modulus unit of the solve (Pa).
    """
    n = system.mesh.nelements
    out = {k: np.zeros(n) for k in ("sigma_zz_Pa", "von_mises_Pa", "mean_stress_Pa",
                                    "mixed_pressure_Pa")}
    out["body"] = np.full(n, -1, dtype=int)
    for ps in system.pressures:
        ub = system.basis_u.with_elements(system.mesh.subdomains[ps.body])
        uh = ub.interpolate(u)
        ph = np.asarray(ps.basis.interpolate(pressure[ps.body]))
        r = np.asarray(ub.global_coordinates())[0]
        srr, szz, srz, stt = stress(uh, ph, ps.mu, r)
        dx = ub.dx

        def average(a):
            return np.sum(np.asarray(a) * dx, axis=1) / np.sum(dx, axis=1) * E_ref

        idx = ub.tind
        out["sigma_zz_Pa"][idx] = average(szz)
        out["von_mises_Pa"][idx] = average(von_mises(srr, szz, srz, stt))
        out["mean_stress_Pa"][idx] = average((srr + szz + stt) / 3.0)
        out["mixed_pressure_Pa"][idx] = average(ph)
        out["body"][idx] = BODIES.index(ps.body)
    return out


def write_vtu(path, mesh, displacement_m: np.ndarray, cells: dict, metadata: dict) -> None:
    """Write the VTU file atomically; ``metadata`` (scene, discretisation) goes in as JSON
    field data so that the file carries the parameters that produced it."""
    from pathlib import Path

    import meshio

    from pillar_xval.outcome import atomic_path, write_atomic

    path = Path(path)
    pts = np.vstack([mesh.points, np.zeros(mesh.points.shape[1])]).T
    disp = np.vstack([displacement_m, np.zeros(displacement_m.shape[1])]).T
    out = meshio.Mesh(pts, [("triangle", mesh.triangles.T)],
                      point_data={"displacement_m": disp},
                      cell_data={k: [np.asarray(v, dtype=float)] for k, v in cells.items()})
    with atomic_path(path, ".vtu") as tmp:
        out.write(tmp)
    # meshio's VTU writer has no field data: the parameters go to a sidecar JSON.
    write_atomic(path.with_suffix(".json"), json.dumps(metadata, indent=2, allow_nan=False))


def lens_in_side_wall(scene: Scene, setup: dict, system, x) -> tuple[float, float]:
    """How deep and how far (units of ell) the deformed lens bottom beyond the rim lies inside the
    pillar's deformed side wall (:func:`fem_reference._floor.side_wall_overlap`).  The lens's bottom
    point at r is at height g(r) - zeta + u_z: its translation and curvature are in the gap."""
    ell, H = setup["ell"], scene.pillars.height_m / setup["ell"]
    u, _ = system.full(x)
    ub = system.basis_u
    bodies = setup["materials"]

    def moved(name):  # undeformed (r, z) and displacement (u_r, u_z) of a boundary's points
        r_dofs, z_dofs = (ub.get_dofs(name).all(c) for c in ("u^1", "u^2"))
        return ub.doflocs[:, r_dofs], u[r_dofs], u[z_dofs]

    if "pillar" in bodies:
        at, ur, uz = moved("free_pillar")
        wall_r, wall_z = at[0] + ur, at[1] + uz
        top = float(uz[np.argmax(at[1])])
    else:  # a rigid pillar: its translation, or none on a rigid substrate
        top = float(x[-1]) if setup["rigid_pillar_on_substrate"] else 0.0
        wall_z = np.linspace(-H, 0.0, 33) + top
        wall_r = np.ones_like(wall_z)
    if "lens" in bodies:
        names = [n for n in ("contact_lens_floor", "free_lens") if n in ub.mesh.boundaries]
        parts = [moved(n) for n in names]
        at = np.hstack([p[0] for p in parts])
        ur, uz = np.concatenate([p[1] for p in parts]), np.concatenate([p[2] for p in parts])
        keep = (at[0] > 1.0) & (at[0] < 4.0 * max(1.0, H))
        r0 = at[0, keep]
        lens_r = r0 + ur[keep]
        lens_z = analytic.lens_gap(scene.lens.radius_m, r0 * ell) / ell \
            - scene.indentation_m / ell + uz[keep]
    else:
        r0 = np.linspace(1.0, 4.0 * max(1.0, H), 200)[1:]
        lens_r = r0
        lens_z = analytic.lens_gap(scene.lens.radius_m, r0 * ell) / ell - scene.indentation_m / ell
    return side_wall_overlap(lens_r, lens_z, top, wall_r, wall_z)
