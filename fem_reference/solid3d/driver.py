"""3D FEM reference: a lens on a hexagonal lattice of elastic pillars bonded to a substrate,
or on a flat substrate (Hertz), frictionless unilateral contact, displacement-controlled.

Model.  The pi/6 wedge of the lattice centred on pillar (0, 0), the D6 primitive cell:
mirror symmetry on theta = 0 (u_y = 0) and on the skew plane theta = pi/6 (u . n = 0 by a
rotated unknown in the reduced transform T, no penalty).  The lens is a sector block of
radius and height L with a flat bottom at z = 0; its spherical shape is the initial gap
g(r) = R - sqrt(R^2 - r^2) between the lens bottom and a pillar top at the same (x, y).  The
lens top moves down by zeta (a roller), the substrate bottom is a roller, the cylindrical
sides are free.  The pillars meshed are those whose top the undeformed lens could reach,
g(|c| - d/2) <= reach_factor * zeta (exact with reach_factor = 1: elastic deflections only
open the gap, so the others carry no load; meshing the unloaded pillars out to 3 zeta of
reach changed F_T by -0.07 % on a 7-pillar scene at mesh_size 2).  The blocks are 1e4 focus
radii wide: truncation ~ F gamma / (pi L zeta), 6e-5 for one pillar (measured 0.8 x the
estimate at L = 1e2); the graded far field itself moves F_T by <= 0.08 % from L = 1e3 to
1e5.  Taylor-Hood P2/P1 tetrahedra, rigid bodies imposed, not meshed.

Solution.  One PARDISO factorisation of the reduced saddle-point matrix; the contact problem
on the P1 mortar multiplier is solved by constrained conjugate gradients with the condensed
operator D^T G K^-1 G^T D applied by one back-substitution per iteration, preconditioned by
the contact faces' half-space model and started from that model's solution
(:mod:`.half_space`).  Linear residual and complementarity residual are checked and
reported.
"""

from __future__ import annotations

import dataclasses
import math
import resource

import numpy as np

from pillar_xval.contact import constrained_cg
from meshes import (MESH_SIZE_RANGE_3D, SECTORS, WedgeGeometry, build_wedge_mesh,
                    floor_clear_of_pillars, sector_pillars)
from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.outcome.memory import memory_short
from pillar_xval.scenes import InputError, Scene, ScopeError, analytic
from pillar_xval.scenes.lattice import lattice_indices

from .._driver import (RTOL_COMPLEMENTARITY, PhaseClock, contact_radius, fem_result,
                       flat_candidate, refuse_rigid_pair, scaled_materials, verdict)
from .._floor import (FINE_EDGE, FLOOR_MARGIN, fine_floor_radius, floor_candidate,
                      floor_contact_area, outgrown_floor, side_wall_diagnostics)
from .contact import contact_area_share, contact_faces, line_profile
from .half_space import HalfSpaceModel, serial_dense_algebra
from .fields import cell_stresses, lens_in_side_walls, write_vtu3d
from .system import assemble_sector

MODEL = "fem-3d"
# Block radius and height over the focus radius: the truncation ~ 2 a_c / (pi L) for a
# contact of radius a_c; the grading makes the large block cost a few shells of elements.
BLOCK_FACTOR = 1e4
MAX_CG_ITERATIONS = 2000
# Most steps of iterative refinement of the solution reported (float32 factor: each gains
# three digits or more, see system.SINGLE_MAX_ERROR), stopping at a residual of 1e-12.
EXACT_REFINE = 4
# Under a force: the tolerance of the first solve on a mesh built for a guess (it decides
# whether the mesh is the solved indentation's: a zeta to ~1e-5, where the pillars' reach
# changes every 0.2-2 % of zeta on the paper's scenes), and the meshes for successive
# indentations before the solve gives up settling them.
LOOSE_TOL = 1e-5
MAX_MESHINGS = 4
# Under a force on pillars the fine mesh is built for the indentation that the same force
# gives on a mesh COARSE_FACTOR times coarser (at most the coarsest allowed; used where that
# has at most half the fine mesh's unknowns, mesh_size <= 2.83), as the FFT model's levels
# design its grids.  The pillars' reach changes every ~1.4 % of zeta on paper-fig3-dense
# (30 sector pillars): the closed-form guess (+0.9 % there) meshed a pillar too many, and a
# second fine mesh and factorisation were paid; the coarse answer costs a quarter of the
# unknowns.  The coarse mesh is stiffer: at mesh_size 4 against 2 it carried 0.74-1.19 %
# more force on paper-fig3-dense (zeta 0.1-0.5 um) and 1.0-4.0 % on four other lattices
# (Phi 0.2-0.82, E_p / E_l 1 and 10), its zeta for a given force 0.50-2.6 % short; the
# design adds COARSE_SHORTFALL per halving of the element size, the least measured.  It
# then holds the solved pillars on 96 % of paper-fig3-dense's zeta 0.1-0.5 um (31 pillar
# changes), against 84 % without.  The coarse mesh is built for the guess times
# COARSE_MARGIN and again, larger, until it holds every pillar in the reach of its answer
# (pillars beyond carry no load, so a wider coarse mesh answers alike).
COARSE_FACTOR = 2.0
COARSE_SHORTFALL = 0.005
COARSE_MARGIN = 1.05
# Element size on the centre pillar's top over the contact element size (see _setup).
CENTRE_RATIO = 0.25
# Element size on the floor's fine disk over the contact element size.  The floor's contact
# on a dense lattice lies in the gaps between rims (2 um at Phi = 0.4, d = 4 um), about one
# element of the contact size wide at mesh_size 1.41; at half of it, about three.  The disk
# holds the floor contact of a coarser solve (mesh_size COARSE_FACTOR times larger, at most
# the coarsest allowed; :func:`.._floor.fine_floor_radius`), not the floor's rigid reach,
# 2-3 times wider on the dense lattices, whose elements the finer size is paid from (Phi =
# 0.4 at mesh_size 2.83-1.41: the floor area 492, 540, 546 um^2, monotone, against 466, 523,
# 534 at the contact size; a quarter of it at 2.83, 514: the elements across the gaps are no
# longer what limits it, PHYSICS.md).  With the floor's area read from the P2 gaps
# (:func:`.._floor.floor_contact_area`) this size meets the BEM on Phi = 0.2 and 0.4; a floor
# sized by its patches (:func:`.._floor.patch_floor_ratio`) made that ladder oscillate.
FLOOR_RATIO = 0.5
# Smallest gap between neighbouring pillars, in diameters: at Phi = 0.9 (gap 0.0038 d) the
# mesh still passes its quality check (q_min 0.047), at Phi = 0.9068 (5.5e-5 d) it fails.
MIN_GAP = 2e-3
# Size and peak memory, fitted on the lattice study's sectors (Phi 0.03-0.4, 2-17 pillars,
# mesh_size 2.83-1.41, 13.6k-455k unknowns): ~6.8e3 unknowns per sector pillar at mesh_size
# 2.83, x2 per sqrt(2) refinement (Phi = 0.03 grows slower: the estimate is conservative);
# peak RSS 160 MiB + 11.5 kB per unknown (the PARDISO factor dominates).  A flat scene
# meshes like one pillar.
DOFS_PER_PILLAR = 6.8e3
DOFS_REFERENCE_SIZE = 2.83
BYTES_FIXED_3D = 160 * 2.0**20
BYTES_PER_DOF_3D = 11.5e3


