"""Axisymmetric FEM reference: a lens on one elastic pillar bonded to a substrate, or on a
flat substrate (Hertz), with frictionless unilateral contact, displacement-controlled;
where the lens can reach the floor around the pillar, the floor is a second contact line
(:mod:`.._floor`).

Model.  The lens is a block of side L with a flat bottom at z = 0; its spherical shape is
the initial gap g(r) = R - sqrt(R^2 - r^2) between the lens bottom and the pillar top (or
the substrate) at the same r.  The lens top moves down by zeta, the substrate bottom is
fixed (rollers on both far faces, free sides).  The contact line has identical P2 points on
both bodies; the contact pressure is a P1 (mortar) field on its vertices (:mod:`.contact`:
node-to-node contact on P2 points made the pressure alternate and left the axis unloaded).
Rigid bodies (E = inf) are not meshed: a rigid lens is a moving rigid surface, a rigid pillar
on an elastic substrate is one rigid translation bonded to it, a rigid substrate clamps the
pillar base.

Solution.  Factorise once; one solve per contact point gives the compliance matrix C; the
LCP of :mod:`.contact` gives the nodal forces; linear residual and complementarity are
checked and reported.

Under a given force the exact LCP solver takes the approach as one more unknown
(:func:`pillar_xval.contact.solve_active_set`, ``force=``): the factorisation and C are the
same, only the contact solve changes.  One pillar's mesh does not depend on the indentation.
A flat scene's mesh is drawn in units of the Hertz radius sqrt(R zeta) and is the same in
those units for every zeta: it follows the solved zeta by a change of unit, the gap vector
recomputed and the LCP solved again, without meshing or factorising again, until the unit's
zeta and the solved one agree (:data:`FLAT_DESIGN_RTOL`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.linalg import block_diag

from pillar_xval.contact import solve_active_set
from meshes import build_axisymmetric_mesh, flat_geometry, pillar_geometry
from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.outcome.memory import memory_short
from pillar_xval.scenes import InputError, Scene, ScopeError, analytic
from pillar_xval.scenes.floor import floor_reach, floor_reachable

from .._driver import (HERTZ_CANDIDATE, RTOL_COMPLEMENTARITY, PhaseClock, contact_radius,
                       fem_result, flat_candidate, refuse_rigid_pair, scaled_materials, verdict)
from .._floor import annulus_edges, floor_candidate, side_wall_diagnostics
from .contact import mortar_matrix
from .fields import cell_stresses, lens_in_side_wall, write_vtu
from .system import assemble

MODEL = "fem-axisym"
# Block side over the focus radius: truncation ~ 2a/(pi L) = 6e-6 at 1e5 (measured 0.8x that);
# the geometric grading makes the large block cost only a few rings of elements (+10 % dofs
# from 1e4 to 1e5).
BLOCK_FACTOR = 1e5
# Memory model of a solve (measured on single-pillar and hertz at mesh_size 4..0.5): the
# reduced unknowns grow as mesh_size^-1.9 from about 18k (pillar) or 12.5k (flat) at 1; the
# sparse LU takes ~650 B per unknown per log(unknowns) (2D fill ~ n log n); the compliance
# solves keep a dense (unknowns x contact vertices) array; imports and meshing ~40 MB.
DOFS_AT_UNIT_SIZE = {"pillar": 18_000.0, "flat": 12_500.0}
DOFS_EXPONENT = 1.9
CONTACT_POINTS_AT_UNIT_SIZE = 60.0
BYTES_PER_DOF_LOG = 650.0
BYTES_FIXED = 40 * 2.0**20
# A flat scene under a force: the mesh unit's zeta and the solved one agree within this (the
# answer then differs from the indentation-controlled one at the solved zeta by this times
# the discrete force's sensitivity to the element size, < 1e-2).
FLAT_DESIGN_RTOL = 1e-6
MAX_DESIGN_ROUNDS = 6
# A pillar scene under a force whose solved indentation reaches the floor beyond the meshed
# candidate segment is meshed again for this much more than that indentation (fewer rounds).
FLOOR_DESIGN_MARGIN = 1.05


def estimate_memory(scene: Scene, mesh_size: float = 1.0) -> dict:
    """Peak memory of :func:`solve` on ``scene`` (estimated, nothing built).

    Returns
    -------
    dict
        ``bytes`` (peak), ``dofs`` (reduced unknowns) and ``contact_points`` (P2 points on
        the contact line), floats.
    """
    if not isinstance(mesh_size, (int, float)) or not math.isfinite(mesh_size) \
            or mesh_size <= 0:
        raise InputError(f"mesh_size = {mesh_size!r}: must be a number > 0")
    kind = "flat" if scene.is_flat else "pillar"
    dofs = DOFS_AT_UNIT_SIZE[kind] * mesh_size ** -DOFS_EXPONENT
    if not scene.is_flat:  # taller pillars hold more elements along their side
        dofs *= max(1.0, 2.0 * scene.pillars.height_m / scene.pillars.diameter_m) ** 0.5
    contact = CONTACT_POINTS_AT_UNIT_SIZE / mesh_size
    peak = (BYTES_FIXED + BYTES_PER_DOF_LOG * dofs * math.log(dofs)
            + 8.0 * dofs * contact / 2.0 + 8.0 * contact**2)
    return {"bytes": float(peak), "dofs": float(dofs), "contact_points": float(contact)}


def _refuse_if_too_large(scene: Scene, mesh_size: float) -> None:
    need = estimate_memory(scene, mesh_size)
    short = memory_short(need["bytes"])
    if short is not None:
        raise ScopeError(
            f"mesh_size = {mesh_size:g}: this mesh needs about {need['bytes'] / 2**30:.3g} GiB "
            f"(~{need['dofs']:.3g} unknowns), {short}; use a larger mesh_size")


def solve(scene: Scene, mesh_size: float = 1.0, *, vtu_path=None,
                       block_factor: float = BLOCK_FACTOR, progress=None) -> ContactResult:
    """Solve ``scene`` with the axisymmetric finite-element model.

    Parameters
    ----------
    scene : Scene
        A flat (Hertz) scene, or a pillar scene in the single-pillar regime
        (surface fraction below the spring-model threshold Phi_S).
    mesh_size : float
        Dimensionless refinement factor; 0.5 halves every element size.
    vtu_path : path-like, optional
        Where to write the VTU of displacement (m) and stresses (Pa); a JSON sidecar with the
        scene and discretisation is written beside it.
    block_factor : float
        Side of the lens and substrate blocks in units of the pillar radius d/2 (or of the
        Hertz radius); the truncation error is about 2 a / (pi L).
    progress : callable, optional
        ``progress(text)`` is called as each phase starts (meshing, assembling, factorising,
        compliance, contact).

    Returns
    -------
    ContactResult
        ``model = "fem-axisym"``; ``pillar_top_profile`` is the contact pressure (Pa) at the
        mesh vertices of the pillar top, r = 0 to d/2, graded towards the edge (flat scenes:
        of the candidate contact zone, 0 to 1.5 a).  ``diagnostics`` holds
        ``linear_residual`` (scaled, relative), ``contact_residual`` (the min-map
        residual of :mod:`pillar_xval.contact` on the mean gaps, relative to zeta),
        ``compliance_asymmetry``,
        ``block_size_m``, ``truncation_estimate`` (F (gamma_l + gamma_s) / (pi L zeta), an
        upper bound of the relative force error from the finite block: measured 0.8 x it),
        ``max_pointwise_penetration`` (over zeta, at the P2 points; the mortar contact
        enforces the gap weighted by each vertex's hat function, and near a punch edge the
        pointwise gap wobbles by <1 % of zeta within the last three elements), the mesh
        quality, timings, and for a rigid pillar on an elastic substrate
        ``pillar_translation_m`` (its vertical displacement, negative downwards); with a
        pillar, the side walls' diagnostic (:func:`.._floor.side_wall_diagnostics`); the
        floor's ``floor_force_N``, ``floor_contact_area_m2``, ``floor_contact_radius_m`` and
        the ``regime`` are the result's own fields (:mod:`.._floor`: the floor is a contact
        line where the lens can reach it, ``fields`` then hold ``floor_r_m`` and
        ``floor_pressure_Pa``).
        ``fields`` holds the arrays (pressure at the vertices, gaps and nodal forces at the
        P2 points, the condensed compliance).

    Raises
    ------
    ScopeError
        For a scene the model cannot represent (two or more pillars in contact, rigid lens
        on a rigid pillar).
    SolveError
        If the sparse factorisation fails or returns non-finite values.  A solution that
        misses a tolerance comes back with ``converged = False`` and the reason in
        ``diagnostics["message"]``.
    """
    clock = PhaseClock(progress)
    force = scene.force_N
    solved = scene
    if force is not None:  # refused before solving when the least indentation is beyond
        _implied(scene, analytic.least_indentation(scene), "at least: the lens on a rigid "
                 "flat", bound=True)
        solved = scene.designed(analytic.indentation_estimate(scene))
    setup = _setup(solved, mesh_size, block_factor, scope=force is None)
    _refuse_if_too_large(solved, mesh_size)
    mesh, system = _mesh_and_factorise(setup, mesh_size, clock)
    compliance = _compliance(system, clock)
    contact = _contact(solved, setup, system, compliance, clock, force)
    rounds, settled = [], True
    while force is not None:
        zeta = contact["zeta"]
        rounds.append({"design_indentation_m": solved.indentation_m, "indentation_m": zeta})
        if not scene.is_flat:
            settled = _floor_holds(scene, setup, zeta)
            if settled or len(rounds) == MAX_DESIGN_ROUNDS:
                solved = _implied(scene, zeta, f"fem-axisym at mesh_size {mesh_size:g}")
                break
            # the floor's candidate segment follows the solved zeta: mesh again
            solved = scene.designed(zeta * FLOOR_DESIGN_MARGIN)
            setup = _setup(solved, mesh_size, block_factor, scope=False)
            mesh, system = _mesh_and_factorise(setup, mesh_size, clock)
            compliance = _compliance(system, clock)
            contact = _contact(solved, setup, system, compliance, clock, force)
            continue
        settled = abs(zeta / solved.indentation_m - 1.0) <= FLAT_DESIGN_RTOL
        if settled or len(rounds) == MAX_DESIGN_ROUNDS:
            solved = _implied(scene, zeta, f"fem-axisym at mesh_size {mesh_size:g}")
            break
        # The flat mesh in units of the Hertz radius: the unit follows the solved zeta.
        mesh = dataclasses.replace(mesh, points=mesh.points * math.sqrt(
            zeta / solved.indentation_m))
        solved = scene.designed(zeta)
        setup = _setup(solved, mesh_size, block_factor, scope=False)
        contact = _contact(solved, setup, system, compliance, clock, force)
    result = _result(solved, setup, mesh, system, compliance, contact, mesh_size, clock)
    if force is not None:
        if not settled:
            result.converged = False
            result.diagnostics["message"] = (
                f"the mesh unit's indentation did not settle in {MAX_DESIGN_ROUNDS} rounds"
                if scene.is_flat else f"the floor's candidate segment did not hold the solved "
                f"indentation's reach in {MAX_DESIGN_ROUNDS} meshings")
        result.for_force(scene.to_dict(), zeta, design_rounds=rounds)
    if vtu_path is not None:
        _write_fields(vtu_path, solved, setup, mesh, system, contact["x"], result)
    return result


def _floor_holds(scene: Scene, setup: dict, zeta: float) -> bool:
    """Whether the meshed floor segment (or its absence) holds the rigid reach of the floor
    at the indentation ``zeta`` (m), beyond which there is no contact."""
    end = setup["geometry"].floor_radius_m
    return not floor_reachable(scene, zeta) or (end is not None
                                                and floor_reach(scene, zeta) <= end)


def _implied(scene: Scene, zeta: float, how: str, bound: bool = False) -> Scene:
    """The force-controlled ``scene`` at the indentation ``zeta`` (m) found ``how`` for it,
    within the scope of a given indentation and of this model (one pillar: Phi < Phi_S at
    zeta; ``bound``: zeta is a lower bound, at which only that is checked), else a ScopeError
    naming the force and zeta."""
    solved = scene.designed(zeta) if bound else scene.implied(zeta, how)
    problem = "" if scene.is_flat else _beyond_one_pillar(solved)
    if problem:
        raise ScopeError(f"load.force_uN = {scene.force_N * 1e6:.6g}: implies an indentation "
                         f"of {zeta * 1e6:.4g} um ({how}): {problem}")
    return solved


def _mesh_and_factorise(setup: dict, mesh_size: float, clock: PhaseClock):
    """Mesh, assemble and factorise: (mesh, system)."""
    clock.say(f"meshing (mesh_size {mesh_size:g})")
    mesh = build_axisymmetric_mesh(setup["geometry"])
    clock.done("mesh")
    ell = setup["ell"]
    skmesh = mesh.to_skfem().scaled([1.0 / ell, 1.0 / ell])
    clock.say(f"assembling ({mesh.nelements} elements)")
    system = assemble(skmesh, setup["materials"], contact=setup["contact"],
                      rigid_pillar_on_substrate=setup["rigid_pillar_on_substrate"],
                      clamp_pillar_base=setup["clamp_pillar_base"])
    clock.done("assemble")
    clock.say(f"factorising ({system.n_reduced} unknowns)")
    system.factorise()
    clock.done("factorise")
    return mesh, system


def _compliance(system, clock: PhaseClock) -> dict:
    """The condensed compliance C on the contact vertices, by one solve per vertex: the P1
    multiplier's nodal-force patterns G^T D (half as many right-hand sides as P2 points);
    ``U[:, j]`` is the gap change at the P2 points."""
    lines = np.split(system.contact_r, np.cumsum(system.contact_lines)[:-1])
    D = block_diag(*[mortar_matrix(r) for r in lines])
    clock.say(f"compliance ({D.shape[1]} contact points, one solve each)")
    X, residual = system.solve(system.G.T @ D)
    U = system.G @ X
    C = D.T @ U
    asymmetry = float(np.max(np.abs(C - C.T)) / np.max(np.abs(C)))
    # Reciprocity makes the exact compliance symmetric; the solves leave a rounding asymmetry
    # that grows with the stiffness contrast (5.6e-9 at E_p/E_s = 6e5).  The contact solver
    # factorises one triangle, so its residual, computed with the full C, would report that
    # asymmetry as a contact error: solve with the symmetric part, report the asymmetry apart.
    C = 0.5 * (C + C.T)
    clock.done("compliance")
    return {"D": D, "X": X, "U": U, "C": C, "asymmetry": asymmetry, "residual": residual}


def _contact(scene: Scene, setup: dict, system, compliance: dict, clock: PhaseClock,
             force: float | None = None) -> dict:
    """The mortar LCP, exactly: pressures ``lam`` (units of E_ref), nodal forces ``f``,
    pointwise gaps ``w`` at the P2 points, the displacement ``x`` (units of ell) and the
    indentation ``zeta`` (m): the scene's, or with ``force`` (N) the one found for it."""
    D, U, C, X = compliance["D"], compliance["U"], compliance["C"], compliance["X"]
    ell, E_ref = setup["ell"], setup["E_ref"]
    R, zeta = scene.lens.radius_m, scene.indentation_m
    r_m = system.contact_r * ell
    gap = analytic.lens_gap(R, r_m) / ell
    if setup["floor"]:  # the floor line lies h below the pillar top
        gap[system.contact_lines[0]:] += scene.pillars.height_m / ell
    weight = D.sum(axis=0)  # integral of psi_j r dr: turns weighted gaps into mean gaps
    clock.say("contact")
    if force is None:
        sol = solve_active_set(C, D.T @ (gap - zeta / ell), scale=zeta / ell, weights=weight,
                               tol=RTOL_COMPLEMENTARITY)
    else:  # the force is 2 pi E_ref ell^2 weight . lam (see _result)
        sol = solve_active_set(C, D.T @ gap, scale=zeta / ell, weights=weight,
                               tol=RTOL_COMPLEMENTARITY, load=weight,
                               force=force / (2.0 * math.pi * E_ref * ell**2))
        zeta = sol.approach * ell
    lam = sol.pressure
    out = {"sol": sol, "lam": lam, "f": D @ lam, "w": U @ lam + gap - zeta / ell,
           "x": X @ lam, "r_m": r_m, "zeta": zeta}
    clock.done("contact")
    return out


