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
from scipy.linalg import cho_factor, cho_solve
from scipy.spatial import cKDTree
from scipy.spatial.distance import cdist
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
    unknown, ``pillar_of_vertex`` the index into ``pillar_names`` (-1 for a flat scene).
    """

    points: np.ndarray
    vertex_points: np.ndarray
    D: sp.csr_matrix
    weights: np.ndarray
    G: sp.csr_matrix
    pillar_of_vertex: np.ndarray
    pillar_names: list

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
                        pillar_names)


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


# Rows of the half-space model computed at a time (bounds its temporaries to ROWS x n).
ROWS = 512


def preconditioner(faces, springs, compliance: float, sector_angle: float):
    """Approximate inverse of the condensed operator on the free set: the half-space model of
    the contact faces (:func:`half_space_compliance`), inverted once and restricted to the
    free set F as the FFT BEM restricts its circulant inverse, z = I_F H^-1 I_F r.

    ``springs``: each sector pillar's Hooke compliance per unit sector force, or None;
    ``compliance``: (1 - nu^2) / E of the two faces (units of the condensed operator).
    Returns (precondition(r, free), 1 / diag H, name).  Where the lumped H is not positive
    definite (not met), the diagonal preconditioner with the springs' Sherman-Morrison term
    is returned instead, and its name says so.

    Measured on the lattice study's scene at mesh_size 2.83 (the condensed operator formed
    column by column, the CG run on it): the operator's applications fell from 115 to 56 at
    Phi = 0.82, from 196 to 50 at Phi = 0.2 with E_p = 1e6 E_l, from 211 to 58 at Phi = 0.4,
    E_p = 10 E_l, from 95 to 46 (E_p = E_s = 1e-3 E_l) and from 85 to 40 (E_p = 0.1 E_l);
    the spread of the eigenvalues of H^-1 C was 25 against 1.3e3 for C's own diagonal.
    """
    H = half_space_compliance(faces.vertex_points, faces.weights, compliance, sector_angle)
    pillar = faces.pillar_of_vertex
    if springs is not None and pillar.min() >= 0:
        for k, c in enumerate(springs):  # the Hooke term c_k W_k W_k^T of each pillar
            idx = np.nonzero(pillar == k)[0]
            H[np.ix_(idx, idx)] += c * np.outer(faces.weights[idx], faces.weights[idx])
    inv_d = 1.0 / np.diag(H).copy()
    try:
        factor = cho_factor(H, lower=True, overwrite_a=True, check_finite=False)
    except np.linalg.LinAlgError:
        return (_diagonal(faces.weights, pillar, springs, inv_d), inv_d,
                "diagonal (the half-space model was not positive definite)")

    def apply(r, free):
        mask = free.astype(float)
        return mask * cho_solve(factor, mask * r, check_finite=False)

    return apply, inv_d, "half-space"


def half_space_compliance(vertex_points, weights, compliance: float,
                          sector_angle: float) -> np.ndarray:
    """The contact faces' compliance as a half-space's, lumped at the vertices (mesh units):

        H[i, j] = compliance / pi  w_i w_j  sum_g 1 / |x_i - g x_j|,

    the hat function psi_j as a point force w_j at its vertex and at its images under the
    sector's mirror group (D6 for the wedge: a sector load stands for its symmetric
    extension), Boussinesq's response gamma / (pi r) (Johnson 1985, sec. 3.2).  An image that
    falls on the vertex itself (a vertex on a mirror plane, or the centre) joins its hat: the
    diagonal adds the mean deflection of a uniform pressure on a disk of the whole hat's area
    m_i w_i, 16 gamma rho / (3 pi) with rho = sqrt(m_i w_i / pi), times w_i, to the other
    images' terms.  The lens and
    the lower bodies both enter through ``compliance``, the sum of the faces' (1 - nu^2) / E;
    a pillar's own compression is the caller's (:func:`preconditioner`).
    """
    x = np.asarray(vertex_points, dtype=float).T  # (n, 2)
    w = np.asarray(weights, dtype=float)
    n = len(w)
    tol = 1e-9 * max(1.0, float(np.max(np.abs(x))) if n else 1.0)
    S = np.zeros((n, n))
    merged = np.zeros(n)
    images = [x @ g.T for g in mirror_group(sector_angle)]
    for lo in range(0, n, ROWS):  # a block of rows at a time: n^2 temporaries would double H
        rows = slice(lo, lo + ROWS)
        for gx in images:
            d = cdist(x[rows], gx)
            same = d <= tol
            merged[rows] += same.sum(axis=1)  # only the vertex itself can coincide
            d[same] = np.inf
            np.reciprocal(d, out=d)
            S[rows] += d
    S *= compliance / math.pi
    S *= w[:, None]
    S *= w[None, :]
    S[np.diag_indices(n)] += 16.0 / (3.0 * math.pi) * compliance * w * np.sqrt(
        merged * w / math.pi)
    return S


def mirror_group(sector_angle: float) -> list:
    """The 2 x 2 matrices of the group generated by the mirrors theta = 0 and theta =
    ``sector_angle`` (pi / sector_angle rotations by multiples of twice the angle, and as many
    reflections): 12 for the D6 wedge."""
    k = int(round(math.pi / sector_angle))
    out = []
    for j in range(k):
        c, s = math.cos(2 * j * sector_angle), math.sin(2 * j * sector_angle)
        rotation = np.array([[c, -s], [s, c]])
        out += [rotation, rotation @ np.diag([1.0, -1.0])]
    return out


def _diagonal(weights, pillar_of_vertex, springs, inv_d):
    """Jacobi on H's diagonal with each pillar's Hooke term c_k W_k W_k^T added by
    Sherman-Morrison (the soft pillars' uniform mode)."""
    if springs is None or pillar_of_vertex.min() < 0:
        return lambda r, active: r * inv_d * active
    w = np.asarray(weights, dtype=float)
    springs = np.asarray(springs, dtype=float)
    npil, pil = len(springs), pillar_of_vertex
    inv_0 = 1.0 / (1.0 / inv_d - springs[pil] * w * w)  # the diagonal without the springs

    def apply(r, active):
        z = r * inv_0 * active
        wa = w * active
        denom = 1.0 / springs + np.bincount(pil, weights=wa * wa * inv_0, minlength=npil)
        coef = np.bincount(pil, weights=wa * z, minlength=npil) / denom
        return (z - coef[pil] * wa * inv_0) * active

    return apply


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