def estimate_memory(scene: Scene, mesh_size: float = 1.0, *,
                       sector_angle: float = math.pi / 6.0, reach_factor: float = 1.0) -> dict:
    """Peak memory of :func:`solve` on ``scene`` (estimated; nothing is meshed).

    Returns
    -------
    dict
        ``bytes`` (peak), ``dofs`` (unknowns) and ``pillars`` (sector pillars meshed).

    Raises
    ------
    InputError, ScopeError
        As :func:`solve` for a bad option or a scene it cannot mesh.
    """
    _check_options(mesh_size, sector_angle, BLOCK_FACTOR, reach_factor, RTOL_COMPLEMENTARITY)
    if scene.is_flat:
        pillars = 0
    else:
        p = scene.pillars
        _check_packing(p)
        reach = _reach(scene.lens.radius_m, reach_factor * scene.indentation_m)
        if reach / p.pitch_m > 3e3:  # beyond ~1e6 sector pillars: no need to list them
            pillars = int(sector_angle / 2.0 * (reach / p.pitch_m) ** 2 * 2.0 / math.sqrt(3.0))
        else:
            pillars = len(sector_pillars(p.pitch_m, p.diameter_m, reach, sector_angle))
    dofs = DOFS_PER_PILLAR * max(pillars, 1) * (DOFS_REFERENCE_SIZE / mesh_size) ** 2
    return {"bytes": float(BYTES_FIXED_3D + BYTES_PER_DOF_3D * dofs), "dofs": float(dofs),
            "pillars": pillars}


def _check_packing(p) -> None:
    if p.pitch_m - p.diameter_m < MIN_GAP * p.diameter_m:
        raise ScopeError(
            f"pillars.surface_fraction = {p.surface_fraction:.6g}: neighbouring pillars are "
            f"{(p.pitch_m - p.diameter_m) * 1e9:.3g} nm apart, below {MIN_GAP:g} d; the "
            "substrate between them cannot be meshed (fem-3d meshes up to Phi = 0.9; "
            "use the BEM closer to close packing)")


def _refuse_if_too_large(scene: Scene, mesh_size: float, sector_angle: float,
                         reach_factor: float) -> None:
    need = estimate_memory(scene, mesh_size, sector_angle=sector_angle,
                              reach_factor=reach_factor)
    short = memory_short(need["bytes"])
    if short is not None:
        raise ScopeError(
            f"mesh_size = {mesh_size:g}: fem-3d would mesh {need['pillars']} pillars in its "
            f"sector (~{need['dofs']:.3g} unknowns, about {need['bytes'] / 2**30:.3g} GiB), "
            f"{short}; use a larger mesh_size, or the BEM for lattices this wide")


