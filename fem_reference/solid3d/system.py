"""Assembly of the 3D sector model, its constraints and one sparse factorisation.

Units: the solver works in units of a length ell and a modulus E_ref (see :mod:`.driver`).

Unknowns.  P2 displacement (vector dof 3 s + c of scalar P2 node s, component c) continuous
over the conforming pillar-substrate mesh (the bond), one P1 pressure space per body (the
mean stress jumps across the bonded base), the lens disconnected from the lower bodies.

Constraints, all through one reduced-unknown transform T (full = T reduced), never a
penalty.  Each P2 node carries the constraint normals that apply to it, n . u = 0: the
theta = 0 mirror (0, 1, 0); the theta = alpha mirror (-sin alpha, cos alpha, 0), skew for
the pi/6 wedge; the far-face rollers (0, 0, 1); a clamp (all three).  Its free displacements
are u = Q t with Q an orthonormal basis of the complement of those normals, so on the skew
plane the two in-plane unknowns become one tangential unknown t along (cos alpha, sin alpha).
Nodes bonded to a rigid pillar move with that pillar's rigid motion u = t + w x (x - c),
restricted to the motions that the mirror planes through its centre leave invariant (6, 3 or
1 unknowns).

Solver.  MKL PARDISO (:mod:`._pardiso`) on the diagonally scaled symmetric indefinite
matrix, factorised once, with iterative refinement against the scaled matrix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector

from .._pardiso import Pardiso
from .._reduced import ReducedSystem, SolveError, relative_residual
from ..forms.solid3d import (derivative_coupling, gradient_product, mixed_coefficients,
                             pressure_mass)

# Quadrature: P2 gradients are P1, their products P2: degree 2 is exact on straight tets.
INTORDER = 2
E_Z = np.array([0.0, 0.0, 1.0])


@dataclass
class PressureSpace3D:
    body: str
    basis: object
    dofs: np.ndarray
    beta: float
    mu: float
    offset: int


@dataclass
class RigidPillar:
    """Rigid motion unknowns of one rigid pillar: ``modes`` (6 x k) in the (t, w) basis about
    ``centre`` (x, y, z), ``columns`` their reduced indices."""

    name: str
    centre: np.ndarray
    modes: np.ndarray
    columns: np.ndarray = field(default=None)

    def displacement(self, points: np.ndarray) -> np.ndarray:
        """Displacement of each mode at ``points`` (3, n): array (3, n, k)."""
        rel = points - self.centre[:, None]
        t, w = self.modes[:3], self.modes[3:]
        rot = np.cross(w.T[:, None, :], rel.T[None, :, :])  # (k, n, 3)
        return t[:, None, :] + np.transpose(rot, (2, 1, 0))


def mirror_normals(sector_angle: float) -> dict:
    return {"mirror_0": np.array([0.0, 1.0, 0.0]),
            "mirror_1": np.array([-math.sin(sector_angle), math.cos(sector_angle), 0.0])}


def rigid_modes(centre_xy, sector_angle: float, tol: float) -> np.ndarray:
    """Rigid motions (t, w) invariant under the mirrors through the pillar centre (6 x k)."""
    rows = []
    for n in mirror_normals(sector_angle).values():
        if abs(n[0] * centre_xy[0] + n[1] * centre_xy[1]) <= tol:
            S = np.eye(3) - 2.0 * np.outer(n, n)
            R = np.block([[S, np.zeros((3, 3))], [np.zeros((3, 3)), -S]])  # w is axial
            rows.append(R - np.eye(6))
    if not rows:
        return np.eye(6)
    _, s, vt = np.linalg.svd(np.vstack(rows))
    rank = int(np.sum(s > 1e-12))
    return vt[rank:].T


@dataclass
class SectorSystem(ReducedSystem):
    """Assembled, constrained and factorised system of the elastic bodies.

    ``K`` is T^T K_full T on the reduced unknowns; ``T`` maps reduced to full unknowns;
    ``scale`` the symmetric diagonal scaling of the factorised matrix.
    """

    mesh: object
    basis_u: object
    basis_s: object
    pressures: list
    K: sp.csr_matrix
    T: sp.csr_matrix
    scale: np.ndarray
    rigid: list
    factor: object = None

    def factorise(self) -> None:
        S = sp.diags(self.scale)
        self._Ks = (S @ self.K @ S).tocsr()
        self.factor = Pardiso(self._Ks)

    def solve(self, rhs: np.ndarray, refine: int = 2) -> tuple[np.ndarray, float]:
        """Solve K x = rhs (columns allowed) with iterative refinement; returns x and the
        relative scaled residual max_j ||S (K x_j - b_j)|| / ||S b_j|| (NaN, not computed,
        with ``refine=0``: one back-substitution and nothing else)."""
        rhs = np.asarray(rhs, dtype=float)
        b = self.scale[:, None] * rhs.reshape(rhs.shape[0], -1)
        y = self.factor.solve(b)
        if refine == 0:  # inside the contact iterations: the caller checks at the end
            return (self.scale[:, None] * y).reshape(rhs.shape), float("nan")
        rel = relative_residual(b - self._Ks @ y, b)
        for _ in range(refine):
            if rel < 1e-12:
                break
            y += self.factor.solve(b - self._Ks @ y)
            rel = relative_residual(b - self._Ks @ y, b)
        return (self.scale[:, None] * y).reshape(rhs.shape), rel



def assemble_sector(mesh, materials: dict, *, sector_angle: float, clamp_pillar_base: bool,
                    rigid_pillars: list, progress=None) -> SectorSystem:
    """Assemble the elastic bodies of the dimensionless skfem ``mesh`` and their constraints.

    Parameters
    ----------
    mesh : skfem.MeshTet
        Named subdomains and boundaries (see :func:`meshes.build_wedge_mesh`).
    materials : dict
        Body name -> (E / E_ref, nu) for every meshed body.
    sector_angle : float
        alpha (rad): the mirror planes are theta = 0 and theta = alpha.
    clamp_pillar_base : bool
        The substrate is rigid: the pillar bases are clamped.
    rigid_pillars : list of (name, (x, y))
        Rigid pillars bonded to the elastic substrate (their ``pillar_base_{name}`` faces
        move rigidly), centres in mesh units.
    """
    ub = Basis(mesh, ElementVector(ElementTetP2()), intorder=INTORDER)
    sb = Basis(mesh, ElementTetP2(), intorder=INTORDER)  # scalar: pieces, positions and sets
    nu_dofs = ub.N
    blocks_A, blocks_B, blocks_C, pressures = [], [], [], []
    offset = nu_dofs
    for body, (E, nu) in materials.items():
        if progress:
            progress(f"assembling {body}")
        elements = mesh.subdomains[body]
        mu, beta, c = mixed_coefficients(E, nu)
        sb_b = sb.with_elements(elements)
        pb = Basis(mesh, ElementTetP1(), elements=elements, intorder=INTORDER)
        dofs = np.unique(pb.element_dofs)
        A_b, B = vector_blocks(sb_b, pb, mu)
        blocks_A.append(A_b)
        B = B[dofs]
        M = pressure_mass.assemble(pb).tocsr()[dofs][:, dofs]
        blocks_B.append(beta * B)
        blocks_C.append(-c * M)
        pressures.append(PressureSpace3D(body, pb, dofs, beta, mu, offset))
        offset += len(dofs)
    A = sum(blocks_A[1:], blocks_A[0])
    B = sp.vstack(blocks_B)
    K = sp.bmat([[A, B.T], [B, sp.block_diag(blocks_C)]], format="csr")

    T, rigid = _transform(mesh, sb, K.shape[0], sector_angle, clamp_pillar_base, rigid_pillars)
    if progress:
        progress(f"reducing {K.shape[0]} unknowns to {T.shape[1]}")
    Kr = (T.T @ K @ T).tocsr()
    Kr.eliminate_zeros()
    # Scaling: 1/sqrt|diag| for displacements and rigid motions, 1/sqrt(diag M) for pressures.
    scale = np.zeros(T.shape[1])
    is_u = np.ones(T.shape[1], dtype=bool)
    reduced_of = _reduced_of(T)
    for ps in pressures:
        M_diag = pressure_mass.assemble(ps.basis).diagonal()[ps.dofs]
        red = reduced_of[ps.offset:ps.offset + len(ps.dofs)]
        scale[red] = 1.0 / np.sqrt(M_diag)
        is_u[red] = False
    diag = np.abs(Kr.diagonal())
    if np.any(diag[is_u] <= 0):
        raise SolveError("a displacement unknown has no stiffness (a body is not held)")
    scale[is_u] = 1.0 / np.sqrt(diag[is_u])
    return SectorSystem(mesh, ub, sb, pressures, Kr, T.tocsr(), scale, rigid)


def vector_blocks(sb, pb, mu: float):
    """A (shear stiffness) and B (divergence coupling) of vector P2 from scalar pieces.

    Vector dof 3 s + c is component c of scalar node s (skfem's ElementVector layout).
    Equal to assembling :func:`forms.solid3d.shear_stiffness` and ``divergence_coupling``
    on the vector basis (tested), about 5x faster: 10 x 10 local matrices, not 30 x 30.
    """
    n = sb.N
    K = [[None] * 3 for _ in range(3)]
    for p in range(3):
        for q in range(p, 3):
            K[p][q] = gradient_product(p, q).assemble(sb, mu=mu).tocsr()
            K[q][p] = K[p][q].T.tocsr()
    lap = K[0][0] + K[1][1] + K[2][2]
    rows, cols, vals = [], [], []
    for a in range(3):      # trial component
        for b in range(3):  # test component
            blk = (K[a][b] + lap if a == b else K[a][b]).tocoo()
            rows.append(3 * blk.row + b)
            cols.append(3 * blk.col + a)
            vals.append(blk.data)
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(3 * n, 3 * n))
    Bs = [derivative_coupling(a).assemble(sb, pb).tocoo() for a in range(3)]
    B = sp.csr_matrix((np.concatenate([blk.data for blk in Bs]),
                       (np.concatenate([blk.row for blk in Bs]),
                        np.concatenate([3 * blk.col + a for a, blk in enumerate(Bs)]))),
                      shape=(pb.N, 3 * n))
    return A, B


def _reduced_of(T) -> np.ndarray:
    """Reduced index of every full unknown that T maps one-to-one (-1 otherwise)."""
    Tc = T.tocsr()
    out = np.full(Tc.shape[0], -1)
    single = np.diff(Tc.indptr) == 1
    rows = np.nonzero(single)[0]
    vals = Tc.data[Tc.indptr[rows]]
    one = np.isclose(vals, 1.0, rtol=0, atol=1e-14)
    out[rows[one]] = Tc.indices[Tc.indptr[rows[one]]]
    return out


def _transform(mesh, sb, n_full, alpha, clamp_pillar_base, rigid_pillars):
    """The reduced-unknown transform T (n_full x n_reduced) and the rigid pillars."""
    n_nodes = sb.N
    normals = mirror_normals(alpha)
    flags = np.zeros(n_nodes, dtype=np.int64)  # bit 0, 1: mirrors; 2: roller z; 3: clamp
    vectors = [normals["mirror_0"], normals["mirror_1"], E_Z]

    def nodes(name):
        return np.unique(sb.get_dofs(name).all()) if name in mesh.boundaries else \
            np.zeros(0, dtype=np.int64)

    flags[nodes("mirror_0")] |= 1
    flags[nodes("mirror_1")] |= 2
    for far in ("far_lens", "far_substrate"):
        flags[nodes(far)] |= 4
    if clamp_pillar_base:
        flags[nodes("pillar_base")] |= 8
    tied = np.full(n_nodes, -1)
    rigid = []
    tol = 1e-9 * max(1.0, float(np.max(np.abs(sb.doflocs))))
    for k, (name, centre) in enumerate(rigid_pillars):
        base = nodes(f"pillar_base_{name}")
        tied[base] = k
        z = float(sb.doflocs[2, base].mean()) if len(base) else 0.0
        rigid.append(RigidPillar(name, np.array([centre[0], centre[1], z]),
                                 rigid_modes(centre, alpha, tol)))

    rows, cols, vals = [], [], []
    col = 0
    free_nodes = np.nonzero(tied < 0)[0]
    for sig in np.unique(flags[free_nodes]):
        group = free_nodes[flags[free_nodes] == sig]
        if sig & 8:
            continue
        N = np.array([vectors[b] for b in range(3) if sig & (1 << b)]).reshape(-1, 3)
        Q = _complement(N)
        # one reduced unknown per (node, free direction), numbered node-major
        for j in range(Q.shape[1]):
            cidx = col + np.arange(len(group)) * Q.shape[1] + j
            for c in range(3):
                if abs(Q[c, j]) > 1e-15:
                    rows.append(3 * group + c)
                    cols.append(cidx)
                    vals.append(np.full(len(group), Q[c, j]))
        col += len(group) * Q.shape[1]
    for k, rp in enumerate(rigid):
        base = np.nonzero(tied == k)[0]
        rp.columns = col + np.arange(rp.modes.shape[1])
        disp = rp.displacement(sb.doflocs[:, base])  # (3, n, k)
        for c in range(3):
            for j in range(rp.modes.shape[1]):
                rows.append(3 * base + c)
                cols.append(np.full(len(base), rp.columns[j]))
                vals.append(disp[c, :, j])
        col += rp.modes.shape[1]
    n_u = 3 * n_nodes
    rows.append(np.arange(n_u, n_full))
    cols.append(col + np.arange(n_full - n_u))
    vals.append(np.ones(n_full - n_u))
    col += n_full - n_u
    T = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n_full, col))
    T.eliminate_zeros()
    return T, rigid


def _complement(N: np.ndarray) -> np.ndarray:
    """Orthonormal basis (3 x k) of the vectors orthogonal to the rows of N."""
    if N.shape[0] == 0:
        return np.eye(3)
    _, s, vt = np.linalg.svd(N)
    rank = int(np.sum(s > 1e-12))
    Q = vt[rank:].T
    Q[np.abs(Q) < 1e-15] = 0.0
    # deterministic sign: largest component positive
    for j in range(Q.shape[1]):
        if Q[np.argmax(np.abs(Q[:, j])), j] < 0:
            Q[:, j] = -Q[:, j]
    return Q
