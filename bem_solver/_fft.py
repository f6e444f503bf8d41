"""Fast matrix-free boundary-element model: regular grid, FFT kernel, constrained CG.

``solve_fft(scene, cells_per_diameter)`` discretises the candidate contact region (pillar tops
within the disk where the undeformed gap does not exceed zeta; for a flat scene the disk of
radius 1.25 sqrt(R zeta)) by square cells of side L = d / N (flat scene: L = 2 sqrt(R zeta)
/ N, N cells across the Hertz contact diameter), applies the half-space kernel by zero-padded
FFT, adds the Hooke shortening of each pillar, and solves the complementarity problem with
Polonsky-Keer constrained conjugate gradients, warm-started from the solution at half the
resolution (nested iteration) and preconditioned by the inverse of the half-space kernel as a
circulant on the grid's periodic box plus a coarse space of one uniform mode per pillar
(:class:`bem_solver._fft_operator.CirculantPreconditioner`): the iterations then grow slowly
with the grid (26-30 from 3e5 to 1e6 cells on paper-fig3-dense with rigid pillars, where the
Jacobi preconditioner took 110-140).

Edge cells.  A pillar-top cell carries its exact covered fraction phi, so the discrete tops
have the true area.  Its force acts on a square of area phi L^2 centred on the centroid of its
covered part, where it is also collocated (the dense model's ``covered`` cells); the FFT
applies the regular-grid kernel and a sparse symmetric correction swaps in these
equivalent-square coefficients within three cells of every partly covered cell.  Without it
the collocation points of edge cells stick out of the pillar and the error of F_T jumps by
+-50 % from one N to the next (0.5/N to 1.1/N for a rigid punch); with it the error is
~0.13/N to 0.2/N and smooth within each parity of N (the centre pillar is centred on a cell
for every N, so odd and even N cut its edge differently: keep one parity in a ladder).

Precision.  By default (``precision="mixed"``) the CG's step applications, its clipping
updates and the preconditioner run their FFTs in float32 (0.6-0.65 of the float64 time; the
rest of the operator, the vectors and the sums stay float64), and the CG recomputes the gap in
float64 whenever the float32 rounding it has carried could reach a tenth of the residual, and
before it accepts a residual within ``tol`` (:func:`pillar_xval.contact.constrained_cg`): the answer
meets the tolerance in float64 exactly as before and moves within it (F_T by 1e-11 to 2e-9,
sigma_0 by up to 4e-8 on the paper's scenes, with the same iterations).  ``precision="double"``
keeps float64 throughout.

Devices.  The model is written once against an array namespace (:mod:`bem_solver._xp`):
``device="cpu"`` (default) runs it with numpy and scipy.fft, ``device="gpu"`` with cupy and
cuFFT on a CUDA GPU (optional extra ``[gpu]``), ``device="auto"`` takes the GPU when cupy
finds one.  The grid geometry is built on the host (on the GPU itself from
``GPU_GRID_MIN_POINTS`` points of the candidate square on, all tops at once); the kernel
table, its spectrum, the near-field correction, the preconditioner and the constrained CG
run on the device, in float64 (the elastic pillar's term too); results come back to the
host once.  On the GPU the default start is cold (``GPU_WARM_START_LEVELS``): the coarse
levels' host work costs more there than the fine iterations it saves.

Units: SI (m, Pa, N) in and out.

References
----------
.. [1] I. A. Polonsky, L. M. Keer, Wear 231 (1999) 206-219 (constrained CG).
.. [2] S. Liu, Q. Wang, G. Liu, Wear 243 (2000) 101-111 (DC-FFT, zero padding).
.. [3] R. Ledesma-Alonso et al. (seed paper): the lens-on-pillars model and its Hooke term.
.. [4] E. A. H. Vollebregt, J. Optim. Theory Appl. 162 (2014) 931-953 (preconditioned
   bound-constrained CG).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pillar_xval.contact import constrained_cg, diagonal_preconditioner
from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.outcome.memory import memory_short
from pillar_xval.scenes import InputError, Scene, ScopeError

from ._dense import _smooth_edge_radius
from ._fft_grid import (CellGrid, build_grid, candidate_side, check_grid_side,
                        estimate_host_memory, outer_radii, rim_radii)
from ._elastic_pillar import (FFTPillarTerm, TopsOnlyTerm, check_pillars, operator_records,
                              pillar_record, scene_compliance, tops_grid, uses_elastic_block)
from ._fft_operator import (CirculantPreconditioner, CompliancePlan, TransformWorkspace,
                            near_field_correction)
from ._fft_working_set import gap_left_out, left_out_floor, whole, working_grid
from ._limits import PRECISIONS
from ._xp import NumpyDevice, fft_point_limit, select_backend

if TYPE_CHECKING:  # scikit-fem and gmsh load only with the elastic pillar
    from fem_reference._pillar_compliance import ModalCompliance

__all__ = ["finish", "run_cg", "solve_fft", "warm_levels"]

MODEL_NAME = "bem-fft"
DEFAULT_TOLERANCE = 1e-8
# Residual histories longer than this are thinned (every k-th entry, first and last kept).
HISTORY_MAX = 2000
# Nested iteration: coarsest level and tolerance of the coarse solves (their only job is to
# give the fine solve a good start; the fine tolerance decides the accuracy).  The
# interpolated start's residual is 0.05-0.2 zeta whatever the coarse tolerance (the
# discretisation differs between the levels), so a coarse residual below 1e-2 buys the fine
# solve nothing: at 1e-2 instead of 1e-4 the coarse levels took 11 and 3 iterations instead
# of 19 and 11 with the floor reached (R = 1 mm, Phi = 0.03, N = 36) and the fine one 25
# instead of 27; the fine level took 19 instead of 17 on the suspended scene and 33 instead
# of 32 on paper-fig3-dense (N = 32), its coarse levels 7 and 10 fewer.
WARM_START_MIN_CELLS = 8
WARM_START_TOL = 1e-2
# On a GPU the default warm start nests no level: each coarse level's grid, kernel table and
# result are host work and launches that cost more than the CG iterations they save.  On an
# H200 at 1e6 cells (paper-fig3-dense) a cold start took 0.63 s against 0.80 s with one level
# and 1.05 s with all (39 iterations against 31); at 2e7 cells 3.6 against 5.5 and 6.2 s.
GPU_WARM_START_LEVELS = 0
# A GPU builds the grid itself (cupy) from this many points of the candidate square: there
# the tops' fractions come from every cell's four nearest lattice sites in a fixed number of
# whole-array passes (bem_solver._fft_grid._fractions_dense).  Measured on an H200
# (paper-fig3-dense, repeated solves): ~0.035 s plus 0.018 s per 1e6 points on the device
# (1e6 cells 0.05 s, 2e7 cells 0.31-0.43 s), ~0.18 s per 1e6 points on the host: equal
# near 2.2e5 points.  (Pillar by pillar, ~10 launches each, the device took 0.65-1.2 s at
# 1e6 cells.)
GPU_GRID_MIN_POINTS = 250_000
# Fewest cells across the Hertz-like contact 2 sqrt(R zeta) on the centre pillar top for an
# answer: the flat (Hertz) scene is the same problem, and there 5 cells across is the
# coarsest grid whose contact stays clear of the candidate disk (F_T within 2 %).  At
# zeta = 1e-12 um and N = 32 the contact is 1/1400 of a cell: its one cell reported a
# contact radius 1400 times the overlap radius and F_T 1800 times Hertz's.
MIN_CELLS_ACROSS_CONTACT = 5


def solve_fft(scene: Scene, cells_per_diameter: int = 32, *, tol: float = DEFAULT_TOLERANCE,
              max_iterations: int | None = None, workers: int | None = None,
              warm_start: bool | int = True, edge_correction: bool = True, progress=None,
              device: str = "cpu", backend=None, preconditioner: str = "circulant",
              pillars: str = "hooke", compliance=None, precision: str = "mixed",
              _nested: bool = False, _workspace=None) -> ContactResult:
    """Solve the lens-on-pillars contact with the FFT-accelerated BEM.

    Parameters
    ----------
    scene : Scene
        The problem (SI units).
    cells_per_diameter : int
        N, square cells across a pillar diameter (cell side L = d / N, m).  For a flat scene
        (no pillars): cells across the Hertz contact diameter 2 sqrt(R zeta).
    tol : float
        Stopping tolerance of the constrained CG: the max-norm min-map complementarity residual
        (|gap| on the contact set, interpenetration off it) divided by zeta.
    max_iterations : int, optional
        Iteration cap; default 20 sqrt(n_cells) + 500.  Reaching it returns
        ``converged = False`` with the reason in ``diagnostics["message"]``.
    workers : int, optional
        Threads for the FFTs (default: :func:`pillar_xval.threads.thread_count`, the CPUs the
        process may use or ``PILLAR_XVAL_THREADS``).
    warm_start : bool or int
        Start from the solution at N // 2 cells per diameter (recursively, down to
        ``WARM_START_MIN_CELLS``), interpolated bilinearly (nested iteration).  An integer
        k >= 0 nests at most k levels (the coarsest of them starts cold; 0 is False).  On a
        GPU, an indentation-controlled solve takes True as ``GPU_WARM_START_LEVELS`` (none):
        there the coarse levels' set-up outweighs the iterations they save.  Under a force
        the coarse level also designs the grid, so it is kept on either device.
    edge_correction : bool
        True (default): partly covered cells act on an equivalent square at the centroid of
        their covered part and are collocated there (module docstring).  False: the plain grid
        operator, every cell loaded and collocated at its centre (the discrete problem
        ContactMechanics solves on a masked grid; used by the side-by-side benchmark).
    progress : callable, optional
        ``progress(iteration, error)`` called every iteration, and ``progress(text)`` on the
        phases of an elastic pillar's compliance build.
    device : {"cpu", "gpu", "auto"}
        Where to solve: numpy on the CPU (default), cupy on a CUDA GPU (``InputError`` saying
        what to install when none is usable), or the GPU when cupy finds one ("auto"), for
        either pillar model (the elastic pillar on an H200 at 1e6 cells: 0.93 s, 0.40 s in a
        study, against the 16-thread CPU's 10.9 s).
    backend : optional
        An array backend object (:mod:`bem_solver._xp`) used instead of ``device``: another
        array library, or a strict one in the tests.
    preconditioner : {"circulant", "jacobi"}
        The constrained CG's preconditioner: the inverse half-space kernel on the periodic
        box plus per-pillar uniform modes (default), or the diagonal with the pillar springs
        by Sherman-Morrison (slower to converge; the answers agree within the tolerance).
    pillars : {"hooke", "elastic"}
        The paper's uniformly shortening pillar (default), or the elastic pillar: a
        per-pillar excess compliance from the pillar's finite-element compliance
        (:class:`bem_solver._elastic_pillar.FFTPillarTerm`, in the operator and in the
        preconditioner's pillar modes and kernel), set up and applied on the device.
    compliance : fem_reference.ModalCompliance, optional
        With ``pillars="elastic"``: the pillar's mode matrices (default: the cached ones of
        the scene's pillar kind).
    precision : {"mixed", "double"}
        "mixed" (default): the CG's steps and the preconditioner run their FFTs in float32
        (about 0.65 of the float64 time), and the gap is recomputed in float64 whenever the
        steps' rounding could reach a tenth of the residual and before the residual is
        accepted, so the answer meets ``tol`` in float64 as before (it moves within the
        tolerance: ~1e-9 relative in F_T).  "double": float64 throughout, the iterates of the
        model before mixed precision.

    Returns
    -------
    ContactResult
        ``model = "bem-fft"``; pressures in Pa, forces in N, lengths in m.  ``fields`` holds
        the cell centres ``x_m``, ``y_m``, pressures ``pressure_Pa`` (force / covered area),
        ``covered_fraction``, ``gap_m`` and owning ``pillar`` index.

    References
    ----------
    .. [1] I. A. Polonsky, L. M. Keer, Wear 231 (1999) 206-219.
    """
    start = time.perf_counter()
    check_pillars(pillars, scene)
    _check_warm_start(warm_start)
    if precision not in PRECISIONS:
        raise InputError(f"precision = {precision!r}: choose one of {', '.join(PRECISIONS)}")
    elastic = uses_elastic_block(scene, pillars)
    be = select_backend(device, workers) if backend is None else backend
    if elastic:
        if scene.force_N is None:  # a refused grid never waits for a compliance build
            _refuse_grid(scene, cells_per_diameter, be, elastic)
        compliance = scene_compliance(scene, compliance, progress=progress)
    opts = _Options(tol, max_iterations, workers, warm_start, edge_correction, progress,
                    preconditioner, pillars, compliance if elastic else None, precision,
                    elastic)
    if scene.force_N is not None:
        from ._fft_force import solve_under_force

        return solve_under_force(scene, cells_per_diameter, opts, be, start, _nested,
                                 _workspace)
    coarse = cells_per_diameter // 2
    if warm_start is True and be.device == "gpu":
        warm_start = GPU_WARM_START_LEVELS
    if not (warm_start and coarse >= WARM_START_MIN_CELLS):
        setup = _prepare(scene, cells_per_diameter, opts, be, _workspace, start)
        b = be.asarray(setup.grid.gap0, dtype=be.xp.float64)
        lap = time.perf_counter()
        q0 = _initial_pressure(setup.plan, b, be)
        be.synchronize()
        setup.timings["warm_start"] = time.perf_counter() - lap
        outcome = run_cg(setup, b, q0, scene.indentation_m, opts, be)
        return finish(scene, setup, outcome, cells_per_diameter, opts, be, [], start)
    # Nested iteration: the solution at half the resolution, interpolated, brings the
    # contact set nearly right, so the fine constrained CG restarts seldom; it also says
    # which floor cells stay clear of the lens (bem_solver._fft_working_set).  The levels
    # share one set of transform work arrays.
    _refuse_grid(scene, cells_per_diameter, be, opts.elastic)
    grid = _grid(scene, cells_per_diameter, opts, be)
    built = time.perf_counter() - start
    workspace = _workspace if _workspace is not None else TransformWorkspace()
    lap = time.perf_counter()
    rough = _coarser(scene, coarse, opts, be, workspace)
    left_out = left_out_floor(rough, grid, scene.indentation_m)
    warm = time.perf_counter() - lap
    work, kept = (grid, None) if left_out is None else working_grid(grid, left_out)
    setup = _prepare(scene, cells_per_diameter, opts, be, workspace, start, work)
    if left_out is not None:  # the CG's last exact application gives the check its gaps
        setup.plan.watch_at(be.asarray(grid.flat_index[left_out]))
    setup.timings["grid"] = built
    lap = time.perf_counter()
    q0 = _interpolate(rough, work, be, slivers=edge_correction)
    be.synchronize()
    setup.timings["warm_start"] = warm + time.perf_counter() - lap
    outcome = run_cg(setup, be.asarray(work.gap0, dtype=be.xp.float64), q0,
                     scene.indentation_m, opts, be)
    if left_out is not None:
        setup, outcome = _check_left_out(scene, cells_per_diameter, opts, be, workspace,
                                         start, grid, setup, outcome, kept, left_out)
    return finish(scene, setup, outcome, cells_per_diameter, opts, be,
                  warm_levels(rough, coarse), start)


def _check_left_out(scene, cells_per_diameter, opts, be, workspace, start, grid, setup,
                    outcome, kept, left_out):
    """The solve on the working grid carried onto the whole ``grid``: accepted if no
    left-out cell interpenetrates by more than the tolerance (``diagnostics`` say how
    many were left out), else the whole grid solved from it
    (:mod:`bem_solver._fft_working_set`)."""
    lap = time.perf_counter()
    gap_out = gap_left_out(setup.plan, grid, left_out, outcome.pressure, be)
    worst = max(-float(gap_out.min()), 0.0) / scene.indentation_m
    pressure = whole(grid, kept, left_out, outcome.pressure, 0.0)
    record = {"left_out_floor_cells": int(left_out.size),
              "left_out_worst_interpenetration": worst, "left_out_accepted": True}
    if worst <= opts.tol:
        outcome.pressure = pressure
        outcome.gap = whole(grid, kept, left_out, outcome.gap, gap_out)
        setup.grid = grid
        setup.timings["solve"] += time.perf_counter() - lap
    else:  # a left-out cell would touch the lens: the whole grid, from this answer
        record.update(left_out_accepted=False, working_set_iterations=outcome.iterations)
        timings = setup.timings
        setup.plan = setup.precondition = None  # freed before the whole grid's are made
        setup = _prepare(scene, cells_per_diameter, opts, be, workspace, start, grid)
        setup.timings = {**timings, "solve": timings["solve"] + time.perf_counter() - lap}
        outcome = run_cg(setup, be.asarray(grid.gap0, dtype=be.xp.float64),
                         be.asarray(pressure, dtype=be.xp.float64), scene.indentation_m,
                         opts, be)
    setup.working_set = record
    return setup, outcome


@dataclass(frozen=True)
class _Options:
    """The options of one solve, handed on to its coarser levels."""

    tol: float
    max_iterations: int | None
    workers: int
    warm_start: bool | int
    edge_correction: bool
    progress: object
    preconditioner: str
    pillars: str
    compliance: ModalCompliance | None
    precision: str
    elastic: bool


@dataclass
class _Setup:
    """The grid, its operator and preconditioner, the timings so far, and what the solve
    left out of the grid (:func:`_check_left_out`)."""

    grid: CellGrid
    plan: CompliancePlan
    precondition: object
    timings: dict
    working_set: dict | None = None


def _grid(scene: Scene, cells_per_diameter: int, opts: _Options, be) -> CellGrid:
    """The candidate cells of ``scene`` (built on the device from ``GPU_GRID_MIN_POINTS``
    points of the candidate square on), collocated at the centres without the edge
    correction."""
    xp = getattr(be, "numpy_like", np)
    if candidate_side(scene, cells_per_diameter) ** 2 < GPU_GRID_MIN_POINTS:
        xp = np  # a small grid is built faster on the host than by a device's launches
    grid = build_grid(scene, cells_per_diameter,
                      max_fft_points=fft_point_limit(be, opts.elastic), xp=xp)
    return grid if opts.edge_correction else _plain_grid(grid, scene)


def _prepare(scene: Scene, cells_per_diameter: int, opts: _Options, be, workspace,
             start: float, grid: CellGrid | None = None) -> _Setup:
    """Grid (unless given), operator and preconditioner of ``scene``
    (indentation-controlled: its indentation sets the candidate region, and on a flat scene
    the cell size)."""
    if grid is None:
        _refuse_grid(scene, cells_per_diameter, be, opts.elastic)
        grid = _grid(scene, cells_per_diameter, opts, be)
    L = grid.cell_size
    spring = 0.0 if grid.flat or opts.elastic else scene.pillar_spring_compliance
    timings = {"grid": time.perf_counter() - start}
    lap = time.perf_counter()
    correction = near_field_correction(grid, scene.half_space_compliance, backend=be) \
        if opts.edge_correction else None
    term: FFTPillarTerm | TopsOnlyTerm | None = None
    if opts.elastic:
        tops = tops_grid(grid) if grid.has_floor else grid
        def tops_correction(gamma, where):
            return near_field_correction(tops, gamma, backend=where) \
                if opts.edge_correction else None

        term = FFTPillarTerm(scene, tops, opts.compliance, tops_correction, backend=be)
        if grid.has_floor:
            term = TopsOnlyTerm(term, grid.n_cells)
    floor = grid.has_floor
    plan = CompliancePlan(grid.shape, grid.flat_index, L, scene.half_space_compliance,
                          pillar=grid.pillar, spring_compliance=spring, workers=opts.workers,
                          correction=correction, backend=be, pillar_term=term,
                          precision=opts.precision, workspace=workspace,
                          n_unique=grid.n_unique if floor else None,
                          floor_pillar=len(grid.pillar_nm) if floor else None)
    be.synchronize()
    timings["kernel_table"] = time.perf_counter() - lap
    return _Setup(grid, plan, _preconditioner(plan, opts.preconditioner), timings)


def _refuse_grid(scene: Scene, cells_per_diameter: int, be,
                 elastic: bool = False) -> None:
    """Refuse, before any array is built, a grid of ``scene`` beyond the FFT size limit (by
    its side; on a GPU, with the elastic pillar's term where ``elastic``) or one that would
    not fit in the memory this process may take."""
    side = candidate_side(scene, cells_per_diameter)
    check_grid_side(side, cells_per_diameter, fft_point_limit(be, elastic))
    need = estimate_host_memory(scene, cells_per_diameter, isinstance(be, NumpyDevice))
    short = memory_short(need)
    if short is not None:
        raise ScopeError(f"cells_per_diameter = {cells_per_diameter}: this grid needs about "
                         f"{need / 2**30:.3g} GiB, {short}; choose fewer cells per diameter")


def _coarser(scene: Scene, cells_per_diameter: int, opts: _Options, be, workspace):
    """The solution at ``cells_per_diameter`` (a warm start), with this solve's options."""
    deeper = True if opts.warm_start is True else int(opts.warm_start) - 1
    return solve_fft(scene, cells_per_diameter, tol=max(opts.tol, WARM_START_TOL),
                     workers=opts.workers, warm_start=deeper,
                     edge_correction=opts.edge_correction, backend=be,
                     preconditioner=opts.preconditioner, pillars=opts.pillars,
                     compliance=opts.compliance, precision=opts.precision, _nested=True,
                     _workspace=workspace)


def _check_warm_start(warm_start) -> None:
    """Refuse (InputError) a ``warm_start`` that is neither a bool nor an int >= 0."""
    if isinstance(warm_start, bool):
        return
    if not isinstance(warm_start, int) or warm_start < 0:
        raise InputError(f"warm_start = {warm_start!r}: must be True, False or a number of "
                         "nested levels >= 0")


def warm_levels(rough: ContactResult, cells_per_diameter: int) -> list:
    """The warm start's levels, coarsest first, ending with ``rough`` itself."""
    return rough.diagnostics["warm_start_levels"] + [{
        "cells_per_diameter": cells_per_diameter, "iterations": rough.iterations,
        "operator_applications": rough.diagnostics["operator_applications"],
        "cells": rough.discretisation["cells"]}]


def run_cg(setup: _Setup, b, q0, scale: float, opts: _Options, be, force=None):
    """The constrained CG on ``setup`` (``force``: the given sum of the cell pressures,
    force over L^2), its answer back on the host; the time in ``setup.timings``."""
    max_iterations = opts.max_iterations
    if max_iterations is None:
        max_iterations = int(20 * math.sqrt(setup.grid.n_cells)) + 500
    lap = time.perf_counter()
    outcome = constrained_cg(setup.plan, b, q0, scale=scale, tol=opts.tol,
                             max_iterations=max_iterations, precondition=setup.precondition,
                             callback=opts.progress, backend=be, force=force,
                             cut_outward=True)
    outcome.pressure = be.to_numpy(outcome.pressure)
    outcome.gap = be.to_numpy(outcome.gap)
    setup.timings["solve"] = setup.timings.get("solve", 0.0) + time.perf_counter() - lap
    return outcome


def finish(scene: Scene, setup: _Setup, outcome, cells_per_diameter: int, opts: _Options, be,
           levels: list, start: float) -> ContactResult:
    """The result of ``outcome`` on ``setup`` for ``scene`` (indentation-controlled: the
    grid's scene, or the one at the indentation a force-controlled solve found)."""
    grid, plan = setup.grid, setup.plan
    message = outcome.message
    converged = outcome.converged
    if converged:
        coarse_message = _flat_edge_contact(grid, outcome.pressure) if grid.flat else \
            _unresolved_contact(scene, grid, cells_per_diameter)
        if coarse_message:
            converged = False
            message = coarse_message
    wall = time.perf_counter() - start
    result = _result(scene, grid, plan, outcome, cells_per_diameter, opts.tol, converged,
                     message, wall)
    result.diagnostics["warm_start_levels"] = levels
    result.diagnostics["device"] = be.device
    result.diagnostics["preconditioner"] = _PRECONDITIONERS[opts.preconditioner] + (
        " + pillar springs" if plan.has_spring else
        " + elastic pillars" if opts.elastic else "")
    result.diagnostics.update(pillar_record(scene, opts.pillars, opts.compliance.kind
                                            if opts.elastic else None))
    if opts.elastic:
        result.diagnostics["operators"] = operator_records(opts.compliance.diagnostics)
        result.discretisation["pillars"] = "elastic"
    result.diagnostics["timings_s"] = setup.timings
    if setup.working_set is not None:
        result.diagnostics.update(setup.working_set)
    return result


_PRECONDITIONERS = {
    "circulant": "inverse half-space kernel (circulant) + pillar modes",
    "jacobi": "diagonal (Sherman-Morrison)",
}


def _preconditioner(plan: CompliancePlan, name: str):
    """The constrained CG's preconditioner on the free set (see ``solve_fft``)."""
    if name == "circulant":
        return CirculantPreconditioner(plan)
    if name == "jacobi":
        return diagonal_preconditioner(plan.diagonal, plan.spring, plan.pillar,
                                       plan.n_pillars, backend=plan.backend)
    raise ValueError(f"preconditioner = {name!r}: choose circulant or jacobi")


def _initial_pressure(plan: CompliancePlan, b, be):
    """Pressure proportional to the interpenetration, scaled by an exact line search."""
    d = be.xp.maximum(-b, 0.0)
    curvature = be.dot(d, plan(d))
    if curvature <= 0:
        return d
    return d * (be.dot(d, d) / curvature)


def _plain_grid(grid: CellGrid, scene: Scene) -> CellGrid:
    """The same cells collocated at their centres (no edge correction)."""
    from dataclasses import replace

    from pillar_xval.scenes.analytic import lens_gap

    gap0 = lens_gap(scene.lens.radius_m, np.hypot(grid.x, grid.y)) - scene.indentation_m
    if grid.has_floor:
        gap0[grid.floor] += scene.pillars.height_m
    return replace(grid, colloc_x=grid.x, colloc_y=grid.y, gap0=gap0, reach=None)


def _interpolate(rough: ContactResult, grid: CellGrid, be, slivers: bool = True):
    """Coarse solution carried onto the cells of ``grid`` (smeared pressure, Pa), on the
    device of ``be``.

    Mostly covered fine cells (phi >= 1/2) take the bilinear interpolation of the coarse
    smeared pressure.  Thin edge slivers take phi times the pressure of the mostly covered
    coarse cells around them (bilinear with normalised weights): a sliver's own coarse value is
    the least accurate one and, with the equivalent-square self-compliance ~ 1 / sqrt(phi), a
    wrong sliver pressure costs many constrained-CG iterations to undo.  Without the edge
    correction (``slivers=False``) every cell takes the plain bilinear interpolation.  The
    tops and the floor are carried separately, each from its own coarse cells, and each
    pillar's top and the floor then carry the coarse solution's forces
    (:func:`_keep_forces`)."""
    f = rough.fields
    coarse_floor = f.get("floor")
    if not grid.has_floor and (coarse_floor is None or not coarse_floor.any()):
        return _keep_forces(rough, grid, _interpolate_layer(f, None, grid, slice(None), be,
                                                            slivers), be)
    xp = be.xp
    q = xp.zeros(grid.n_cells, dtype=xp.float64)
    for layer in (False, True):
        coarse = np.ones(len(f["x_m"]), dtype=bool) if coarse_floor is None else \
            coarse_floor == layer
        cells = np.flatnonzero(grid.floor == layer)
        if not coarse.any() or not cells.size:
            continue
        part = _interpolate_layer(f, coarse, grid, cells, be, slivers)
        q = be.put(q, be.asarray(cells), part)
    return _keep_forces(rough, grid, q, be)


def _keep_forces(rough: ContactResult, grid: CellGrid, q, be):
    """``q`` (the coarse pressure interpolated onto ``grid``) scaled on each pillar's top and
    on the floor to the force the coarse solution puts there.

    The coarse level's forces are accurate to its discretisation error (F_T within 0.1 %
    between N = 18 and 36), but the interpolation misses the pressure's edge singularity at
    the pillars' rims: it lost 12 % of the tops' force at N = 36 (rigid pillars, R = 1 mm,
    Phi = 0.03, zeta = 3 um).  With the floor reached, that deficit lets the lens sink
    onto the floor around its contact (1.6e5 cells interpenetrating at the start, the first
    residual 0.18 zeta); kept, 1.1e3 cells and 0.08 zeta.  A pillar or the floor without a
    force on either side keeps its interpolated values."""
    if grid.flat or (not rough.pillar_forces and not rough.floor_force_N):
        return q
    xp = be.xp
    n_pillars = len(grid.pillar_nm)
    coarse = np.zeros(n_pillars + 1)
    where = {(int(n), int(m)): k for k, (n, m) in enumerate(grid.pillar_nm)}
    for pf in rough.pillar_forces:
        k = where.get((pf.n, pf.m))
        if k is not None:
            coarse[k] = pf.force_N
    coarse[n_pillars] = rough.floor_force_N
    fine = np.bincount(grid.pillar, weights=be.to_numpy(q) * grid.cell_size**2,
                       minlength=n_pillars + 1)[:n_pillars + 1]
    ratio = np.where((coarse > 0.0) & (fine > 0.0), coarse / np.where(fine > 0.0, fine, 1.0),
                     1.0)
    return q * xp.take(be.asarray(ratio, dtype=xp.float64), be.asarray(grid.pillar))


def _interpolate_layer(f: dict, coarse, grid: CellGrid, cells, be, slivers: bool):
    """:func:`_interpolate` from the coarse cells ``coarse`` (a mask, or None: all) onto the
    fine cells ``cells`` (indices on the host, or a slice): their values, in that order."""
    xp = be.xp
    Lc = f["cell_size_m"]
    p, phi = f["pressure_Pa"], f["covered_fraction"]
    if coarse is not None:
        p, phi = p[coarse], phi[coarse]
    solid = phi >= 0.5
    # The coarse grids (a quarter of the fine cells) are laid out on the host.
    at, shape, (y0, x0) = coarse_layout(f, coarse)
    pressure, weight, smeared = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    pressure[at] = np.where(solid, p, 0.0)
    weight[at] = solid
    smeared[at] = p * phi
    cy = be.asarray(grid.y[cells], dtype=xp.float64) / Lc - float(y0)
    cx = be.asarray(grid.x[cells], dtype=xp.float64) / Lc - float(x0)
    bulk = _bilinear(xp, be.asarray(smeared), cy, cx)
    covered = grid.covered[cells]
    thin = np.flatnonzero(covered < 0.5) if slivers else np.empty(0, dtype=np.int64)
    if thin.size:  # the slivers, a few per cent of the cells (rims), interpolated apart
        at_thin = be.asarray(thin)
        ty, tx = xp.take(cy, at_thin), xp.take(cx, at_thin)
        num = _bilinear(xp, be.asarray(pressure), ty, tx)
        den = _bilinear(xp, be.asarray(weight), ty, tx)
        sliver = xp.where(den > 1e-3, num / xp.maximum(den, 1e-3), 0.0) \
            * be.asarray(covered[thin], dtype=xp.float64)
        bulk = be.put(bulk, at_thin, sliver)
    return xp.maximum(bulk, 0.0)


def coarse_layout(f: dict, mask=None):
    """Where a coarse result's cells (its ``fields`` ``f``; those of ``mask``, or all) sit
    in their bounding box of cells: their (row, column) indices, the box's shape and the
    (row, column) of its first cell on the grid of cell centres (multiples of the cell
    size from the axis)."""
    Lc = f["cell_size_m"]
    x, y = (f["x_m"], f["y_m"]) if mask is None else (f["x_m"][mask], f["y_m"][mask])
    ix = np.rint(x / Lc).astype(np.int64)
    iy = np.rint(y / Lc).astype(np.int64)
    x0, y0 = int(ix.min()), int(iy.min())
    return (iy - y0, ix - x0), (int(iy.max()) - y0 + 1, int(ix.max()) - x0 + 1), (y0, x0)


def _bilinear(xp, values, cy, cx):
    """Bilinear interpolation of the 2-D array ``values`` at fractional (row, column)
    coordinates; 0 outside [0, n - 1] on either axis (scipy.ndimage.map_coordinates with
    order=1, mode='constant')."""
    ny, nx = values.shape
    inside = (cy >= 0.0) & (cy <= ny - 1) & (cx >= 0.0) & (cx <= nx - 1)
    y0 = xp.clip(xp.floor(cy), 0.0, float(max(ny - 2, 0)))
    x0 = xp.clip(xp.floor(cx), 0.0, float(max(nx - 2, 0)))
    fy, fx = cy - y0, cx - x0
    i0, j0 = xp.astype(y0, xp.int64), xp.astype(x0, xp.int64)
    i1, j1 = xp.minimum(i0 + 1, ny - 1), xp.minimum(j0 + 1, nx - 1)
    flat = xp.reshape(values, (-1,))

    def at(i, j):
        return xp.take(flat, i * nx + j)

    value = (1.0 - fy) * ((1.0 - fx) * at(i0, j0) + fx * at(i0, j1)) \
        + fy * ((1.0 - fx) * at(i1, j0) + fx * at(i1, j1))
    return xp.where(inside, value, 0.0)


def _flat_edge_contact(grid: CellGrid, q: np.ndarray) -> str:
    r = np.hypot(grid.x, grid.y)
    touching = (q > 0) & (r > grid.candidate_radius - grid.cell_size)
    if touching.any():
        return ("contact reaches the edge of the candidate disk "
                f"({grid.candidate_radius:g} m): the discretisation is too coarse")
    return ""


def _unresolved_contact(scene: Scene, grid: CellGrid, cells_per_diameter: int) -> str:
    """Why the contact on the centre pillar is too small for the cells, or ''."""
    across = 2.0 * math.sqrt(scene.lens.radius_m * scene.indentation_m)
    cells = across / grid.cell_size
    if cells >= MIN_CELLS_ACROSS_CONTACT:
        return ""
    needed = math.ceil(cells_per_diameter * MIN_CELLS_ACROSS_CONTACT / cells)
    return (f"the contact on the centre pillar, about 2 sqrt(R zeta) = {across:.3g} m across, "
            f"spans {cells:.2g} cells of side {grid.cell_size:.3g} m (at least "
            f"{MIN_CELLS_ACROSS_CONTACT} needed): the discretisation is too coarse; use "
            f"cells_per_diameter >= {needed}")


def _result(scene, grid, plan, outcome, cells_per_diameter, tol, converged, message, wall):
    L, L2 = grid.cell_size, grid.cell_size**2
    q, gap = outcome.pressure, outcome.gap
    pressure = q / grid.covered
    contact = q > 0.0
    cell_force = q * L2
    total = float(cell_force.sum())
    n_p = len(grid.pillar_nm)
    pillar_force = np.bincount(grid.pillar, weights=cell_force, minlength=n_p)[:n_p]
    # The contact radii: the largest outer radius (outer_radii) of the tops' and the floor's
    # cells in contact, from the grid's radii where a device built them, else computed for
    # the cells in contact alone (1e7 cells: a pass over all cost a second of a 2e7 solve).
    n_top = grid.n_top
    floor_force = float(cell_force[n_top:].sum())  # the floor's unknowns come last
    floor_area = float(grid.covered[n_top:][contact[n_top:]].sum() * L2)
    if grid.reach is not None:  # built with the grid (on a device), the tops' capped
        floor_radius = float(np.max(grid.reach[n_top:], where=contact[n_top:], initial=0.0))
    else:  # the cells in contact only
        touching = np.flatnonzero(contact)
        far = outer_radii(grid.colloc_x[touching], grid.colloc_y[touching],
                          grid.covered[touching], L, grid.pillar[touching],
                          None if grid.flat else rim_radii(grid.pillar_xy,
                                                           scene.pillars.diameter_m))
        floor_radius = float(far[touching >= n_top].max(initial=0.0))
    if grid.flat:
        # Same definition as the dense model: where p^2 (linear in r^2 at a square-root edge)
        # extrapolates to zero; area pi a^2.
        # Fit over one quadrant (x, y >= 0), like the dense model's symmetry-reduced cells.
        quadrant = (grid.x > -0.25 * L) & (grid.y > -0.25 * L)
        contact_radius = _smooth_edge_radius(np.hypot(grid.x, grid.y)[quadrant],
                                             pressure[quadrant], contact[quadrant], L)
        area = math.pi * contact_radius**2
    else:
        # Outermost point of contact: collocation radius plus half the side of the
        # (equivalent) loaded square, as in the dense model, capped at the pillar's rim.
        if grid.reach is not None:
            contact_radius = float(np.max(grid.reach, where=contact, initial=0.0))
        else:
            contact_radius = float(far.max(initial=0.0))
        area = float((grid.covered[contact]).sum() * L2)
    forces = []
    if not grid.flat:
        for k in np.nonzero(pillar_force > 0)[0]:
            n, m = (int(v) for v in grid.pillar_nm[k])
            forces.append(PillarForce(n, m, float(grid.pillar_xy[k, 0]),
                                      float(grid.pillar_xy[k, 1]), float(pillar_force[k])))
    profile = _centre_profile(scene, grid, pressure)
    history = outcome.history
    if len(history) > HISTORY_MAX:
        step = math.ceil(len(history) / HISTORY_MAX)
        history = history[::step] + [history[-1]]
    interpenetration = max(-float(gap.min()), 0.0) if gap.size else 0.0
    diagnostics = {
        "tolerance": tol,
        "stopping_criterion": "max |min-map residual| / zeta: |gap| on contact cells, "
                              "interpenetration elsewhere",
        "contact_residual": float(outcome.residual),
        "residual_history": [float(v) for v in history],
        "message": message,
        "operator_applications": plan.applications,
        # Of them, in float32 (the CG's steps between its exact gap refreshes).
        "single_precision_applications": plan.single_applications,
        # Clipping steps whose gap was updated from the kernel table (few cells clipped)
        # instead of an application.
        "direct_gap_updates": plan.direct_updates,
        "reentry_iterations": int(outcome.reentries),
        # Truncated steps shortened because they would have raised the energy (contact._cg).
        "step_halvings": int(outcome.halvings),
        "fft_shape": list(plan.fft_shape),
        "grid_shape": list(grid.shape),
        "candidate_cells": grid.n_cells,
        "contact_cells": int(contact.sum()),
        "max_interpenetration_m": interpenetration,
        "max_complementarity_N_per_m": float(np.max(q * np.abs(gap), initial=0.0) * L),
        "force_balance_N": float(total - pillar_force.sum() - floor_force),
        "near_field_pairs": 0 if plan.correction is None else int(plan.correction.nnz),
    }
    if grid.has_floor:
        diagnostics["floor_cells"] = int(grid.floor.sum())
        diagnostics["floor_contact_cells"] = int(np.count_nonzero(contact[n_top:]))
        diagnostics["floor_reach_m"] = grid.floor_radius
    disc = {"cells_per_diameter": int(cells_per_diameter), "cell_size_m": L,
            "cells": grid.n_cells, "tolerance": tol,
            "edge_cells": "equivalent-square" if plan.correction is not None else "grid"}
    if grid.flat:
        disc["length_across_m"] = 2.0 * math.sqrt(scene.lens.radius_m * scene.indentation_m)
    n = grid.n_cells
    # Names shared with the dense model's fields (validation.output.report draws cells from them).
    fields = {"x_m": grid.x, "y_m": grid.y, "pressure_Pa": pressure,
              "covered_fraction": grid.covered, "gap_m": gap, "pillar": grid.pillar,
              "cell_force_N": cell_force, "force_N": cell_force, "cell_size_m": L,
              "side_m": np.full(n, L), "angle_rad": np.zeros(n), "weight": np.ones(n),
              "area_m2": grid.covered * L2, "collocation_x_m": grid.colloc_x,
              "collocation_y_m": grid.colloc_y, "floor": grid.floor}
    return ContactResult(
        model=MODEL_NAME, scene=scene.to_dict(), discretisation=disc,
        total_force_N=total, centre_pressure_Pa=float(pressure[grid.centre_cell]),
        contact_radius_m=contact_radius, real_contact_area_m2=area,
        pillars_in_contact=len(forces), pillar_forces=forces,
        converged=bool(converged), iterations=int(outcome.iterations), wall_time_s=wall,
        pillar_top_profile=profile, diagnostics=diagnostics, fields=fields,
        floor_force_N=floor_force, floor_contact_area_m2=floor_area,
        floor_contact_radius_m=floor_radius)


def _centre_profile(scene, grid, pressure) -> dict:
    """Pressure along the +x axis across the central pillar top (flat: across the contact)."""
    centre_pillar = grid.pillar[grid.centre_cell]
    # The centre's row of the top unknowns: they are in row-major grid order (the floor's
    # come after them), so the row is one slice, found by bisection, not a pass over all.
    nx = grid.shape[1]
    first = grid.flat_index[grid.centre_cell] // nx * nx
    lo, hi = np.searchsorted(grid.flat_index[:grid.n_top], [first, first + nx])
    idx = np.arange(lo, hi)
    row = (grid.x[idx] >= 0) & (grid.pillar[idx] == centre_pillar)
    if not grid.flat:
        row &= grid.x[idx] <= 0.5 * scene.pillars.diameter_m
    idx = idx[row]
    idx = idx[np.argsort(grid.x[idx])]
    return {"r_m": [float(v) for v in grid.x[idx]],
            "pressure_Pa": [float(v) for v in pressure[idx]]}