def solve(scene: Scene, mesh_size: float = 1.0, *, vtu_path=None, progress=None,
                sector_angle: float = math.pi / 6.0, block_factor: float = BLOCK_FACTOR,
                reach_factor: float = 1.0, tol: float = RTOL_COMPLEMENTARITY,
                grading: dict | None = None) -> ContactResult:
    """Solve ``scene`` with the 3D finite-element model of the lattice sector.

    Parameters
    ----------
    scene : Scene
        A flat (Hertz) scene or any pillar scene (zeta < h).
    mesh_size : float
        Dimensionless refinement factor; 0.5 halves every element size.
    vtu_path : path-like, optional
        Where to write the VTU of the sector (displacement in m, stresses in Pa) and its
        JSON sidecar.
    progress : callable, optional
        ``progress(text)`` receives a line now and then (meshing, assembly, factorisation,
        contact iterations with their residual).
    sector_angle : float
        pi/6 (the D6 wedge, default), pi/3 or pi/2 (a quadrant): wider sectors with their own
        mirror planes, for symmetry checks.
    block_factor : float
        Block radius and height in focus radii (d/2, or the Hertz radius).
    reach_factor : float
        Pillars whose nearest top point has an undeformed gap <= reach_factor * zeta are
        meshed (1 is exact; more adds unloaded pillars).
    tol : float
        Complementarity tolerance (min-map residual over zeta).
    grading : dict, optional
        ``elements_across_contact``, ``edge_ratio``, ``growth``, ``centre_ratio`` of
        :class:`WedgeGeometry` (pillar scenes: ``centre_ratio`` = :data:`CENTRE_RATIO`).

    Returns
    -------
    ContactResult
        ``model = "fem-3d"``.  ``pillar_top_profile``: pressure (Pa) at the mesh vertices of
        the centre pillar top along theta = 0, r = 0 to d/2 (flat: along theta = 0 over the
        candidate zone).  ``diagnostics["pillar_top_profile_alpha"]``: the same along
        theta = alpha (pi/6 for the wedge).  ``pillar_forces``: every lattice pillar in
        contact, unfolded from the sector by its mirror group (D6 for the wedge), each image
        with its own (n, m) and centre.  ``diagnostics`` also holds ``linear_residual``,
        ``contact_residual``, ``cg_iterations``, ``operator_asymmetry``, ``time_s`` by phase,
        ``peak_rss_GiB``, the mesh quality, ``pillars_meshed`` and the truncation estimate.
        ``fields`` holds the vertex pressures and positions, gaps at the P2 points and the
        per-sector-pillar forces.

    Raises
    ------
    ScopeError
        A rigid lens on rigid pillars (no pressure distribution to compute).
    SolveError
        The factorisation fails or returns non-finite values.  A solution that misses a
        tolerance comes back with ``converged = False`` and the reason in
        ``diagnostics["message"]``.
    """
    _check_options(mesh_size, sector_angle, block_factor, reach_factor, tol)
    clock = PhaseClock(progress)
    # Under a force the mesh is the one of the solved indentation (the pillars in its reach;
    # a flat mesh's unit, the Hertz radius, follows it without meshing again).  It is built
    # for the coarse level's answer (:data:`COARSE_FACTOR`), or, without one, for the
    # closed-form guess and first solved loosely, to learn whether it is that mesh; if not,
    # it is built again for the solved indentation.
    force, held = scene.force_N, True
    rounds: list[dict] = []
    ell = 0.0  # the previous round's length unit (a flat mesh rescales from it)
    options = (sector_angle, block_factor, reach_factor, grading or {})
    coarse = _coarse_size(mesh_size) if force is not None and not scene.is_flat else None
    # The floor's fine disk (m; None: no floor, or the whole candidate at the contact size)
    # from a coarse solve's floor contact: the force's coarse design, else its own.
    fine: float | None = None
    floor_design: list[dict] = []
    if force is None:
        solved = scene
    elif coarse is None:
        solved = scene.designed(analytic.indentation_estimate(scene))
    else:  # refused at the guess, as the closed-form path is, before the coarse solves
        guess = scene.designed(analytic.indentation_estimate(scene))
        _refuse_if_too_large(guess, mesh_size, sector_angle, reach_factor)
        shortfall = 1.0 + COARSE_SHORTFALL * math.log2(coarse / mesh_size)
        zeta, fine = _coarse_design(scene, coarse, options, clock, rounds, floor_design)
        solved = scene.designed(shortfall * zeta)
    if not floor_design:
        _refuse_if_too_large(solved, mesh_size, sector_angle, reach_factor)
        fine = _floor_design(solved, mesh_size, options, clock, floor_design)
    fine_rounds, floor_meshings = len(rounds), 0
    while True:
        _refuse_if_too_large(solved, mesh_size, sector_angle, reach_factor)
        setup = _setup(solved, mesh_size, *options, floor_fine=fine)
        if not rounds or not scene.is_flat:
            mesh, skmesh, system, faces = _mesh_and_factorise(setup, mesh_size, sector_angle,
                                                              clock)
        else:
            mesh = dataclasses.replace(mesh, points=mesh.points * (setup["ell"] / ell))
        ell = setup["ell"]
        sector_force = None if force is None else force * sector_angle / (2.0 * math.pi)
        # loose only on the closed-form guess: a mesh built for a solved indentation is
        # almost always the solved one's, and solved to the tolerance at once
        loose = sector_force is not None and not scene.is_flat and not rounds
        contact = _contact(solved, setup, system, faces, max(tol, LOOSE_TOL) if loose else tol,
                           clock, sector_force)
        wider = _outgrown(setup, faces, contact["lam"])
        if wider is not None and floor_meshings < MAX_MESHINGS:
            clock.say(f"the floor contact passes {FINE_EDGE:.0%} of its fine disk: meshing "
                      f"again with one of {wider * 1e6:.4g} um")
            floor_design.append({"mesh_size": float(mesh_size), "fine_radius_m": wider,
                                 "floor_contact_radius_m": _floor_radius(faces, contact["lam"])
                                 * setup["ell"]})
            fine, floor_meshings = wider, floor_meshings + 1
            del mesh, skmesh, system, faces, contact  # before the next factor is built
            continue
        if force is None:
            break
        zeta = contact["zeta"]
        rounds.append({"design_indentation_m": solved.indentation_m, "indentation_m": zeta,
                       "mesh_size": float(mesh_size)})
        held = _meshed_alike(setup, _setup(scene.designed(zeta), mesh_size, *options,
                                           floor_fine=fine))
        if held and loose:  # the mesh is the solved one's: on to the tolerance from here
            contact = _contact(solved, setup, system, faces, tol, clock, sector_force,
                               start=contact["lam"])
            zeta = rounds[-1]["indentation_m"] = contact["zeta"]
            held = _meshed_alike(setup, _setup(scene.designed(zeta), mesh_size, *options,
                                               floor_fine=fine))
        if held or len(rounds) - fine_rounds == MAX_MESHINGS:
            solved = scene.implied(zeta, f"fem-3d at mesh_size {mesh_size:g}")
            break
        solved = scene.designed(zeta)
    result = _result(solved, setup, mesh, system, faces, contact, mesh_size, sector_angle,
                     reach_factor, clock)
    if setup["geometry"].floor_radius_m is not None:
        result.diagnostics["floor_fine_radius_m"] = setup["geometry"].floor_fine_radius_m
        result.diagnostics["floor_design"] = floor_design
    if force is not None:
        result.for_force(scene.to_dict(), zeta, design_rounds=rounds)
        if not held:
            result.converged = False
            result.diagnostics["message"] = f"the mesh did not settle in {MAX_MESHINGS} rounds"
    if vtu_path is not None:
        clock.say(f"writing {vtu_path}")
        _write_fields(vtu_path, solved, setup, mesh, skmesh, system, contact["x"], result)
    clock.say(f"done: F_T = {result.total_force_N:.6g} N, {contact['sol'].iterations} contact "
              "iterations")
    return result


