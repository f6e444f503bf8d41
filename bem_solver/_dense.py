"""The paper's boundary-element superposition method, made exact: ``solve_dense``.

Uniform-pressure square elements on the pillar tops (Love's coefficients, compliance
(gamma_l + gamma_s)/pi), the Hooke shortening of each pillar, the D6 symmetry of the lattice,
and either an exact complementarity solver (default) or the paper's contact-radius search.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from pillar_xval.contact import ContactSolution, min_map_residual, solve_active_set as solve_contact
from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.scenes import Scene, ScopeError, analytic
from pillar_xval.scenes.floor import check_floor_scope
from pillar_xval.outcome.memory import memory_short
from pillar_xval.threads import thread_count

from ._cells import VARIANTS, cell_pattern
from ._discretise import Discretisation, discretise, overlap_radius
from ._elastic_pillar import (cached_excess_block, check_pillars, coupling_block, image_cells,
                              operator_records, pillar_record, reduced_block,
                              representative_rows, scene_compliance, uses_coupling,
                              uses_elastic_block)
from ._operator import BYTES_PER_THREAD, reduced_operator

MAX_UNKNOWNS = 12_000  # dense reduced operator: 1.2 GB at this size
RTOL_COMPLEMENTARITY = 1e-8
# Bytes per image element while a discretisation is assembled (coordinates, angles, sides,
# areas, owners and the 12-image work arrays of the D6 expansion; measured ~150-190 B) and per
# entry of the dense reduced operator at its peak (row sums, their upper triangle, the
# symmetrised copy and the active-set solve's submatrix: about five n x n arrays).
BYTES_PER_IMAGE = 200.0
BYTES_PER_OPERATOR_ENTRY = 5 * 8.0
# Work arrays of a solve of any size: blocks of Love coefficients on two threads (measured
# peaks of 5-40 MB on scenes with under a hundred unknowns); each further assembly thread
# adds its own blocks (BYTES_PER_THREAD).
BYTES_FIXED = 48 * 2.0**20
# Love's exact pairs of the assembly, kept until the sums are done: ~230 per unknown within
# FAR_FIELD_RATIO sides (the upper triangle of a flat scene's 452; 179 on paper-fig3-dense),
# two int32 indices each, twice while they are gathered from the blocks.
BYTES_PER_UNKNOWN_NEAR = 4e3


def lens_gap(scene: Scene, x, y):
    """Gap before loading between the lens and the pillar-top plane at (x, y) (m)."""
    return analytic.lens_gap(scene.lens.radius_m, np.hypot(x, y))


def _check_options(per_diameter, cells, contact):
    if isinstance(per_diameter, bool) or not isinstance(per_diameter, (int, np.integer)):
        raise ValueError(f"elements_per_diameter = {per_diameter!r}: expected an integer")
    if not 2 <= per_diameter <= 400:
        raise ValueError(f"elements_per_diameter = {per_diameter}: allowed range is [2, 400]")
    if cells not in VARIANTS:
        raise ValueError(f"cells = {cells!r}: allowed values are {', '.join(VARIANTS)}")
    if contact not in ("exact", "paper"):
        raise ValueError(f"contact = {contact!r}: allowed values are exact, paper")


def solve_dense(scene: Scene, elements_per_diameter: int = 11, cells: str = "covered",
                contact: str = "exact", *, pillars: str = "hooke",
                compliance=None, progress=None) -> ContactResult:
    """Solve ``scene`` with the dense, symmetry-reduced BEM.

    Parameters
    ----------
    scene : Scene
    elements_per_diameter : int
        P, square elements across a pillar diameter (b = d/P); for a flat scene, across the
        Hertz contact diameter 2 sqrt(R zeta).
    cells : {"covered", "centre"}
        Edge cells weighted by their covered area (smooth convergence), or the paper's cells
        whose centre lies on the pillar top.
    contact : {"exact", "paper"}
        Exact complementarity (p >= 0, gap >= 0, p gap = 0 on every element) or the paper's
        iterative contact-radius search (supplementary material, sec. 4), which only removes
        tensile zones and does not check interpenetration outside the contact.
    pillars : {"hooke", "elastic"}
        The paper's uniformly shortening pillar (default), or the elastic pillar: a dense
        excess-compliance block per pillar from the pillar's finite-element compliance
        (:mod:`bem_solver._elastic_pillar`; computed once per pillar kind and cached).
    compliance : fem_reference.ModalCompliance, optional
        With ``pillars="elastic"``: the pillar's mode matrices (default: the cached ones of
        the scene's pillar kind at the default discretisation).
    progress : callable, optional
        ``progress(text)`` hears of a compliance build (once per pillar kind, then cached).
    """
    _check_options(elements_per_diameter, cells, contact)
    check_pillars(pillars, scene)
    t0 = time.perf_counter()
    P = int(elements_per_diameter)
    if scene.force_N is not None:
        from ._dense_force import solve_under_force

        return solve_under_force(scene, P, cells, contact, pillars, compliance, progress, t0)
    check_floor_scope(scene, "bem")
    _refuse_if_too_large(scene, P, cells, contact)
    elastic = elastic_setup(scene, P, cells, pillars, compliance, progress)
    level = solve_rounds(scene, P, cells, contact, elastic)
    return level_result(scene, level, time.perf_counter() - t0, pillars)


def level_result(scene: Scene, level: "Level", wall: float, pillars: str) -> ContactResult:
    """The result of ``level`` for ``scene`` (indentation-controlled: the given indentation,
    or the one a force-controlled solve found); ``wall``: its time (s); ``pillars``: the
    pillar model asked for, recorded with the notes on its moduli."""
    kind = None if level.elastic is None else level.elastic["modal"].kind
    return _result(scene, level.disc, level.sol, level.P, level.cells, level.contact,
                   level.rounds, {**level.extra, **pillar_record(scene, pillars, kind)}, wall)


def elastic_setup(scene: Scene, P: int, cells: str, pillars: str, compliance=None,
                  progress=None) -> dict | None:
    """The elastic pillar's compliance and its block of excess compliance on the cells of
    one pillar (None with Hooke pillars)."""
    if not uses_elastic_block(scene, pillars):
        return None
    modal = scene_compliance(scene, compliance, progress=progress)
    pattern = cell_pattern(P, cells)
    cells_m = pattern.scaled(scene.pillars.diameter_m)
    rows = representative_rows(scene, pattern)
    _refuse_large_block(P, len(rows), len(pattern.x), modal)
    return {"modal": modal, "pattern": pattern, "rows": rows,
            "X": cached_excess_block(scene, cells_m, modal, rows, (P, cells))}


@dataclass
class Level:
    """A finished dense solve that can be solved again at another approach on the same
    operator (:func:`resolve`): the scene it was discretised for, its options, the candidate
    region (``radius``, m) with its discretisation and reduced operator ``M``, the solution,
    its indentation ``zeta`` (m), and the collocation points of the outside check."""

    scene: Scene
    P: int
    cells: str
    contact: str
    elastic: dict | None
    disc: Discretisation
    M: np.ndarray
    radius: float
    sol: ContactSolution
    rounds: int
    extra: dict
    zeta: float
    reach: tuple | None = None
    reach_radius: float = 0.0


def solve_rounds(scene: Scene, P: int, cells: str, contact: str, elastic: dict | None,
                 force: float | None = None, zeta: float | None = None,
                 start: Level | None = None) -> Level:
    """The contact on candidate regions grown until no contact is possible beyond them.

    ``scene`` is indentation-controlled: its indentation is the given one, or with ``force``
    (N) the design indentation of a force-controlled solve (the first candidate region, and a
    flat scene's cell size), whose indentation is then solved for with the force.  ``zeta``
    (m) solves at another indentation than the scene's on the discretisation of ``start``
    (:func:`resolve`), whose region and operator are reused while they hold the contact."""
    zeta = scene.indentation_m if zeta is None else zeta
    r_max = _overlap(scene.lens.radius_m, zeta) if start is not None else overlap_radius(scene)
    hertz_radius = math.sqrt(scene.lens.radius_m * zeta)
    radius = _initial_radius(scene, contact) if start is None else start.radius
    reach, reach_radius = (None, 0.0) if start is None else (start.reach, start.reach_radius)
    rounds = 0
    while True:
        rounds += 1
        if start is not None and radius == start.radius:
            disc, M = start.disc, start.M
            guess = start.sol.pressure > 0
        else:
            disc, M = _operator(scene, P, cells, radius, elastic)
            # Start from the Hertz contact disk: a few active-set steps fewer than {overlap}.
            guess = np.hypot(disc.rep_x, disc.rep_y) <= hertz_radius
        # Rows of the reduced operator are weighted by the orbit sizes: gap_i / w_i is in m.
        gap0 = lens_gap(scene, disc.rep_x, disc.rep_y)
        b = disc.rep_weight * (gap0 if force is not None else gap0 - zeta)
        if contact == "exact":
            sol = solve_contact(M, b, scale=zeta, weights=disc.rep_weight,
                                groups=disc.rep_orbit, initial=guess, tol=RTOL_COMPLEMENTARITY,
                                force=force, load=None if force is None else disc.rep_weight)
            extra = {}
            if force is not None:
                zeta = sol.approach
                r_max = _overlap(scene.lens.radius_m, zeta)
            if not sol.converged:
                break  # reported in the result; the candidate region is not grown further
        else:
            sol, extra = _paper_search(scene, disc, M, b)
        if contact == "exact" and radius < r_max * (1.0 - 1e-12) and reach_radius < r_max:
            outer = discretise(scene, P, cells, r_max)
            reach, reach_radius = (outer.rep_x, outer.rep_y), r_max
        violated = (None if contact == "paper" else
                    _outside_violations(scene, disc, sol.pressure, reach, radius, r_max,
                                        elastic, zeta))
        if violated is None:
            break
        radius = min(r_max, violated + (scene.pillars.diameter_m if scene.pillars else
                                        4 * disc.cell_side))
    if elastic is not None:
        extra = {**extra, "pillar_compliance": _compliance_summary(elastic["modal"]),
                 "operators": operator_records(elastic["modal"].diagnostics)}
    return Level(scene, P, cells, contact, elastic, disc, M, radius, sol, rounds, extra, zeta,
                 reach, reach_radius)


def resolve(level: Level, zeta: float) -> Level:
    """``level`` solved again under the indentation ``zeta`` (m) on its discretisation: its
    operator while its candidate region holds the contact, grown otherwise."""
    return solve_rounds(level.scene, level.P, level.cells, level.contact, level.elastic,
                        zeta=zeta, start=level)


def _operator(scene: Scene, P: int, cells: str, radius: float, elastic: dict | None):
    """(discretisation, reduced operator) of the candidate region ``radius`` (m)."""
    disc = discretise(scene, P, cells, radius)
    if disc.n_unknowns > MAX_UNKNOWNS:
        raise ScopeError(
            f"elements_per_diameter = {P}: {disc.n_unknowns} unknowns exceed the dense "
            f"limit {MAX_UNKNOWNS}; use a smaller P or the FFT model (--model bem-fft)")
    block = None
    if elastic is not None:
        img_cell = image_cells(disc, elastic["pattern"], scene.pillars.diameter_m)
        block = reduced_block(disc, elastic["X"], img_cell, elastic["rows"])
        if uses_coupling(scene, elastic["modal"]):
            block += coupling_block(scene, disc, elastic["modal"])
    return disc, reduced_operator(scene, disc, block)


def _overlap(radius_m: float, zeta: float) -> float:
    """Radius (m) where the undeformed lens meets the tops at approach ``zeta``
    (:func:`._discretise.overlap_radius` at an indentation the scene does not give)."""
    return math.sqrt(max(2.0 * radius_m * zeta - zeta * zeta, 0.0))


def _compliance_summary(modal) -> dict:
    """What the result records of the pillar compliance it used."""
    d = modal.diagnostics
    return {"modes": modal.modes, "mesh_size": modal.mesh_size,
            "top_points": int(len(modal.r_top)), "cached": bool(d.get("cached", False)),
            "reciprocity_asymmetry": d.get("reciprocity_asymmetry"),
            "build_time_s": d.get("time_s", {}).get("total"),
            "coupling": ("half-space at the tops, corrected by the base's second moments"
                         if getattr(modal, "base_moments", None) is not None
                         else "half-space at the tops")}


def _initial_radius(scene: Scene, contact: str) -> float:
    """First candidate radius (m): 1.15 Hertz radii, at least a pillar diameter, at most the
    overlap radius (the paper's search starts from the overlap radius)."""
    r_max = overlap_radius(scene)
    if contact == "paper":
        return r_max
    radius = min(r_max, 1.15 * math.sqrt(scene.lens.radius_m * scene.indentation_m))
    if scene.pillars is not None:
        radius = min(r_max, max(radius, scene.pillars.diameter_m))
    return radius


def _elements_within(scene: Scene, P: int, cells: str, radius: float) -> float:
    """Expected number of elements (all images) with collocation radius <= ``radius``, from
    the lattice's element density, without building them (cheap for any scene size)."""
    if scene.pillars is None:
        side = 2.0 * math.sqrt(scene.lens.radius_m * scene.indentation_m) / P
        return math.pi * radius**2 / side**2 + 1.0
    per_pillar = len(cell_pattern(P, cells).x)
    cell_area = math.sqrt(3.0) / 2.0 * scene.pillars.pitch_m ** 2  # one pillar per cell
    return per_pillar * max(1.0, math.pi * radius**2 / cell_area)


def estimate_memory(scene: Scene, elements_per_diameter: int = 11, cells: str = "covered",
                    contact: str = "exact") -> dict:
    """Peak memory a :func:`solve_dense` call needs, estimated without discretising.

    The elements within the first candidate radius give the unknowns (one per D6 orbit, about
    a twelfth: a quarter on a flat scene) and the dense operator; the outside check holds
    every element out to the overlap radius, and its lower bound pairs each of them with every
    loaded pillar.  Candidate regions that grow in later rounds are not foreseen.

    Returns
    -------
    dict
        ``bytes`` (peak estimate), ``unknowns``, ``elements`` (first candidate region),
        ``outer_elements`` (out to the overlap radius, 0 when not needed), each a float.
    """
    _check_options(elements_per_diameter, cells, contact)
    P = int(elements_per_diameter)
    r_max = overlap_radius(scene)
    radius = _initial_radius(scene, contact)
    elements = _elements_within(scene, P, cells, radius)
    if scene.pillars is None:
        unknowns = elements / 4.0  # one quadrant (D2)
    else:  # the centre pillar by D2, the others by D6
        centre = float(len(cell_pattern(P, cells).x))
        unknowns = centre / 4.0 + (elements - centre) / 12.0
    outer = _elements_within(scene, P, cells, r_max) if (
        contact == "exact" and radius < r_max) else 0.0
    loaded = 1.0 if scene.pillars is None else max(
        1.0, elements / len(cell_pattern(P, cells).x))
    check = 3 * 8.0 * outer / 12.0 * (loaded if scene.pillars is not None else elements)
    peak = (BYTES_FIXED + BYTES_PER_THREAD * max(0, thread_count() - 2)
            + BYTES_PER_IMAGE * (elements + outer)
            + BYTES_PER_OPERATOR_ENTRY * unknowns**2 + BYTES_PER_UNKNOWN_NEAR * unknowns)
    return {"bytes": float(peak + check), "unknowns": float(unknowns),
            "elements": float(elements), "outer_elements": float(outer)}


def _refuse_if_too_large(scene: Scene, P: int, cells: str, contact: str) -> None:
    """ScopeError before any array is built when the solve would not fit in memory (or would
    exceed the dense limit by far)."""
    need = estimate_memory(scene, P, cells, contact)
    short = memory_short(need["bytes"])
    if short is not None:
        raise ScopeError(
            f"elements_per_diameter = {P}: this scene needs about {need['bytes'] / 2**30:.3g} "
            f"GiB ({need['elements'] + need['outer_elements']:.3g} elements, "
            f"{need['unknowns']:.3g} unknowns), {short}; use a smaller P, a smaller lens or "
            "indentation, or the FFT model (--model bem-fft)")
    if need["unknowns"] > 2 * MAX_UNKNOWNS:
        raise ScopeError(
            f"elements_per_diameter = {P}: about {need['unknowns']:.3g} unknowns, far beyond "
            f"the dense limit {MAX_UNKNOWNS}; use a smaller P or the FFT model "
            "(--model bem-fft)")


def _refuse_large_block(P: int, rows: int, cells: int, modal) -> None:
    """ScopeError when the elastic pillar's block (rows x cells, with the Love and mode
    temporaries: about four such arrays, plus the mode columns) would not fit in memory."""
    need = 8.0 * (4.0 * rows * cells + 2.0 * cells * (2 * modal.modes + 1) * len(modal.r_top))
    short = memory_short(need)
    if short is not None:
        raise ScopeError(
            f"elements_per_diameter = {P}: the elastic pillar's block ({rows} x {cells} cells) "
            f"needs about {need / 2**30:.3g} GiB, {short}; use a smaller P or the FFT model "
            "(--model bem-fft), whose elastic pillar needs no dense block")


def _paper_search(scene, disc, M, b):
    """Bisection-like contact radius search of the paper (supplementary sec. 4).

    Its answer is not a solution of the complementarity problem (it leaves tensile elements
    and interpenetration); ``converged`` says only that the search met its own criterion
    |a_i+1 - a_i| < b, and the residual and violations are reported beside it."""
    r = np.hypot(disc.rep_x, disc.rep_y)
    a = overlap_radius(scene)
    side = disc.cell_side
    stopped = False
    for it in range(1, 200):
        idx = np.nonzero(r <= a)[0]
        q = np.zeros(len(b))
        if len(idx):
            q[idx] = np.linalg.solve(M[np.ix_(idx, idx)], -b[idx])
        tensile = idx[q[idx] <= 0]
        a_next = r[tensile].min() if len(tensile) else a
        if len(tensile) == 0 or abs(a_next - a) < side:
            stopped = True
            break
        a = a_next * (1.0 - 1e-12)  # elements at the tensile radius leave the contact
    # Tensile elements are kept as the search leaves them: evaluate the gap of q as is.
    gap = M @ q + b
    sol = ContactSolution(q, gap, stopped, it, float("nan"), "paper-radius-search",
                          "search met |a_i+1 - a_i| < b" if stopped else
                          "search did not settle in 199 rounds")
    extra = {"search_radius_m": float(a), "search_stopped": stopped,
             "min_pressure_Pa": float(min(0.0, (q / disc.rep_area).min())),
             "max_interpenetration_m": float(max(0.0, -(gap / disc.rep_weight).min()))}
    return sol, extra


def _outside_violations(scene, disc, q, reach, radius, r_max, elastic=None, zeta=None):
    """Largest radius beyond the candidate region where contact cannot be ruled out, or None.

    ``reach`` holds the representative collocation points out to the overlap radius;
    ``zeta`` is the indentation (default the scene's).
    Displacements are bounded below by (gamma/pi) F / (|x - x_F| + rho) for a force F spread
    within rho of x_F (the Hooke shortening, also >= 0, is left out of the bound); where the
    lens gap plus this bound stays positive, no contact is possible.  An elastic pillar's own
    top may rise where it tilts: on a loaded pillar the bound takes the lens term alone plus
    F times the smallest entry of X when negative (a lower bound of gamma_s Love + X; the rows
    kept hold every entry up to the pattern's symmetry).
    """
    if reach is None or radius >= r_max * (1.0 - 1e-12):
        return None
    rx, ry = reach
    sel = np.hypot(rx, ry) > radius
    if not sel.any():
        return None
    ox, oy = rx[sel], ry[sel]
    scale = scene.half_space_compliance / math.pi
    force_img = q[disc.img_rep]
    if scene.pillars is None:
        fx, fy, rho = disc.img_x, disc.img_y, disc.img_side / math.sqrt(2.0)
        forces = force_img
    else:
        forces = np.bincount(disc.img_pillar, force_img, minlength=len(disc.pillar_xy))
        fx, fy = disc.pillar_xy[:, 0], disc.pillar_xy[:, 1]
        rho = np.full(len(forces), scene.pillars.diameter_m / 2.0)
    loaded = forces > 0
    dist = np.hypot(ox[:, None] - fx[loaded][None, :], oy[:, None] - fy[loaded][None, :])
    terms = scale * forces[loaded][None, :] / (dist + rho[loaded][None, :])
    if elastic is not None:
        own = dist <= rho[loaded][None, :] * (1.0 + 1e-9)  # a point on a loaded pillar
        lens_share = scene.lens.material.compliance / scene.half_space_compliance
        floor = min(0.0, float(elastic["X"].min()))
        terms = np.where(own, lens_share * terms + floor * forces[loaded][None, :], terms)
    u_low = terms.sum(axis=1)
    gap_low = lens_gap(scene, ox, oy) - (scene.indentation_m if zeta is None else zeta) + u_low
    bad = gap_low < 0
    return float(np.hypot(ox[bad], oy[bad]).max()) if bad.any() else None


def _smooth_edge_radius(r, pressure, touching, b):
    """Contact radius of a smooth (flat-scene) contact: where p^2, linear in r^2 near a
    square-root edge, extrapolates to zero, fitted over the elements in contact within three
    cells of the outermost one.  The staircase of cells alone is off by up to half a cell and
    jumps with refinement."""
    if not touching.any():
        return 0.0
    r_out = r[touching].max()
    band = touching & (r >= r_out - 3.0 * b)
    if band.sum() >= 3:
        beta, alpha = np.polyfit(r[band] ** 2, pressure[band] ** 2, 1)
        if beta < 0 and alpha > 0:
            a = math.sqrt(-alpha / beta)
            if r_out - b <= a <= r_out + b:
                return a
    return float(r_out + b / 2.0)


def _result(scene, disc: Discretisation, sol: ContactSolution, P, cells, contact, rounds, extra,
            wall) -> ContactResult:
    q, w = sol.pressure, disc.rep_weight  # q: force on each element of an orbit (N)
    pressure = q / disc.rep_area
    force_each = q
    touching = q > 0
    total = float((w * q).sum())

    # Centre pressure: the element(s) nearest r = 0 on the centre pillar (all equal by D2).
    r = np.hypot(disc.rep_x, disc.rep_y)
    centre_idx = np.argmin(np.where(disc.rep_centre, r, np.inf))
    centre_pressure = float(pressure[centre_idx])

    if scene.pillars is None:
        contact_radius = _smooth_edge_radius(r, pressure, touching, disc.cell_side)
        area = math.pi * contact_radius**2
    else:
        # Outermost point of a loaded element, no further than its pillar's rim.
        centre = disc.pillar_xy[disc.img_pillar[disc.rep_start[:-1]]]
        rim = np.hypot(centre[:, 0], centre[:, 1]) + scene.pillars.diameter_m / 2.0
        reach = np.minimum(r + disc.rep_side / 2.0, rim)
        contact_radius = float(reach[touching].max()) if touching.any() else 0.0
        area = float((w * disc.rep_area)[touching].sum())

    pillar_forces = []
    if scene.pillars is not None:
        img_force = force_each[disc.img_rep]
        per_pillar = np.bincount(disc.img_pillar, img_force, minlength=len(disc.pillar_xy))
        for k in np.nonzero(per_pillar > 0)[0]:
            pillar_forces.append(PillarForce(
                int(disc.pillar_nm[k, 0]), int(disc.pillar_nm[k, 1]),
                float(disc.pillar_xy[k, 0]), float(disc.pillar_xy[k, 1]), float(per_pillar[k])))

    # Profile across the central pillar (or the flat contact): the row of centre elements
    # nearest the x axis.
    row = disc.rep_centre & np.isclose(disc.rep_local[:, 1],
                                       disc.rep_local[disc.rep_centre, 1].min())
    order = np.argsort(disc.rep_x[row])
    profile = {"r_m": disc.rep_x[row][order].tolist(),
               "pressure_Pa": pressure[row][order].tolist()}

    gap = sol.gap / w
    diagnostics = {
        "solver": sol.method,
        "message": sol.message,
        "contact_residual": _residual_of(sol, q, gap, scene),
        "max_gap_violation_m": float(max(0.0, -gap.min())),
        "candidate_radius_m": disc.candidate_radius,
        "overlap_radius_m": overlap_radius(scene),
        "candidate_rounds": rounds,
        "unknowns": disc.n_unknowns,
        "elements": disc.n_elements,
        "force_balance_N": float(abs(total - sum(p.force_N for p in pillar_forces)))
        if pillar_forces else 0.0,
        **extra,
    }
    # The paper's search has converged when it met its own criterion |a_i+1 - a_i| < b; its
    # remaining tensile elements and interpenetration are reported in the diagnostics.
    converged = sol.converged
    return ContactResult(
        model="bem",
        scene=scene.to_dict(),
        discretisation={"elements_per_diameter": P, "cells": cells, "contact": contact,
                        "element_side_m": disc.cell_side},
        total_force_N=total,
        centre_pressure_Pa=centre_pressure,
        contact_radius_m=contact_radius,
        real_contact_area_m2=area,
        pillars_in_contact=len(pillar_forces),
        pillar_forces=pillar_forces,
        converged=bool(converged),
        iterations=int(sol.iterations),
        wall_time_s=float(wall),
        pillar_top_profile=profile,
        diagnostics=diagnostics,
        fields={"x_m": disc.rep_x, "y_m": disc.rep_y, "pressure_Pa": pressure,
                "force_N": force_each, "weight": w, "gap_m": gap, "area_m2": disc.rep_area,
                "side_m": disc.rep_side, "angle_rad": disc.rep_angle,
                "pillar_orbit": disc.rep_orbit, "disc": disc},
    )


def _residual_of(sol, q, gap, scene) -> float:
    """The min-map residual / zeta; for the paper's search, computed on its own answer (its
    tensile elements count as in contact)."""
    if np.isfinite(sol.residual):
        return float(sol.residual)
    return min_map_residual(np.abs(q), gap) / scene.indentation_m


__all__ = ["Level", "elastic_setup", "estimate_memory", "lens_gap", "level_result", "resolve",
           "solve_dense", "solve_rounds"]
