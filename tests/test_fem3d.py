"""Verification of the 3D FEM reference (fem-3d): closed forms, the axisymmetric FEM, the
dense BEM on rigid pillars, symmetry, incompressibility and stiffness extremes.

Tolerances are named by their source and set from measurements on this machine (gmsh 4.15,
scikit-fem 12, MKL PARDISO), each a few times the measured value:

- RTOL_SOLVER: PARDISO residual after refinement (measured <= 2e-13) and the min-map
  complementarity residual (stops at 1e-8 zeta).
- Hertz, mesh_size 1 (8 elements across a): force +0.18 %, centre pressure +0.43 %,
  contact radius -0.23 % (measured).  A coarse mesh is stiffer (force and pressure high).
- Single pillar against fem-axisym (mesh_size 0.5), measured at mesh_size 2 / 1.41 / 1 /
  0.71: force +0.62 / +0.38 / +0.22 / +0.11 %, centre pressure -0.54 / +0.38 / +0.03 /
  -0.04 %.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from fem_reference import axisym, solid3d
from fem_reference.solid3d.system import mirror_normals, rigid_modes
from pillar_xval.scenes import ScopeError, analytic, load_scene

RTOL_SOLVER = 1e-8
RTOL_HERTZ_FORCE = 1e-2      # mesh_size 1 (measured +1.8e-3)
RTOL_HERTZ_CENTRE = 1.5e-2   # measured +4.3e-3
RTOL_HERTZ_RADIUS = 1e-2     # measured -2.3e-3
RTOL_AXISYM_COARSE = 2e-2    # single pillar at mesh_size 2 (measured 6.2e-3 and 5.4e-3)
RTOL_SYMMETRY = 1.5e-2       # two independent meshes at mesh_size 2 (measured <= 8.2e-3)
RTOL_EQUIVALENT = 6e-3       # D6-equivalent pillars in one sector (measured 2.8e-3)
# A float32 factor refined against the float64 one (E_p = 100 E_l): the contact CG stops at
# another point within its tolerance (min-map 1e-8 zeta); F_T measured 1.8e-9, the pointwise
# sigma0 9.4e-7 (as between two CG paths in validation/bench/measured/fem3d_ab.md: 8.6e-7).
RTOL_REFINED_FORCE = 1e-8
RTOL_REFINED_CENTRE = 5e-6


def assert_verified(result):
    d = result.diagnostics
    assert result.converged, d["message"]
    assert d["linear_residual"] < RTOL_SOLVER
    assert d["contact_residual"] < RTOL_SOLVER
    assert d["operator_asymmetry"] < 1e-10


# --- building blocks ------------------------------------------------------------------
def test_rigid_modes_respect_the_mirrors():
    alpha = math.pi / 6
    assert rigid_modes((3.0, 1.0), alpha, 1e-9).shape == (6, 6)   # off both planes
    m0 = rigid_modes((3.0, 0.0), alpha, 1e-9)                     # on theta = 0
    assert m0.shape == (6, 3)
    # invariant motions: t in the plane (t_y = 0), rotation about the normal (w_x = w_z = 0)
    np.testing.assert_allclose(m0[[1, 3, 5]], 0.0, atol=1e-12)
    c = (math.cos(alpha), math.sin(alpha))
    m1 = rigid_modes(c, alpha, 1e-9)                               # on theta = pi/6
    n = mirror_normals(alpha)["mirror_1"]
    np.testing.assert_allclose(n @ m1[:3], 0.0, atol=1e-12)       # no translation across it
    centre = rigid_modes((0.0, 0.0), alpha, 1e-9)
    assert centre.shape == (6, 1) and abs(centre[2, 0]) == pytest.approx(1.0)  # t_z only


def test_skew_roller_is_exact():
    """Every reduced vector gives u . n = 0 on both mirror planes (a transform, not a
    penalty), and u_z = 0 on the far faces."""
    from fem_reference.solid3d.driver import _setup
    from fem_reference.solid3d.system import assemble_sector
    from meshes import build_wedge_mesh

    scene = load_scene("single-pillar")
    setup = _setup(scene, 2.0, math.pi / 6, 1e3, 1.0, {})
    mesh = build_wedge_mesh(setup["geometry"]).to_skfem().scaled([0.5e6] * 3)
    system = assemble_sector(mesh, setup["materials"], sector_angle=math.pi / 6,
                             clamp_pillar_base=False, rigid_pillars=[])
    rng = np.random.default_rng(7)
    u = (system.T @ rng.standard_normal(system.n_reduced))[:system.basis_u.N].reshape(-1, 3).T
    sb = system.basis_s
    for name, n in mirror_normals(math.pi / 6).items():
        nodes = np.unique(sb.get_dofs(name).all())
        assert len(nodes) > 100
        assert np.max(np.abs(n @ u[:, nodes])) < 1e-14
        # the tangential in-plane motion is free (not over-constrained)
        assert np.max(np.abs(u[:2, nodes])) > 0.1
    far = np.unique(sb.get_dofs("far_lens").all())
    assert np.max(np.abs(u[2, far])) == 0.0


# --- closed forms ---------------------------------------------------------------------
def test_hertz_coarse():
    scene = load_scene("hertz", ["load.indentation_um=0.005"])
    ref = analytic.hertz(scene)
    res = solid3d.solve(scene, 1.0)
    assert_verified(res)
    assert res.total_force_N == pytest.approx(ref.force, rel=RTOL_HERTZ_FORCE)
    assert res.centre_pressure_Pa == pytest.approx(ref.centre_pressure, rel=RTOL_HERTZ_CENTRE)
    assert res.contact_radius_m == pytest.approx(ref.contact_radius, rel=RTOL_HERTZ_RADIUS)
    assert res.pillars_in_contact == 0 and res.pillar_forces == []
    assert res.diagnostics["truncation_estimate"] < 1e-4


# --- the axisymmetric FEM -----------------------------------------------------------------
def test_single_pillar_against_axisymmetric_coarse():
    scene = load_scene("single-pillar")
    ax = axisym.solve(scene)
    res = solid3d.solve(scene, 2.0)
    assert_verified(res)
    assert res.total_force_N == pytest.approx(ax.total_force_N, rel=RTOL_AXISYM_COARSE)
    assert res.centre_pressure_Pa == pytest.approx(ax.centre_pressure_Pa,
                                                   rel=RTOL_AXISYM_COARSE)
    assert res.pillars_in_contact == 1
    history = res.fields["residual_history"]
    assert len(history) == res.iterations + 1 and history[-1] < RTOL_SOLVER
    assert history[len(history) // 2] < 1e-3 * history[0]  # falls steadily, no stagnation
    (p,) = res.pillar_forces
    assert (p.n, p.m) == (0, 0) and p.force_N == pytest.approx(res.total_force_N, rel=1e-12)
    # both profiles run from the axis to the rim and agree at the axis
    for prof in (res.pillar_top_profile, res.diagnostics["pillar_top_profile_alpha"]):
        r = np.array(prof["r_m"])
        assert r[0] == 0.0 and r[-1] == pytest.approx(scene.pillars.diameter_m / 2)
        assert np.all(np.diff(r) > 0) and np.all(np.array(prof["pressure_Pa"]) >= 0)
        assert prof["pressure_Pa"][0] == res.centre_pressure_Pa


def test_rigid_lens_against_axisymmetric():
    """A rigid lens (not meshed: the contact faces are the pillar top's alone) on an elastic
    pillar and substrate, against fem-axisym."""
    scene = load_scene("single-pillar", ["lens.rigid=true"])
    ax = axisym.solve(scene)
    res = solid3d.solve(scene, 2.0)
    assert_verified(res)
    assert res.total_force_N == pytest.approx(ax.total_force_N, rel=RTOL_AXISYM_COARSE)


def test_incompressible_limit_is_continuous():
    """nu = 0.5 (exact, no 1/lambda) against 0.4999: the compliance changes by
    d gamma / gamma = 2 nu dnu / (1 - nu^2) = 1.3e-4; a locking element would be ~30 % stiff."""
    base = ["pillars.surface_fraction=1e-7"]
    f = {}
    for nu in (0.5, 0.4999):
        scene = load_scene("single-pillar", [*base, f"lens.nu={nu}", f"pillars.nu={nu}"])
        res = solid3d.solve(scene, 2.0)
        assert_verified(res)
        f[nu] = res.total_force_N
    change = f[0.4999] / f[0.5] - 1
    assert -5e-4 < change < 0.0


def test_stiffness_extremes_and_monotone_force():
    """E_p / E_l = 1e-3 and 1e6 (E_s = E_p) converge, are finite, agree with fem-axisym
    (measured +0.63 % and +0.81 % at mesh_size 2), and F_T rises with E_p."""
    forces = {}
    for ratio in (1e-3, 1.0, 1e6):
        scene = load_scene("single-pillar", [f"pillars.E_Pa={ratio * 1.6e6}"])
        res = solid3d.solve(scene, 2.0)
        assert_verified(res)
        assert all(math.isfinite(v) for v in res.pillar_top_profile["pressure_Pa"])
        forces[ratio] = res.total_force_N
        if ratio != 1.0:
            ax = axisym.solve(scene)
            assert res.total_force_N == pytest.approx(ax.total_force_N, rel=RTOL_AXISYM_COARSE)
    assert forces[1e-3] < forces[1.0] < forces[1e6]


def test_a_float32_factor_within_its_bound_refines_to_the_float64_answer(monkeypatch):
    """Single pillar with E_p = 100 E_l at mesh_size 2: the float32 solve's error (measured
    2.4e-4) lies within SINGLE_MAX_ERROR, so the factor stays float32, and its refined
    solution gives the float64 factor's answers (forced by a zero bound) within the CG's
    tolerance (RTOL_REFINED_FORCE, RTOL_REFINED_CENTRE)."""
    from fem_reference.solid3d import system

    scene = load_scene("single-pillar", [f"pillars.E_Pa={100 * 1.6e6}"])
    single = solid3d.solve(scene, 2.0)
    factor = single.diagnostics["factor"]
    assert factor["precision"] == "single" and factor["ordering"] == "given"
    assert 1e-4 < factor["single_solve_error"] <= system.SINGLE_MAX_ERROR
    assert_verified(single)
    assert single.diagnostics["linear_residual"] < 1e-12
    monkeypatch.setattr(system, "SINGLE_MAX_ERROR", 0.0)
    double = solid3d.solve(scene, 2.0)
    assert double.diagnostics["factor"]["precision"] == "double"
    assert single.total_force_N == pytest.approx(double.total_force_N, rel=RTOL_REFINED_FORCE)
    assert single.centre_pressure_Pa == pytest.approx(double.centre_pressure_Pa,
                                                      rel=RTOL_REFINED_CENTRE)


# --- result, files, refusals --------------------------------------------------------------
def test_result_schema_and_vtu(tmp_path):
    import meshio

    scene = load_scene("single-pillar")
    lines = []
    res = solid3d.solve(scene, 2.0, vtu_path=tmp_path / "fem3d.vtu", progress=lines.append)
    assert res.model == "fem-3d"
    assert {"mesh_size", "dofs", "elements", "block_size_m"} <= set(res.discretisation)
    assert any("factorising" in t for t in lines) and any("contact" in t for t in lines)
    doc = json.loads(res.to_json())
    assert set(doc["diagnostics"]["time_s"]) == {"mesh", "assemble", "factorise", "contact",
                                                 "post"}
    vtu = meshio.read(tmp_path / "fem3d.vtu")
    disp = vtu.point_data["displacement_m"]
    assert disp.shape[1] == 3 and disp[:, 2].min() == pytest.approx(-scene.indentation_m,
                                                                     rel=1e-9)
    for name in ("von_mises_Pa", "sigma_zz_Pa", "mean_stress_Pa", "body"):
        assert np.all(np.isfinite(vtu.cell_data[name][0]))
    pillar = vtu.cell_data["body"][0] == 1
    assert np.mean(vtu.cell_data["sigma_zz_Pa"][0][pillar]) < 0
    meta = json.loads((tmp_path / "fem3d.json").read_text())
    assert meta["model"] == "fem-3d" and meta["discretisation"]["dofs"] > 0


@pytest.mark.parametrize("kwargs, match", [
    (dict(mesh_size=0.0), "mesh_size"), (dict(mesh_size=float("nan")), "mesh_size"),
    (dict(sector_angle=1.0), "sector_angle"), (dict(reach_factor=0.5), "reach_factor"),
])
def test_bad_options_are_refused_clearly(kwargs, match):
    from pillar_xval.scenes import InputError

    with pytest.raises(InputError, match=match):
        solid3d.solve(load_scene("single-pillar"), **kwargs)


def test_hertz_on_a_rigid_substrate():
    """Only the lens is meshed: F = Hertz with gamma_l alone (closed form)."""
    scene = load_scene("hertz", ["load.indentation_um=0.005", "substrate.rigid=true"])
    res = solid3d.solve(scene, 1.0)
    assert_verified(res)
    assert res.total_force_N == pytest.approx(analytic.hertz(scene).force, rel=RTOL_HERTZ_FORCE)


def test_rigid_pillar_on_elastic_substrate_is_two_springs_in_series():
    """A rigid pillar bonded to an elastic substrate moves as one rigid body (its rigid
    motion unknowns, reduced to t_z by the two mirrors): with nu = 0.5 a bonded rigid punch
    acts like a frictionless one, so F = d zeta / (gamma_l + gamma_s) exactly.  Tolerance:
    the mesh_size 2 discretisation (fem-axisym reaches 1e-4 at its finest)."""
    scene = load_scene("single-pillar", ["pillars.rigid=true", "lens.radius_mm=1e5",
                                         "pillars.surface_fraction=1e-7",
                                         "substrate.E_Pa=6.4e6", "substrate.nu=0.5"])
    gl, gs = scene.lens.material.compliance, scene.substrate.compliance
    res = solid3d.solve(scene, 2.0)
    assert_verified(res)
    d, zeta = scene.pillars.diameter_m, scene.indentation_m
    assert res.total_force_N == pytest.approx(d * zeta / (gl + gs), rel=RTOL_AXISYM_COARSE)


def test_close_packing_is_refused():
    with pytest.raises(ScopeError, match="surface_fraction"):
        solid3d.solve(load_scene("paper-fig3-dense", ["pillars.surface_fraction=0.9068"]))


def test_rigid_lens_on_rigid_pillars_is_refused():
    scene = load_scene("single-pillar", ["lens.rigid=true", "pillars.rigid=true",
                                         "substrate.E_Pa=1.6e6", "substrate.nu=0.5"])
    with pytest.raises(ScopeError, match="rigid"):
        solid3d.solve(scene)


# --- symmetry -------------------------------------------------------------------------------
SMALL_LATTICE = ["pillars.surface_fraction=0.05", "load.indentation_um=0.1",
                 "substrate.E_Pa=1.6e6"]  # centre pillar and ring 1 within reach


def same_forces_in_wedge_and_quadrant(scene, mesh_size):
    """Solve on the pi/6 wedge and on the quadrant; assert the same 7 pillars carry the same
    forces within RTOL_SYMMETRY; return both results and the quadrant's forces by (n, m)."""
    wedge = solid3d.solve(scene, mesh_size)
    quad = solid3d.solve(scene, mesh_size, sector_angle=math.pi / 2)
    for res in (wedge, quad):
        assert_verified(res)
    fw = {(p.n, p.m): p.force_N for p in wedge.pillar_forces}
    fq = {(p.n, p.m): p.force_N for p in quad.pillar_forces}
    assert set(fw) == set(fq) and len(fw) == 7
    for key, f in fw.items():
        assert fq[key] == pytest.approx(f, rel=RTOL_SYMMETRY), key
    return wedge, quad, fq