def _result(scene: Scene, setup: dict, mesh, system, compliance: dict, contact: dict,
            mesh_size: float, clock: PhaseClock) -> ContactResult:
    """The verdict and the result, in SI units."""
    ell, E_ref = setup["ell"], setup["E_ref"]
    zeta = scene.indentation_m
    sol, lam, f, w, x = (contact[k] for k in ("sol", "lam", "f", "w", "x"))
    # Residual of the displacement actually returned, under the contact load it carries.
    residual = max(system.residual(x, system.G.T @ f), compliance["residual"])
    # (the order of these products decides the last bit of F, and a force given back from
    # it designs the flat mesh of a round trip: kept as it was)
    force = 2.0 * math.pi * float(np.sum(f)) * E_ref * ell**2
    n_top = system.contact_lines[0]  # the pillar top's (or the flat's) P2 points
    r_top, nv_top = system.contact_r[:n_top], n_top // 2 + 1
    r_vertex = r_top[::2]
    pressure = lam[:nv_top] * E_ref
    a, reaches_end = contact_radius(r_top, lam[:nv_top], w[:n_top])
    a *= ell
    area = math.pi * a * a
    penetration = float(max(0.0, -w.min()) / (zeta / ell))
    end = (f"contact reached the end of the candidate zone r = {contact['r_m'][-1]:g} m "
           f"({HERTZ_CANDIDATE} Hertz radii)") if scene.is_flat and reaches_end else ""
    floor = {"floor_force_N": 0.0, "floor_contact_area_m2": 0.0, "floor_contact_radius_m": 0.0}
    if setup["floor"]:
        r_floor = system.contact_r[n_top:]
        inner, outer = annulus_edges(r_floor, lam[nv_top:], w[n_top:])
        floor = {"floor_force_N": 2.0 * math.pi * float(np.sum(f[n_top:])) * E_ref * ell**2,
                 "floor_contact_area_m2": math.pi * (outer * outer - inner * inner) * ell**2,
                 "floor_contact_radius_m": outer * ell}
        if outer > 0.0:
            a = outer * ell
            area += floor["floor_contact_area_m2"]
        if outer >= r_floor[-1]:
            end = (f"the floor contact reached the end of its candidate zone r = "
                   f"{r_floor[-1] * ell:g} m")
    failures = verdict([force, a, pressure[0], residual, sol.residual, *lam * E_ref],
                       residual, sol, force, zeta, penetration, end)
    pillar_force = force - floor["floor_force_N"]
    diagnostics = {
        "compliance_asymmetry": compliance["asymmetry"], "active_set_rounds": sol.iterations,
        "contact_points": int(len(f)), "points_in_contact": int(np.sum(lam > 0)),
        "displacement_dofs": int(system.basis_u.N),
        "mesh_min_angle_deg": mesh.min_angle_deg(),
    }
    if setup["rigid_pillar_on_substrate"]:
        diagnostics["pillar_translation_m"] = float(x[-1] * ell)
    if not scene.is_flat:
        diagnostics.update(side_wall_diagnostics(
            tuple(v * ell for v in lens_in_side_wall(scene, setup, system, x)),
            scene.pillars.height_m))
    floor_fields = {}
    if setup["floor"]:
        floor_fields = {"floor_r_m": system.contact_r[n_top::2] * ell,
                        "floor_pressure_Pa": lam[nv_top:] * E_ref}
    return fem_result(
        MODEL, scene, clock, failures, mesh=mesh, system=system, mesh_size=mesh_size,
        block_size_m=setup["geometry"].block_size_m, ell=ell, E_ref=E_ref, residual=residual,
        contact_residual=sol.residual, penetration=penetration, force=force,
        centre_pressure=float(pressure[0]), contact_radius_m=a, area=area,
        pillar_forces=[] if scene.is_flat or pillar_force <= 0.0
        else [PillarForce(0, 0, 0.0, 0.0, pillar_force)],
        iterations=sol.iterations,
        profile={"r_m": (r_vertex * ell).tolist(), "pressure_Pa": pressure.tolist()},
        fields={"pressure_r_m": r_vertex * ell, "contact_pressure_Pa": pressure,
                "gap_r_m": contact["r_m"], "gap_m": w * ell,
                "contact_force_N_per_rad": f * E_ref * ell**2,
                "mortar_compliance": compliance["C"], **floor_fields},
        discretisation={}, diagnostics=diagnostics, floor=floor)


