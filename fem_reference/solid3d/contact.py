"""Mortar contact on the contact faces of the 3D sector model.

The contact pressure is a P1 field lam on the vertices of the contact faces (the pillar tops,
or the flat candidate sector); the nodal forces on the P2 points are f = D lam with
D[i, j] = integral of phi_i psi_j over the faces (P2 phi_i, P1 psi_j).  P2 corner functions
integrate to zero on a triangle, so node-based contact on P2 points would leave the corners
unloaded under a uniform pressure; the P1 multiplier does not.  The two sides of every
contact face are meshed node for node (a periodic copy in gmsh), so the gap at a P2 point is
simply u_z(lens) - u_z(lower body) + g(r) - zeta, and the condensed problem is::

    w~ = D^T G K^-1 G^T D lam + D^T (g - zeta) >= 0,   lam >= 0,   lam . w~ = 0,

solved by :func:`pillar_xval.contact.constrained_cg` with the operator applied by one
back-substitution per iteration (no compliance matrix is formed).  With a candidate floor,
its faces at z = -h are contact faces too, their gap g(r) + h - zeta plus the same
displacements, on multiplier vertices of their own.  Weights w_j = integral of psi_j turn the
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
    unknown, ``pillar_of_vertex`` the index into ``pillar_names`` (-1 for a flat scene and
    on the floor), ``triangles`` (3, m) the face triangles' vertices, ``floor_points`` and
    ``floor_vertices`` which points and vertices lie on the floor (all False without one).
    The floor's vertices are its own, apart from the pillar tops' where their rims meet in
    (x, y): a vertex's weighted gap never mixes a top's gap with the floor's.
    """

    points: np.ndarray
    vertex_points: np.ndarray
    D: sp.csr_matrix
    weights: np.ndarray
    G: sp.csr_matrix
    pillar_of_vertex: np.ndarray
    pillar_names: list
    triangles: np.ndarray
    floor_points: np.ndarray = None    # bool per point: on the floor (h below the tops)
    floor_vertices: np.ndarray = None  # bool per vertex

    @property
    def n_vertices(self) -> int:
        return self.D.shape[1]


def contact_faces(mesh, system, *, lens_meshed: bool, lower: str,
                  floor: tuple | None = None) -> ContactFaces:
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
    floor : tuple, optional
        (h in mesh units, the substrate is elastic): the floor is a contact face too, its
        faces ``contact_floor`` below the lens's ``contact_lens_floor``.
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

    floor_ref, height = None, 0.0
    if floor is not None:
        height, substrate_meshed = floor
        floor_ref = "contact_floor" if substrate_meshed else "contact_lens_floor"
    # The reference side's triangles, as one 2D mesh in (x, y): the tops', then the floor's
    # on vertices of their own.
    local_sets, owner, xy_sets, on_floor = [], [], [], []
    offset = 0
    for refs in (face_sets, [(-1, floor_ref)] if floor_ref else []):
        if not refs:
            continue
        tri_nodes = []
        for k, ref in refs:
            if ref not in mesh.boundaries:
                raise SolveError(f"the mesh has no contact face group {ref!r}")
            f = mesh.facets[:, mesh.boundaries[ref]]
            tri_nodes.append(f)
            owner.append(np.full(f.shape[1], k))
        tri_nodes = np.hstack(tri_nodes)
        verts, local = np.unique(tri_nodes, return_inverse=True)
        local_sets.append(local.reshape(tri_nodes.shape) + offset)
        offset += len(verts)
        xyz = mesh.p[:, verts]
        plane = -height if refs[0][1] == "contact_floor" else 0.0
        if np.max(np.abs(xyz[2] - plane)) > 1e-9 * max(1.0, np.max(np.abs(xyz[:2]))):
            raise SolveError(f"contact faces do not lie in the plane z = {plane:g}")
        xy_sets.append(xyz[:2])
        on_floor.append(np.full(len(verts), refs is not face_sets))
    local = np.hstack(local_sets)
    owner = np.concatenate(owner)
    xy = np.hstack(xy_sets)
    floor_vertices = np.concatenate(on_floor)
    face = MeshTri(np.ascontiguousarray(xy), np.ascontiguousarray(local))
    b2 = Basis(face, ElementTriP2(), intorder=4)
    b1 = Basis(face, ElementTriP1(), intorder=4)
    D = _face_mass.assemble(b1, b2).tocsr()  # (P2 points, P1 vertices)
    points = b2.doflocs
    weights = np.asarray(D.sum(axis=0)).ravel()
    pillar_of_vertex = np.full(b1.N, -1)
    # skfem's MeshTri keeps the vertex order it was given: vertex j of ``face`` is verts[j]
    vert_owner = np.full(xy.shape[1], -1)
    vert_owner[local.ravel()] = np.tile(owner, 3)  # local is (3, n_tri), row-major
    pillar_of_vertex[:] = vert_owner
    floor_points = np.zeros(points.shape[1], dtype=bool)
    floor_points[b2.element_dofs[:, np.any(floor_vertices[local], axis=0)].ravel()] = True

    # Gap change: + u_z of the lens, - u_z of the lower body, at each P2 point.
    sb = system.basis_s
    n_pts = points.shape[1]
    Gfull_rows, Gfull_cols, Gfull_vals = [], [], []
    sides = []  # (sign, groups, which points, their plane)
    tops = ~floor_points
    if lens_meshed:
        sides.append((+1.0, ["contact_lens"] + (["contact_lens_floor"] if floor else []),
                      np.ones(n_pts, dtype=bool), 0.0))
    if lower in ("pillar", "substrate"):
        sides.append((-1.0, ["contact_pillar" if lower == "pillar" else "contact_substrate"],
                      tops, 0.0))
    if floor is not None and floor[1]:
        sides.append((-1.0, ["contact_floor"], floor_points, -height))
    for sign, groups, sel, plane in sides:
        nodes = np.unique(np.concatenate([sb.get_dofs(g).all() for g in groups]))
        loc = sb.doflocs[:, nodes]
        tree = cKDTree(loc.T)
        rows = np.nonzero(sel)[0]
        dist, idx = tree.query(np.vstack([points[:, rows], np.full(len(rows), plane)]).T)
        scale = max(1.0, float(np.max(np.abs(points))))
        if len(rows) and np.max(dist) > 1e-8 * scale:
            raise SolveError(f"contact points of {groups[0]!r} do not match the face mesh "
                             f"(distance {np.max(dist):.3g})")
        Gfull_rows.append(rows)
        Gfull_cols.append(3 * nodes[idx] + 2)
        Gfull_vals.append(np.full(len(rows), sign))
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
                        pillar_names, local, floor_points, floor_vertices)


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
