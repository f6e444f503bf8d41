"""Fields out of an axisymmetric solution: element stresses and the VTU file.

The VTU holds the linear mesh in metres (z = 0 plane for the (r, z) coordinates): point data
``displacement_m`` (u_r, u_z, 0) at the vertices (the P2 vertex values), and cell data, the
element averages of ``sigma_zz_Pa``, ``von_mises_Pa``, ``mean_stress_Pa``
((sigma_rr + sigma_zz + sigma_tt) / 3) and the ``mixed_pressure_Pa`` unknown, plus ``body``
(0 lens, 1 pillar, 2 substrate).  Rigid bodies are not meshed and do not appear.
"""

from __future__ import annotations

import json

import numpy as np

from meshes import BODIES

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