def _write_fields(vtu_path, scene: Scene, setup: dict, mesh, system, x, result) -> None:
    """Displacement (m) and stresses (Pa) as VTU, with the lens translation removed."""
    ell, zeta = setup["ell"], scene.indentation_m
    u, p_body = system.full(x)
    if "lens" in setup["materials"]:
        lens_z = system.basis_u.get_dofs(elements="lens").all("u^2")
        u[lens_z] -= zeta / ell  # the lens translation, removed by superposition
    vertex = system.basis_u.nodal_dofs
    cells = cell_stresses(system, u, p_body, setup["E_ref"])
    write_vtu(vtu_path, mesh, u[vertex] * ell, cells,
              {"model": MODEL, "scene": result.scene, "discretisation": result.discretisation,
               "indentation_m": result.indentation_m})


def _beyond_one_pillar(scene: Scene) -> str:
    """Why ``scene`` (at its indentation) is beyond the one pillar this model holds, or ''."""
    phi, phi_s = scene.pillars.surface_fraction, analytic.single_pillar_threshold_rim(scene)
    if phi < phi_s:
        return ""
    return (f"pillars.surface_fraction = {phi:.4g} >= Phi_S = {phi_s:.4g}: the lens, pushed "
            "by the centre pillar's flat-punch field, reaches the rim of the next ring; the "
            "axisymmetric FEM holds the centre pillar only (use fem-3d, the lattice's 3D FEM, or "
            "the BEM, or lower Phi)")