def test_wedge_against_quadrant():
    """The pi/6 wedge (skew mirror plane) and the quadrant (two axis-aligned mirror planes,
    3x the volume, independent meshes) give the same per-pillar forces; in the quadrant the
    D6-equivalent pillars (1, 0) (halved by a plane) and (1, 1) (whole) are solved
    independently and must agree.  Tolerance: the discretisation error at mesh_size 2
    (0.6 % on the single pillar against fem-axisym); measured differences: pillar forces
    +0.55..0.82 %, F_T +0.68 % (the quadrant mesh is finer near the axis), (1, 1) against
    (1, 0) in the quadrant +0.28 %.  A wrong skew roller moves forces by many per cent."""
    scene = load_scene("paper-fig3-sparse", SMALL_LATTICE)
    wedge, quad, fq = same_forces_in_wedge_and_quadrant(scene, 2.0)
    assert fq[(1, 1)] == pytest.approx(fq[(1, 0)], rel=RTOL_EQUIVALENT)
    assert quad.total_force_N == pytest.approx(wedge.total_force_N, rel=RTOL_SYMMETRY)


@pytest.mark.slow
def test_rigid_pillars_tilt_the_same_in_wedge_and_quadrant():
    """Rigid pillars bonded to an elastic substrate move with their rigid motions (6 off the
    mirror planes, 3 on one, 1 at the centre): the off-centre pillars tilt.  The wedge and
    the quadrant reduce the motions with different planes and must give the same forces.
    Measured differences at mesh_size 2.83 / 2 / 1.41: <= 1.8 / 0.94 / 0.35 % (shrinking
    with the mesh: the rigid edges' r^-1/2 singularity is resolved better by the quadrant's
    mesh near the axis), so RTOL_SYMMETRY at mesh_size 2."""
    scene = load_scene("paper-fig3-sparse", [*SMALL_LATTICE[:2], "pillars.rigid=true",
                                             "substrate.E_Pa=1.6e6", "substrate.nu=0.5"])
    same_forces_in_wedge_and_quadrant(scene, 2.0)