def _coarse_size(mesh_size: float) -> float | None:
    """The coarse level that designs a force-controlled pillar mesh (:data:`COARSE_FACTOR`),
    or None where it would save less than half the unknowns."""
    coarse = min(COARSE_FACTOR * mesh_size, MESH_SIZE_RANGE_3D[1])
    return coarse if coarse >= math.sqrt(2.0) * mesh_size * (1.0 - 1e-3) else None


def _coarse_design(scene: Scene, coarse: float, options: tuple, clock: PhaseClock,
                   rounds: list, floor_design: list) -> tuple:
    """The indentation (m) that ``scene``'s force gives on the coarse mesh ``coarse``, solved
    to :data:`LOOSE_TOL` on a mesh holding every pillar in its reach (see
    :data:`COARSE_FACTOR`), each round appended to ``rounds``, and the floor's fine disk (m)
    from its floor contact (:func:`_floor_design`)."""
    sector_angle = options[0]
    sector_force = scene.force_N * sector_angle / (2.0 * math.pi)
    design = COARSE_MARGIN * analytic.indentation_estimate(scene)
    for _ in range(MAX_MESHINGS):
        at = scene.designed(design)
        setup = _setup(at, coarse, *options)
        _, _, system, faces = _mesh_and_factorise(setup, coarse, sector_angle, clock)
        contact = _contact(at, setup, system, faces, LOOSE_TOL, clock, sector_force)
        zeta = contact["zeta"]
        del system  # the coarse factor goes before the next one is built
        rounds.append({"design_indentation_m": design, "indentation_m": zeta,
                       "mesh_size": float(coarse)})
        if _holds(setup, _setup(scene.designed(zeta), coarse, *options)):
            break
        design = COARSE_MARGIN * zeta
    return zeta, _fine_from(setup, faces, contact["lam"], coarse, floor_design)


def _floor_design(scene: Scene, mesh_size: float, options: tuple, clock: PhaseClock,
                  floor_design: list) -> float | None:
    """The floor's fine disk (m) for ``scene`` at ``mesh_size``: from the floor contact of a
    solve :data:`COARSE_FACTOR` times coarser (at most the coarsest allowed), on its whole
    candidate floor at the contact size, to :data:`LOOSE_TOL`; None without a floor."""
    if scene.is_flat or floor_candidate(scene, options[2] * scene.indentation_m) is None:
        return None
    coarse = min(COARSE_FACTOR * mesh_size, MESH_SIZE_RANGE_3D[1])
    setup = _setup(scene, coarse, *options)
    _, _, system, faces = _mesh_and_factorise(setup, coarse, options[0], clock)
    lam = _contact(scene, setup, system, faces, LOOSE_TOL, clock)["lam"]
    return _fine_from(setup, faces, lam, coarse, floor_design)


def _fine_from(setup: dict, faces, lam, mesh_size: float, floor_design: list):
    """The fine disk (m) for the floor contact of a coarse solve (``setup``, ``faces``, its
    multipliers ``lam``), recorded in ``floor_design``; None without a floor."""
    candidate = setup["geometry"].floor_radius_m
    if candidate is None:
        return None
    reach = _floor_radius(faces, lam) * setup["ell"]
    fine = fine_floor_radius(reach, candidate)
    floor_design.append({"mesh_size": float(mesh_size), "floor_contact_radius_m": reach,
                         "fine_radius_m": fine})
    return fine


def _floor_radius(faces, lam) -> float:
    """Outer radius (mesh units) of the floor's contact: its farthest floor vertex in
    contact; 0 without one."""
    on = (lam > 0) & faces.floor_vertices
    return float(np.max(np.hypot(*faces.vertex_points)[on])) if on.any() else 0.0


def _outgrown(setup: dict, faces, lam) -> float | None:
    """The wider fine disk (m) where the floor contact of ``lam`` passes
    :data:`.._floor.FINE_EDGE` of the set-up's (:func:`.._floor.outgrown_floor`), else None."""
    geo = setup["geometry"]
    if geo.floor_fine_radius_m is None:
        return None
    return outgrown_floor(_floor_radius(faces, lam) * setup["ell"], geo.floor_fine_radius_m,
                          geo.floor_radius_m)


