"""The elastic-pillar BEM: the pillar's compliance by Fourier modes and its use in the BEM.

The compliance runs on coarse meshes here (mesh_size 4, few modes: seconds per pillar kind),
cached once per test session in a temporary folder.  Each tolerance says where it comes from.
"""

import math

import numpy as np
import pytest

from bem_solver import expansion, full_operator, solve_dense
from bem_solver._cells import cell_pattern
from bem_solver._discretise import discretise
from bem_solver._extrapolated import solve_dense_extrapolated
from bem_solver._elastic_pillar import (excess_block, full_block, image_cells, reduced_block,
                                        scene_compliance)
from bem_solver._love import unit_force_influence
from bem_solver._operator import reduced_operator
from fem_reference import PillarKind, modal_compliance
from fem_reference.axisym import solve as solve_axisymmetric
from pillar_xval.scenes import InputError, analytic, load_scene

COARSE = {"mesh_size": 4.0}


pytestmark = pytest.mark.usefixtures("compliance_cache")


def _modal(scene, modes=2):
    return modal_compliance(PillarKind.of_scene(scene), modes, **COARSE)


def _single(*overrides):
    return load_scene("single-pillar", list(overrides))


def _cells(scene, P):
    pattern = cell_pattern(P, "covered")
    return pattern, pattern.scaled(scene.pillars.diameter_m)


@pytest.mark.parametrize("kind", [PillarKind(0.5, 1.0, 0.5, 0.5), PillarKind(1.0, 10.0, 0.3, 0.4),
                                  PillarKind(0.5, 1e-2, 0.5, 0.5)])
def test_compliance_is_reciprocal_symmetric_and_positive(kind):
    m = modal_compliance(kind, 2, **COARSE)
    # Betti: the FEM's top-to-top compliance is symmetric before any symmetrisation; the
    # solves are direct, so only round-off remains.
    assert m.diagnostics["reciprocity_asymmetry"] < 1e-9
    assert m.diagnostics["linear_residual"] < 1e-9
    for C in (*m.pillar, *m.halfspace):
        np.testing.assert_array_equal(C, C.T)
        ev = np.linalg.eigvalsh(C)
        assert ev.min() > -1e-10 * ev.max()
    # On the BEM's cells: the pillar's whole top compliance gamma_s Love + X is symmetric and
    # positive definite (X alone need not be: a stiff pillar spreads the load).
    scene = _single(f"pillars.height_um={4 * kind.height_over_diameter}",
                    f"pillars.E_Pa={1.6e6 * kind.modulus_ratio}", f"pillars.nu={kind.nu_pillar}",
                    f"substrate.nu={kind.nu_substrate}")
    _, c = _cells(scene, 9)
    X = excess_block(scene, c["x"], c["y"], c["side"], m)
    np.testing.assert_allclose(X, X.T, rtol=0, atol=1e-14 * np.abs(X).max())
    L = unit_force_influence(c["x"][:, None], c["y"][:, None], c["x"][None, :],
                             c["y"][None, :], 0.0, c["side"][None, :])
    G = X + scene.substrate.compliance / math.pi * 0.5 * (L + L.T)
    assert np.linalg.eigvalsh(G).min() > 0.0


def test_half_space_mode_zero_matches_boussinesq():
    """The half-space part under a uniform load on the top: mean displacement
    16 gamma F / (3 pi^2 a) (Johnson, Contact Mechanics, sec. 3.2).  Coarse mesh: 0.5 %."""
    m = modal_compliance(PillarKind(0.5, 1.0, 0.5, 0.5), 2, **COARSE)
    r = np.linspace(0.0, 1.0, 40001)
    mid, dr = 0.5 * (r[1:] + r[:-1]), np.diff(r)
    moments = (m.trace_basis(mid) * (mid * dr)[:, None]).sum(axis=0)  # int phi_i r dr
    u = m.halfspace[0] @ (moments / math.pi)  # unit force, E = a = 1
    mean = 2.0 * moments @ u
    assert mean == pytest.approx(16.0 * 0.75 / (3.0 * math.pi**2), rel=5e-3)