def _setup(scene: Scene, mesh_size: float, block_factor: float, scope: bool = True) -> dict:
    """Geometry, units, meshed bodies and constraints for ``scene`` (``scope``: refuse a
    second pillar in reach at the scene's indentation; the mesh of one pillar does not depend
    on it)."""
    lens, sub = scene.lens.material, scene.substrate
    if scene.is_flat:
        ell, candidate = flat_candidate(scene)
        geometry = flat_geometry(
            ell, block_factor * ell, candidate_radius_m=candidate, mesh_size=mesh_size,
            bodies=[b for b, m in (("lens", lens), ("substrate", sub)) if not m.rigid])
        pillar = None
        contact: tuple[tuple[str | None, str | None], ...]
        contact = (("contact_lens" if not lens.rigid else None,
                    "contact_substrate" if not sub.rigid else None),)
    else:
        p = scene.pillars
        if scope:
            problem = _beyond_one_pillar(scene)
            if problem:
                raise ScopeError(problem)
        pillar = p.material
        refuse_rigid_pair(lens, pillar, "a rigid pillar")
        ell = 0.5 * p.diameter_m
        bodies = tuple(b for b, m in (("lens", lens), ("pillar", pillar), ("substrate", sub))
                       if not m.rigid)
        floor = floor_candidate(scene, scene.indentation_m)
        geometry = pillar_geometry(p.diameter_m, p.height_m, block_factor * ell,
                                   bodies=bodies, mesh_size=mesh_size, floor_radius_m=floor)
        lower = ("contact_pillar" if not pillar.rigid
                 else "rigid-translation" if not sub.rigid else None)
        contact = (("contact_lens" if not lens.rigid else None, lower),)
        if floor is not None:
            if lens.rigid and sub.rigid:
                raise ScopeError("lens.rigid and substrate.rigid are both true: a rigid lens "
                                 "reaching a rigid floor has no contact pressure to compute")
            contact += (("contact_lens_floor" if not lens.rigid else None,
                         "contact_floor" if not sub.rigid else None),)
    E_ref, materials = scaled_materials(lens, pillar, sub, geometry.bodies)
    return {"geometry": geometry, "ell": ell, "E_ref": E_ref, "materials": materials,
            "contact": contact, "floor": len(contact) > 1,
            "rigid_pillar_on_substrate": bool(pillar is not None and pillar.rigid
                                              and not sub.rigid),
            "clamp_pillar_base": bool(pillar is not None and not pillar.rigid and sub.rigid)}

