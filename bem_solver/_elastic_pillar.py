"""The elastic pillar on the BEM's cells: ``pillars="elastic"`` (PHYSICS.md, "The
elastic-pillar BEM").

The Hooke BEM writes the displacement of a pillar top as the half-space response (gamma_l +
gamma_s) Love plus a uniform shortening c_h = 4 h / (pi d^2 E_p) per unit force on the pillar.
The elastic model replaces c_h by the pillar's excess compliance X, a dense block per pillar
(the same block for every pillar of a scene, in the pillar's own frame, since a cylinder is a
body of revolution):

    X[a, b] = 1/(E_p a) sum_{n <= N} w_n phi(r_a)^T S_n phi(r_b) cos(n (theta_a - theta_b))
              + (gamma_p - gamma_s) / pi * D(x_a; square_b) / area_b,

S_n the smooth difference of the mode-n compliance of the pillar on its substrate and of a
half-space of pillar material on the P2 points of the top (:mod:`fem_reference`, computed
once per pillar kind and cached), phi the P2 hats of those points, (r, theta) cell collocation
points relative to the pillar centre, and the second term the local singular part, on the same
Love coefficients as the half-space term.  Both terms are symmetric (the second as the BEM
symmetrises Love's coefficients).

Pillar-to-pillar coupling.  The half-space term couples two pillars as if each passed its
top load straight down to the substrate (a column).  A real pillar spreads it: a stiff one
passes it on as a rigid punch.  The load's force and moment reach the base unchanged
(equilibrium), so the first correction is in the second moments of the load at the base:
with ΔM_i(x) (m^2, per unit force at x on pillar i) their excess over the column's (x - c_i)
(x - c_i)^T, the coupling of cells x on pillar i and x' on pillar j != i gains

    ΔK(x, x') = gamma_s / (2 pi) [ΔM_i(x) + ΔM_j(x')] : grad grad (1/|c_i - c_j|),

the next term of the multipole expansion of the Boussinesq field between the two bases
(:func:`coupling_moments`, :func:`coupling_kernel`; the moments come from the same Fourier
FEM, ``ModalCompliance.base_moments``).  ΔK is symmetric, zero on one pillar and decays like
|c_i - c_j|^-3.

The compliance comes from :mod:`fem_reference` (imported when first needed, the one place
where the boundary-element package uses the finite-element one) unless the caller passes a
``ModalCompliance`` as ``compliance``.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft as sfft
import scipy.sparse as sp

from pillar_xval.scenes import InputError, Scene

from ._limits import PILLAR_MODELS
from ._love import unit_force_influence

CHUNK_CELLS = 8192  # cells per chunk of the mode projections


def check_pillars(pillars: str, scene: Scene | None = None) -> None:
    """InputError for a pillar model that is not one of :data:`PILLAR_MODELS`, or for the
    elastic pillar on a flat ``scene`` (no pillar to model: refused, not run as Hooke)."""
    if pillars not in PILLAR_MODELS:
        raise InputError(f"pillars = {pillars!r}: allowed values are {', '.join(PILLAR_MODELS)}")
    if pillars == "elastic" and scene is not None and scene.pillars is None:
        raise InputError("pillars = 'elastic': the scene is flat, it has no pillars to model "
                         "(leave the pillar model out)")


def pillar_record(scene: Scene, pillars: str, kind=None) -> dict:
    """What a BEM result records of its pillar model: ``pillars`` ("hooke" or "elastic"; none
    on a flat scene) and, where the elastic pillar (of ``kind``, its compliance's
    ``PillarKind``) solves a moduli contrast beyond its cap as the cap, ``notes`` saying so:
    E_p/E_s = 1e9 is modelled as 1e6, where the stiffer body's compliance is 1e-6 of the
    other's, below any discretisation error, and beyond which the mode solves lose accuracy
    (fem_reference's RIGID_CONTRAST)."""
    if scene.pillars is None:
        return {}
    out = {"pillars": pillars}
    if kind is not None and not kind.rigid_substrate \
            and kind.modulus_ratio != kind.modelled_ratio:
        given = ("rigid pillars" if kind.rigid_pillar else
                 f"E_p/E_s = {kind.modulus_ratio:.3g}")
        out["notes"] = [f"{given} modelled as E_p/E_s = {kind.modelled_ratio:.3g} (the elastic "
                        "pillar's moduli contrast is capped there: the stiffer body's "
                        "compliance is below the discretisation error)"]
    return out


def uses_elastic_block(scene: Scene, pillars: str) -> bool:
    """True when ``pillars="elastic"`` changes the operator: a pillar scene whose pillar has a
    compliance (pillars and substrate both rigid: the two models coincide, X = 0)."""
    check_pillars(pillars)
    return (pillars == "elastic" and scene.pillars is not None
            and not (scene.pillars.material.rigid and scene.substrate.rigid))


def scene_compliance(scene: Scene, compliance=None, modes: int | None = None,
                     mesh_size: float = 1.0, progress=None):
    """The ``ModalCompliance`` of the scene's pillar kind (cached on disk), or ``compliance``
    when given (checked against the scene's kind); ``progress(text)`` hears of a build (tens
    of seconds, once per pillar kind)."""
    from fem_reference import DEFAULT_MODES, PillarKind, modal_compliance

    kind = PillarKind.of_scene(scene)
    if compliance is not None:
        if compliance.kind != kind:
            raise ValueError(f"compliance is for {compliance.kind}, the scene's pillar kind is "
                             f"{kind}")
        return compliance
    say = None if progress is None else (
        lambda text: progress(f"elastic pillar's compliance (once per pillar kind): {text}"))
    return modal_compliance(kind, DEFAULT_MODES if modes is None else modes, mesh_size,
                            progress=say)


def operator_records(*diagnostics: dict) -> list[dict]:
    """The records of the cached operators behind a result, each once: from a compliance's
    ``diagnostics["operator"]`` or a result's ``diagnostics["operators"]`` (its store, key and
    content hash; a compliance passed in by the caller and never stored has none).  A result
    keeps them in ``diagnostics["operators"]``: a study reuses its cached case only while the
    cache still holds them."""
    out = []
    for d in diagnostics:
        for record in [d.get("operator")] + list(d.get("operators", [])):
            if isinstance(record, dict) and record not in out:
                out.append(record)
    return out


def _constants(scene: Scene, compliance):
    """(1 / (E_p* a), gamma_p* - gamma_s): E_p* the modelled pillar modulus."""
    p, s = scene.pillars, scene.substrate
    E_s = s.E_Pa
    E_p = compliance.kind.effective_pillar_modulus(E_s, p.material.E_Pa)
    gamma_p = (1.0 - p.material.nu ** 2) / E_p
    return 1.0 / (E_p * 0.5 * p.diameter_m), gamma_p - s.compliance


def p2_hats(vert, r, xp=np):
    """(edge, (h0, h1, h2)): the edge of the top's P2 trace (``vert``: its vertices, units
    of a) that holds each radius r (units of a, in [0, 1]) and the three P2 hats of that edge
    at r, the only non-zero columns of ``trace_basis(r)``; ``xp``: numpy or cupy."""
    e = xp.clip(xp.searchsorted(vert, r, side="right") - 1, 0, vert.shape[0] - 2)
    t = (r - vert[e]) / (vert[e + 1] - vert[e])
    return e, ((1.0 - t) * (1.0 - 2.0 * t), 4.0 * t * (1.0 - t), t * (2.0 * t - 1.0))


def coupling_moments(scene: Scene, compliance, x, y, xp=np):
    """(len(x), 3): the excess second moment ΔM(x) = alpha I + beta R(2 theta) of the load a
    pillar passes to its substrate per unit force at (x, y) on its top (m, relative to the
    pillar centre, global axes), as (alpha, beta cos 2 theta, beta sin 2 theta) in m^2:
    alpha = a^2 (R_0 - r^2) / 2, beta = a^2 (R_2 - r^2) / 2 (the column's moments r^2
    subtracted), their traces at r by the three P2 hats of its edge (:func:`p2_hats`).
    ``xp``: the namespace of x and y (numpy, or cupy on a GPU).  Callers check
    :func:`uses_coupling` first."""
    x, y = xp.asarray(x, dtype=xp.float64), xp.asarray(y, dtype=xp.float64)
    a = 0.5 * scene.pillars.diameter_m
    r = xp.clip(xp.hypot(x, y) / a, 0.0, 1.0)
    e, hats = p2_hats(xp.asarray(compliance.r_top[::2]), r, xp)
    excess = xp.asarray(np.asarray(compliance.base_moments)
                        - compliance.r_top[None, :] ** 2)              # (2, n_top)

    def trace(v):  # phi(r) @ v: the hats times the values at the edge's three points
        return hats[0] * v[2 * e] + hats[1] * v[2 * e + 1] + hats[2] * v[2 * e + 2]

    alpha = 0.5 * a * a * trace(excess[0])
    beta = 0.5 * a * a * trace(excess[1])
    theta2 = 2.0 * xp.arctan2(y, x)
    return xp.stack([alpha, beta * xp.cos(theta2), beta * xp.sin(theta2)], axis=1)


def coupling_kernel(scene: Scene, centres) -> np.ndarray:
    """(3, n, n): gamma_s / (2 pi) times (tr H, H_xx - H_yy, 2 H_xy) of H = grad grad 1/|D|
    between the pillar centres (D = c_i - c_j; zero for i = j), so that the coupling
    correction of x on pillar i and x' on pillar j is sum_k (m_k(x) + m_k(x')) h_k[i, j] with
    m = :func:`coupling_moments` (m/N)."""
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    dx = c[:, None, 0] - c[None, :, 0]
    dy = c[:, None, 1] - c[None, :, 1]
    d2 = dx * dx + dy * dy
    same = d2 <= (1e-9 * scene.pillars.diameter_m) ** 2
    d2 = np.where(same, 1.0, d2)
    inv3 = np.where(same, 0.0, d2 ** -1.5)
    scale = scene.substrate.compliance / (2.0 * math.pi)
    # H = (3 e e^T - I) / D^3: tr H = 1/D^3, H_xx - H_yy = 3 cos 2psi / D^3, 2 H_xy = 3 sin 2psi / D^3.
    return scale * np.stack([inv3, 3.0 * (dx * dx - dy * dy) / d2 * inv3,
                             6.0 * dx * dy / d2 * inv3])


def uses_coupling(scene: Scene, compliance) -> bool:
    """True when the coupling correction applies: elastic pillars on an elastic substrate."""
    return (not scene.substrate.rigid and scene.substrate.compliance > 0.0
            and getattr(compliance, "base_moments", None) is not None)


def coupling_block(scene: Scene, disc, compliance) -> np.ndarray:
    """C[i, j] = sum over the images b of rep j on pillars other than rep i's of
    ΔK(x_i, x_b) (m/N, unweighted, as :func:`reduced_block`)."""
    n = disc.n_unknowns
    centre = disc.pillar_xy[disc.img_pillar]
    m_img = coupling_moments(scene, compliance, disc.img_x - centre[:, 0],
                             disc.img_y - centre[:, 1])
    rep_img = disc.rep_start[:-1]
    m_rep, p_rep = m_img[rep_img], disc.img_pillar[rep_img]
    h = coupling_kernel(scene, disc.pillar_xy)
    n_p = len(disc.pillar_xy)
    shape = (n_p, n)
    count = sp.csr_matrix((np.ones(len(disc.img_x)), (disc.img_pillar, disc.img_rep)),
                          shape=shape)
    C = np.zeros((n, n))
    for k in range(3):
        moment = sp.csr_matrix((m_img[:, k], (disc.img_pillar, disc.img_rep)), shape=shape)
        hk = h[k][:, p_rep]                                   # (n_p, n_i), symmetric h
        C += m_rep[:, k, None] * (count.T @ hk).T + (moment.T @ hk).T
    return C


def excess_block(scene: Scene, x, y, side, compliance, rows=None) -> np.ndarray:
    """X (m/N) between cells of one pillar: collocation points (x, y) relative to the pillar
    centre (m, in the frame of its cell grid), equivalent-square sides ``side`` (m, squares
    aligned with that frame); symmetric.  ``rows`` (indices): only those rows of X, the
    rows that a reduced operator needs."""
    x, y, side = (np.asarray(v, dtype=float) for v in (x, y, side))
    rows = np.arange(len(x)) if rows is None else np.asarray(rows)
    a = 0.5 * scene.pillars.diameter_m
    fem_scale, local = _constants(scene, compliance)
    r = np.hypot(x, y) / a
    theta = np.arctan2(y, x)
    phi = compliance.trace_basis(r)
    w = compliance.mode_weights()
    # sum_n w_n (phi S_n phi^T) cos(n (theta_a - theta_b)) = U W U^T, with U the columns
    # cos(n theta) phi and sin(n theta) phi of every mode and W = diag(w_n S_n, w_n S_n):
    # one matrix product instead of an elementwise cosine per mode.
    U, WU = [], []
    for n in range(compliance.modes + 1):
        Sn = w[n] * compliance.excess[n]
        for trig in ((np.cos,) if n == 0 else (np.cos, np.sin)):
            Un = trig(n * theta)[:, None] * phi
            U.append(Un)
            WU.append(Un[rows] @ Sn)
    X = np.hstack(WU) @ np.hstack(U).T
    X *= fem_scale
    if local != 0.0:  # zero when pillar and substrate have the same compliance
        # Love's coefficients, symmetrised (the same for every pair of cells of a pillar).
        L = unit_force_influence(x[rows, None], y[rows, None], x[None, :], y[None, :], 0.0,
                                 side[None, :])
        L += unit_force_influence(x[:, None], y[:, None], x[None, rows], y[None, rows], 0.0,
                                  side[None, rows]).T
        X += 0.5 * local / math.pi * L
    return X


_BLOCKS: dict = {}
_BLOCKS_KEPT = 8


def cached_excess_block(scene: Scene, cells: dict, compliance, rows, resolution) -> np.ndarray:
    """:func:`excess_block` of the cells ``cells`` (``x``, ``y``, ``side`` in m), kept in
    memory for the last few (compliance, pillar physics, resolution, rows): a ladder or a
    sweep over the load pays for it once."""
    p, s = scene.pillars, scene.substrate
    key = (id(compliance), p.diameter_m, p.material.E_Pa, p.material.nu, s.E_Pa, s.nu,
           tuple(resolution), tuple(np.asarray(rows).tolist()))
    hit = _BLOCKS.get(key)
    if hit is not None and hit[0] is compliance:
        return hit[1]
    X = excess_block(scene, cells["x"], cells["y"], cells["side"], compliance, rows)
    X.setflags(write=False)
    if len(_BLOCKS) >= _BLOCKS_KEPT:
        _BLOCKS.pop(next(iter(_BLOCKS)))
    _BLOCKS[key] = (compliance, X)
    return X


def representative_rows(scene: Scene, pattern) -> np.ndarray:
    """Cells of the pattern that can be representatives: the centre pillar's quadrant, and
    every cell when another pillar can touch (its orbit's representatives are all its cells
    or one half)."""
    from ._discretise import overlap_radius

    quadrant = (pattern.grid_x >= -1e-12) & (pattern.grid_y >= -1e-12)
    p = scene.pillars
    if p.pitch_m - 0.5 * p.diameter_m < overlap_radius(scene):
        return np.arange(len(pattern.x))
    return np.nonzero(quadrant)[0]


def image_cells(disc, pattern, diameter: float) -> np.ndarray:
    """Index into ``pattern`` (a :class:`~bem_solver._cells.CellPattern`) of the cell that
    every image element of ``disc`` is, found from its position in its pillar's frame (the
    grid cell that holds it; the patterns are symmetric, so mirrored images are cells too).
    One frame per pillar, so that X sees the true relative position of two cells."""
    P = int(round(1.0 / pattern.cell_side))
    centre = disc.pillar_xy[disc.img_pillar]
    dx, dy = disc.img_x - centre[:, 0], disc.img_y - centre[:, 1]
    # A pillar's grid points along its radial direction; the centre pillar's along x (its
    # images under a rotation by pi carry the angle pi, but lie on the same grid).
    on_centre = np.hypot(centre[:, 0], centre[:, 1]) < 1e-9 * diameter
    angle = np.where(on_centre, 0.0, np.arctan2(centre[:, 1], centre[:, 0]))
    c, s = np.cos(angle), np.sin(angle)
    lx, ly = (c * dx + s * dy) / diameter, (-s * dx + c * dy) / diameter
    b = pattern.cell_side
    key = lambda u, v: (np.floor(u / b + P / 2.0).astype(np.int64) * (P + 2)  # noqa: E731
                        + np.floor(v / b + P / 2.0).astype(np.int64))
    table = key(pattern.grid_x, pattern.grid_y)
    order = np.argsort(table)
    k = key(lx, ly)
    pos = np.clip(np.searchsorted(table, k, sorter=order), 0, len(order) - 1)
    cell = order[pos]
    if not np.array_equal(table[cell], k):
        raise RuntimeError("an image element matches no cell of its pillar's pattern")
    return cell


def reduced_block(disc, X: np.ndarray, img_cell: np.ndarray, rows=None) -> np.ndarray:
    """B[i, j] = sum over the images b of rep j on rep i's own pillar of X[cell(i), cell(b)]
    (m/N, not yet weighted by the orbit size of i: :func:`reduced_operator` does that).
    ``rows``: the cells that the rows of X hold (default: all, in order)."""
    if rows is not None:
        row_of = np.full(X.shape[1], -1)
        row_of[np.asarray(rows)] = np.arange(len(rows))
    n = disc.n_unknowns
    B = np.zeros((n, n))
    own = disc.img_pillar[disc.rep_start[:-1]]  # image 0 of a rep is the rep itself
    rep_cell = img_cell[disc.rep_start[:-1]]
    if rows is not None:
        rep_cell = row_of[rep_cell]
        if np.any(rep_cell < 0):
            raise RuntimeError("a representative's cell is not among the rows of X")
    by_pillar = {}
    for i, p in enumerate(own):
        by_pillar.setdefault(int(p), []).append(i)
    for p, reps in by_pillar.items():
        imgs = np.nonzero(disc.img_pillar == p)[0]
        reps = np.asarray(reps)
        S = sp.csr_matrix((np.ones(len(imgs)), (np.arange(len(imgs)), disc.img_rep[imgs])),
                          shape=(len(imgs), n))
        B[reps] += (S.T @ X[np.ix_(rep_cell[reps], img_cell[imgs])].T).T
    return B


def full_block(disc, X: np.ndarray, img_cell: np.ndarray) -> np.ndarray:
    """The excess compliance over every image element (m/N): X between cells of one pillar."""
    same = disc.img_pillar[:, None] == disc.img_pillar[None, :]
    return np.where(same, X[np.ix_(img_cell, img_cell)], 0.0)


__all__ = ["FFTPillarTerm", "PILLAR_MODELS", "cached_excess_block", "check_pillars",
           "coupling_block", "coupling_kernel", "coupling_moments", "excess_block",
           "full_block", "image_cells", "operator_records", "pillar_record", "reduced_block",
           "representative_rows",
           "scene_compliance", "uses_coupling", "uses_elastic_block"]


class FFTPillarTerm:
    """The elastic pillars' excess compliance on the FFT model's cells, matrix-free.

    ``term(q)`` adds, for smeared cell pressures q (Pa; the force of cell b is q_b L^2), the
    displacement sum_b X[a, b] q_b L^2 over the cells b of the pillar of a (m):

    - the mode part, per pillar: the cell forces are projected onto the P2 hats of the top
      times cos(n theta), sin(n theta) (three sparse products, one column per mode and
      trigonometric factor), the moments are multiplied by w_n S_n / (E_p* a) and projected
      back: O(cells x modes) work and memory, never a dense block;
    - the local part (gamma_p - gamma_s) / pi Love: a convolution on each pillar's own box of
      the grid (a batched, zero-padded FFT of the boxes) plus the near-field correction of
      partly covered cells restricted to pairs on the same pillar.

    Collocation points: the grid's (centroids of partly covered cells), relative to their
    pillar's centre.  Set up and applied on the device of ``backend`` (:mod:`bem_solver._xp`,
    default numpy on the CPU; the set-up on the host where the device lacks numpy's API):
    ``term(q)`` takes and returns that device's vectors, and ``diagonal`` lives there; the
    near-field pairs come from ``correction_builder(gamma, backend)``, built on that backend
    (None: the host).  On numpy the projections
    run in chunks of whole pillars (cache-sized) and the boxes' transforms on the backend's
    threads; on another device each projection is one sparse product over every pillar.
    """

    def __init__(self, scene: Scene, grid, compliance, correction_builder, backend=None):
        from ._xp import NumpyDevice

        be = NumpyDevice() if backend is None else backend
        self.backend = be
        self.on_host = isinstance(be, NumpyDevice)
        # The per-cell set-up runs where the term is applied when that device has numpy's
        # API (cupy: the elastic solve's kernel table 0.06 s instead of 1.07 s at 1e6 cells on
        # an H200), else on the host.
        xp = np if self.on_host else getattr(be, "numpy_like", np)
        self._setup_xp = xp
        self.modal = compliance
        self.half_space = scene.half_space_compliance
        a = 0.5 * scene.pillars.diameter_m
        fem_scale, local = _constants(scene, compliance)
        self.local_compliance = local
        L = grid.cell_size
        self.L2 = L * L
        self.n = grid.n_cells
        centre = grid.pillar_xy[grid.pillar]
        dx = xp.asarray(grid.colloc_x - centre[:, 0])
        dy = xp.asarray(grid.colloc_y - centre[:, 1])
        pillar = xp.asarray(grid.pillar)
        r = xp.clip(xp.hypot(dx, dy) / a, 0.0, 1.0)
        theta = xp.arctan2(dy, dx)
        e, values = p2_hats(xp.asarray(compliance.r_top[::2]), r, xp)
        self.n_pillars = len(grid.pillar_xy)
        self.n_edges = len(compliance.r_top[::2]) - 1
        self.n_top = len(compliance.r_top)
        # Projection of cell forces onto the P2 points of their pillar's top: a sparse
        # matrix (pillar, point) x cells with the three hats of each cell's edge.  The cells
        # are taken by pillar (the permutation ``order``); the projection back is the
        # transpose.
        if xp is np:
            order = np.argsort(grid.pillar, kind="stable")
            position = np.argsort(order)  # of each cell in ``order``
        else:  # any order of a pillar's cells serves (the products sum them in that order)
            order = xp.argsort(pillar)
            position = xp.empty_like(order)
            position[order] = xp.arange(self.n, dtype=order.dtype)
        rows = xp.concatenate([pillar * self.n_top + 2 * e + l for l in range(3)])
        cols = xp.tile(xp.asarray(position), 3)
        hats = xp.concatenate(values)
        self.chunks = self._chunks(grid.pillar[order] if self.on_host else None, rows, cols,
                                   hats)
        self.order = be.asarray(order)
        self.position = position if self.on_host else be.asarray(position)
        trig, modes = [], []
        w = compliance.mode_weights()
        for m in range(compliance.modes + 1):
            for f in ((xp.cos,) if m == 0 else (xp.cos, xp.sin)):
                trig.append(f(m * theta))
                modes.append(m)
        trig = xp.stack(trig, axis=1)                              # (cells, K)
        self.trig = be.asarray(trig[xp.asarray(order)])            # (cells by pillar, K)
        S = compliance.excess
        S = np.stack([w[m] * S[m] for m in modes]) * fem_scale     # (K, n_top, n_top)
        self.S = be.asarray(S)
        # Local Love part: each pillar's box of the grid.
        self.local = None
        if local != 0.0:
            self.local = self._local_plan(grid, local, correction_builder)
        self.diagonal = be.asarray(self._diagonal(S, values, e, trig, xp))
        # Mean excess of the mode part under a uniform load on the whole top (m/N).
        rr = np.linspace(0.0, 1.0, 4001)
        mid, dr = 0.5 * (rr[1:] + rr[:-1]), np.diff(rr)
        moments = (compliance.trace_basis(mid) * (mid * dr)[:, None]).sum(axis=0)
        self.mean_mode = float(2.0 * moments @ (S[0] / w[0]) @ moments / math.pi)
        # Pillar-to-pillar coupling correction (module docstring): per cell its excess base
        # moments (3, cells), per pillar pair the kernel h.
        self.coupling = None
        if uses_coupling(scene, compliance):
            moments = xp.ascontiguousarray(coupling_moments(scene, compliance, dx, dy, xp).T)
            self.coupling = {"m": be.asarray(moments),
                             "h": be.asarray(coupling_kernel(scene, grid.pillar_xy)),
                             "pillar": be.asarray(pillar)}

    @property
    def applies_few(self) -> bool:
        """Whether :meth:`apply_few` can apply the term on a few cells' pillars alone."""
        return self.local is None and self.on_host

    def _chunks(self, pillar_sorted, rows, cols, hats):
        """(c0, c1, r0, r1, P, P^T) per chunk: cells [c0, c1) in ``order``, rows [r0, r1) of
        the projection.  On numpy, chunks of whole pillars of about CHUNK_CELLS cells: each
        chunk's product reads its cells x modes block in cache and writes only its pillars'
        rows.  On another device one chunk: its products are whole-array launches."""
        be = self.backend
        n_rows = self.n_pillars * self.n_top
        if not self.on_host:
            rows, cols, hats = be.asarray(rows), be.asarray(cols), be.asarray(hats)
            return [(0, self.n, 0, n_rows, be.sparse(rows, cols, hats, n_rows, self.n),
                     be.sparse(cols, rows, hats, self.n, n_rows))]
        project = be.sparse(rows, cols, hats, n_rows, self.n)
        first = np.searchsorted(pillar_sorted, np.arange(self.n_pillars + 1))
        chunks, p0 = [], 0
        while p0 < self.n_pillars:
            p1 = p0 + 1
            while p1 < self.n_pillars and first[p1 + 1] - first[p0] <= CHUNK_CELLS:
                p1 += 1
            r0, r1 = p0 * self.n_top, p1 * self.n_top
            block = project[r0:r1, first[p0]:first[p1]]
            chunks.append((first[p0], first[p1], r0, r1, block, block.T.tocsr()))
            p0 = p1
        self.chunk_of = np.repeat(np.arange(len(chunks)), [c1 - c0 for c0, c1, *_ in chunks])
        return chunks

    def _local_plan(self, grid, local, correction_builder):
        """The boxes' layout and kernel spectrum, and the near-field correction's pairs on
        one pillar (``correction_builder(gamma, backend)``: None, or the correction built
        where the term is set up, whose pairs are kept there), kept on the device."""
        from ._fft_operator import kernel_block

        be = self.backend
        ny, nx = grid.shape
        iy, ix = grid.flat_index // nx, grid.flat_index % nx
        y0 = np.full(self.n_pillars, np.iinfo(np.int64).max)
        x0 = np.full(self.n_pillars, np.iinfo(np.int64).max)
        np.minimum.at(y0, grid.pillar, iy)
        np.minimum.at(x0, grid.pillar, ix)
        ly, lx = iy - y0[grid.pillar], ix - x0[grid.pillar]
        B = int(max(ly.max(), lx.max())) + 1
        M = sfft.next_fast_len(2 * B - 1, real=True)  # linear convolution of B-point boxes
        block = kernel_block((B, B), grid.cell_size, local)
        padded = np.zeros((M, M))
        padded[:B, :B] = block
        padded[M - B + 1:, :B] = block[1:, :][::-1]
        padded[:, M - B + 1:] = padded[:, 1:B][:, ::-1]
        spectrum = np.real(sfft.rfft2(padded))
        index = (grid.pillar * M + ly) * M + lx
        xp = self._setup_xp
        correction = correction_builder(local, None if xp is np else be)
        diagonal = None
        if correction is not None:  # keep the pairs on one pillar (where the matrix is)
            c = correction.tocoo()
            pillar = xp.asarray(grid.pillar)
            same = pillar[c.row] == pillar[c.col]
            kept = [c.row[same], c.col[same], c.data[same]]
            diagonal = xp.zeros(self.n)  # the pairs are distinct: the diagonal's own entries
            on = kept[0] == kept[1]
            diagonal[kept[0][on]] = kept[2][on]
            correction = be.sparse(*(be.asarray(v) for v in kept), self.n)
        return {"M": M, "index": be.asarray(index), "spectrum": be.asarray(spectrum),
                "correction": correction, "correction_diagonal": diagonal,
                "self": float(block[0, 0])}

    def _diagonal(self, S, values, e, trig, xp=np):
        """X[b, b] (m/Pa per unit q: times L^2): sum_k trig_k^2 v^T S_k[edge] v over the
        three hats v of each cell's edge, by edge: (cells x K) (K x 6) products with the
        unique entries of the 3 x 3 blocks of S_k on that edge; on the host of the cells of
        each edge, on a device (``xp`` cupy) of every cell, kept where the edge is theirs
        (no host synchronisation per edge)."""
        n = self.n
        d = xp.zeros(n)
        v = xp.stack(values, axis=1)                                   # (cells, 3)
        iu, ju = np.triu_indices(3)
        vv = v[:, xp.asarray(iu)] * v[:, xp.asarray(ju)] \
            * xp.asarray(np.where(iu == ju, 1.0, 2.0))                 # (cells, 6)
        t2 = trig * trig
        for edge in range(self.n_edges):
            nodes = 2 * edge + np.arange(3)
            blocks = xp.asarray(S[:, nodes[iu], nodes[ju]])            # (K, 6)
            if xp is np:
                cells = np.nonzero(e == edge)[0]
                if cells.size:
                    d[cells] = np.einsum("bm,bm->b", t2[cells] @ blocks, vv[cells])
            else:
                d += xp.where(e == edge, xp.einsum("bm,bm->b", t2 @ blocks, vv), 0.0)
        d *= self.L2
        if self.local is not None:
            d += self.local["self"]
            if self.local["correction_diagonal"] is not None:
                d += self.local["correction_diagonal"]
        return d

    def __call__(self, q):
        u = self._modes(q, range(len(self.chunks)))
        if self.local is not None:
            u += self._local_apply(q)
        if self.coupling is not None:
            u += self._coupling_apply(q)
        return u

    def _coupling_apply(self, q):
        """sum_b ΔK[a, b] q_b L^2 over the cells b of the other pillars: per pillar the force
        and the moment-weighted forces, three pillar-by-pillar products (O(cells + pillars^2))."""
        be = self.backend
        xp = be.xp
        c = self.coupling
        f = q * self.L2
        pillar, m, h = c["pillar"], c["m"], c["h"]
        force = be.segment_sum(pillar, f, self.n_pillars)
        u = xp.zeros(self.n, dtype=xp.float64)
        per_pillar = xp.zeros(self.n_pillars, dtype=xp.float64)
        for k in range(3):
            hk, mk = h[k, :, :], m[k, :]
            u += mk * xp.take(hk @ force, pillar)
            per_pillar += hk @ be.segment_sum(pillar, f * mk, self.n_pillars)
        return u + xp.take(per_pillar, pillar)

    def apply_few(self, index, values):
        """The term of d = ``values`` on the cells ``index`` and zero elsewhere, on the chunks
        of their pillars only (zero on the other pillars, but for the coupling correction,
        which reaches every pillar); None where that does not pay (:attr:`applies_few`: a
        local part, a box convolution of every pillar; a device, whose one chunk is every
        pillar)."""
        if not self.applies_few:
            return None
        q = np.zeros(self.n)
        q[index] = values
        u = self._modes(q, np.unique(self.chunk_of[self.position[index]]).tolist())
        if self.coupling is not None:   # every pillar: O(cells) work, no FFT
            u += self._coupling_apply(q)
        return u

    def _modes(self, q, chunks):
        """The mode part of the term of q, computed on the given chunks (zero elsewhere)."""
        be = self.backend
        xp = be.xp
        F = xp.take(q, self.order) * self.L2
        trig = self.trig
        K = trig.shape[1]
        M = xp.zeros((self.n_pillars * self.n_top, K), dtype=xp.float64)
        for c in chunks:
            c0, c1, r0, r1, P, _ = self.chunks[c]
            M[r0:r1, :] = P @ (xp.reshape(F[c0:c1], (-1, 1)) * trig[c0:c1, :])
        # Per mode column k: U_k = M_k S_k (S_k symmetric), one batched matrix product.
        M = xp.reshape(M, (self.n_pillars, self.n_top, K))
        U = xp.permute_dims(xp.matmul(xp.permute_dims(M, (2, 0, 1)), self.S), (1, 2, 0))
        U = xp.reshape(U, (-1, K))                                  # (pillars x n_top, K)
        u_sorted = xp.zeros(self.n, dtype=xp.float64)
        for c in chunks:
            c0, c1, r0, r1, _, B = self.chunks[c]
            u_sorted[c0:c1] = _row_dot(be, B @ U[r0:r1, :], trig[c0:c1, :])
        return xp.take(u_sorted, self.position)

    def _local_apply(self, q):
        be = self.backend
        xp = be.xp
        loc = self.local
        M = loc["M"]
        box = be.put(xp.zeros(self.n_pillars * M * M, dtype=xp.float64), loc["index"], q)
        spec = be.rfft2(xp.reshape(box, (self.n_pillars, M, M)))
        spec *= loc["spectrum"]
        u = xp.take(xp.reshape(be.irfft2(spec, (M, M)), (-1,)), loc["index"])
        if loc["correction"] is not None:
            u += loc["correction"] @ q
        return u

    def mode_compliance(self, counts):
        """1^T X 1 over ``counts`` cells of a pillar under a unit q on each (m/Pa), estimated
        as for a uniform load on the whole top: the mode part's mean response (m/N) times the
        force counts L^2, summed over the counts cells, plus the local Love part as the mean
        of a disk of the same area (16 gamma L counts^1.5 / (3 pi^1.5)).  The preconditioner's
        coarse space uses it (``counts`` on the term's device)."""
        xp = self.backend.xp
        share = self.mean_mode * self.L2 * counts * counts
        L = math.sqrt(self.L2)
        disk = 16.0 * L * counts * xp.sqrt(counts) / (3.0 * math.pi ** 1.5)
        share = share + self.local_compliance * disk
        # The whole 1^T A 1 is positive; keep the estimate so: at least half the half-space
        # part's disk value remains.
        return xp.maximum(share, -0.5 * self.half_space * disk)

    def dense_matrix(self) -> np.ndarray:
        """The term as a dense numpy matrix (m/Pa), column by column (tests on small grids)."""
        be = self.backend
        eye = np.eye(self.n)
        return np.column_stack([be.to_numpy(self(be.asarray(eye[:, j])))
                                for j in range(self.n)])


def _row_dot(be, a, b):
    """sum_k a[i, k] b[i, k] per row i: numpy's (or cupy's) einsum, else the standard's."""
    numpy_like = getattr(be, "numpy_like", None)
    if numpy_like is not None:
        return numpy_like.einsum("ik,ik->i", a, b)
    return be.xp.sum(a * b, axis=1)


def tops_grid(grid):
    """The pillar-top cells of ``grid`` alone (the first ``grid.n_top`` unknowns), the grid
    an elastic pillar term is built on when the floor's cells are candidates too."""
    from dataclasses import replace

    n = grid.n_top
    return replace(grid, flat_index=grid.flat_index[:n], x=grid.x[:n], y=grid.y[:n],
                   covered=grid.covered[:n], gap0=grid.gap0[:n], pillar=grid.pillar[:n],
                   colloc_x=grid.colloc_x[:n], colloc_y=grid.colloc_y[:n], floor=None,
                   n_unique=None, floor_radius=0.0,
                   reach=None if grid.reach is None else grid.reach[:n])


class TopsOnlyTerm:
    """An elastic pillar term (:class:`FFTPillarTerm`) built on the top cells, acting on a
    grid whose floor cells follow them: zero on and from the floor.  The floor meets the
    pillars through the half-space kernel alone (the column model of the coupling:
    PHYSICS.md, "The floor between the pillars")."""

    def __init__(self, term: FFTPillarTerm, n_cells: int):
        self.term = term
        self.backend = term.backend
        self.n = n_cells
        self.n_top = term.n
        self.local_compliance = term.local_compliance
        self.diagonal = self._pad(term.diagonal)

    def _pad(self, u):
        xp = self.backend.xp
        return xp.concat([u, xp.zeros(self.n - self.n_top, dtype=xp.float64)])

    def __call__(self, q):
        return self._pad(self.term(q[:self.n_top]))

    def apply_few(self, index, values):
        if not self.term.applies_few:
            return None
        on_top = index < self.n_top
        return self._pad(self.term.apply_few(index[on_top], values[on_top]))

    def mode_compliance(self, counts):
        """The term's for the pillars; 0 for the floor's index (the last)."""
        xp = self.backend.xp
        return xp.concat([self.term.mode_compliance(counts[:-1]),
                          xp.zeros(1, dtype=xp.float64)])

    def dense_matrix(self) -> np.ndarray:
        mat = np.zeros((self.n, self.n))
        mat[:self.n_top, :self.n_top] = self.term.dense_matrix()
        return mat
