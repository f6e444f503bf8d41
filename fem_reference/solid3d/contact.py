"""Mortar contact on the contact faces of the 3D sector model.

The contact pressure is a P1 field lam on the vertices of the contact faces (the pillar tops,
or the flat candidate sector); the nodal forces on the P2 points are f = D lam with
D[i, j] = integral of phi_i psi_j over the faces (P2 phi_i, P1 psi_j).  P2 corner functions
integrate to zero on a triangle, so node-based contact on P2 points would leave the corners
unloaded under a uniform pressure; the P1 multiplier does not.  The two sides of every
contact face are meshed node for node (a periodic copy in gmsh), so the gap at a P2 point is
simply u_z(lens) - u_z(lower body) + g(r) - zeta, and the condensed problem is::

    w~ = D^T G K^-1 G^T D lam + D^T (g - zeta) >= 0,   lam >= 0,   lam . w~ = 0,

solved by :func:`pillar_xval.contact.constrained_cg` with the operator applied by one back-substitution
per iteration (no compliance matrix is formed).  Weights w_j = integral of psi_j turn the
weighted gaps w~ into mean gaps for the residual.

References
----------
.. [1] B. I. Wohlmuth, Acta Numerica 20 (2011) 569 (mortar contact).
.. [2] I. A. Polonsky, L. M. Keer, Wear 231 (1999) 206 (constrained conjugate gradients).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree
from skfem import Basis, BilinearForm, ElementTriP1, ElementTriP2, MeshTri

from .._reduced import SolveError


@BilinearForm
def _face_mass(u, v, w):
    return u * v


@dataclass
class ContactFaces:
    """Contact points and multiplier of the sector model (mesh units).

    ``points`` (2, n) are the P2 points of the contact faces, ``vertices`` their vertex
    subset carrying lam (indices into ``points``), ``D`` (n x n_v) the mortar matrix,
    ``weights`` w_j = integral of psi_j, ``G`` (n x n_reduced) the gap change per reduced
    unknown, ``pillar_of_vertex`` the index into ``pillar_names`` (-1 for a flat scene),
    ``triangles`` (3, m) the face triangles' vertices.
    """

    points: np.ndarray
    vertex_points: np.ndarray
    D: sp.csr_matrix
    weights: np.ndarray
    G: sp.csr_matrix
    pillar_of_vertex: np.ndarray
    pillar_names: list
    triangles: np.ndarray

    @property
    def n_vertices(self) -> int:
        return self.D.shape[1]


def contact_faces(mesh, system, *, lens_meshed: bool, lower: str) -> ContactFaces:
    """Build the contact points, the mortar matrix and the gap operator G.

    Parameters
    ----------
    mesh : skfem.MeshTet
        Dimensionless mesh with named boundaries.
    system : SectorSystem
    lens_meshed : bool
        The lens is elastic (its contact faces are ``contact_lens_*`` / ``contact_lens``).
    lower : str
        ``"pillar"`` (elastic pillars, faces ``contact_pillar_{n}_{m}``), ``"rigid-pillar"``
        (pillars moving rigidly with ``system.rigid``), ``"substrate"`` (flat scene) or
        ``"fixed"`` (a rigid lower body that does not move).
    """
    names = sorted(b for b in mesh.boundaries
                   if re.fullmatch(r"contact_(lens|pillar)_-?\d+_-?\d+", b))
    pillar_names = sorted({re.sub(r"contact_(lens|pillar)_", "", b) for b in names})
    if pillar_names:
        face_sets = []
        for k, pn in enumerate(pillar_names):
            ref = f"contact_pillar_{pn}" if lower == "pillar" else f"contact_lens_{pn}"
            face_sets.append((k, ref))
    else:
        ref = "contact_substrate" if lower == "substrate" else "contact_lens"
        face_sets = [(-1, ref)]

    # The reference side's triangles, as one 2D mesh in (x, y).
    tri_nodes, owner = [], []
    for k, ref in face_sets:
        if ref not in mesh.boundaries:
            raise SolveError(f"the mesh has no contact face group {ref!r}")
        f = mesh.facets[:, mesh.boundaries[ref]]
        tri_nodes.append(f)
        owner.append(np.full(f.shape[1], k))
    tri_nodes = np.hstack(tri_nodes)
    owner = np.concatenate(owner)
    verts, local = np.unique(tri_nodes, return_inverse=True)
    local = local.reshape(tri_nodes.shape)
    xy = mesh.p[:2, verts]
    if np.max(np.abs(mesh.p[2, verts])) > 1e-9 * max(1.0, np.max(np.abs(xy))):
        raise SolveError("contact faces do not lie in the plane z = 0")
    face = MeshTri(np.ascontiguousarray(xy), np.ascontiguousarray(local))
    b2 = Basis(face, ElementTriP2(), intorder=4)
    b1 = Basis(face, ElementTriP1(), intorder=4)
    D = _face_mass.assemble(b1, b2).tocsr()  # (P2 points, P1 vertices)
    points = b2.doflocs
    weights = np.asarray(D.sum(axis=0)).ravel()
    pillar_of_vertex = np.full(b1.N, -1)
    # skfem's MeshTri keeps the vertex order it was given: vertex j of ``face`` is verts[j]
    vert_owner = np.full(len(verts), -1)
    vert_owner[local.ravel()] = np.tile(owner, 3)  # local is (3, n_tri), row-major
    pillar_of_vertex[:] = vert_owner

    # Gap change: + u_z of the lens, - u_z of the lower body, at each P2 point.
    sb = system.basis_s
    n_pts = points.shape[1]
    Gfull_rows, Gfull_cols, Gfull_vals = [], [], []
    sides = []
    if lens_meshed:
        sides.append((+1.0, "contact_lens"))
    if lower in ("pillar", "substrate"):
        sides.append((-1.0, "contact_pillar" if lower == "pillar" else "contact_substrate"))
    for sign, group in sides:
        nodes = np.unique(sb.get_dofs(group).all())
        loc = sb.doflocs[:, nodes]
        tree = cKDTree(loc.T)
        dist, idx = tree.query(np.vstack([points, np.zeros(n_pts)]).T)
        scale = max(1.0, float(np.max(np.abs(points))))
        if np.max(dist) > 1e-8 * scale:
            raise SolveError(f"contact points of {group!r} do not match the face mesh "
                             f"(distance {np.max(dist):.3g})")
        Gfull_rows.append(np.arange(n_pts))
        Gfull_cols.append(3 * nodes[idx] + 2)
        Gfull_vals.append(np.full(n_pts, sign))
    n_full = system.T.shape[0]
    if Gfull_rows:
        Gfull = sp.csr_matrix((np.concatenate(Gfull_vals),
                               (np.concatenate(Gfull_rows), np.concatenate(Gfull_cols))),
                              shape=(n_pts, n_full))
        G = (Gfull @ system.T).tocsr()
    else:
        G = sp.csr_matrix((n_pts, system.T.shape[1]))
    if lower == "rigid-pillar":
        G = G + _rigid_rows(system, points, pillar_names, b2, owner)
    if G.nnz == 0:
        raise SolveError("no elastic body carries the contact faces")
    return ContactFaces(points, b1.doflocs, D, weights, G.tocsr(), pillar_of_vertex,
                        pillar_names, local)


def _rigid_rows(system, points, pillar_names, b2, owner):
    """-u_z of the rigid pillar under each contact point (reduced columns of its motions)."""
    # Owner of each P2 point: the pillar of any triangle that holds it.
    point_owner = np.full(points.shape[1], -1)
    point_owner[b2.element_dofs.ravel()] = np.tile(owner, b2.element_dofs.shape[0])
    by_name = {rp.name: rp for rp in system.rigid}
    rows, cols, vals = [], [], []
    for k, pn in enumerate(pillar_names):
        rp = by_name.get(pn)
        if rp is None:
            raise SolveError(f"pillar {pn} has no rigid motion unknowns")
        sel = np.nonzero(point_owner == k)[0]
        pts = np.vstack([points[:, sel], np.zeros(len(sel))])
        uz = rp.displacement(pts)[2]  # (n, k)
        for j, c in enumerate(rp.columns):
            rows.append(sel)
            cols.append(np.full(len(sel), c))
            vals.append(-uz[:, j])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(points.shape[1], system.T.shape[1]))


def contact_area_share(weights, lam) -> float:
    """Area where the pressure is positive: sum of w_j over vertices in contact (mesh units),
    exact for a fully loaded face (w_j sums to its area)."""
    return float(np.sum(weights[lam > 0]))


def line_profile(vertex_points, lam, angle, tol):
    """Vertices on the ray theta = ``angle`` (a mirror edge of the faces), sorted by r:
    (r, lam)."""
    x, y = vertex_points
    n = np.array([-math.sin(angle), math.cos(angle)])
    on = np.abs(n[0] * x + n[1] * y) <= tol
    r = np.hypot(x[on], y[on])
    order = np.argsort(r)
    return r[order], lam[on][order]