def _mesh_and_factorise(setup: dict, mesh_size: float, sector_angle: float,
                        clock: PhaseClock):
    """Mesh the sector, assemble it and its contact faces, factorise:
    (mesh, scaled skfem mesh, system, faces)."""
    geo = setup["geometry"]
    clock.say(f"meshing the sector ({len(geo.pillars)} pillars, mesh_size {mesh_size:g})")
    mesh = build_wedge_mesh(geo, progress=clock.say)
    clock.done("mesh")
    ell = setup["ell"]
    clock.say(f"mesh: {mesh.nelements} tetrahedra; assembling")
    skmesh = mesh.to_skfem().scaled([1.0 / ell] * 3)
    system = assemble_sector(skmesh, setup["materials"], sector_angle=sector_angle,
                             clamp_pillar_base=setup["clamp_pillar_base"],
                             rigid_pillars=setup["rigid_pillars"], progress=clock.say)
    faces = contact_faces(skmesh, system, lens_meshed=setup["lens_meshed"],
                          lower=setup["lower"], floor=setup["floor"])
    clock.done("assemble")
    clock.say(f"factorising {system.n_reduced} unknowns (PARDISO)")
    system.factorise()
    clock.done("factorise")
    return mesh, skmesh, system, faces


class _Condensed:
    """The condensed operator D^T G K^-1 G^T D with a float32 factor: exact applications by
    the refined solve, the constrained CG's steps and clipping updates by one float32
    back-substitution (:class:`pillar_xval.contact.MixedPrecision`,
    :class:`pillar_xval.contact.FewCellUpdates`).

    ``probes`` (columns) ride along the first exact application of one vector: PARDISO
    reads its factor once a back-substitution whatever the columns (Phi = 0.82, mesh_size
    2: 0.16 s for one column, 0.18 s for two), so their solutions (``probe_x``) cost little
    there, where the solve after the CG would take its own refinement steps.  ``last``: the
    multipliers and the solution of the latest exact application of one vector."""

    def __init__(self, D, G, system, n: int, probes=None):
        self.D, self.G, self.system, self.n = D, G, system, n
        # its error bound for the CG's bookkeeping (the accepted gap is always exact)
        self.approximate_error = 10.0 * system.single_error
        self.probes, self.probe_x, self.last = probes, None, None

    def __call__(self, lam):  # columns allowed
        lam = np.asarray(lam)
        rhs = self.G.T @ (self.D @ lam)
        along = lam.ndim == 1 and self.probes is not None and self.probe_x is None
        if along:
            rhs = np.column_stack([rhs, self.G.T @ (self.D @ self.probes)])
        x = self.system.exact(rhs)
        if along:
            x, self.probe_x = x[:, 0], x[:, 1:]
        if lam.ndim == 1:
            self.last = (lam.copy(), x)
        return self.D.T @ (self.G @ x)

    def approximate(self, lam):
        x, _ = self.system.solve(self.G.T @ (self.D @ lam), refine=0)
        return self.D.T @ (self.G @ x)

    def apply_few(self, index, values, single: bool = False):
        lam = np.zeros(self.n)
        lam[index] = values
        return (self.approximate if single else self)(lam)

    def start(self, lam):
        """The solutions of ``lam`` and the probes from the CG's exact applications, as
        columns (a start for their refinement), or None where it did not make them."""
        if self.probe_x is None or self.last is None or not np.array_equal(self.last[0], lam):
            return None
        return np.column_stack([self.last[1], self.probe_x])


def _contact(scene: Scene, setup: dict, system, faces, tol: float, clock: PhaseClock,
             force: float | None = None, start=None) -> dict:
    """The mortar contact by constrained CG on the condensed operator D^T G K^-1 G^T D (one
    back-substitution per application); then the displacement ``x`` under the contact load,
    its residual, the pointwise gaps ``w``, the operator's asymmetry and the indentation
    ``zeta`` (m; with ``force``, the sector's force in N, the one found for it).  ``start``:
    the multipliers to start from.

    With a float32 factor (:meth:`.system.SectorSystem.factorise`) the CG's steps and its
    clipping updates apply the operator by one float32 back-substitution, and the gap it
    accepts is recomputed with the refined solve (the CG's mixed precision, as the FFT BEM's
    float32 transforms: :func:`pillar_xval.contact.constrained_cg`)."""
    ell, E_ref = setup["ell"], setup["E_ref"]
    R, zeta = scene.lens.radius_m, scene.indentation_m
    r_pts = np.hypot(*faces.points) * ell
    # the floor lies h below the pillar tops
    lift = 0.0 if setup["floor"] is None else setup["floor"][0] * faces.floor_points
    gap0 = (analytic.lens_gap(R, r_pts) - zeta) / ell + lift
    D, G = faces.D, faces.G
    single = system.single_error > 0.0

    # two seeded probes of the operator's symmetry (:func:`_asymmetry`)
    probes = np.random.default_rng(12345).random((faces.n_vertices, 2))
    condensed = _Condensed(D, G, system, faces.n_vertices, probes if single else None)
    # In float64 the CG gets the exact application alone (no cheaper step, no few-cell
    # update: either would cost a whole back-substitution).
    apply = condensed if single else condensed.__call__

    def report(it, err):
        if it % 10 == 0:
            clock.say(f"contact iteration {it}: residual {err:.3g}")

    clock.say(f"contact: {faces.n_vertices} pressure unknowns")
    b, target = D.T @ gap0, None
    with serial_dense_algebra():
        model = HalfSpaceModel(faces, _springs(scene, setup, faces, E_ref, ell),
                               setup["face_compliance"] * E_ref,
                               setup["geometry"].sector_angle)
        # under a force the model's contact at the guessed indentation, rescaled by the CG
        q0 = model.warm_start(b, zeta / ell) if start is None else start
        if force is not None:  # Polonsky-Keer's force control; the weighted gap moves by weights
            b, target = b + faces.weights * (zeta / ell), force / (E_ref * ell**2)
        sol = constrained_cg(apply, b, q0, scale=zeta / ell,
                             tol=tol, max_iterations=MAX_CG_ITERATIONS,
                             precondition=model.precondition,
                             inverse_diagonal=model.inverse_diagonal, weights=faces.weights,
                             callback=report, force=target,
                             load=None if force is None else faces.weights,
                             cut_outward=True)
    if force is not None:
        zeta = sol.approach * ell
        gap0 = (analytic.lens_gap(R, r_pts) - zeta) / ell + lift
    lam = sol.pressure
    clock.done("contact")
    if single:
        # The displacement under the contact load and the operator on the probes, both
        # refined, in one solve of three columns, from the CG's exact solutions where it
        # made them (then one step of refinement or none, against four).
        rhs = G.T @ (D @ np.column_stack([lam, probes]))
        X, _ = system.solve(rhs, refine=EXACT_REFINE, start=condensed.start(lam))
        x, applied = X[:, 0], D.T @ (G @ X[:, 1:])
        residual = system.residual(x, rhs[:, 0])
    else:  # the CG's applications are single back-substitutions: the probes' are too
        x, residual = system.solve(G.T @ (D @ lam), refine=EXACT_REFINE)
        applied = apply(probes)
    w = G @ x + gap0
    asym = _asymmetry(probes, applied)
    clock.done("post")
    return {"sol": sol, "lam": lam, "x": x, "residual": residual, "w": w, "asymmetry": asym,
            "preconditioner": model.name, "zeta": zeta}