def _mean_excess_under_uniform_load(aspect):
    """Mean top displacement of the excess under a uniform load, over Hooke's shortening."""
    m = modal_compliance(PillarKind(aspect, 1.0, 0.5, 0.5), 0, **COARSE)
    r = np.linspace(0.0, 1.0, 40001)
    mid, dr = 0.5 * (r[1:] + r[:-1]), np.diff(r)
    phi = m.trace_basis(mid)
    moments = (phi * (mid * dr)[:, None]).sum(axis=0)
    u = m.excess[0] @ (moments / math.pi)
    hooke = 4.0 * (2.0 * aspect) / (math.pi * 4.0)  # 4 h / (pi d^2 E) with a = 1, E = 1
    return 2.0 * moments @ u / hooke, (phi @ u).max() / hooke, (phi @ u).min() / hooke


def test_long_pillars_tend_to_hooke():
    """The ends of a long pillar (the loaded top, the bonded base of an incompressible rod, and
    the settlement of its base against the half-space response to the same load) change the
    compliance by an amount that does not depend on h, while Hooke's grows like h: the
    relative deviation from Hooke falls like d/h.  Doubling h/d from 8 to 16 must halve it
    (within 10 %: the coarse mesh), and at h/d = 16 the mean and the spread across the top
    must lie within 1 % and 2 % of the uniform shortening."""
    mean8, hi8, lo8 = _mean_excess_under_uniform_load(8.0)
    mean16, hi16, lo16 = _mean_excess_under_uniform_load(16.0)
    assert (mean16 - 1.0) == pytest.approx(0.5 * (mean8 - 1.0), rel=0.1)
    assert (hi16 - lo16) == pytest.approx(0.5 * (hi8 - lo8), rel=0.1)
    assert abs(mean16 - 1.0) < 0.01 and hi16 - lo16 < 0.02


def test_rigid_substrate_and_stiff_pillar_give_the_rigid_hooke_bem():
    """E_p = 1e6 E_l on a rigid substrate: the pillar's compliance is 1e-6 of the lens's, so
    the elastic BEM must equal the Hooke BEM with rigid pillars to ~1e-6 (tolerance 1e-5)."""
    stiff = _single("pillars.E_Pa=1.6e12", "substrate.rigid=true")
    rigid = _single("pillars.rigid=true", "substrate.rigid=true")
    elastic = solve_dense(stiff, 11, pillars="elastic", compliance=_modal(stiff))
    hooke = solve_dense(rigid, 11)
    assert elastic.converged and hooke.converged
    assert elastic.total_force_N == pytest.approx(hooke.total_force_N, rel=1e-5)
    assert elastic.centre_pressure_Pa == pytest.approx(hooke.centre_pressure_Pa, rel=1e-5)


def test_rigid_pillar_on_elastic_substrate_moves_as_a_rigid_body():
    """A rigid pillar's top can only translate and tilt: the pillar's top compliance
    gamma_s Love + X on the cells has rank 3 (translation, two tilts).  The rigid pillar is
    modelled with E_p = 1e6 E_s, so the rest of the spectrum is the pillar's own compliance,
    1e-6 of the substrate's times the ratio of a cell's local response to the whole top's
    (a few times): bound 1e-4."""
    scene = _single("pillars.rigid=true")
    m = _modal(scene)
    _, c = _cells(scene, 9)
    X = excess_block(scene, c["x"], c["y"], c["side"], m)
    L = unit_force_influence(c["x"][:, None], c["y"][:, None], c["x"][None, :],
                             c["y"][None, :], 0.0, c["side"][None, :])
    G = X + scene.substrate.compliance / math.pi * 0.5 * (L + L.T)
    ev = np.sort(np.abs(np.linalg.eigvalsh(G)))[::-1]
    assert ev[2] > 1e-3 * ev[0]
    assert ev[3] < 1e-4 * ev[0]