# --- slow: convergence and cross-checks ------------------------------------------------------
def observed_order(sizes, errors):
    """Slope of log|error| against log(mesh size), least squares."""
    return np.polyfit(np.log(sizes), np.log(np.abs(errors)), 1)[0]


@pytest.mark.slow
def test_hertz_converges_at_a_rate():
    """Four levels, ratio sqrt(2): measured force errors +0.70, +0.41, +0.18, +0.045 %
    (fitted order 2.6; truncation 4e-5 at L = 1e4 a), centre pressure +2.2 .. +0.15 %."""
    scene = load_scene("hertz", ["load.indentation_um=0.005"])
    ref = analytic.hertz(scene)
    sizes = [2.0, 1.41, 1.0, 0.71]
    results = [solid3d.solve(scene, s) for s in sizes]
    for res in results:
        assert_verified(res)
    force = [r.total_force_N / ref.force - 1 for r in results]
    centre = [r.centre_pressure_Pa / ref.centre_pressure - 1 for r in results]
    assert 1.8 < observed_order(sizes, force) < 3.5, force
    assert all(f > 0 for f in force)  # a conforming mesh is stiff
    assert abs(force[-1]) < 1e-3 and abs(centre[-1]) < 4e-3


@pytest.mark.slow
def test_single_pillar_agrees_with_axisymmetric_within_gcis():
    """F_T and sigma0 of fem-3d (mesh_size 1.41, 1, 0.71) and fem-axisym (2, 1, 0.5) agree
    within the sum of their GCIs (Roache; validation.verification), each GCI with the
    observed order capped at the formal order 2 (Roache's advice: an observed order above
    the formal one, here 4.4 for the 3D sigma0, a single vertex value at the wedge apex,
    makes the GCI over-optimistic).  Measured against fem-axisym at 0.5: F_T +0.38, +0.22,
    +0.11 %; sigma0 +0.38, +0.03, -0.04 %."""
    scene = load_scene("single-pillar")
    s3 = [0.71, 1.0, 1.41]
    r3 = [solid3d.solve(scene, s) for s in s3]
    sa = [0.5, 1.0, 2.0]
    ra = [axisym.solve(scene, s) for s in sa]
    for get in (lambda r: r.total_force_N, lambda r: r.centre_pressure_Pa):
        band = (capped_gci(s3, [get(r) for r in r3]) + capped_gci(sa, [get(r) for r in ra]))
        assert abs(get(r3[0]) - get(ra[0])) <= band
        assert band < 0.01 * abs(get(ra[0]))  # the check has teeth: bands below 1 %


