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
matrix, factorised once (in float32 in an order built from the mesh where that is accurate,
else after a weighted matching in float64), with iterative refinement against the scaled
matrix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector

from pillar_xval.threads import limited

from .._pardiso import Pardiso, metis_positions
from .._reduced import ReducedSystem, SolveError, relative_residual
from ..forms import tet_p2
from ..forms.solid3d import mixed_coefficients
from .reduction import SPARE, NodeBases, ReducedStiffness

# Quadrature: P2 gradients are P1, their products P2: degree 2 is exact on straight tets.
INTORDER = 2
# The largest relative error of a float32 solve for which the factor stays in float32: each
# step of refinement then gains at least three digits.  Measured on paper-fig3-sparse at
# Phi = 0.82: 2.6e-6, 7.8e-5 and 1.5e-4 at mesh_size 2.83, 2 and 1.41 (at 1.41 refined to a
# residual of 4.2e-13; a float64 factor there, after the matching, took 68 s more than the
# float32 one's 26 s and 2 GiB more, for answers 4e-9 apart); 2.4e-4 on single-pillar with
# E_p = 100 E_l (refined to 3.5e-13).  The error jumps where the moduli differ more (5.7e-2
# at E_p = 1e4 E_l, whose refinement stalled at 1.4e-8): beyond the bound the matrix is
# factorised in float64 after the weighted matching.
SINGLE_MAX_ERROR = 1e-3
# The relative error of a solve the contact iterations take as exact: a tenth of their
# tolerance, 1e-8 of the indentation on gaps of the order of the indentation.
EXACT_ERROR = 1e-9
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

    ``K`` is S T^T K_full T S on the reduced unknowns, scaled by ``scale`` (S, its diagonal):
    the matrix factorised, kept once; ``T`` maps reduced to full unknowns.
    """

    mesh: object
    basis_s: object
    pressures: list
    K: sp.csr_matrix
    T: sp.csr_matrix
    scale: np.ndarray
    rigid: list
    nodes: np.ndarray = None
    factor: object = None
    single_error: float = 0.0
    exact_steps: int = 0
    _basis_u: object = field(default=None, repr=False)

    @property
    def basis_u(self):
        """The vector P2 basis (built when first asked for: only the fields need it)."""
        if self._basis_u is None:
            self._basis_u = Basis(self.mesh, ElementVector(ElementTetP2()), intorder=INTORDER)
        return self._basis_u

    def factorise(self) -> None:
        """PARDISO's factorisation of the scaled matrix: in float32, in the order of
        :func:`elimination_order`, where that is accurate (:data:`SINGLE_MAX_ERROR`), else
        PARDISO's default ordering after a weighted matching in float64 (where the moduli
        differ by 1e6, the mesh-ordered factor without the matching's pivots loses accuracy
        too: a refined solve's residual stalled at 3e-11, the condensed operator's asymmetry
        was 4e-9).

        ``single_error``: the relative error of one float32 solve of a random right-hand side
        (max norm, measured by one step of refinement; 0 for a float64 factor)."""
        Ks = self._Ks = self.K
        n_p = sum(len(ps.dofs) for ps in self.pressures)  # the last unknowns
        self.factor = Pardiso(Ks, order=elimination_order(self.mesh, self.basis_s,
                                                          self.nodes, n_p), single=True)
        b = np.random.default_rng(0).standard_normal(Ks.shape[0])
        y = self.factor.solve(b)
        self.single_error = float(np.max(np.abs(self.factor.solve(b - Ks @ y)))
                                  / np.max(np.abs(y)))
        if not self.single_error <= SINGLE_MAX_ERROR:
            self.factor = None  # its memory first
            self.factor = Pardiso(Ks)
            self.single_error = 0.0
        # Refinement steps for an error below EXACT_ERROR: each multiplies it by single_error.
        self.exact_steps = 0 if self.single_error == 0.0 else int(math.ceil(
            math.log(EXACT_ERROR) / math.log(self.single_error) - 1.0 - 1e-9))

    def exact(self, rhs: np.ndarray) -> np.ndarray:
        """K^-1 rhs to a relative error below :data:`EXACT_ERROR` (``exact_steps`` steps of
        refinement, no residual computed); one back-substitution with a float64 factor."""
        x, _ = self.solve(rhs, refine=self.exact_steps, check=False)
        return x

    def solve(self, rhs: np.ndarray, refine: int = 2, check: bool = True,
              start: np.ndarray | None = None) -> tuple[np.ndarray, float]:
        """Solve K x = rhs (columns allowed) with up to ``refine`` steps of iterative
        refinement against the float64 matrix, until the residual is below 1e-12; returns x
        and the relative scaled residual max_j ||S (K x_j - b_j)|| / ||S b_j|| (NaN, not
        computed, with ``refine=0``: one back-substitution and nothing else, of relative
        error ``single_error`` for a float32 factor; ``check=False``: ``refine`` steps and
        no residual).  ``start``: an approximate x (shaped as ``rhs``) that the refinement
        starts from in place of the first back-substitution."""
        rhs = np.asarray(rhs, dtype=float)
        b = self.scale[:, None] * rhs.reshape(rhs.shape[0], -1)
        y = self.factor.solve(b) if start is None else \
            np.asarray(start, dtype=float).reshape(b.shape) / self.scale[:, None]
        if refine == 0 or not check:  # inside the contact iterations
            for _ in range(refine):
                y += self.factor.solve(b - self._Ks @ y)
            return (self.scale[:, None] * y).reshape(rhs.shape), float("nan")
        r = b - self._Ks @ y  # the residual judged is the one the next step corrects
        rel = relative_residual(r, b)
        for _ in range(refine):
            if rel < 1e-12:
                break
            y += self.factor.solve(r)
            r = b - self._Ks @ y
            rel = relative_residual(r, b)
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
    # numbering, positions and sets only: the one-point rule spares the basis values at four
    sb = Basis(mesh, ElementTetP2(), intorder=1)
    n_u = 3 * sb.N
    pressures, offset = [], n_u
    for body, (E, nu) in materials.items():
        mu, beta, c = mixed_coefficients(E, nu)
        elements = mesh.subdomains[body]
        pb = Basis(mesh, ElementTetP1(), elements=elements, intorder=INTORDER)
        dofs = np.unique(mesh.t[:, elements])  # P1 dofs are the vertices
        pressures.append(PressureSpace3D(body, pb, dofs, beta, mu, offset))
        offset += len(dofs)
    if progress:
        progress(f"assembling {', '.join(materials)}")
    (row, col, blocks), B, M = assemble_blocks(mesh, sb, pressures)
    T, rigid, bases = _transform(mesh, sb, offset, sector_angle, clamp_pillar_base,
                                 rigid_pillars)
    if progress:
        progress(f"reducing {offset} unknowns to {T.shape[1]}")
    n_p = offset - n_u
    T_u = T[:n_u, :T.shape[1] - n_p]  # T is block diagonal: the pressures map one to one
    if bases.direct:  # written by stack_csr where the reduced matrix holds it
        K_uu = ReducedStiffness(row, col, blocks, bases, T_u.shape[1])
    else:  # a rigid pillar's base nodes share its motion columns: the sparse products
        A = _vector_csr(row, col, blocks, sb.N)
        K_uu = T_u.T.tocsr() @ (A @ T_u)
        del A
    del blocks
    K_pu = sp.vstack([ps.beta * b for ps, b in zip(pressures, B)], format="csr") @ T_u
    K_pp = sp.block_diag([-mixed_coefficients(*materials[ps.body])[2] * m
                          for ps, m in zip(pressures, M)], format="csr")
    Kr = stack_csr(((K_uu, K_pu.T.tocsr()), (K_pu, K_pp)))  # [[K_uu, K_pu^T], [K_pu, K_pp]]
    del K_uu
    Kr.eliminate_zeros()
    # Scaling: 1/sqrt|diag| for displacements and rigid motions, 1/sqrt(diag M) for pressures.
    scale = np.zeros(T.shape[1])
    is_u = np.ones(T.shape[1], dtype=bool)
    reduced_of = _reduced_of(T)
    for ps, m in zip(pressures, M):
        red = reduced_of[ps.offset:ps.offset + len(ps.dofs)]
        scale[red] = 1.0 / np.sqrt(m.diagonal())
        is_u[red] = False
    diag = np.abs(Kr.diagonal())
    if np.any(diag[is_u] <= 0):
        raise SolveError("a displacement unknown has no stiffness (a body is not held)")
    scale[is_u] = 1.0 / np.sqrt(diag[is_u])
    # Scaled in place: the solves use S K S alone (an unscaled copy would cost its 12 bytes
    # per entry, 0.3 GiB at mesh_size 2, through the whole solve); the rows' scales, then the
    # columns', a few thousand rows at a time (the entries' scales for the whole matrix at
    # once were 0.3 GB of fresh pages at Phi = 0.2, mesh_size 1.41).
    for r0 in range(0, Kr.shape[0], STACK_ROWS):
        rows = slice(r0, min(r0 + STACK_ROWS, Kr.shape[0]) + 1)
        entries = slice(Kr.indptr[rows.start], Kr.indptr[rows.stop - 1])
        part = Kr.data[entries]
        part *= np.repeat(scale[rows.start:rows.stop - 1], np.diff(Kr.indptr[rows]))
        part *= scale[Kr.indices[entries]]
    nodes = _nodes_of(T, n_u, pressures, reduced_of, rigid)
    return SectorSystem(mesh, sb, pressures, Kr, T.tocsr(), scale, rigid, nodes)


# Rows per pass of :func:`stack_csr` and of the reduced matrix's scaling: their temporary
# arrays hold about this many rows' entries.
STACK_ROWS = 8192


def stack_csr(blocks) -> sp.csr_matrix:
    """The CSR matrix of the block rows ``blocks``, pairs (left, right) of CSR matrices (the
    left ones of one width, each pair of one height), its arrays written once, a few
    thousand rows at a time: the arrays of scipy's ``vstack`` of ``hstack`` (the same bits),
    for whose copies (the data twice, the indices up to four times) the kernel maps and
    zeroes fresh pages: 6.1e5 -> 4.6e5 page faults in the cold assembly at Phi = 0.2,
    mesh_size 1.41 (4 KiB pages; a 0.23 GB result), its peak 0.84 -> 0.74 GB.

    A block may also be one that writes itself (:class:`.reduction.ReducedStiffness`: its
    row ``lengths``, ``write`` into the arrays at its rows' starts): no copy of it at all."""
    def lengths(m):  # of its rows
        return np.diff(m.indptr) if sp.issparse(m) else m.lengths

    width = blocks[0][0].shape[1]
    shape = (sum(left.shape[0] for left, _ in blocks), width + blocks[0][1].shape[1])
    counts = np.concatenate([lengths(left) + lengths(right) for left, right in blocks])
    indptr = np.zeros(len(counts) + 1, dtype=np.int64)
    np.cumsum(counts, out=indptr[1:])
    index_dtype = np.int32 if max(indptr[-1], shape[1]) < 2**31 else np.int64
    # slots past the entries for the discarded writes of a block that writes itself
    data = np.empty(int(indptr[-1]) + SPARE, dtype=np.result_type(*[m.dtype for p in blocks
                                                                  for m in p]))
    indices = np.empty(len(data), dtype=index_dtype)
    first = 0  # the pair's first row
    for pair in blocks:
        rows = pair[0].shape[0]
        start = indptr[first:first + rows].copy()  # where each row's next entries go
        for m, shift in zip(pair, (0, width)):
            if sp.issparse(m):
                _copy_rows(m, data, indices, start, shift)
            else:
                m.write(data, indices, start, shift)
            start += lengths(m)
        first += rows
    return sp.csr_matrix((data[:-SPARE], indices[:-SPARE], indptr.astype(index_dtype)),
                         shape=shape)


def _copy_rows(m, data, indices, start, shift) -> None:
    """The CSR matrix ``m``'s row r into ``data`` and ``indices`` (its columns plus
    ``shift``) from ``start[r]`` on, a few thousand rows at a time."""
    for r0 in range(0, m.shape[0], STACK_ROWS):
        r1 = min(r0 + STACK_ROWS, m.shape[0])
        lo, hi = m.indptr[r0], m.indptr[r1]
        n = np.diff(m.indptr[r0:r1 + 1])
        at = np.arange(lo, hi) + np.repeat(start[r0:r1] - m.indptr[r0:r1], n)
        data[at] = m.data[lo:hi]
        indices[at] = m.indices[lo:hi] + shift


# Elements per block of the element integrals: 30 MB of 3 x 3 blocks at a time (the cold
# assembly's page faults at Phi = 0.2, mesh_size 2: 3.5e5 with blocks of 16384, 2.9e5 of
# 4096, 2.8e5 of 2048; the same CPU time within the runs' spread).
CHUNK = 4096


def assemble_blocks(mesh, sb, pressures: list):
    """The shear stiffness A (3 N x 3 N, vector dof 3 s + c of P2 node s, summed over the
    bodies) as its node pairs and their blocks, and each body's divergence coupling B_b (its
    vertices x 3 N) and pressure mass M_b, with the body's mu (unscaled by beta, 1/lambda).

    The element integrals come from :mod:`..forms.tet_p2`.  A is summed on the pattern of
    P2 node pairs, one 3 x 3 block per pair (a ninth of the unknowns' pairs to sort):
    (row, col, blocks), the pairs sorted by row then column, ``blocks[k]`` (3, 3) (row
    component b, column component a; :func:`_vector_csr` lays them out as CSR).
    """
    N = sb.N
    bodies = [mesh.subdomains[ps.body] for ps in pressures]
    elements = np.concatenate(bodies)
    first = np.cumsum([0] + [len(e) for e in bodies])  # body k: elements[first[k]:first[k+1]]
    mu = np.concatenate([np.full(len(e), ps.mu) for ps, e in zip(pressures, bodies)])
    nodes = sb.element_dofs[:, elements].T  # (E, 10)
    row, col, where = _pair_pattern(nodes, N)
    blocks = np.zeros(9 * len(row))
    grad, volume = tet_p2.barycentric_gradients(mesh.p, mesh.t[:, elements])
    divergence = np.empty((len(elements), 4, 10, 3))
    # The blocks' products (an inner dimension of 16 and 4: bound by memory) on one BLAS
    # thread: a chunk and its scatter took 0.12-0.16 s against 0.23-0.26 s on two on a 2-core
    # machine at a load of 1-1.4, where two threads' CPU time was up to 2.8 times one's.
    # Two buffers for a chunk's blocks and their places, reused chunk after chunk, each
    # chunk summed into ``blocks`` in place (ufunc.at, as fast as bincount here): no array
    # of the pattern's size per chunk, whose fresh pages the kernel maps and zeroes (the
    # cold assembly's page faults 4.2e5 -> 2.9e5 at Phi = 0.2, mesh_size 2 on 4 KiB pages).
    size = min(CHUNK, len(elements))
    V, index = np.empty((size, 9, 100)), np.empty((size, 9, 100), dtype=np.int64)
    component = np.arange(9)[:, None]
    with limited(1):
        for lo in range(0, len(elements), CHUNK):
            sl = slice(lo, lo + CHUNK)
            n = len(volume[sl])
            # [e, 3 b + a, 10 t + s]
            v = tet_p2.elasticity_blocks(grad[sl], volume[sl], mu[sl], out=V[:n])
            i = np.multiply(where[sl, None, :], 9, out=index[:n])
            i += component
            np.add.at(blocks, i.ravel(), v.ravel())
            divergence[sl] = tet_p2.divergence_blocks(grad[sl], volume[sl])
    del grad
    B, M = [], []
    for k, ps in enumerate(pressures):
        sl = slice(first[k], first[k + 1])
        # the test vertices q < 4 of the pairs 10 q + s
        B.append(_coupling_csr(row, col, where[sl, :40], divergence[sl], ps.dofs, N))
        vertex = np.searchsorted(ps.dofs, nodes[sl, :4])  # vertex q of each element, the body's
        m = tet_p2.pressure_masses(volume[sl])
        r = np.broadcast_to(vertex[:, :, None], m.shape)
        c = np.broadcast_to(vertex[:, None, :], m.shape)
        M.append(sp.csr_matrix((m.ravel(), (r.ravel(), c.ravel())),
                               shape=(len(ps.dofs), len(ps.dofs))))
    return (row, col, blocks.reshape(-1, 3, 3)), B, M


def _pair_pattern(nodes: np.ndarray, N: int):
    """(row, col) of the node pairs that share an element, sorted by row then column, and
    where[e, 10 t + s]: the index of the pair (nodes[e, t], nodes[e, s]).

    The pairs are the pattern of P^T P, P the elements' node incidence (scipy's sparse
    product finds them without sorting the elements' 100 pairs each), and ``where`` is read
    from that pattern holding each pair's index."""
    E, k = nodes.shape
    incidence = sp.csr_matrix((np.ones(nodes.size), nodes.ravel(),
                               np.arange(0, nodes.size + 1, k)), shape=(E, N))
    pattern = (incidence.T.tocsr() @ incidence).tocsr()
    pattern.sort_indices()
    row = np.repeat(np.arange(N, dtype=np.int64), np.diff(pattern.indptr))
    pattern.data = np.arange(pattern.nnz, dtype=float)  # exact integers (< 2^53)
    where = pattern[np.repeat(nodes, k, axis=1).ravel(), np.tile(nodes, k).ravel()]
    return row, pattern.indices.astype(np.int64), np.asarray(where).astype(np.int64).reshape(E, -1)


def _coupling_csr(row, col, where, values, dofs, N) -> sp.csr_matrix:
    """One body's divergence coupling B (its vertices ``dofs`` x 3 N) from its elements'
    integrals ``values[e, q, s, a]`` (test vertex q, trial node s, component a), summed on
    the node pairs they touch (``where[e, 10 q + s]``, the pair's index in ``row``, ``col``:
    :func:`_pair_pattern`), which are sorted by row, then column: laid out as CSR directly
    (scipy's coordinate path sorts every row's duplicates)."""
    sums = np.bincount((where[:, :, None] * 3 + np.arange(3)).ravel(), weights=values.ravel(),
                       minlength=3 * len(row)).reshape(-1, 3)
    pairs = np.nonzero(np.bincount(where.ravel(), minlength=len(row)))[0]
    local = np.searchsorted(dofs, row[pairs])  # each pair's row among the body's vertices
    indptr = 3 * np.searchsorted(local, np.arange(len(dofs) + 1))
    indices = (3 * col[pairs][:, None] + np.arange(3)).ravel()
    B = sp.csr_matrix((sums[pairs].ravel(), indices, indptr), shape=(len(dofs), 3 * N))
    B.has_sorted_indices = True
    return B


def _vector_csr(row, col, blocks, N) -> sp.csr_matrix:
    """The 3 N x 3 N CSR matrix with the 3 x 3 block ``blocks[k]`` (row component b, column
    component a) at node pair (row[k], col[k]), the pairs sorted by row, then column: the
    pairs are a block sparse row layout as they stand, which scipy expands in C (its rows'
    columns sorted as the blocks are)."""
    indptr = np.searchsorted(row, np.arange(N + 1))
    A = sp.bsr_matrix((blocks, col, indptr), shape=(3 * N, 3 * N)).tocsr()
    A.has_sorted_indices = True
    return A


def elimination_order(mesh, sb, nodes: np.ndarray, n_pressures: int) -> np.ndarray:
    """The reduced unknowns in the order PARDISO eliminates them (:mod:`.._pardiso`).

    The vertices in METIS's nested-dissection order of the mesh's vertex graph (vertices
    sharing an element), a sixth of the P2 nodes: each vertex's displacements, then those of
    the edge nodes whose other end comes later (every element around such an edge holds the
    vertex, so the edge node's neighbours are the vertex's, made one clique by its
    elimination: ordering it next adds no fill), then the vertex's pressure (its pivot then
    carries the Schur complement of the displacements around it), then the motions of
    rigid pillars.  ``nodes``: the mesh node of every reduced unknown (P2 numbering,
    vertices first; past them, a rigid pillar's label), the last ``n_pressures`` of them
    pressures.  On paper-fig3-sparse at Phi = 0.82, mesh_size 2 it took 0.15 s against 1.4
    s for METIS on the graph of all P2 nodes, for 1.9 % more factor entries (1.453e8) and
    no slower a factorisation or back-substitution (6.2-6.4 against 6.6-6.7 CPU s, 0.17 s).
    """
    nv = mesh.p.shape[1]
    E = mesh.t.shape[1]
    incidence = sp.csr_matrix((np.ones(4 * E), mesh.t.T.ravel(), np.arange(0, 4 * E + 1, 4)),
                              shape=(E, nv))
    position = metis_positions(incidence.T.tocsr() @ incidence)
    # Sort keys: 3 p for the vertex placed p-th, 3 p + 1 for the edge nodes that follow it,
    # 3 p + 2 for its pressure; rigid motions after all.
    key = np.full(max(sb.N, int(nodes.max()) + 1), 3 * nv, dtype=np.int64)
    key[:nv] = 3 * position
    dofs = sb.element_dofs
    for k, (i, j) in enumerate(tet_p2.EDGES):
        key[dofs[4 + k]] = 3 * np.minimum(position[dofs[i]], position[dofs[j]]) + 1
    unknown_key = key[nodes]
    unknown_key[len(nodes) - n_pressures:] += 2
    return np.lexsort((np.arange(len(nodes)), unknown_key))


def _nodes_of(T, n_u: int, pressures: list, reduced_of: np.ndarray, rigid: list):
    """The mesh node of every reduced unknown: a displacement's P2 node, a pressure's vertex
    (P1 dofs are vertices, numbered first by the P2 basis too), and a label past the nodes
    for the motions of each rigid pillar."""
    Tc = T.tocsc()
    nodes = Tc.indices[Tc.indptr[:-1]] // 3  # a displacement column's first row: 3 s + c
    for k, rp in enumerate(rigid):
        nodes[rp.columns] = n_u // 3 + k
    for ps in pressures:
        nodes[reduced_of[ps.offset:ps.offset + len(ps.dofs)]] = ps.dofs
    return nodes


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
    """The reduced-unknown transform T (n_full x n_reduced), the rigid pillars and each
    node's reduced unknowns (:class:`.reduction.NodeBases`)."""
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
    # a clamped node's kind: no columns
    bases = NodeBases(np.zeros(n_nodes, dtype=np.int64), np.where(tied < 0, 0, -1),
                      np.zeros(n_nodes, dtype=np.int64), [np.zeros((3, 3))])
    for sig in np.unique(flags[free_nodes]):
        group = free_nodes[flags[free_nodes] == sig]
        if sig & 8:
            continue
        N = np.array([vectors[b] for b in range(3) if sig & (1 << b)]).reshape(-1, 3)
        Q = _complement(N)
        bases.first[group] = col + np.arange(len(group)) * Q.shape[1]
        bases.count[group] = Q.shape[1]
        bases.kind[group] = len(bases.bases)
        bases.bases.append(np.hstack([Q, np.zeros((3, 3 - Q.shape[1]))]))
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
    bases.bases = np.array(bases.bases)
    return T, rigid, bases


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
