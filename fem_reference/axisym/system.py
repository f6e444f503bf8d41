"""Assembly of the bodies, their constraints and the contact operator; one factorisation.

Units: the solver works in units of a length ell (the focus radius) and a modulus E_ref, so
that every number it factorises is O(1) before scaling; :mod:`.driver` converts back to SI.

Each body has its own P1 pressure space (the mean stress jumps at the bonded pillar-base
interface, so a pressure continuous across it would be wrong), while the P2 displacement is
continuous over the conforming pillar-substrate mesh: that is the bond.  The lens mesh is
disconnected from the lower body; they interact only through the contact operator G.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import Basis, ElementTriP1, ElementTriP2, ElementVector

from .._reduced import ReducedSystem, SolveError, relative_residual
from ..forms.axisymmetric import (divergence_coupling, mixed_coefficients, pressure_mass,
                                  shear_stiffness)


# Quadrature degree: exact for the polynomial r-weighted terms (degree <= 3 for P2); the hoop
# term u_r v_r / r is rational near the axis (see the measured effect in the tests).
INTORDER = 4


@dataclass
class PressureSpace:
    body: str
    basis: object     # skfem Basis restricted to the body's elements
    dofs: np.ndarray  # global P1 dofs that belong to the body
    beta: float       # p = beta * p~ (see forms.axisymmetric.mixed_coefficients)
    mu: float
    offset: int       # first index of this body's p~ in the full vector


@dataclass
class AxisymmetricSystem(ReducedSystem):
    """Assembled, constrained and factorised system of the elastic bodies.

    ``K`` is the saddle-point matrix on the reduced unknowns, T^T K_full T (u then each
    body's p~), ``T`` maps reduced to full unknowns (full = T @ reduced), ``G`` maps reduced
    unknowns to the gap change at the contact points (n_contact x n_reduced): the points of
    each contact line in turn (the pillar top or the flat's segment, then the floor), a line's
    points sorted by r.
    """

    mesh: object
    basis_u: object
    pressures: list
    K: sp.csr_matrix
    T: sp.csr_matrix
    G: sp.csr_matrix
    contact_r: np.ndarray
    scale: np.ndarray
    contact_lines: list  # points on each contact line, in the order of contact_r
    lu: object = None

    def factorise(self) -> None:
        # Symmetric diagonal scaling: stiff and soft bodies (E ratio up to 1e9) and pressure
        # unknowns all get unit diagonal magnitude, which keeps SuperLU's pivots sane.
        S = sp.diags(self.scale)
        self._Ks = (S @ self.K @ S).tocsc()
        try:
            self.lu = splu(self._Ks, permc_spec="COLAMD", diag_pivot_thresh=0.1)
        except (RuntimeError, MemoryError) as exc:
            raise SolveError(f"SuperLU could not factorise the {self._Ks.shape[0]}-unknown "
                             f"system: {exc}") from None

    def solve(self, rhs: np.ndarray) -> tuple[np.ndarray, float]:
        """Solve K_red x = rhs (columns allowed) with one step of iterative refinement.

        Returns x and the relative residual max_j ||S (K x_j - b_j)|| / ||S b_j||.
        """
        rhs = np.asarray(rhs, dtype=float)
        b = self.scale[:, None] * rhs.reshape(rhs.shape[0], -1)
        # Column by column: SuperLU's multi-column solve measured 2x slower here.
        y = np.column_stack([self.lu.solve(col) for col in b.T])
        for _ in range(2):
            res = b - self._Ks @ y
            rel = relative_residual(res, b)
            if rel < 1e-13:
                break
            y += np.column_stack([self.lu.solve(col) for col in res.T])
        rel = relative_residual(b - self._Ks @ y, b)
        x = self.scale[:, None] * y
        return x.reshape(rhs.shape), rel


def assemble(mesh, materials: dict, *, rigid_pillar_on_substrate: bool,
             clamp_pillar_base: bool, contact: tuple) -> AxisymmetricSystem:
    """Assemble the elastic bodies of ``mesh`` and their constraints.

    Parameters
    ----------
    mesh : skfem.MeshTri
        Dimensionless mesh with named subdomains and boundaries (see :mod:`meshes`).
    materials : dict
        Body name -> (E / E_ref, nu) for every meshed body.
    rigid_pillar_on_substrate : bool
        The pillar is rigid and bonded to an elastic substrate: the substrate's pillar-base
        nodes move with one rigid translation w (u_r = 0, u_z = w).
    clamp_pillar_base : bool
        The substrate is rigid: the pillar base is clamped (u = 0).
    contact : tuple of (lens, lower) pairs
        One pair per contact line: the name of the lens contact boundary (or None for a
        rigid lens) and of the lower one (a boundary name, ``"rigid-translation"`` for the
        rigid pillar's w, or None for a fixed rigid surface).
    """
    ub = Basis(mesh, ElementVector(ElementTriP2()), intorder=INTORDER)
    nu_dofs = ub.N
    A = sp.csr_matrix((nu_dofs, nu_dofs))
    blocks_B, blocks_C, pressures = [], [], []
    offset = nu_dofs
    for body, (E, nu) in materials.items():
        elements = mesh.subdomains[body]
        mu, beta, c = mixed_coefficients(E, nu)
        ub_b = ub.with_elements(elements)
        A = A + shear_stiffness.assemble(ub_b, mu=mu)
        pb = Basis(mesh, ElementTriP1(), elements=elements, intorder=INTORDER)
        dofs = np.unique(pb.element_dofs)
        B = divergence_coupling.assemble(ub_b, pb).tocsr()[dofs]
        M = pressure_mass.assemble(pb).tocsr()[dofs][:, dofs]
        blocks_B.append(beta * B)
        blocks_C.append(-c * M)
        pressures.append(PressureSpace(body, pb, dofs, beta, mu, offset))
        offset += len(dofs)
    B = sp.vstack(blocks_B)
    K = sp.bmat([[A, B.T], [B, sp.block_diag(blocks_C)]], format="csr")

    # --- constraints -----------------------------------------------------------------
    fixed = [ub.get_dofs("axis").all("u^1")]  # u_r = 0 on the axis
    for far in ("far_lens", "far_substrate"):
        if far in mesh.boundaries:
            fixed.append(ub.get_dofs(far).all("u^2"))  # roller: u_z = 0 far away
    if clamp_pillar_base:
        fixed.append(ub.get_dofs("pillar_base").all())
    tied = np.zeros(0, dtype=np.int64)
    if rigid_pillar_on_substrate:
        base = ub.get_dofs("pillar_base")
        fixed.append(base.all("u^1"))
        tied = base.all("u^2")
    n_full = K.shape[0]
    constrained = np.unique(np.concatenate(fixed + [tied]))
    free = np.setdiff1d(np.arange(n_full), constrained)
    T = sp.csr_matrix((np.ones(len(free)), (free, np.arange(len(free)))),
                      shape=(n_full, len(free) + (1 if len(tied) else 0)))
    if len(tied):
        T = T + sp.csr_matrix((np.ones(len(tied)), (tied, np.full(len(tied), len(free)))),
                              shape=T.shape)
    reduced_of = np.full(n_full, -1)
    reduced_of[free] = np.arange(len(free))

    # --- contact operator: gap change = u_z(lens) - u_z(lower) at matched points --------
    blocks = [_contact_rows(ub, reduced_of, T.shape[1], pair) for pair in contact]
    G = sp.vstack([b[0] for b in blocks], format="csr")
    r_points = np.concatenate([b[1] for b in blocks])
    lines = [len(b[1]) for b in blocks]

    # --- scaling: 1/sqrt|diag| for displacements and w, 1/sqrt(diag C) for pressures -----
    Kr = (T.T @ K @ T).tocsc()  # reduced once: for the scaling here and the factorisation
    Kr_diag = np.abs(Kr.diagonal())
    scale = np.zeros(T.shape[1])
    is_u = np.ones(T.shape[1], dtype=bool)
    for ps in pressures:
        M_diag = pressure_mass.assemble(ps.basis).diagonal()[ps.dofs]
        red = reduced_of[ps.offset:ps.offset + len(ps.dofs)]
        scale[red[red >= 0]] = 1.0 / np.sqrt(M_diag[red >= 0])
        is_u[red[red >= 0]] = False
    scale[is_u] = 1.0 / np.sqrt(Kr_diag[is_u])
    return AxisymmetricSystem(mesh, ub, pressures, Kr, T, G, r_points, scale, lines)


def _contact_rows(ub, reduced_of, n_reduced: int, pair: tuple):
    """(G rows, r of the points) of one contact line: the gap change u_z(lens) - u_z(lower)
    at its P2 points, sorted by r; ``pair`` names the lens and lower boundaries as
    :func:`assemble`'s ``contact``."""
    lens_name, lower_name = pair
    columns, r_points = [], None
    for name, sign in ((lens_name, 1.0), (lower_name, -1.0)):
        if name is None:
            continue
        if name == "rigid-translation":
            columns.append((sign, None))
            continue
        dofs = ub.get_dofs(name).all("u^2")
        r = ub.doflocs[0, dofs]
        order = np.argsort(r)
        dofs, r = dofs[order], r[order]
        if r_points is None:
            r_points = r
        elif len(r) != len(r_points) or np.max(np.abs(r - r_points)) > 1e-9:
            raise SolveError(f"contact points of {lens_name!r} and {name!r} do not match")
        if np.any(reduced_of[dofs] < 0):
            raise SolveError(f"contact unknowns on {name!r} are constrained")
        columns.append((sign, reduced_of[dofs]))
    if r_points is None:
        raise SolveError("no elastic body carries the contact line")
    n_c = len(r_points)
    rows, cols, vals = [], [], []
    for sign, idx in columns:
        rows.append(np.arange(n_c))
        cols.append(np.full(n_c, n_reduced - 1) if idx is None else idx)
        vals.append(np.full(n_c, sign))
    G = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(n_c, n_reduced))
    return G, r_points