FORMAL_ORDER = 2.0


def capped_gci(h, f) -> float:
    """Uncertainty (unit of f) of the finest of three solutions: the GCI with the observed
    order capped at FORMAL_ORDER, or the conservative fallback when no order is observed."""
    from validation.analysis.verification import FS_THREE_GRIDS, gci_three, gci_two

    g = gci_three(h, f)
    if g.order is None:
        return g.fallback_uncertainty
    return gci_two(h[:2], f[:2], min(g.order, FORMAL_ORDER), fs=FS_THREE_GRIDS).uncertainty


@pytest.mark.slow
def test_rigid_pillars_against_dense_bem():
    """Rigid pillars on a rigid substrate: the elastic lens alone, a half-space in the BEM
    and a large graded block in the FEM, so the two models solve the same equations and
    their Richardson estimates of F_T must agree within the two GCIs (plus the FEM block's
    truncation estimate)."""
    from bem_solver import solve_dense
    from validation.analysis.verification import gci_three

    scene = load_scene("paper-fig3-sparse", [*SMALL_LATTICE[:2], "pillars.rigid=true",
                                             "substrate.rigid=true"])
    P = [29, 21, 15]
    bem = [solve_dense(scene, p) for p in P]
    s3 = [1.0, 1.41, 2.0]
    fem = [solid3d.solve(scene, s) for s in s3]
    for res in fem:
        assert_verified(res)
    gb = gci_three([1.0 / p for p in P], [r.total_force_N for r in bem])
    gf = gci_three(s3, [r.total_force_N for r in fem])
    fb = gb.f_exact if gb.f_exact is not None else bem[0].total_force_N
    ff = gf.f_exact if gf.f_exact is not None else fem[0].total_force_N
    band = (gb.fallback_uncertainty + gf.fallback_uncertainty
            + fem[0].diagnostics["truncation_estimate"] * ff)
    assert abs(ff - fb) <= band, (gb, gf)
    assert fem[0].pillars_in_contact == bem[0].pillars_in_contact == 7