def _result(scene: Scene, setup: dict, mesh, system, faces, contact: dict, mesh_size: float,
            sector_angle: float, reach_factor: float, clock: PhaseClock) -> ContactResult:
    """Forces unfolded from the sector, profiles, the verdict and the result, in SI units."""
    ell, E_ref, geo = setup["ell"], setup["E_ref"], setup["geometry"]
    zeta = scene.indentation_m
    sol, lam, w, residual = (contact[k] for k in ("sol", "lam", "w", "residual"))
    mult = 2.0 * math.pi / sector_angle
    unit_force = E_ref * ell**2
    f_vertex = faces.weights * lam
    force = mult * float(np.sum(f_vertex)) * unit_force
    pressure = lam * E_ref
    vx, vy = faces.vertex_points
    at_origin = np.argmin(np.hypot(vx, vy))
    sigma0 = float(pressure[at_origin])
    tol_line = 1e-9 * max(1.0, float(np.max(np.abs(faces.vertex_points))))
    tops = ~faces.floor_vertices
    r0, p0 = line_profile(faces.vertex_points[:, tops], pressure[tops], 0.0, tol_line)
    r1, p1 = line_profile(faces.vertex_points[:, tops], pressure[tops], sector_angle, tol_line)
    pillar_forces, per_sector_pillar, floor = [], {}, {}
    if scene.is_flat:
        a = _flat_radius(faces, lam, w, tol_line) * ell
        area = math.pi * a * a
        reaches_end = a >= 0.999 * setup["candidate_m"]
    else:
        edge = 1.0 + tol_line  # centre pillar radius in mesh units
        keep0, keep1 = r0 <= edge, r1 <= edge
        r0, p0, r1, p1 = r0[keep0], p0[keep0], r1[keep1], p1[keep1]
        touching = lam > 0
        a = float(np.max(np.hypot(vx, vy)[touching])) * ell if touching.any() else 0.0
        area = mult * contact_area_share(faces.weights[tops], lam[tops]) * ell**2
        reaches_end = False
        pillar_forces, per_sector_pillar = _pillar_forces(scene, geo, faces, f_vertex,
                                                          unit_force, sector_angle)
        on_floor = touching & faces.floor_vertices
        floor = {"floor_force_N": mult * float(np.sum(f_vertex[faces.floor_vertices]))
                 * unit_force,
                 "floor_contact_area_m2": mult * floor_contact_area(
                     faces.vertex_points, faces.triangles, faces.floor_vertices, lam,
                     faces.points, w) * ell**2,
                 "floor_contact_radius_m": _floor_radius(faces, lam) * ell}
        area += floor["floor_contact_area_m2"]
        if on_floor.any() and floor["floor_contact_radius_m"] >= 0.98 * geo.floor_radius_m:
            reaches_end = True
    end = "contact reached the end of the candidate zone" if reaches_end else ""
    if not end and _outgrown(setup, faces, lam) is not None:
        end = (f"the floor contact passed {FINE_EDGE:.0%} of its fine disk of "
               f"{geo.floor_fine_radius_m * 1e6:.4g} um after {MAX_MESHINGS} wider meshes")
    penetration = float(max(0.0, -w.min()) / (zeta / ell))
    failures = verdict([force, a, sigma0, residual, sol.residual, *pressure], residual, sol,
                       force, zeta, penetration, end)
    walls = {} if scene.is_flat else side_wall_diagnostics(
        lens_in_side_walls(scene, setup, system, contact["x"]), scene.pillars.height_m)
    diagnostics = {
        "cg_iterations": int(sol.iterations), "cg_reentries": int(sol.reentries),
        "operator_asymmetry": contact["asymmetry"], "preconditioner": contact["preconditioner"],
        "contact_vertices": int(faces.n_vertices), "vertices_in_contact": int(np.sum(lam > 0)),
        "pillars_meshed": [p.name for p in geo.pillars], "reach_factor": reach_factor,
        "factor_nonzeros": system.factor.factor_nonzeros,
        "factor": {"ordering": system.factor.ordering,
                   "precision": "single" if system.factor.single else "double",
                   "single_solve_error": system.single_error},
        "peak_rss_GiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20,
        "pillar_top_profile_alpha": {"theta_rad": float(sector_angle),
                                     "r_m": (r1 * ell).tolist(), "pressure_Pa": p1.tolist()},
        **walls,
    }
    return fem_result(
        MODEL, scene, clock, failures, mesh=mesh, system=system, mesh_size=mesh_size,
        block_size_m=geo.block_size_m, ell=ell, E_ref=E_ref, residual=residual,
        contact_residual=sol.residual, penetration=penetration, force=force,
        centre_pressure=sigma0, contact_radius_m=a, area=area, pillar_forces=pillar_forces,
        iterations=sol.iterations,
        profile={"r_m": (r0 * ell).tolist(), "pressure_Pa": p0.tolist()},
        fields={"vertex_x_m": vx * ell, "vertex_y_m": vy * ell, "contact_pressure_Pa": pressure,
                "point_x_m": faces.points[0] * ell, "point_y_m": faces.points[1] * ell,
                "gap_m": w * ell, "sector_pillar_force_N": per_sector_pillar,
                "floor_vertex": faces.floor_vertices,
                "residual_history": np.asarray(sol.history)},
        discretisation={"sector_angle_rad": float(sector_angle)}, diagnostics=diagnostics,
        floor=floor)


