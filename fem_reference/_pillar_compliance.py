"""The excess compliance of one elastic pillar bonded to a substrate, by Fourier modes in theta.

What the elastic-pillar BEM needs (PHYSICS.md, "The elastic-pillar BEM").  A normal point force
F at (r', theta') on the top of a pillar (radius a = d/2, height h; E_p, nu_p) bonded to a
substrate half-space (E_s, nu_s) moves the top at (r, theta) by G(r, r', theta - theta') F.
The cylinder is a body of revolution, so G splits into Fourier modes,

    G = sum_n  w_n g_n(r, r') cos(n (theta - theta')),    w_0 = 1/(2 pi), w_n = 1/pi,

and each g_n is one 2D finite-element solve (:mod:`.forms.fourier`, Taylor-Hood P2/P1, exact
at nu = 1/2).  Its singular part, the local half-space response gamma_p / (pi |x - x'|), is
taken out by a second solve of the same mesh with the region around the pillar filled by
pillar material (a half-space of material p with the same top): the difference

    s_n = g_n(pillar on substrate) - g_n(half-space of pillar material)

is smooth away from the pillar edge (the meshes coincide on the pillar, so their
discretisation errors near the load cancel as well), and the excess compliance over the
half-space that the BEM carries (gamma_s Love) is

    X(x, x') = sum_n w_n s_n(r, r') cos(n dtheta) + (gamma_p - gamma_s) / pi * Love(x, x').

This module computes s_n as matrices on the P2 points of the top (the unit nodal loads are
the "rings" of load: quadratic hats in r), for n = 0 .. ``modes``; :mod:`bem_solver` maps
them onto its cells.  The operator depends on the pillar kind only (h/d, E_p/E_s, nu_p,
nu_s) and on the discretisation, and is cached on disk under that key and the code version
(:mod:`._compliance_store`).

Units.  Lengths in units of a, moduli of E_p* (E_p clipped to at most 1e6 E_s, see
RIGID_CONTRAST): a compliance matrix C here gives the physical top displacement u = C f / (E_p a)
for nodal loads f (N) of the mode (f_i = F phi_i(r') cos(n theta') / (pi eps_n)).
"""

from __future__ import annotations

import functools
import hashlib
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from skfem import Basis, ElementTriP1, ElementTriP2, ElementVector

from meshes import AxisymmetricMesh, MeshError
from pillar_xval.scenes import InputError, Scene, ScopeError

from ._pardiso import Pardiso
from ._reduced import SolveError
from .forms.axisymmetric import mixed_coefficients, pressure_mass
from .forms.fourier import mode_divergence_coupling, mode_shear_stiffness

# Version of the operator's definition and discretisation: part of the cache key, with the
# hash of this module's and the form's sources.
COMPLIANCE_VERSION = 2   # 2: the base moments
DEFAULT_MODES = 6   # n <= 6: tilt (n = 1) matters, n >= 2 below 3e-5 (PHYSICS.md); 6 is the
#                    centre pillar's D6 harmonic
# Moduli contrasts are capped at RIGID_CONTRAST: a pillar stiffer than RIGID_CONTRAST * E_s
# (a rigid one included) is modelled as E_p = RIGID_CONTRAST * E_s, a substrate stiffer than
# RIGID_CONTRAST * E_p as E_s = RIGID_CONTRAST * E_p (a rigid substrate is clamped exactly).
# The stiffer body's compliance is then 1e-6 of the other's, below any discretisation error;
# beyond it the solves lose accuracy like eps * contrast (1e-5 at 1e9, measured).
RIGID_CONTRAST = 1e6
BLOCK_FACTOR = 1e5          # substrate block side over a (truncation ~ a / L)
ELEMENTS_ACROSS_TOP = 12.0  # elements across the pillar radius at mesh_size 1
EDGE_RATIO = 0.03           # element size at the top edge and the base corner, relative
GROWTH = 0.25
PILLAR_CAP = 0.35           # largest element inside the pillar (a), at mesh_size 1
# Scaled relative residual of every mode solve, times the moduli contrast (the floor of
# round-off in K x when one body is that much stiffer); checked.
RTOL_LINEAR = 1e-10
RTOL_PARDISO = 1e-11      # above it, the solve is repeated with SuperLU
# The half-space of pillar material is a mesa: the collar fills r <= Rc = COLLAR_FACTOR
# max(H, a) around the pillar.  The missing layer beyond Rc changes the top response by about
# H a / Rc^2 relative (< 3e-5), and keeps the collar's elements no longer than its thickness.
COLLAR_FACTOR = 200.0