@pytest.mark.slow
def test_unloaded_pillars_change_little():
    """Meshing the pillars out to twice the reach of the undeformed lens (unloaded ones)
    changes F_T by less than the discretisation error (measured -0.069 % at mesh_size 2 with
    reach_factor 3: 4 pillars of the wedge meshed instead of 2, the same 7 in contact)."""
    scene = load_scene("paper-fig3-sparse", SMALL_LATTICE)
    base = solid3d.solve(scene, 2.0)
    wide = solid3d.solve(scene, 2.0, reach_factor=3.0)
    assert len(wide.diagnostics["pillars_meshed"]) > len(base.diagnostics["pillars_meshed"])
    assert wide.pillars_in_contact == base.pillars_in_contact
    assert wide.total_force_N == pytest.approx(base.total_force_N, rel=2e-3)


@pytest.mark.parametrize("chunk", [None, 7])
def test_closed_form_assembly_equals_the_forms(chunk, monkeypatch):
    """The vectorised element integrals (forms.tet_p2) summed by the assembler equal skfem's
    assembly of the forms of forms.solid3d (shear stiffness, divergence coupling, pressure
    mass) on a distorted mesh of two bodies with their own moduli, to round-off (measured
    7e-16 of the largest entry); in one block of elements and in blocks of 7 (the reused
    buffers, a partial last block)."""
    from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector, MeshTet

    from fem_reference.forms.solid3d import divergence_coupling, pressure_mass, shear_stiffness
    from fem_reference.solid3d import system
    from fem_reference.solid3d.system import PressureSpace3D, _vector_csr, assemble_blocks

    if chunk is not None:
        monkeypatch.setattr(system, "CHUNK", chunk)

    mesh = MeshTet().refined(2)
    inner = (mesh.p > 0) & (mesh.p < 1)  # move the interior nodes: general tetrahedra
    shift = 0.02 * np.random.default_rng(0).standard_normal(mesh.p.shape) * inner
    mesh = MeshTet(mesh.p + shift, mesh.t)
    low = mesh.p[2, mesh.t].mean(axis=0) < 0.5
    mesh = mesh.with_subdomains({"a": np.nonzero(~low)[0], "b": np.nonzero(low)[0]})
    spaces = [PressureSpace3D(body, Basis(mesh, ElementTetP1(), elements=mesh.subdomains[body],
                                          intorder=2),
                              np.unique(mesh.t[:, mesh.subdomains[body]]), 1.0, mu, 0)
              for body, mu in (("a", 1.3), ("b", 0.7))]
    sb = Basis(mesh, ElementTetP2())
    (row, col, blocks), B, M = assemble_blocks(mesh, sb, spaces)
    A = _vector_csr(row, col, blocks, sb.N)
    A_ref = 0
    for ps, B_b, M_b in zip(spaces, B, M):
        ub = Basis(mesh, ElementVector(ElementTetP2()), elements=mesh.subdomains[ps.body],
                   intorder=2)
        A_ref = A_ref + shear_stiffness.assemble(ub, mu=ps.mu)
        B_ref = divergence_coupling.assemble(ub, ps.basis).tocsr()[ps.dofs]
        M_ref = pressure_mass.assemble(ps.basis).tocsr()[ps.dofs][:, ps.dofs]
        assert abs(B_b - B_ref).max() < 1e-14 * abs(B_ref).max()
        assert abs(M_b - M_ref).max() < 1e-14 * abs(M_ref).max()
    assert abs(A - A_ref).max() < 1e-14 * abs(A_ref).max()
    assert all(np.all(np.diff(A.indices[A.indptr[k]:A.indptr[k + 1]]) > 0)  # sorted, as said
               for k in range(A.shape[0]))