def _write_fields(vtu_path, scene: Scene, setup: dict, mesh, skmesh, system, x,
                  result) -> None:
    """The sector's displacement (m) and stresses (Pa) as VTU, the lens translation removed."""
    ell, zeta = setup["ell"], scene.indentation_m
    u, p_body = system.full(x)
    if setup["lens_meshed"]:
        u[3 * np.unique(system.basis_s.get_dofs(elements="lens").all()) + 2] -= zeta / ell
    cells = cell_stresses(system, u, p_body, setup["E_ref"])
    nv = skmesh.p.shape[1]
    disp = u[:3 * nv].reshape(-1, 3).T * ell  # vertex dofs come first (3 s + c)
    write_vtu3d(vtu_path, mesh.points, mesh.tets, disp, cells,
                {"model": MODEL, "scene": result.scene, "discretisation": result.discretisation,
                 "indentation_m": result.indentation_m})


def _setup(scene: Scene, mesh_size, sector_angle, block_factor, reach_factor, grading,
           floor_fine: float | None = None) -> dict:
    """Geometry, units, meshed bodies and constraints for ``scene``; ``floor_fine``: the
    radius (m) of the floor's fine disk (at most its candidate; None: the whole candidate
    at the contact size)."""
    lens, sub = scene.lens.material, scene.substrate
    out = {"clamp_pillar_base": False, "rigid_pillars": [], "lens_meshed": not lens.rigid,
           "floor": None}
    if scene.is_flat:
        ell, candidate = flat_candidate(scene)
        # The Hertz edge is smooth (sqrt): no edge refinement, finer contact faces (cheap here).
        grading = {"edge_ratio": 1.0, "elements_across_contact": 8.0, **grading}
        geo = WedgeGeometry(ell, block_factor * ell, contact_radius_m=candidate,
                            sector_angle=sector_angle, mesh_size=mesh_size,
                            bodies=tuple(b for b, m in (("lens", lens), ("substrate", sub))
                                         if not m.rigid), **grading)
        out.update(lower="fixed" if sub.rigid else "substrate", candidate_m=candidate)
        pillar = None
    else:
        p = scene.pillars
        pillar = p.material
        _check_packing(p)
        refuse_rigid_pair(lens, pillar, "rigid pillars")
        ell = 0.5 * p.diameter_m
        reach = _reach(scene.lens.radius_m, reach_factor * scene.indentation_m)
        pillars = sector_pillars(p.pitch_m, p.diameter_m, reach, sector_angle)
        bodies = tuple(b for b, m in (("lens", lens), ("pillar", pillar), ("substrate", sub))
                       if not m.rigid)
        floor = floor_candidate(scene, reach_factor * scene.indentation_m)
        if floor is not None:  # within the pillars' reach, its circle clear of them
            floor = floor_clear_of_pillars(min(floor, reach), pillars, ell)
            if lens.rigid and sub.rigid:
                raise ScopeError("lens.rigid and substrate.rigid are both true: a rigid lens "
                                 "reaching a rigid floor has no contact pressure to compute")
            out["floor"] = (p.height_m / ell, not sub.rigid)
        # The centre pillar's top holds sigma0 and the profile: at the contact element size
        # its P1 multiplier's centre value moved 6-11 % between mesh levels (Phi = 0.2,
        # E_p = 10 E_l: 21.3, 19.1, 20.5 kPa at mesh_size 2.83, 2, 1.41); at a quarter of it,
        # 20.02, 20.12, 20.12 kPa, and 12.33, 12.32, 12.33 kPa for rigid pillars at Phi = 0.4.
        grading = {"centre_ratio": CENTRE_RATIO, "floor_ratio": FLOOR_RATIO, **grading}
        fine = None if floor is None or floor_fine is None else min(floor_fine, floor)
        geo = WedgeGeometry(ell, block_factor * ell, pillars=pillars,
                            pillar_height_m=p.height_m, floor_radius_m=floor,
                            floor_fine_radius_m=fine, sector_angle=sector_angle,
                            bodies=bodies, mesh_size=mesh_size, **grading)
        if pillar.rigid:
            out["lower"] = "rigid-pillar" if not sub.rigid else "fixed"
            if not sub.rigid:
                out["rigid_pillars"] = [(q.name, (q.x_m / ell, q.y_m / ell)) for q in pillars]
        else:
            out["lower"] = "pillar"
            out["clamp_pillar_base"] = sub.rigid
    E_ref, out["materials"] = scaled_materials(lens, pillar, sub, geo.bodies)
    # (1 - nu^2) / E of the two faces in contact (1/Pa), for the contact preconditioner
    out["face_compliance"] = lens.compliance + (sub.compliance if pillar is None else
                                                (pillar.compliance or sub.compliance))
    out.update(geometry=geo, ell=ell, E_ref=E_ref)
    return out