@dataclass(frozen=True)
class PillarKind:
    """The dimensionless pillar: ``height_over_diameter`` h/d, ``modulus_ratio`` E_p/E_s
    (inf: rigid pillar; 0: rigid substrate), ``nu_pillar``, ``nu_substrate``."""

    height_over_diameter: float
    modulus_ratio: float
    nu_pillar: float
    nu_substrate: float

    def __post_init__(self):
        h = self.height_over_diameter
        if not (isinstance(h, (int, float)) and math.isfinite(h) and 0.01 <= h <= 100.0):
            raise InputError(f"height_over_diameter = {h!r}: allowed range is [0.01, 100]")
        e = self.modulus_ratio
        if not (isinstance(e, (int, float)) and not math.isnan(e) and e >= 0.0):
            raise InputError(f"modulus_ratio = {e!r}: allowed range is [0, inf] "
                             "(0: rigid substrate, inf: rigid pillar)")
        if e == 0.0 and math.isinf(e):
            raise InputError("modulus_ratio: pillar and substrate cannot both be rigid")
        for name in ("nu_pillar", "nu_substrate"):
            nu = getattr(self, name)
            if not (isinstance(nu, (int, float)) and 0.0 <= nu <= 0.5):
                raise InputError(f"{name} = {nu!r}: allowed range is [0, 0.5]")

    @classmethod
    def of_scene(cls, scene: Scene) -> "PillarKind":
        p = scene.pillars
        if p is None:
            raise ScopeError("the scene has no pillars: there is no pillar compliance")
        if p.material.rigid and scene.substrate.rigid:
            raise ScopeError("pillars and substrate are both rigid: the pillar has no "
                             "compliance (the elastic and Hooke models coincide)")
        ratio = (math.inf if p.material.rigid else
                 0.0 if scene.substrate.rigid else p.material.E_Pa / scene.substrate.E_Pa)
        return cls(p.height_m / p.diameter_m, ratio, p.material.nu, scene.substrate.nu)

    @property
    def rigid_pillar(self) -> bool:
        return math.isinf(self.modulus_ratio)

    @property
    def rigid_substrate(self) -> bool:
        return self.modulus_ratio == 0.0

    @property
    def modelled_ratio(self) -> float:
        """E_p/E_s as modelled: the ratio clipped to [1/RIGID_CONTRAST, RIGID_CONTRAST]
        (0 for a rigid substrate)."""
        if self.rigid_substrate:
            return 0.0
        return min(max(self.modulus_ratio, 1.0 / RIGID_CONTRAST), RIGID_CONTRAST)

    def effective_pillar_modulus(self, E_s: float, E_p: float) -> float:
        """E_p in Pa as modelled: at most RIGID_CONTRAST E_s (a rigid pillar: exactly that)."""
        if self.rigid_substrate:
            return E_p
        return min(E_p, RIGID_CONTRAST * E_s)