def test_the_element_products_run_on_one_blas_thread(monkeypatch):
    """assemble_blocks holds BLAS to one thread for the element blocks' products (bound by
    memory: two threads cost more than they gained), inside a solve's count of two, which
    comes back after it."""
    from skfem import Basis, ElementTetP1, ElementTetP2, MeshTet
    from threadpoolctl import ThreadpoolController

    from fem_reference.forms import tet_p2
    from fem_reference.solid3d.system import PressureSpace3D, assemble_blocks
    from pillar_xval.threads import limited

    def blas_threads():
        return {c.num_threads for c in
                ThreadpoolController().select(user_api="blas").lib_controllers}

    seen = []
    products = tet_p2.elasticity_blocks

    def spy(*args, **kwargs):
        seen.append(blas_threads())
        return products(*args, **kwargs)

    monkeypatch.setattr(tet_p2, "elasticity_blocks", spy)
    mesh = MeshTet().refined(1)
    space = PressureSpace3D("all", Basis(mesh, ElementTetP1(), intorder=2),
                            np.arange(mesh.p.shape[1]), 1.0, 1.0, 0)
    mesh = mesh.with_subdomains({"all": np.arange(mesh.t.shape[1])})
    with limited(2):
        assemble_blocks(mesh, Basis(mesh, ElementTetP2()), [space])
        assert seen == [{1}] and blas_threads() == {2}