def _check_options(mesh_size, sector_angle, block_factor, reach_factor, tol) -> None:
    def number(name, value, low, high, why=""):
        ok = isinstance(value, (int, float)) and not isinstance(value, bool) and \
            math.isfinite(value) and low <= value <= high
        if not ok:
            raise InputError(f"{name} = {value!r}: allowed range is [{low:g}, {high:g}]{why}")

    number("mesh_size", mesh_size, *MESH_SIZE_RANGE_3D)
    number("block_factor", block_factor, 100.0, 1e7)
    number("reach_factor", reach_factor, 1.0, 10.0,
           " (below 1, pillars within the undeformed reach of the lens would be left out)")
    number("tol", tol, 1e-14, 1e-2)
    if not any(math.isclose(sector_angle, s, rel_tol=1e-12) for s in SECTORS):
        raise InputError(f"sector_angle = {sector_angle!r}: allowed values are pi/6, pi/3 "
                         "and pi/2 (both planes must be mirror planes of the lattice)")


def _meshed_alike(a: dict, b: dict) -> bool:
    """Whether two set-ups mesh alike: the same pillars, in the same unit (a flat mesh's
    Hertz radius, within 5e-7: the element sizes, to the round-off of a solve), and a floor
    in both or neither, ``a``'s holding the reach of ``b``'s (its candidate over the margin)."""
    return ([p.name for p in a["geometry"].pillars] == [p.name for p in b["geometry"].pillars]
            and abs(b["ell"] / a["ell"] - 1.0) <= 5e-7
            and (a["geometry"].floor_radius_m is None) == (b["geometry"].floor_radius_m is None)
            and _holds(a, b))


def _holds(a: dict, b: dict) -> bool:
    """Whether set-up ``a`` meshes every pillar of ``b`` and a floor reaching as far."""
    fa, fb = a["geometry"].floor_radius_m, b["geometry"].floor_radius_m
    return ({p.name for p in b["geometry"].pillars} <= {p.name for p in a["geometry"].pillars}
            and (fb is None or (fa is not None and fb <= FLOOR_MARGIN * fa)))


def _reach(R: float, gap: float) -> float:
    """Radius where the undeformed lens gap R - sqrt(R^2 - r^2) equals ``gap``."""
    return math.sqrt(max(0.0, 2.0 * R * gap - gap * gap))


def _springs(scene, setup, faces, E_ref, ell):
    """Hooke compliance of each sector pillar per unit sector force (mesh units), for the
    preconditioner; None without elastic pillars."""
    if scene.is_flat or setup["lower"] != "pillar":
        return None
    c = scene.pillar_spring_compliance * E_ref * ell  # dimensionless m/N
    share = {p.name: p.share for p in setup["geometry"].pillars}
    return [c / share[name] for name in faces.pillar_names]


def _asymmetry(probes: np.ndarray, applied: np.ndarray) -> float:
    """|x.Ay - y.Ax| / (|x| |Ay|) for two seeded random vectors x, y (``probes``' columns)
    and the condensed operator applied to them (``applied``: refined as the solution is with
    a float32 factor, one back-substitution with a float64 one): its symmetry."""
    x, y = probes.T
    ax, ay = applied.T
    return float(abs(x @ ay - y @ ax) / max(np.linalg.norm(x) * np.linalg.norm(ay), 1e-300))


def _flat_radius(faces, lam, w, tol):
    """Hertz edge along theta = 0 from the gap law (:func:`._contact.contact_radius`)."""
    x, y = faces.points
    on = np.abs(y) <= tol
    order = np.argsort(x[on])
    r = x[on][order]
    w_line = w[on][order]
    vx, vy = faces.vertex_points
    von = np.abs(vy) <= tol
    vorder = np.argsort(vx[von])
    lam_line = lam[von][vorder]
    a, _ = contact_radius(r, lam_line, w_line)
    return a


def _pillar_forces(scene, geo, faces, f_vertex, unit_force, alpha):
    """Force on every lattice pillar in contact, unfolded from the sector (N)."""
    tops = ~faces.floor_vertices
    per = np.bincount(faces.pillar_of_vertex[tops], weights=f_vertex[tops],
                      minlength=len(faces.pillar_names)) * unit_force
    share = {p.name: p for p in geo.pillars}
    pitch = scene.pillars.pitch_m
    k = int(round(math.pi / alpha))
    out, seen, per_sector = [], set(), {}
    for name, f in zip(faces.pillar_names, per):
        p = share[name]
        per_sector[name] = float(f)
        if f <= 0:
            continue
        total = float(f) / p.share
        for flip in (False, True):
            y0 = -p.y_m if flip else p.y_m
            for j in range(k):
                c, s = math.cos(2 * j * alpha), math.sin(2 * j * alpha)
                x, y = c * p.x_m - s * y0, s * p.x_m + c * y0
                n, m = (int(v) for v in lattice_indices(x, y, pitch))
                if (n, m) not in seen:
                    seen.add((n, m))
                    out.append(PillarForce(n, m, float(x), float(y), total))
    out.sort(key=lambda q: (math.hypot(q.x_m, q.y_m), math.atan2(q.y_m, q.x_m)))
    return out, per_sector