@dataclass
class ModalCompliance:
    """Mode matrices of one pillar kind on the P2 points of its top.

    ``r_top``: the P2 points of the top, 0 .. 1 in units of a (vertices at even, midpoints at
    odd indices); ``pillar[n]`` and ``halfspace[n]`` (len(r_top) square, dimensionless, see
    the module's units): compliance of mode n of the pillar on its substrate and of the
    half-space of pillar material; ``excess[n]`` = their difference, symmetrised.
    ``base_moments`` (2 x n_top): for a unit load at each top point, the second radial
    moment (units of a^2) of the normal load the pillar passes to its substrate, its mode-0
    part R_0 = int t rho^2 and mode-2 part R_2 = int t rho^2 cos 2(phi - theta) (a column
    passes the load straight down: R_0 = R_2 = r^2; a rigid pillar as a rigid punch:
    R_0 = 2/3, R_2 = 0; a rigid substrate: r^2, unused).  The BEM's pillar-to-pillar
    coupling corrects its top-plane Boussinesq field with them.
    ``diagnostics``: reciprocity (relative asymmetry of every matrix before symmetrising),
    linear residual, mesh and timing."""

    kind: PillarKind
    modes: int
    mesh_size: float
    r_top: np.ndarray
    pillar: np.ndarray       # (modes + 1, n_top, n_top)
    halfspace: np.ndarray
    diagnostics: dict = field(default_factory=dict)
    base_moments: np.ndarray | None = None   # (2, n_top): R_0, R_2 (units of a^2)

    @property
    def excess(self) -> np.ndarray:
        return self.pillar - self.halfspace

    def trace_basis(self, r: np.ndarray) -> np.ndarray:
        """phi (len(r) x n_top): the P2 hats of the top evaluated at radii r (units of a)."""
        r = np.clip(np.asarray(r, dtype=float), 0.0, 1.0)
        vert = self.r_top[::2]
        k = np.clip(np.searchsorted(vert, r, side="right") - 1, 0, len(vert) - 2)
        x = (r - vert[k]) / (vert[k + 1] - vert[k])
        phi = np.zeros((len(r), len(self.r_top)))
        rows = np.arange(len(r))
        phi[rows, 2 * k] = (1.0 - x) * (1.0 - 2.0 * x)
        phi[rows, 2 * k + 1] = 4.0 * x * (1.0 - x)
        phi[rows, 2 * k + 2] = x * (2.0 * x - 1.0)
        return phi

    def mode_weights(self) -> np.ndarray:
        """w_n: 1/(2 pi) for n = 0, 1/pi otherwise."""
        w = np.full(self.modes + 1, 1.0 / math.pi)
        w[0] = 0.5 / math.pi
        return w


# --- mesh ---------------------------------------------------------------------------------

def _size_rule(H: float, L: float, Rc: float, mesh_size: float):
    h_top = 1.0 / ELEMENTS_ACROSS_TOP
    h_edge = EDGE_RATIO * h_top

    def size(r, z):
        s = h_top + GROWTH * math.hypot(max(r - 1.0, 0.0), z)
        for (rp, zp) in ((1.0, 0.0), (1.0, -H)):
            s = min(s, h_edge + GROWTH * math.hypot(r - rp, z - zp))
        if r <= 1.0 and z >= -H:
            s = min(s, PILLAR_CAP)
        # The collar, a layer of thickness H, and a graded transition around it.
        s = min(s, 0.7 * H + GROWTH * math.hypot(max(r - Rc, 0.0), max(-H - z, 0.0, z)))
        return mesh_size * min(s, 0.1 * L)
    return size