def test_stack_csr_writes_scipys_arrays(monkeypatch):
    """system.stack_csr, the reduced matrix's block layout written once, gives the arrays of
    scipy's vstack of hstacks bit for bit (data, indices, row pointers, dtypes), over several
    passes of rows, with an empty row and an empty block."""
    import scipy.sparse as sp

    from fem_reference.solid3d import system

    rng = np.random.default_rng(1)

    def block(m, n, density):
        return sp.random(m, n, density=density, format="csr", random_state=rng)

    uu, up, pu = block(30, 30, 0.2), block(30, 7, 0.3), block(7, 30, 0.3)
    uu = sp.csr_matrix(uu.multiply(np.arange(30)[:, None] != 4))  # row 4 empty on the left
    uu.eliminate_zeros()
    up = sp.csr_matrix(up.multiply(np.arange(30)[:, None] != 4))
    up.eliminate_zeros()
    pp = sp.csr_matrix((7, 7))
    monkeypatch.setattr(system, "STACK_ROWS", 4)
    got = system.stack_csr(((uu, up), (pu, pp)))
    ref = sp.vstack([sp.hstack([uu, up], format="csr"), sp.hstack([pu, pp], format="csr")],
                    format="csr")
    assert got.shape == ref.shape and np.diff(got.indptr)[4] == 0
    for name in ("data", "indices", "indptr"):
        a, b = getattr(got, name), getattr(ref, name)
        assert a.dtype == b.dtype and np.array_equal(a, b)


def test_the_elimination_order_follows_the_vertices():
    """system.elimination_order on a two-body mesh: every reduced unknown once; each edge
    node's unknowns after the displacements of the edge's end ordered first and before that
    vertex's pressure in each body (the order that adds no fill and gives every pressure
    pivot its displacements' Schur complement); the vertices in METIS's order."""
    from skfem import MeshTet

    from fem_reference.forms.tet_p2 import EDGES
    from fem_reference.solid3d.system import assemble_sector, elimination_order

    mesh = MeshTet().refined(2)
    low = mesh.p[2, mesh.t].mean(axis=0) < 0.5
    mesh = mesh.with_subdomains({"a": np.nonzero(~low)[0], "b": np.nonzero(low)[0]})
    mesh = mesh.with_boundaries({"far_substrate": lambda x: np.isclose(x[2], 0.0)})
    system = assemble_sector(mesh, {"a": (1.0, 0.3), "b": (2.0, 0.45)},
                             sector_angle=math.pi / 6, clamp_pillar_base=False,
                             rigid_pillars=[])
    n_p = sum(len(ps.dofs) for ps in system.pressures)
    order = elimination_order(system.mesh, system.basis_s, system.nodes, n_p)
    n = len(system.nodes)
    assert np.array_equal(np.sort(order), np.arange(n))
    place = np.empty(n, dtype=np.int64)
    place[order] = np.arange(n)
    pressure = np.arange(n) >= n - n_p
    first_u = np.full(system.basis_s.N, n)  # each node's first and last place
    last_u, last_p = np.full(system.basis_s.N, -1), np.full(system.basis_s.N, -1)
    np.minimum.at(first_u, system.nodes[~pressure], place[~pressure])
    np.maximum.at(last_u, system.nodes[~pressure], place[~pressure])
    np.maximum.at(last_p, system.nodes[pressure], place[pressure])
    first_p = np.full(system.basis_s.N, n)
    np.minimum.at(first_p, system.nodes[pressure], place[pressure])
    dofs = system.basis_s.element_dofs
    assert np.array_equal(dofs[:4], mesh.t)  # the vertices are the first P2 nodes
    for k, (i, j) in enumerate(EDGES):
        early = np.where(first_u[dofs[i]] < first_u[dofs[j]], dofs[i], dofs[j])
        assert np.all(first_u[dofs[4 + k]] > last_u[early])
        assert np.all(last_u[dofs[4 + k]] < first_p[early])
    # The vertices come in METIS's order of the graph of vertices sharing a tetrahedron,
    # built here from the tetrahedra's six vertex pairs.
    import scipy.sparse as sp

    from fem_reference._pardiso import metis_positions

    nv = mesh.p.shape[1]
    a, b = np.array([(i, j) for i in range(4) for j in range(i + 1, 4)]).T
    graph = sp.csr_matrix((np.ones(6 * mesh.t.shape[1]),
                           (mesh.t[a].ravel(), mesh.t[b].ravel())), shape=(nv, nv))
    assert np.array_equal(np.argsort(first_u[:nv]), np.argsort(metis_positions(graph)))


@pytest.mark.slow
def test_block_truncation_is_measured():
    """Rigid punch on the lens (only the lens meshed): the block of L = 1e2 focus radii is
    softer than the default L = 1e4 by about the a-priori estimate F gamma / (pi L zeta)
    (measured 0.80 x it at mesh_size 1.41, as in the axisymmetric model); from 1e3 to 1e5
    the force moves by <= 0.08 % (the far-field grading, not the truncation: measured
    +0.14, +0.18, +0.22 % against the closed form)."""
    scene = load_scene("single-pillar", ["pillars.rigid=true", "substrate.rigid=true",
                                         "lens.radius_mm=1e5", "pillars.surface_fraction=1e-7"])
    exact = analytic.rigid_punch(scene).force
    f = {b: solid3d.solve(scene, 1.41, block_factor=b) for b in (1e2, 1e3, 1e4, 1e5)}
    measured = f[1e2].total_force_N / f[1e4].total_force_N - 1
    estimate = f[1e2].diagnostics["truncation_estimate"]
    assert 0.5 * estimate < measured < 1.2 * estimate
    big = [f[b].total_force_N / exact - 1 for b in (1e3, 1e4, 1e5)]
    assert max(big) - min(big) < 1.5e-3 and max(abs(e) for e in big) < 5e-3