def test_hooke_stays_the_default_and_bad_values_are_refused():
    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                             "load.indentation_um=0.1"])
    a, b = solve_dense(scene, 5), solve_dense(scene, 5, pillars="hooke")
    assert a.total_force_N == b.total_force_N and a.centre_pressure_Pa == b.centre_pressure_Pa
    with pytest.raises(ValueError, match="pillars = 'spring'"):
        solve_dense(scene, 5, pillars="spring")
    with pytest.raises(InputError, match="modes"):
        modal_compliance(PillarKind(1.0, 1.0, 0.5, 0.5), -1)
    with pytest.raises(InputError, match="mesh_size"):
        modal_compliance(PillarKind(1.0, 1.0, 0.5, 0.5), 2, 10.0)
    with pytest.raises(InputError, match="nu_pillar"):
        PillarKind(1.0, 1.0, 0.6, 0.5)
    # Rigid pillars on a rigid substrate have no compliance: both models coincide.
    rigid = _single("pillars.rigid=true", "substrate.rigid=true")
    assert solve_dense(rigid, 7, pillars="elastic").total_force_N == \
        solve_dense(rigid, 7).total_force_N


def test_cache_returns_the_same_operator():
    kind = PillarKind(0.5, 1.0, 0.5, 0.5)
    first, again = modal_compliance(kind, 2, **COARSE), modal_compliance(kind, 2, **COARSE)
    assert again.diagnostics["cached"]
    np.testing.assert_array_equal(first.excess, again.excess)


def test_single_pillar_dense_equals_a_direct_solve_on_the_whole_top():
    """The symmetry-reduced dense BEM against the unreduced system of the centre pillar's
    cells, solved directly (every cell is in contact): catches any frame or image error."""
    scene = _single("pillars.E_Pa=1.6e7")
    m = _modal(scene)
    P = 11
    _, c = _cells(scene, P)
    X = excess_block(scene, c["x"], c["y"], c["side"], m)
    L = unit_force_influence(c["x"][:, None], c["y"][:, None], c["x"][None, :],
                             c["y"][None, :], 0.0, c["side"][None, :])
    K = scene.half_space_compliance / math.pi * 0.5 * (L + L.T) + X
    gap = analytic.lens_gap(scene.lens.radius_m, np.hypot(c["x"], c["y"]))
    q = np.linalg.solve(K, scene.indentation_m - gap)
    assert q.min() > 0.0
    result = solve_dense(scene, P, pillars="elastic", compliance=m)
    # Love's coefficients are symmetrised differently (by orbit order in the BEM): O(1e-4).
    assert result.total_force_N == pytest.approx(q.sum(), rel=2e-3)


def test_lattice_reduced_operator_equals_an_independent_full_one():
    """E^T K E with K built here from global positions (X depends only on the cells' places
    relative to their pillar's centre, the Love part on their true orientation) equals the
    reduced operator, on a lattice with mirror-line and general pillars."""
    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                             "load.indentation_um=0.1",
                                             "pillars.E_Pa=1.6e7"])
    m = _modal(scene)
    P = 5
    pattern, c = _cells(scene, P)
    d = scene.pillars.diameter_m
    disc = discretise(scene, P, "covered", 5.9 * d)
    assert {1, 6, 12} <= set(disc.orbit_size.tolist())  # centre, mirror-line and general
    X = excess_block(scene, c["x"], c["y"], c["side"], m)
    M = reduced_operator(scene, disc, reduced_block(disc, X, image_cells(disc, pattern, d)))
    # Independent: relative global positions, squares at their image angles.
    centre = disc.pillar_xy[disc.img_pillar]
    gx, gy = disc.img_x - centre[:, 0], disc.img_y - centre[:, 1]
    K = full_operator(scene, disc, pillar_full=_global_block(scene, m, disc, gx, gy))
    E = expansion(disc)
    np.testing.assert_allclose(M, E.T @ K @ E, rtol=0, atol=1e-9 * np.abs(M).max())


