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
