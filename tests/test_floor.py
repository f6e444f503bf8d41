"""The floor between the pillars: the scope of an indentation, the FFT grid's floor cells, its
operator with two unknowns in a rim cell, the short-pillar (Hertz) limit and the models that
refuse a scene whose floor is reached."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest

from pillar_xval.scenes import ScopeError, analytic, load_scene
from pillar_xval.scenes.floor import floor_onset_bound, floor_reach, floor_reachable
from pillar_xval.scenes.lattice import pillars_within
from validation.registry import get_model, run_model

from bem_solver._disk import disk_rectangle_area, disk_rectangle_centroid
from bem_solver._elastic_pillar import scene_compliance
from bem_solver._fft import _Options, _prepare, solve_fft
from bem_solver._fft_grid import build_grid
from bem_solver._xp import NumpyDevice

# Round-off of the FFT operator against its dense matrix (as tests/test_bem_fft.py).
RTOL_ROUNDOFF = 1e-12
# Areas from the closed-form disk-square intersections: round-off of sums of ~1e4 terms.
RTOL_AREA = 1e-12
# A floor sliver below MIN_COVERED_FRACTION (1e-3 of a cell) is dropped.
SLIVER = 1e-3
# Short pillars: F_T against Hertz on the flat substrate, extrapolated to h = 0 by a quadratic
# in h through h = 20, 10, 5 nm (measured -1.6e-4; the flat scene's own discretisation error
# at the same cells 7e-6): the O(h^3) remainder, bound at 6x.
RTOL_SHORT_PILLARS = 1e-3

SMALL = ["lens.radius_mm=0.05", "pillars.surface_fraction=0.3"]


def _setup(overrides, n=4, pillars="hooke"):
    scene = load_scene("paper-fig3-sparse", SMALL + overrides)
    opts = _Options(1e-8, None, 2, False, True, None, "circulant", pillars, None, "double",
                    False)
    return scene, _prepare(scene, n, opts, NumpyDevice(2), None, 0.0)


def test_the_floor_is_reached_beyond_h_plus_the_lens_gap_at_the_rim():
    scene = load_scene("paper-fig3-sparse")
    bound = floor_onset_bound(scene)
    assert bound == pytest.approx(2e-6 + (2e-6) ** 2 / (2 * 2e-3), rel=1e-9)
    assert not floor_reachable(scene, 0.999 * bound) and floor_reachable(scene, 1.001 * bound)
    assert floor_reach(scene, 1.9e-6) == 0.0
    assert floor_reach(scene, 3e-6) == pytest.approx(np.sqrt(2 * 2e-3 * 1e-6 - 1e-12))


def test_suspended_grid_has_no_floor_cells_and_a_mixed_one_has_exact_floor_areas():
    suspended = build_grid(load_scene("paper-fig3-sparse", SMALL + ["load.indentation_um=1.9"]),
                           6)
    assert not suspended.has_floor and suspended.n_unique == suspended.n_cells
    scene = load_scene("paper-fig3-sparse", SMALL + ["load.indentation_um=2.8"])
    grid = build_grid(scene, 6)
    L = grid.cell_size
    assert grid.has_floor and grid.n_top + int(grid.floor.sum()) == grid.n_cells
    assert not grid.floor[:grid.n_top].any() and grid.floor[grid.n_top:].all()
    # The floor cells are within the floor's reach, and beyond the tops' index range.
    assert np.hypot(grid.x[grid.floor], grid.y[grid.floor]).max() <= grid.floor_radius
    assert (grid.pillar[grid.floor] == len(grid.pillar_nm)).all()
    # Each floor part is its cell less the tops' exact covered area (from the closed form,
    # pillar by pillar), and its centroid makes, with the tops', the cell's centre.
    fx, fy = grid.x[grid.floor], grid.y[grid.floor]
    fcov = grid.covered[grid.floor]
    rad = 0.5 * scene.pillars.diameter_m
    top_area, top_mx, top_my = np.zeros(fx.size), np.zeros(fx.size), np.zeros(fx.size)
    for _, _, px, py in pillars_within(grid.floor_radius + 2 * rad, scene.pillars.pitch_m):
        x0, x1, y0, y1 = fx - px - L / 2, fx - px + L / 2, fy - py - L / 2, fy - py + L / 2
        area = disk_rectangle_area(x0, x1, y0, y1, rad)
        some = area > 0
        cx, cy = disk_rectangle_centroid(x0[some], x1[some], y0[some], y1[some], rad)
        top_area += area
        top_mx[some] += area[some] * (cx + px)
        top_my[some] += area[some] * (cy + py)
    np.testing.assert_allclose(fcov, 1.0 - top_area / L**2, rtol=0, atol=RTOL_AREA)
    assert fcov.min() > SLIVER
    np.testing.assert_allclose(top_mx + fcov * L**2 * grid.colloc_x[grid.floor], fx * L**2,
                               rtol=0, atol=RTOL_AREA * L**3)
    np.testing.assert_allclose(top_my + fcov * L**2 * grid.colloc_y[grid.floor], fy * L**2,
                               rtol=0, atol=RTOL_AREA * L**3)
    pos, top = grid.flat_index, ~grid.floor
    # Shared positions come last, each at a top cell's position.
    shared = grid.floor.copy()
    shared[:grid.n_unique] = False
    assert np.isin(pos[shared], pos[top]).all()
    assert len(np.unique(pos[:grid.n_unique])) == grid.n_unique
    # The floor's undeformed gap is h below the tops'.
    gap = analytic.lens_gap(scene.lens.radius_m, np.hypot(grid.colloc_x, grid.colloc_y)) \
        - scene.indentation_m
    np.testing.assert_allclose(grid.gap0[grid.floor], gap[grid.floor] + 2e-6, rtol=0,
                               atol=1e-18)


@pytest.mark.parametrize("pillars", ["hooke", "rigid"])
def test_operator_with_two_unknowns_in_a_rim_cell_is_its_dense_matrix(pillars):
    extra = ["pillars.rigid=true"] if pillars == "rigid" else []
    _, setup = _setup(["load.indentation_um=2.8"] + extra)
    grid, plan = setup.grid, setup.plan
    A = plan.dense_matrix(grid.x, grid.y)
    n = grid.n_cells
    q = np.random.default_rng(1).random(n)
    ref = A @ q
    assert np.abs(plan(q) - ref).max() <= RTOL_ROUNDOFF * np.abs(ref).max()
    assert np.abs(A - A.T).max() <= RTOL_ROUNDOFF * np.abs(A).max()
    assert np.linalg.eigvalsh(A).min() > 0.0
    # A few cells, both parts of a rim cell among them.
    index = np.array([0, grid.n_unique - 1, grid.n_unique, n - 1])
    values = np.array([1.0, -2.0, 3.0, 0.5])
    d = np.zeros(n)
    np.add.at(d, index, values)
    few = plan.apply_few(index, values)
    assert np.abs(few - A @ d).max() <= RTOL_ROUNDOFF * np.abs(A @ d).max()
    # The floor takes no Hooke term: the operator off the floor's cells is the tops'.
    if pillars == "hooke":
        assert plan.has_spring and float(plan.pillar_spring[-1]) == 0.0


def test_preconditioner_keeps_a_rim_cell_s_two_parts_apart():
    """Short pillars put both parts of rim cells in contact: the circulant part sees only their
    sum, and without the parts' Jacobi term the CG took ~3000 iterations (measured 2965 at
    h = 2 nm, N = 8); with it 35."""
    scene = load_scene("paper-fig3-sparse", ["pillars.height_um=0.002", "pillars.rigid=true",
                                             "load.indentation_um=0.3"])
    result = solve_fft(scene, 8, warm_start=False)
    assert result.converged and result.iterations < 200
    assert result.regime == "mixed"


def test_preconditioner_s_rim_term_acts_only_where_both_parts_are_free():
    """The parts' Jacobi term is for a rim cell whose two parts are both free; with one part
    free the circulant part sees it alone, and the term would only overweight it (on the tops
    of a mixed contact, 21 instead of 14 PCG iterations on its final contact set)."""
    from bem_solver._fft_operator import CirculantPreconditioner

    _, setup = _setup(["load.indentation_um=2.8", "pillars.rigid=true"])
    grid, plan = setup.grid, setup.plan
    pre = CirculantPreconditioner(plan)
    bare = CirculantPreconditioner(plan)
    bare.pairs = None
    r = np.random.default_rng(2).random(grid.n_cells)
    rim_tops = np.zeros(grid.n_cells, dtype=bool)
    rim_tops[pre.pairs[0]] = True
    rim_floors = np.arange(grid.n_cells) >= grid.n_unique
    assert rim_tops.any() and rim_floors.sum() == rim_tops.sum()
    for free in (~grid.floor, grid.floor, rim_tops | (grid.floor & ~rim_floors)):
        np.testing.assert_array_equal(pre(r, free), bare(r, free))  # never both parts
    rims = rim_tops | rim_floors
    changed = pre(r, rims) != bare(r, rims)
    assert changed[rims].all() and not changed[~rims].any()


def test_the_warm_start_carries_the_coarse_forces_of_every_pillar_and_the_floor():
    """The interpolated start keeps each pillar's and the floor's force of the coarse solution
    (the bilinear interpolation alone lost 12 % of the tops' force at N = 36, which let the
    lens sink onto the floor around its contact at the fine level's start)."""
    from bem_solver._fft import _interpolate

    scene = load_scene("paper-fig3-sparse", [
        "pillars.rigid=true", "lens.radius_mm=0.2", "pillars.surface_fraction=0.03",
        "pillars.height_um=1", "load.indentation_um=2"])
    rough = solve_fft(scene, 8)
    grid = build_grid(scene, 16)
    q0 = _interpolate(rough, grid, NumpyDevice(2))
    forces = np.bincount(grid.pillar, weights=q0 * grid.cell_size**2)
    assert rough.regime == "mixed" and rough.floor_force_N > 0.0
    assert forces[-1] == pytest.approx(rough.floor_force_N, rel=RTOL_ROUNDOFF)
    index = {(int(n), int(m)): k for k, (n, m) in enumerate(grid.pillar_nm)}
    for pf in rough.pillar_forces:
        assert forces[index[(pf.n, pf.m)]] == pytest.approx(pf.force_N, rel=RTOL_ROUNDOFF)


def test_short_pillars_tend_to_hertz_on_the_flat_substrate():
    heights = (0.02, 0.01, 0.005)
    errors = []
    for h in heights:
        scene = load_scene("paper-fig3-sparse", [f"pillars.height_um={h}",
                                                 "load.indentation_um=0.3"])
        result = solve_fft(scene, 8)
        assert result.converged and result.regime == "mixed"
        errors.append(result.total_force_N / analytic.hertz(scene).force - 1.0)
    # O(h) approach: the errors shrink with h (about -4.4 h per um).
    assert abs(errors[0]) > abs(errors[1]) > abs(errors[2])
    at_zero = np.polyval(np.polyfit(heights, errors, 2), 0.0)
    assert abs(at_zero) < RTOL_SHORT_PILLARS


def test_a_mixed_solve_reports_the_floor_and_its_regime():
    scene = load_scene("paper-fig3-sparse", ["load.indentation_um=5"])
    result = solve_fft(scene, 8)
    assert result.converged and result.regime == "mixed"
    f = result.fields
    floor = f["floor"]
    assert result.floor_force_N == pytest.approx(f["cell_force_N"][floor].sum(), rel=1e-12)
    assert 0.0 < result.floor_force_N < result.total_force_N
    on = floor & (f["pressure_Pa"] > 0)
    assert result.floor_contact_area_m2 == pytest.approx(f["area_m2"][on].sum(), rel=1e-12)
    r = np.hypot(f["x_m"][on], f["y_m"][on])
    assert r.max() - f["cell_size_m"] <= result.floor_contact_radius_m <= \
        floor_reach(scene) + f["cell_size_m"]
    assert abs(result.diagnostics["force_balance_N"]) < 1e-12 * result.total_force_N
    # The floor's gap stays open or closed, never negative beyond the tolerance.
    assert result.diagnostics["max_interpenetration_m"] < 1e-7 * scene.indentation_m
    doc = result.to_dict()
    assert doc["regime"] == "mixed" and doc["floor_force_N"] == result.floor_force_N
    # A suspended solve has none.
    suspended = solve_fft(load_scene("paper-fig3-sparse"), 8)
    assert suspended.floor_force_N == 0.0 and suspended.floor_contact_radius_m == 0.0
    assert suspended.regime == "multi-pillar"


def test_force_control_crosses_onto_the_floor_and_back():
    scene = load_scene("paper-fig3-sparse", ["load.indentation_um=5"])
    given = solve_fft(scene, 8)
    assert given.regime == "mixed"
    under_force = solve_fft(scene.at_force(given.total_force_N), 8)
    assert under_force.indentation_m == pytest.approx(5e-6, rel=1e-6)
    assert under_force.floor_force_N == pytest.approx(given.floor_force_N, rel=1e-5)


@pytest.mark.parametrize("model, options", [("bem", {"elements_per_diameter": 5}),
                                            ("bem-richardson", {"elements_per_diameter": 5}),
                                            ("spring", {})])
def test_models_without_the_floor_refuse_a_scene_that_reaches_it(model, options):
    scene = load_scene("paper-fig3-sparse", ["load.indentation_um=3"])
    with pytest.raises(ScopeError, match="reaches the floor between the pillars.*use bem-fft"):
        run_model(model, scene, **options)


def test_the_loading_curve_crosses_the_transition_and_marks_it(tmp_path, capsys):
    from validation.cli import main

    code = main(["curve", "--scene", "paper-fig3-sparse", "--indentations-um", "1.5,5",
                 "--models", "bem-fft", "--cells-per-diameter", "8", "--out", str(tmp_path),
                 "--executor", "serial"])
    out = capsys.readouterr().out
    assert code == 0 and "touches the floor between the loads 1.5 and 5 um" in out
    doc = json.loads((tmp_path / "curve.json").read_text())
    assert doc["transitions"]["bem-fft"]["mixed_load"] == 5e-6
    rows = list(csv.DictReader(io.StringIO((tmp_path / "curve.csv").read_text())))
    assert [r["regime"] for r in rows] == ["multi-pillar", "mixed"]
    assert float(rows[0]["floor_force_N"]) == 0.0 < float(rows[1]["floor_force_N"])


# Roof collapse against the exact solver's onset: the estimate over the centre pillar's force
# per lattice cell at the onset, measured +2.2 % at Phi = 0.03 and 0.1 on the paper's lens
# (bem-fft N = 8; a contact several pitches wide, as the estimate assumes); bound at 2x.
RTOL_ROOF_COLLAPSE = 0.05


def test_onset_brackets_the_first_floor_contact(tmp_path, capsys):
    from validation.cli import main

    sets = ["--set", "lens.radius_mm=0.2", "--set", "pillars.surface_fraction=0.1",
            "--set", "pillars.height_um=1"]
    code = main(["onset", "--scene", "paper-fig3-sparse", *sets, "--cells-per-diameter", "8",
                 "--rtol", "0.01", "--out", str(tmp_path), "--executor", "serial"])
    assert code == 0 and "the floor is first touched at zeta" in capsys.readouterr().out
    doc = json.loads((tmp_path / "onset.json").read_text())
    lo, hi = doc["bracket_indentation_m"]
    assert doc["geometric_bound_m"] <= lo < doc["onset_indentation_m"] < hi <= lo * 1.0101
    below = [s for s in doc["solves"] if s["indentation_m"] <= lo]
    above = [s for s in doc["solves"] if s["indentation_m"] >= hi]
    assert all(s["floor_force_N"] == 0.0 for s in below)
    assert all(s["floor_force_N"] > 0.0 for s in above)
    flo, fhi = doc["bracket_force_N"]
    assert flo < doc["onset_force_N"] < fhi
    # A model without the floor is refused in one line.
    code = main(["onset", "--scene", "paper-fig3-sparse", "--model", "bem",
                 "--out", str(tmp_path / "b")])
    assert code == 2 and "does not include the floor" in capsys.readouterr().err


@pytest.mark.slow
@pytest.mark.parametrize("phi", [0.03, 0.1])
def test_roof_collapse_estimate_meets_the_solver_s_onset(tmp_path, phi):
    from pillar_xval.scenes.floor import roof_collapse_pressure
    from validation.studies.onset import onset_study

    scene = load_scene("paper-fig3-sparse", [f"pillars.surface_fraction={phi}"])
    doc = onset_study(scene, "bem-fft", tmp_path, options={"cells_per_diameter": 8},
                      rtol=3e-3)
    assert doc["roof_collapse_pressure_Pa"] == roof_collapse_pressure(scene)
    assert doc["roof_collapse_pressure_Pa"] == pytest.approx(
        doc["onset_centre_mean_pressure_Pa"], rel=RTOL_ROOF_COLLAPSE)


def test_roof_collapse_closed_form_limits():
    from pillar_xval.scenes.floor import roof_collapse_pressure

    base = load_scene("paper-fig3-sparse", ["pillars.rigid=true"])
    # Linear in the gap h + g(e / sqrt 3), and inverse in the compliances.
    taller = load_scene("paper-fig3-sparse", ["pillars.rigid=true", "pillars.height_um=4"])
    e = base.pillars.pitch_m
    g = e * e / 3.0 / (2.0 * base.lens.radius_m)
    assert roof_collapse_pressure(taller) / roof_collapse_pressure(base) == pytest.approx(
        (4e-6 + g) / (2e-6 + g), rel=1e-6)
    stiffer = load_scene("paper-fig3-sparse", ["pillars.rigid=true", "lens.E_Pa=3.2e6",
                                               "substrate.E_Pa=3.2e6"])
    assert roof_collapse_pressure(stiffer) == pytest.approx(2 * roof_collapse_pressure(base),
                                                            rel=1e-12)
    # Denser lattices hold the lens up at higher mean pressures.
    dense = load_scene("paper-fig3-sparse", ["pillars.rigid=true",
                                             "pillars.surface_fraction=0.3"])
    assert roof_collapse_pressure(dense) > roof_collapse_pressure(base)


def test_the_planner_plans_a_mixed_scene_with_floor_models_only():
    from validation.planner.plan import plan

    p = plan(load_scene("paper-fig3-sparse", ["load.indentation_um=5"]), 0.05)
    assert p["regime"]["name"] == "mixed"
    assert p["choice"] is not None and get_model(p["choice"]["model"]).floor
    refused = [c for c in p["candidates"] if c["model"] in ("bem", "spring")]
    assert refused and all("does not include the floor" in c["why"] for c in refused)
    assert plan(load_scene("paper-fig3-sparse"), 0.05)["regime"]["name"] == "multi"


@pytest.mark.parametrize("label", ["floor: zeta=10h", "floor: h/d=0.05 zeta=5h",
                                   "floor: Ep- zeta=3h", "floor: Ep+ zeta=3h",
                                   "floor: Phi=0.9 zeta=5h"])
def test_extremes_past_the_pillar_tops_hold_the_invariants(label):
    from validation.studies.extremes.run import corner_scenes, model_options

    scene = next(e["scene"] for e in corner_scenes() if e["label"] == label)
    result = solve_fft(scene, **model_options()["bem-fft"])
    f = result.fields
    assert result.converged, result.diagnostics["message"]
    assert np.all(f["pressure_Pa"] >= 0.0)
    assert result.diagnostics["max_interpenetration_m"] <= 1e-6 * scene.indentation_m
    assert abs(result.diagnostics["force_balance_N"]) <= 1e-9 * result.total_force_N
    # Close packing holds the lens up at 5 h; elsewhere the floor is touched.
    assert result.regime == ("multi-pillar" if "Phi=0.9" in label else "mixed")


def test_elastic_pillars_with_the_floor_act_on_the_tops_alone():
    """The elastic pillar's term sees the top cells only; the floor meets the pillars through
    the half-space kernel (the column model), and the operator stays symmetric and definite."""
    scene = load_scene("paper-fig3-sparse", SMALL + ["load.indentation_um=2.8",
                                                     "pillars.E_Pa=1.6e5"])
    opts = _Options(1e-8, None, 2, False, True, None, "circulant", "elastic",
                    scene_compliance(scene), "double", True)
    setup = _prepare(scene, 4, opts, NumpyDevice(2), None, 0.0)
    grid, plan = setup.grid, setup.plan
    assert grid.has_floor
    term = plan.pillar_term.dense_matrix()
    assert not term[grid.floor].any() and not term[:, grid.floor].any()
    A = plan.dense_matrix(grid.x, grid.y)
    q = np.random.default_rng(2).random(grid.n_cells)
    assert np.abs(plan(q) - A @ q).max() <= RTOL_ROUNDOFF * np.abs(A @ q).max()
    assert np.abs(A - A.T).max() <= 1e-9 * np.abs(A).max()
    assert np.linalg.eigvalsh(0.5 * (A + A.T)).min() > 0.0
    deep = load_scene("paper-fig3-sparse", ["lens.radius_mm=0.25", "pillars.surface_fraction=0.1",
                                            "pillars.E_Pa=1.6e5", "load.indentation_um=6"])
    elastic, hooke = (solve_fft(deep, 8, pillars=p) for p in ("elastic", "hooke"))
    assert elastic.converged and elastic.regime == hooke.regime == "mixed"
    # Soft pillars (E_p = 0.1 E_l): the elastic pillar is stiffer than the Hooke spring's
    # uniform shortening (PHYSICS.md), so the floor carries less (measured 56 % against 60 %).
    assert elastic.floor_force_N / elastic.total_force_N < hooke.floor_force_N / \
        hooke.total_force_N