@pytest.mark.slow
def test_render_of_the_twelve_images(tmp_path):
    from validation.output.render3d import render_sector

    scene = load_scene("paper-fig3-sparse", SMALL_LATTICE)
    solid3d.solve(scene, 2.83, vtu_path=tmp_path / "sector.vtu")
    ok, message = render_sector(tmp_path / "sector.vtu", tmp_path / "disk.png")
    assert ok, message
    assert "von Mises stress (kPa)" in message
    assert (tmp_path / "disk.png").stat().st_size > 20_000


# --- memory: estimated up front, refused when it would not fit ----------------------------
def test_fem3d_memory_estimate_against_a_solve_and_refusal():
    from fem_reference import solid3d

    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2"])
    est = solid3d.estimate_memory(scene, 2.83)
    result = solid3d.solve(scene, 2.83)
    # fitted on the lattice study's sectors: within 30 % of the unknowns actually meshed
    assert est["pillars"] == len(result.diagnostics["pillars_meshed"])
    assert est["dofs"] == pytest.approx(result.discretisation["dofs"], rel=0.3)
    # a 10 m lens on the dense lattice reaches ~1e6 pillars: refused before any meshing
    huge = load_scene("paper-fig3-dense", ["lens.radius_mm=1e4"])
    with pytest.raises(ScopeError, match="mesh_size = 2.83: fem-3d would mesh"):
        solid3d.solve(huge, 2.83)


def test_a_sliver_from_gmsh_is_optimised_away():
    """A scene drawn by the planner validation (Phi = 0.1565, zeta = 0.0437 um, E_p = E_s =
    200 E_l): gmsh's mesh at mesh_size 2 held one tetrahedron of quality 0.0176 on the skew
    mirror plane, below the 0.02 floor, and fem-3d refused the scene.  A mesh below the floor
    now goes through Netgen's optimiser: every tetrahedron passes, the contact faces still
    match node for node (both checked by build_wedge_mesh), and the solve converges with a
    force within 3 % of the coarser mesh's (fem-3d's F_T step from 2.83 to 2 is 0.3-2.2 % on
    the lattice study's scenes)."""
    from meshes import MIN_QUALITY_3D, build_wedge_mesh
    from fem_reference.solid3d.driver import BLOCK_FACTOR, _setup

    scene = load_scene("paper-fig3-sparse", [
        "pillars.surface_fraction=0.1565", "load.indentation_um=0.04373",
        "pillars.E_Pa=3.2e8", "substrate.E_Pa=3.2e8"])
    setup = _setup(scene, 2.0, math.pi / 6.0, BLOCK_FACTOR, 1.0, {})
    mesh = build_wedge_mesh(setup["geometry"])
    assert mesh.quality().min() >= MIN_QUALITY_3D
    forces = []
    for mesh_size in (2.83, 2.0):
        r = solid3d.solve(scene, mesh_size)
        assert r.converged, r.diagnostics.get("message")
        forces.append(r.total_force_N)
    assert forces[1] == pytest.approx(forces[0], rel=0.03)


def test_the_refinement_starts_where_it_is_told():
    """SectorSystem.solve from a start: none of the factor's back-substitutions where the
    start already meets the residual of 1e-12 (the CG's exact solutions after the contact
    phase), one where it is 1e-6 off (a float32 factor gains three digits a step or more)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve

    from fem_reference._pardiso import Pardiso
    from fem_reference.solid3d.system import SectorSystem

    n = 300
    K = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1], format="csr")
    b = np.random.default_rng(0).standard_normal((n, 2))
    exact = np.column_stack([spsolve(K.tocsc(), c) for c in b.T])
    calls = []

    class Counted(Pardiso):
        def solve(self, rhs):
            calls.append(1)
            return super().solve(rhs)

    system = SectorSystem.__new__(SectorSystem)
    system.scale, system._Ks, system.factor = np.ones(n), K, Counted(K, single=True)
    x, rel = system.solve(b, refine=4, start=exact)
    assert not calls and rel < 1e-12 and np.allclose(x, exact, rtol=0, atol=1e-12)
    x, rel = system.solve(b, refine=4, start=exact * (1 + 1e-6))
    assert len(calls) == 1 and rel < 1e-12