def _global_block(scene, m, disc, gx, gy):
    a = 0.5 * scene.pillars.diameter_m
    fem = np.zeros((disc.n_elements, disc.n_elements))
    r, th = np.hypot(gx, gy) / a, np.arctan2(gy, gx)
    phi = m.trace_basis(r)
    w = m.mode_weights()
    for n in range(m.modes + 1):
        fem += w[n] * (phi @ m.excess[n] @ phi.T) * np.cos(n * (th[:, None] - th[None, :]))
    E_p, p = scene.pillars.material.E_Pa, scene.pillars.material
    fem /= E_p * a
    L = unit_force_influence(disc.img_x[:, None], disc.img_y[:, None], disc.img_x[None, :],
                             disc.img_y[None, :], disc.img_angle[None, :],
                             disc.img_side[None, :])
    local = (1 - p.nu**2) / E_p - scene.substrate.compliance
    block = fem + local / math.pi * 0.5 * (L + L.T)
    same = disc.img_pillar[:, None] == disc.img_pillar[None, :]
    return np.where(same, block, 0.0)


def test_full_block_matches_image_cells():
    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                             "load.indentation_um=0.1"])
    pattern, c = _cells(scene, 5)
    disc = discretise(scene, 5, "covered", 1.5 * scene.pillars.diameter_m)
    cells = image_cells(disc, pattern, scene.pillars.diameter_m)
    # Every image sits where its cell does, up to the pattern's mirror y -> -y.
    centre = disc.pillar_xy[disc.img_pillar]
    rel = np.hypot(disc.img_x - centre[:, 0], disc.img_y - centre[:, 1])
    np.testing.assert_allclose(rel, np.hypot(c["x"], c["y"])[cells], atol=1e-12)
    X = np.arange(len(c["x"]))[:, None] * 1.0 + np.zeros(len(c["x"]))
    assert full_block(disc, X, cells).shape == (disc.n_elements,) * 2


@pytest.mark.parametrize("ratio", [0.1, 10.0])
def test_single_pillar_against_fem_axisym(ratio):
    """One pillar (h/d = 1/2, E_s = E_l): the elastic BEM at P = 21 on the coarse compliance
    against fem-axisym at mesh_size 2.  F_T within 1 % and sigma0 within 2 % (the BEM's own
    discretisation error at P = 21, about 0.5 % in sigma0, and the coarse compliance mesh);
    the Hooke BEM misses sigma0 by 7-66 % here."""
    scene = _single(f"pillars.E_Pa={1.6e6 * ratio}")
    fem = solve_axisymmetric(scene, 2.0)
    bem = solve_dense(scene, 21, pillars="elastic", compliance=_modal(scene))
    hooke = solve_dense(scene, 21)
    assert bem.converged and fem.converged
    assert bem.total_force_N == pytest.approx(fem.total_force_N, rel=1e-2)
    assert bem.centre_pressure_Pa == pytest.approx(fem.centre_pressure_Pa, rel=2e-2)
    assert abs(hooke.centre_pressure_Pa / fem.centre_pressure_Pa - 1.0) > 0.05
    assert bem.diagnostics["pillars"] == "elastic"
    assert scene_compliance(scene, _modal(scene)) is not None
    # The two-level extrapolated model passes the pillar model to both levels.
    rich = solve_dense_extrapolated(scene, 11, pillars="elastic", compliance=_modal(scene))
    assert rich.total_force_N == pytest.approx(fem.total_force_N, rel=1e-2)
    assert rich.centre_pressure_Pa == pytest.approx(fem.centre_pressure_Pa, rel=2e-2)