def pillar_halfspace_mesh(height_over_radius: float, mesh_size: float = 1.0,
                          block_factor: float = BLOCK_FACTOR) -> AxisymmetricMesh:
    """(r, z) mesh in units of a: ``pillar`` [0, 1] x [-H, 0], ``collar`` [1, Rc] x [-H, 0] and
    ``substrate`` [0, L] x [-H - L, -H], conforming; boundaries ``top`` (the pillar top,
    z = 0, r <= 1), ``axis``, ``far`` (the substrate bottom) and ``pillar_base``."""
    from meshes._session import gmsh_model, set_size_callback

    H, L = float(height_over_radius), float(block_factor)
    Rc = COLLAR_FACTOR * max(H, 1.0)
    size = _size_rule(H, L, Rc, mesh_size)
    with gmsh_model(f"pillar-halfspace-{H:g}-{mesh_size:g}", "the pillar compliance mesh") \
            as gmsh:
        g = gmsh.model.geo
        P = {k: g.addPoint(*xy, 0.0) for k, xy in {
            "o": (0, 0), "e": (1, 0), "E": (Rc, 0), "b": (0, -H), "c": (1, -H),
            "C": (Rc, -H), "F": (L, -H), "B": (0, -H - L), "D": (L, -H - L)}.items()}
        line = {k: g.addLine(P[k[0]], P[k[1]]) for k in
                ("oe", "eE", "ec", "cC", "CF", "EC", "bc", "ob", "bB", "BD", "DF")}
        pillar = g.addPlaneSurface([g.addCurveLoop(
            [line["oe"], line["ec"], -line["bc"], -line["ob"]])])
        collar = g.addPlaneSurface([g.addCurveLoop(
            [line["eE"], line["EC"], -line["cC"], -line["ec"]])])
        substrate = g.addPlaneSurface([g.addCurveLoop(
            [line["bc"], line["cC"], line["CF"], -line["DF"], -line["BD"], -line["bB"]])])
        g.synchronize()
        groups = {"pillar": (2, [pillar]), "collar": (2, [collar]),
                  "substrate": (2, [substrate]), "top": (1, [line["oe"]]),
                  "axis": (1, [line["ob"], line["bB"]]), "far": (1, [line["BD"]]),
                  "pillar_base": (1, [line["bc"]])}
        for name, (dim, tags) in groups.items():
            gmsh.model.addPhysicalGroup(dim, tags, name=name)
        for key in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints",
                    "MeshSizeFromCurvature"):
            gmsh.option.setNumber(f"Mesh.{key}", 0)
        gmsh.option.setNumber("Mesh.Algorithm", 6)
        gmsh.option.setNumber("Mesh.ElementOrder", 1)
        set_size_callback(gmsh, lambda dim, tag, x, y, z, lc: size(x, y))
        gmsh.model.mesh.generate(2)
        tags, xyz, _ = gmsh.model.mesh.getNodes()
        index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
        index[tags.astype(np.int64)] = np.arange(len(tags))
        tri, sub, lines, bnd = [], {}, [], {}
        nt = nl = 0
        for name, (dim, ents) in groups.items():
            blocks = []
            for ent in ents:
                for _, nodes in zip(*gmsh.model.mesh.getElements(dim, ent)[::2]):
                    blocks.append(index[nodes.astype(np.int64)].reshape(-1, dim + 1).T)
            block = np.hstack(blocks)
            if dim == 2:
                tri.append(block)
                sub[name] = np.arange(nt, nt + block.shape[1])
                nt += block.shape[1]
            else:
                lines.append(block)
                bnd[name] = np.arange(nl, nl + block.shape[1])
                nl += block.shape[1]
    triangles = np.hstack(tri)
    used = np.unique(triangles)
    renumber = np.full(len(tags), -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    points = xyz.reshape(-1, 3)[:, :2].T[:, used]
    mesh = AxisymmetricMesh(points=points, triangles=renumber[triangles],
                            lines=renumber[np.hstack(lines)], subdomains=sub, boundaries=bnd,
                            geometry=None)  # type: ignore[arg-type]  # built from raw nodes
    q = mesh.quality()
    if q.min() < 0.1:
        raise MeshError(f"pillar compliance mesh: triangle quality {q.min():.3g} < 0.1")
    return mesh


# --- the mode systems ---------------------------------------------------------------------

class _Body:
    """Assembled blocks of one body, affine (B) or quadratic (A) in the mode number n."""

    def __init__(self, ub, mesh, elements, E, nu):
        self.mu, self.beta, self.c = mixed_coefficients(E, nu)
        ub_b = ub.with_elements(elements)
        A = [mode_shear_stiffness.assemble(ub_b, mu=self.mu, n=float(n)) for n in (0, 1, 2)]
        self.A0, self.A1 = A[0], A[1] - A[0] - 0.5 * (A[2] - 2 * A[1] + A[0])
        self.A2 = 0.5 * (A[2] - 2 * A[1] + A[0])
        pb = Basis(mesh, ElementTriP1(), elements=elements, intorder=4)
        self.pdofs = np.unique(pb.element_dofs)
        B = [mode_divergence_coupling.assemble(ub_b, pb, n=float(n)).tocsr()[self.pdofs]
             for n in (0, 1)]
        self.B0, self.B1 = B[0], B[1] - B[0]
        self.M = pressure_mass.assemble(pb).tocsr()[self.pdofs][:, self.pdofs]
        self.udofs = np.unique(ub_b.element_dofs)

    def blocks(self, n):
        return (self.A0 + n * self.A1 + n * n * self.A2, self.beta * (self.B0 + n * self.B1),
                -self.c * self.M)


def _mode_compliance(ub, bodies, n, fixed_extra, top, axis_nodes, base=None):
    """Compliance matrix of mode n on the top u_z dofs (n_top square), the linear residual and
    the unknowns; with ``base`` = (base u_z dofs, their weights V), also the load that each top
    point's unit load passes through the base, weighted by V: sum_i V_i r_i over the base
    nodes, r the nodal force of the first body (the pillar) on what lies below it (len
    n_top; None without ``base``)."""
    A = sum(b.blocks(n)[0] for b in bodies)
    Bs = [b.blocks(n)[1] for b in bodies]
    Cs = [b.blocks(n)[2] for b in bodies]
    K = sp.bmat([[A, sp.vstack(Bs).T], [sp.vstack(Bs), sp.block_diag(Cs)]], format="csr")
    n_u, n_full = ub.N, K.shape[0]
    active = np.zeros(n_u, bool)
    for b in bodies:
        active[b.udofs] = True
    fixed = [np.nonzero(~active)[0], fixed_extra]
    ur, ut, uz = axis_nodes
    if n == 0:
        fixed += [ut["all"], ur["axis"]]
    elif n == 1:
        fixed += [uz["axis"]]
    else:
        fixed += [ur["axis"], ut["axis"], uz["axis"]]
    tied = ut["axis"] if n == 1 else np.zeros(0, np.int64)
    constrained = np.unique(np.concatenate(fixed + [tied]).astype(np.int64))
    free = np.setdiff1d(np.arange(n_full), constrained)
    T = sp.csr_matrix((np.ones(len(free)), (free, np.arange(len(free)))),
                      shape=(n_full, len(free)))
    if len(tied):  # n = 1: u_t = -u_r on the axis (a translation across it)
        col = np.searchsorted(free, ur["axis"])
        T = T + sp.csr_matrix((-np.ones(len(tied)), (tied, col)), shape=T.shape)
    Kr = (T.T @ K @ T).tocsr()
    # Symmetric scaling: 1/sqrt|diag| for displacements, 1/sqrt(diag M) for each body's
    # pressure (its diagonal block vanishes at nu = 1/2), as in :mod:`._reduced`.
    d = np.abs(Kr.diagonal())
    mass = np.concatenate([b.M.diagonal() for b in bodies])
    is_p = np.zeros(n_full, bool)
    is_p[n_u:] = True
    d_full = np.zeros(n_full)
    d_full[n_u:] = mass
    d = np.where(is_p[free], d_full[free], d)
    d[d == 0] = 1.0
    s = 1.0 / np.sqrt(d)
    S = sp.diags(s)
    Ks = (S @ Kr @ S).tocsr()
    top_free = np.isin(top, free)
    cols = np.searchsorted(free, top[top_free])
    rhs = np.zeros((len(free), len(cols)))
    rhs[cols, np.arange(len(cols))] = s[cols]
    y = _refined(Pardiso(Ks, _shared_pardiso()).solve, Ks, rhs)
    if _relative(Ks, y, rhs) > RTOL_PARDISO:
        # Stiff contrasts: PARDISO's perturbed pivots can stall the refinement; SuperLU with
        # threshold pivoting is the second opinion, and the better answer is kept.
        try:
            lu = splu(Ks.tocsc(), permc_spec="COLAMD", diag_pivot_thresh=0.1)
        except (RuntimeError, MemoryError) as exc:
            raise SolveError(f"SuperLU could not factorise the {Ks.shape[0]}-unknown mode-{n} "
                             f"system: {exc}") from None
        y2 = _refined(lu.solve, Ks, rhs)
        if _relative(Ks, y2, rhs) < _relative(Ks, y, rhs):
            y = y2
    rel = _relative(Ks, y, rhs)
    x = s[:, None] * y
    C = np.zeros((len(top), len(top)))
    C[np.ix_(top_free, top_free)] = x[cols]
    moment = None
    if base is not None:
        # The pillar's internal nodal forces A_p u + B_p^T p_p: the applied unit load at its
        # top point, zero inside, and at the base nodes minus the load it passes on (the sum
        # over every node vanishes for a rigid translation).
        full = T @ x
        A_p, B_p, _ = bodies[0].blocks(n)
        n_p = B_p.shape[0]
        internal = A_p @ full[:n_u] + B_p.T @ full[n_u:n_u + n_p]
        dofs, weights = base
        moment = np.zeros(len(top))
        moment[top_free] = -(weights @ internal[dofs])
    return C, rel, len(free), moment


_PARDISO: list = []


def _relative(K, y, rhs) -> float:
    """max over columns of ||K y - b|| / ||b||."""
    res = rhs - K @ y
    return float(np.max(np.linalg.norm(res, axis=0) / np.linalg.norm(rhs, axis=0)))


def _refined(solve, K, rhs, steps: int = 3):
    """solve(rhs) with up to ``steps`` rounds of iterative refinement against K."""
    y = solve(rhs)
    for _ in range(steps):
        if _relative(K, y, rhs) < 1e-13:
            break
        y = y + solve(rhs - K @ y)
    return y


def _shared_pardiso():
    """One PyPardisoSolver for every mode solve of the process (see :class:`._pardiso.Pardiso`)."""
    if not _PARDISO:
        try:
            from pypardiso import PyPardisoSolver
        except ImportError as exc:
            raise SolveError(f"pypardiso is not installed ({exc})") from None
        _PARDISO.append(PyPardisoSolver(mtype=-2))
    return _PARDISO[0]


def _axis_dofs(ub):
    """Per component (u_r, u_t, u_z): its dofs on the axis and all of them."""
    out = []
    for comp in ("u^1", "u^2", "u^3"):
        out.append({"axis": ub.get_dofs("axis").all(comp),
                    "all": ub.get_dofs().all(comp)})
    return out


def compute_modal_compliance(kind: PillarKind, modes: int = DEFAULT_MODES,
                             mesh_size: float = 1.0, progress=None) -> ModalCompliance:
    """Solve the mode systems of ``kind`` (no cache; see
    :func:`._compliance_store.modal_compliance`)."""
    say = progress or (lambda text: None)
    t0 = time.perf_counter()
    H = 2.0 * kind.height_over_diameter
    say(f"meshing the pillar (h/d = {kind.height_over_diameter:g})")
    mesh = pillar_halfspace_mesh(H, mesh_size)
    sk = mesh.to_skfem()
    ub = Basis(sk, ElementVector(ElementTriP2(), 3), intorder=4)
    t_mesh = time.perf_counter()
    top = ub.get_dofs("top").all("u^3")
    r_top = ub.doflocs[0, top]
    order = np.argsort(r_top)
    top, r_top = top[order], r_top[order]
    axis_nodes = _axis_dofs(ub)
    far = ub.get_dofs("far").all()
    sub = mesh.subdomains
    # (a) pillar on its substrate; (b) half-space of pillar material (the collar filled).
    E_s = 0.0 if kind.rigid_substrate else 1.0 / kind.modelled_ratio
    nu_p, nu_s = kind.nu_pillar, kind.nu_substrate
    say("assembling")
    pillar = _Body(ub, sk, sub["pillar"], 1.0, nu_p)
    bodies_a = [pillar]
    fixed_a = [far]
    if kind.rigid_substrate:
        fixed_a.append(ub.get_dofs("pillar_base").all())
    else:
        bodies_a.append(_Body(ub, sk, sub["substrate"], E_s, nu_s))
    bodies_b = [pillar, _Body(ub, sk, sub["collar"], 1.0, nu_p),
                _Body(ub, sk, sub["substrate"], 1.0, nu_p)]
    t_asm = time.perf_counter()
    base_z = ub.get_dofs("pillar_base").all("u^3")
    base = (base_z, ub.doflocs[0, base_z] ** 2)   # V = rho^2 (units of a^2)
    # Second radial moments of the load the pillar passes to its substrate (modes 0 and 2),
    # per unit load at each top point; a column (the Hooke model) passes rho^2 = r_top^2.
    moments = np.tile(r_top ** 2, (2, 1))
    Ca: list = []
    Cb: list = []
    residual, asym, dofs = 0.0, 0.0, []
    for n in range(modes + 1):
        say(f"mode {n} of {modes}")
        for bodies, fixed, out in ((bodies_a, np.concatenate(fixed_a), Ca),
                                   (bodies_b, far, Cb)):
            want = (out is Ca and n in (0, 2) and not kind.rigid_substrate)
            C, rel, nd, moment = _mode_compliance(ub, bodies, n, fixed, top, axis_nodes,
                                                  base if want else None)
            if moment is not None:
                moments[n // 2] = moment
            residual = max(residual, rel)
            scale = np.max(np.abs(C)) or 1.0
            asym = max(asym, float(np.max(np.abs(C - C.T)) / scale))
            out.append(0.5 * (C + C.T))
            dofs.append(nd)
    if not np.all(np.isfinite(Ca)) or not np.all(np.isfinite(Cb)):
        raise SolveError("the pillar compliance solves returned non-finite values")
    contrast = 1.0 if kind.rigid_substrate else max(kind.modelled_ratio,
                                                        1.0 / kind.modelled_ratio)
    if residual > RTOL_LINEAR * max(1.0, contrast):
        raise SolveError(f"pillar compliance: linear residual {residual:.3g} exceeds "
                         f"{RTOL_LINEAR:g} (kind {kind})")
    t_end = time.perf_counter()
    diag = {"reciprocity_asymmetry": asym, "linear_residual": residual,
            "elements": int(mesh.nelements), "top_points": int(len(r_top)),
            "max_unknowns": int(max(dofs)),
            "mesh_min_quality": float(mesh.quality().min()),
            "time_s": {"mesh": t_mesh - t0, "assemble": t_asm - t_mesh,
                       "modes": t_end - t_asm, "total": t_end - t0}}
    if not np.all(np.isfinite(moments)):
        raise SolveError("the pillar's base moments are not finite")
    return ModalCompliance(kind, int(modes), float(mesh_size), r_top, np.array(Ca),
                           np.array(Cb), diag, moments)


# --- what the cache key hashes ------------------------------------------------------------

@functools.lru_cache(maxsize=1)
def _source_hash() -> str:
    """Hash of the sources that define the operator, read once per process (a process keeps
    the code it imported)."""
    h = hashlib.sha256()
    here = Path(__file__).resolve().parent
    for path in (here / "_pillar_compliance.py", here / "forms" / "fourier.py",
                 here / "forms" / "axisymmetric.py"):
        h.update(path.read_bytes())
    return h.hexdigest()[:12]


__all__ = ["DEFAULT_MODES", "ModalCompliance", "PillarKind", "compute_modal_compliance",
           "pillar_halfspace_mesh"]