@pytest.mark.parametrize("ratio", [1e-3, 0.1, 1e6])
def test_fft_matches_dense_and_converges_soft_and_stiff(ratio):
    """The FFT model's per-pillar term against the dense block on the same lattice scene
    (Phi = 0.2, E_s = E_l): F_T within 1 % and sigma0 within 3 % (their discretisations differ:
    N = 24 grid cells against P = 15 radial-grid elements; the Hooke models differ as much),
    converged with the circulant and the Jacobi preconditioners for pillars 1e3 times softer
    and 1e6 times stiffer than the lens."""
    from bem_solver import solve_fft

    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                             "load.indentation_um=0.1",
                                             f"pillars.E_Pa={1.6e6 * ratio}"])
    m = _modal(scene)
    dense = solve_dense(scene, 15, pillars="elastic", compliance=m)
    for pc in ("circulant", "jacobi"):
        fft = solve_fft(scene, 24, pillars="elastic", compliance=m, preconditioner=pc)
        assert fft.converged, fft.diagnostics["message"]
        assert fft.total_force_N == pytest.approx(dense.total_force_N, rel=1e-2)
        assert fft.centre_pressure_Pa == pytest.approx(dense.centre_pressure_Pa, rel=3e-2)
        assert fft.diagnostics["pillars"] == "elastic"
    assert dense.pillars_in_contact > 1


def test_fft_pillar_term_is_the_dense_block():
    """On a small grid the FFT model's elastic operator, as a dense matrix, is symmetric and
    its pillar term equals X of the cells' collocation points (the dense model's block)."""
    from bem_solver._elastic_pillar import FFTPillarTerm
    from bem_solver._fft_grid import build_grid
    from bem_solver._fft_operator import near_field_correction

    scene = _single("pillars.E_Pa=1.6e7", "load.indentation_um=0.05")
    m = _modal(scene)
    grid = build_grid(scene, 8)
    term = FFTPillarTerm(scene, grid, m, lambda g, where: near_field_correction(grid, g, backend=where))
    A = term.dense_matrix()
    np.testing.assert_allclose(A, A.T, atol=1e-12 * np.abs(A).max())
    np.testing.assert_allclose(np.diag(A), term.diagonal, rtol=1e-10)
    c = grid.pillar == grid.pillar[grid.centre_cell]
    x, y = grid.colloc_x[c], grid.colloc_y[c]
    side = np.sqrt(grid.covered[c]) * grid.cell_size
    X = excess_block(scene, x, y, side, m)
    L2 = grid.cell_size**2
    # The local Love part is the grid's kernel beyond the near-field correction's three cells
    # (a dipole of the centroid shift, a few 1e-3 of the largest entry): tolerance 1 %.
    np.testing.assert_allclose(A[np.ix_(c, c)], X * L2, rtol=0, atol=1e-2 * np.abs(X).max() * L2)


def test_dense_elastic_refuses_a_block_beyond_memory(monkeypatch):
    """With 1 GiB available, P = 120 fits the Hooke operator (~0.3 GiB) but not the elastic
    pillar's block (2.8k representative rows x 11k cells, ~1.1 GiB): refused, never tried."""
    import bem_solver._dense as dense
    from pillar_xval.scenes import ScopeError

    monkeypatch.setattr(dense, "memory_short",
                        lambda need: "more than 80% of the 1 GiB available"
                        if need > 0.8 * 2.0**30 else None)
    scene = _single("pillars.E_Pa=1.6e7")
    with pytest.raises(ScopeError, match="elements_per_diameter = 120: the elastic pillar"):
        solve_dense(scene, 120, pillars="elastic", compliance=_modal(scene))


def test_lattice_against_fem3d():
    """Phi = 0.2, zeta = 0.1 um, E_p = 0.1 E_l = 0.1 E_s (19 pillars touch): the elastic BEM
    against fem-3d computed here at its coarsest mesh (mesh_size 4, seconds; its F_T still
    moves by about 1 % per refinement step and its sigma0 by 1-2 %, the PHYSICS.md lattice
    table).  Elastic: F_T within 2 %, sigma0 within 5 %, every ring's mean force within 3 %;
    the Hooke BEM misses sigma0 by about 50 % on the same scene."""
    from fem_reference.solid3d import solve as solve_fem3d

    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                             "load.indentation_um=0.1", "pillars.E_Pa=1.6e5"])
    fem = solve_fem3d(scene, 4.0)
    bem = solve_dense(scene, 15, pillars="elastic", compliance=_modal(scene))
    hooke = solve_dense(scene, 15)
    assert fem.converged and bem.converged
    assert bem.pillars_in_contact == fem.pillars_in_contact
    assert bem.total_force_N == pytest.approx(fem.total_force_N, rel=2e-2)
    assert bem.centre_pressure_Pa == pytest.approx(fem.centre_pressure_Pa, rel=5e-2)
    assert abs(hooke.centre_pressure_Pa / fem.centre_pressure_Pa - 1.0) > 0.3

    def rings(result):
        out = {}
        for p in result.pillar_forces:
            out.setdefault(max(abs(p.n), abs(p.m), abs(p.n - p.m)), []).append(p.force_N)
        return {k: sum(v) / len(v) for k, v in out.items()}

    ring_bem, ring_fem = rings(bem), rings(fem)
    assert set(ring_bem) == set(ring_fem)
    for k in ring_fem:
        assert ring_bem[k] == pytest.approx(ring_fem[k], rel=3e-2)


def test_the_elastic_pillar_from_the_cli(cli, tmp_path, monkeypatch):
    """`--pillars elastic` reaches the solver through solve and converge (every level), and is
    refused for a model without it.  (The compliance at the tests' coarse discretisation, as
    everywhere in this file: the default one takes 14 s to build.)"""
    import json

    import fem_reference

    full = fem_reference.modal_compliance
    monkeypatch.setattr(fem_reference, "modal_compliance",
                        lambda kind, modes, mesh_size, progress=None: full(kind, 2, **COARSE))

    scene = ["--scene", "single-pillar", "--set", "pillars.E_Pa=1.6e7"]
    code, out, err = cli("solve", *scene, "--elements-per-diameter", "9", "--pillars",
                         "elastic", "--json")
    assert code == 0, err
    direct = solve_dense(load_scene("single-pillar", ["pillars.E_Pa=1.6e7"]), 9,
                         pillars="elastic")
    assert json.loads(out)["total_force_N"] == pytest.approx(direct.total_force_N, rel=1e-12)
    code, _, err = cli("converge", *scene, "--pillars", "elastic", "--levels", "2",
                       "--elements-per-diameter", "5", "--executor", "serial",
                       "--out", tmp_path / "cv")
    assert code == 0, err
    levels = json.loads((tmp_path / "cv" / "converge.json").read_text())["levels"]
    assert [lv["options"].get("pillars") for lv in levels] == ["elastic", "elastic"]
    code, _, err = cli("converge", "--model", "fem-axisym", *scene, "--pillars", "elastic",
                       "--out", tmp_path / "fem")
    assert code == 2 and "does not apply to --model fem-axisym" in err


def test_compare_with_elastic_pillars_says_so(cli, tmp_path, monkeypatch):
    """`compare --pillars elastic`: every BEM level carries it, and the title, the summary and
    the profile legend name the elastic pillars (they once said Hooke whatever ran)."""
    import json

    import fem_reference

    full = fem_reference.modal_compliance
    monkeypatch.setattr(fem_reference, "modal_compliance",
                        lambda kind, modes, mesh_size, progress=None: full(kind, 2, **COARSE))
    code, out, err = cli("compare", "--scene", "single-pillar", "--set", "pillars.E_Pa=1.6e7",
                         "--pillars", "elastic", "--levels", "2", "--mesh-size", "2",
                         "--elements-per-diameter", "5", "--no-render", "--executor",
                         "serial", "--out", tmp_path)
    assert code in (0, 1), err
    assert out.startswith("BEM (elastic pillars) vs fem-axisym")
    assert (tmp_path / "summary.md").read_text().startswith("# BEM (elastic pillars) vs")
    report = json.loads((tmp_path / "report.json").read_text())
    assert {lv["options"]["pillars"] for lv in report["bem"]["levels"]} == {"elastic"}
    assert report["bem_finest"]["diagnostics"]["pillars"] == "elastic"
