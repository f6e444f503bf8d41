"""Force control: a scene pressed by a given force, in every model.

Tolerances, each by its source:

- ``RTOL_ROUND_TRIP_ZETA`` (1e-6) and ``RTOL_ROUND_TRIP_FIELDS`` (1e-5): the issue's round
  trip (the force of an indentation-controlled solve, given back, returns its indentation and
  its fields).  Measured: 1e-15 (dense BEM, fem-axisym, closed forms: exact solves), 4e-10
  (bem-fft, fem-3d: CG to 1e-8 zeta), 1e-8 (bem-richardson and flat scenes: secants and the
  cells' fixed point to 1e-8 and 1e-6).
- ``HERTZ_BANDS``: each model's discretisation error against Hertz under a 5 uN force on the
  ``hertz`` scene, a and sigma0 (measured: bem P=11 -1.03 %, +0.10 %; bem-fft N=32 +0.065 %,
  +0.026 %; bem-richardson P=5 -0.95 %, +0.094 %; fem-axisym mesh_size 2 +0.13 %, +0.19 %),
  allowed twice that.
- ``RTOL_SPRING_*``: the spring model inverted against the Richardson-extrapolated BEM on one
  pillar at 1 uN (measured, Hooke pillars E_p = 0.1, 1 E_l and rigid: zeta +0.05 to +0.28 %,
  sigma0 +1.31 to +1.34 %, the lens's curvature over the top and the BEM's edge).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pillar_xval.contact import approach_for_force, constrained_cg, solve_active_set
from pillar_xval.scenes import Scene, SceneError, ScopeError, analytic, load_scene, scene_to_toml
from validation.engine import case_key
from validation.registry import run_model

RTOL_ROUND_TRIP_ZETA = 1e-6
RTOL_ROUND_TRIP_FIELDS = 1e-5
HERTZ_BANDS = {("bem", 11): (0.0206, 0.002), ("bem-fft", 32): (0.0013, 0.0006),
               ("bem-richardson", 5): (0.019, 0.0019), ("fem-axisym", 2.0): (0.0026, 0.0038)}
RTOL_SPRING_ZETA = 0.006
RTOL_SPRING_SIGMA0 = 0.027
LATTICE = ("paper-fig3-sparse", ["pillars.surface_fraction=0.2"])


def _same_answer(a, b):
    """The round trip's comparison: indentation, the four quantities, the pillars and the
    profile across the centre pillar."""
    assert b.load_control == "force" and a.load_control == "indentation"
    assert b.indentation_m == pytest.approx(a.indentation_m, rel=RTOL_ROUND_TRIP_ZETA)
    for field in ("total_force_N", "centre_pressure_Pa", "contact_radius_m",
                  "real_contact_area_m2"):
        assert getattr(b, field) == pytest.approx(getattr(a, field),
                                                  rel=RTOL_ROUND_TRIP_FIELDS), field
    assert b.pillars_in_contact == a.pillars_in_contact
    pa, pb = (np.asarray(r.pillar_top_profile["pressure_Pa"]) for r in (a, b))
    assert pa.shape == pb.shape
    assert np.max(np.abs(pb - pa)) <= RTOL_ROUND_TRIP_FIELDS * np.max(np.abs(pa))


ROUND_TRIPS = [
    ("bem", LATTICE, {"elements_per_diameter": 7}),
    ("bem", ("hertz", []), {}),
    ("bem", ("single-pillar", ["pillars.rigid=true", "substrate.rigid=true"]),
     {"pillars": "elastic"}),
    ("bem-fft", LATTICE, {"cells_per_diameter": 16}),
    ("bem-fft", ("hertz", []), {"cells_per_diameter": 16}),
    ("bem-richardson", LATTICE, {}),
    ("bem-richardson", ("hertz", []), {}),
    ("fem-axisym", ("single-pillar", []), {"mesh_size": 4.0}),
    ("fem-axisym", ("hertz", []), {"mesh_size": 4.0}),
    ("fem-3d", ("single-pillar", []), {"mesh_size": 4.0}),
    ("hertz", ("paper-fig3-dense", []), {}),
    ("hertz", ("hertz", []), {}),
    ("spring", ("single-pillar", []), {}),
]


@pytest.mark.parametrize("case", ROUND_TRIPS, ids=lambda c: f"{c[0]}-{c[1][0]}{c[1][1]}")
def test_round_trip(case):
    """The force of an indentation-controlled solve, given back as the load, returns that
    indentation and the same fields."""
    model, (preset, overrides), options = case
    scene = load_scene(preset, overrides)
    given = run_model(model, scene, **options)
    back = run_model(model, scene.at_force(given.total_force_N), **options)
    assert given.converged and back.converged
    _same_answer(given, back)
    assert back.scene["load"] == {"force_N": given.total_force_N}


def test_round_trip_with_elastic_pillars(compliance_cache):
    """Both BEMs with the elastic pillar (a coarse compliance: the round trip holds for any)."""
    from bem_solver import solve_dense, solve_fft
    from fem_reference import PillarKind, modal_compliance

    scene = load_scene(*LATTICE)
    modal = modal_compliance(PillarKind.of_scene(scene), 0, mesh_size=4.0)
    for solve, options in ((solve_fft, {"cells_per_diameter": 12}),
                           (solve_dense, {"elements_per_diameter": 5})):
        given = solve(scene, pillars="elastic", compliance=modal, **options)
        back = solve(scene.at_force(given.total_force_N), pillars="elastic", compliance=modal,
                     **options)
        assert back.diagnostics["pillars"] == "elastic"
        _same_answer(given, back)


@pytest.mark.slow
@pytest.mark.parametrize("mesh_size", [4.0, 2.83])
def test_round_trip_fem3d_on_a_lattice(mesh_size):
    """Without a coarser level (4: the guess's mesh) and with one (2.83, designed at 4)."""
    scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.1",
                                             "load.indentation_um=0.1"])
    given = run_model("fem-3d", scene, mesh_size=mesh_size)
    _same_answer(given, run_model("fem-3d", scene.at_force(given.total_force_N),
                                  mesh_size=mesh_size))


def test_fem3d_under_a_force_meshes_the_fine_level_once():
    """Below mesh_size 2.83 the fine mesh is built for the coarse level's answer under the
    same force (twice the element size, at most 4): on one pillar, whose meshed pillars
    never change, one coarse round and one fine mesh, and the round trip holds."""
    from fem_reference.solid3d.driver import _coarse_size

    assert [_coarse_size(s) for s in (1.41, 2.0, 2.83, 3.0, 4.0)] == [2.82, 4.0, 4.0, None,
                                                                       None]
    scene = load_scene("single-pillar")
    given = run_model("fem-3d", scene, mesh_size=2.83)
    back = run_model("fem-3d", scene.at_force(given.total_force_N), mesh_size=2.83)
    assert [r["mesh_size"] for r in back.diagnostics["design_rounds"]] == [4.0, 2.83]
    assert given.converged and back.converged
    _same_answer(given, back)


@pytest.mark.parametrize("preset", ["paper-fig3-sparse", "single-pillar"])
def test_round_trip_auto(preset, compliance_cache):
    """auto plans a force-controlled scene at its estimated indentation, then at the solved
    one: the answer is the model's its plan chooses there (here the same as for the
    indentation)."""
    scene = load_scene(preset)
    request = {"tolerance": 0.05, "quantities": ["F_T"]}
    given = run_model("auto", scene, **request)
    back = run_model("auto", scene.at_force(given.total_force_N), **request)
    assert back.diagnostics["plan"]["choice"]["label"] == \
        given.diagnostics["plan"]["choice"]["label"]
    _same_answer(given, back)


def test_auto_under_a_force_settles_on_its_own_plan(compliance_cache):
    """Where the estimated indentation's plan and the solved one's differ (a candidate's
    predicted error at its tolerance: bem-fft N=24's sigma0 0.99 % against 1.0 % on a rigid
    pillar), auto solves again until the plan at the solved indentation chooses the model
    that solved it."""
    from validation.planner import plan

    scene = load_scene("single-pillar", ["pillars.rigid=true"])
    force = run_model("auto", scene).total_force_N
    back = run_model("auto", scene.at_force(force))
    again = plan(scene.at_indentation(back.indentation_m))
    assert again["choice"]["label"] == back.diagnostics["plan"]["choice"]["label"]
    assert back.total_force_N == pytest.approx(force, rel=1e-8)


@pytest.mark.parametrize("model,value", sorted(HERTZ_BANDS))
def test_hertz_under_a_force(model, value):
    """a = (3 F R / 4 E*)^(1/3) and sigma0 = 3 F / (2 pi a^2) within each model's band."""
    force = 5e-6
    scene = load_scene("hertz", [f"load.force_uN={force * 1e6}"])
    option = {"bem": "elements_per_diameter", "bem-richardson": "elements_per_diameter",
              "bem-fft": "cells_per_diameter", "fem-axisym": "mesh_size"}[model]
    result = run_model(model, scene, **{option: value})
    a = (3.0 * force * scene.lens.radius_m * scene.half_space_compliance / 4.0) ** (1.0 / 3.0)
    band_a, band_s = HERTZ_BANDS[(model, value)]
    assert result.converged
    assert result.total_force_N == pytest.approx(force, rel=1e-8)
    assert result.contact_radius_m == pytest.approx(a, rel=band_a)
    assert result.centre_pressure_Pa == pytest.approx(3.0 * force / (2.0 * math.pi * a * a),
                                                      rel=band_s)


def test_closed_forms_carry_a_scene_force():
    """scenes.analytic reads a force-controlled scene's closed forms at its force."""
    scene = load_scene("single-pillar", ["load.force_uN=1"])
    for form in (analytic.hertz, analytic.spring_model, analytic.rigid_punch):
        assert form(scene).force == pytest.approx(1e-6, rel=1e-12)


def test_hertz_model_inverts_exactly():
    scene = load_scene("hertz", ["load.force_uN=5"])
    result = run_model("hertz", scene)
    a = (3.0 * 5e-6 * scene.lens.radius_m * scene.half_space_compliance / 4.0) ** (1.0 / 3.0)
    assert result.contact_radius_m == pytest.approx(a, rel=1e-12)
    assert result.centre_pressure_Pa == pytest.approx(3 * 5e-6 / (2 * math.pi * a * a),
                                                      rel=1e-12)
    assert result.indentation_m == pytest.approx(a * a / scene.lens.radius_m, rel=1e-12)


@pytest.mark.parametrize("pillar", ["pillars.E_Pa=1.6e5", "pillars.E_Pa=1.6e6",
                                    "pillars.rigid=true"])
def test_spring_model_inverted_against_the_bem_on_one_pillar(pillar):
    """sigma_0S = 2 F / (pi d^2) and zeta = F gamma* / d for a given F, against the
    Richardson-extrapolated dense BEM (Hooke pillar) on one pillar."""
    scene = load_scene("single-pillar", [pillar, "load.force_uN=1"])
    spring = run_model("spring", scene)
    d = scene.pillars.diameter_m
    assert spring.centre_pressure_Pa == pytest.approx(2e-6 / (math.pi * d * d), rel=1e-12)
    assert spring.indentation_m == pytest.approx(
        1e-6 * analytic.effective_compliance(scene) / d, rel=1e-12)
    bem = run_model("bem-richardson", scene, elements_per_diameter=11)
    assert bem.indentation_m == pytest.approx(spring.indentation_m, rel=RTOL_SPRING_ZETA)
    assert bem.centre_pressure_Pa == pytest.approx(spring.centre_pressure_Pa,
                                                   rel=RTOL_SPRING_SIGMA0)


def test_monotone_along_a_curve(tmp_path):
    """The indentation, the contact radius and the pillar count never fall as the force
    rises (a larger load only adds contact), and the force rises with the indentation."""
    from validation.studies.curve import curve_study

    base = load_scene("paper-fig3-sparse")
    forces = [0.5e-6, 1e-6, 2e-6, 4e-6, 8e-6, 16e-6, 24e-6]
    doc = curve_study([base.at_force(f) for f in forces], ["bem"], tmp_path / "cases",
                      coarsest={"elements_per_diameter": 7})
    assert doc["falls"] == {"bem": []}
    rows = doc["rows"]
    for before, after in zip(rows, rows[1:]):
        for key in ("indentation_m", "contact_radius_m", "pillars_in_contact"):
            assert after[key] >= before[key], key
    assert rows[-1]["pillars_in_contact"] > rows[0]["pillars_in_contact"]
    zetas = [r["indentation_m"] for r in rows[::2]]
    doc = curve_study([base.at_indentation(z) for z in zetas], ["bem"], tmp_path / "cases",
                      coarsest={"elements_per_diameter": 7})
    assert [r["total_force_N"] for r in doc["rows"]] == pytest.approx(forces[::2], rel=1e-6)


# --- the scene -----------------------------------------------------------------------
def test_force_replaces_the_preset_indentation_and_round_trips_through_toml(tmp_path):
    scene = load_scene("paper-fig3-sparse", ["load.force_uN=20"])
    assert scene.load_control == "force" and scene.indentation_m is None
    assert scene.force_N == pytest.approx(2e-5, rel=1e-15)
    path = tmp_path / "s.toml"
    path.write_text(scene_to_toml(scene))
    assert load_scene(path) == scene
    assert Scene.from_dict(scene.to_dict()) == scene


@pytest.mark.parametrize("overrides,words", [
    (["load.force_uN=20", "load.indentation_um=0.3"], "not both"),
    (["load.force_uN=0"], "allowed range"),
    (["load.force_uN=-1"], "allowed range"),
    (["load.force_uN=nan"], "decimal number"),
    (["load.force_uN=abc"], "decimal number"),
    (["load.force_uN=1e40"], "allowed range"),
    (["load.force_uN=1e6"], "implies an indentation of at least"),
])
def test_bad_forces_are_refused_in_one_line(overrides, words):
    with pytest.raises(SceneError) as err:
        load_scene("paper-fig3-sparse", overrides)
    assert words in str(err.value) and "\n" not in str(err.value)


def test_a_file_with_both_loads_is_refused(tmp_path):
    path = tmp_path / "both.toml"
    path.write_text(scene_to_toml(load_scene("hertz")).replace(
        "indentation_um = 0.3", "indentation_um = 0.3\nforce_uN = 2"))
    with pytest.raises(SceneError, match="exactly one of indentation_um and force_uN"):
        load_scene(path)


def test_an_implied_indentation_on_the_floor_names_the_force_and_the_indentation():
    scene = load_scene("paper-fig3-sparse", ["load.force_uN=200"])
    with pytest.raises(ScopeError) as err:
        run_model("bem", scene, elements_per_diameter=5)
    text = str(err.value)
    assert "load.force_uN = 200" in text and "implies an indentation of 3" in text
    assert "reaches the floor between the pillars" in text and "use bem-fft" in text


def test_case_keys_keep_the_controls_apart():
    scene = load_scene("paper-fig3-sparse")
    force = run_model("bem", scene, elements_per_diameter=5).total_force_N
    keys = {case_key("bem", s, {}) for s in (scene, scene.at_force(force))}
    assert len(keys) == 2


def test_least_indentation_bounds_every_model_from_below():
    """The lens on a rigid flat carries a force at the smallest indentation of any model."""
    for preset in ("paper-fig3-dense", "paper-fig3-sparse", "hertz"):
        scene = load_scene(preset, ["load.force_uN=5"])
        bound = analytic.least_indentation(scene)
        assert bound < run_model("bem", scene, elements_per_diameter=7).indentation_m


def test_indentation_estimate_is_a_close_guess():
    """The design guess of the models (0.96-1.3 of the solved indentation on the paper's
    family, its docstring)."""
    for preset, overrides in (("paper-fig3-dense", []), ("paper-fig3-sparse", []), LATTICE,
                              ("single-pillar", [])):
        scene = load_scene(preset, overrides)
        force = run_model("bem", scene, elements_per_diameter=7).total_force_N
        guess = analytic.indentation_estimate(scene.at_force(force))
        assert 0.95 <= guess / scene.indentation_m <= 1.3


# --- the contact solvers ---------------------------------------------------------------
def _problem(n=300, seed=3):
    """A smooth SPD compliance (a 1D Boussinesq-like kernel) and a parabolic gap."""
    x = np.linspace(-1.0, 1.0, n)
    A = 1.0 / (np.abs(x[:, None] - x[None, :]) + 0.02) / n
    load = np.random.default_rng(seed).uniform(0.5, 1.5, n)
    return A, x**2, load


def test_active_set_and_cg_take_the_force_natively():
    A, gap, load = _problem()
    zeta = 0.1
    given = solve_active_set(A, gap - zeta * load, scale=zeta)
    force = float(load @ given.pressure)
    exact = solve_active_set(A, gap, scale=zeta, force=force, load=load)
    cg = constrained_cg(lambda q: A @ q, gap, np.zeros(len(gap)), scale=zeta, force=force,
                        load=load, inverse_diagonal=1.0 / np.diag(A))
    for sol in (exact, cg):
        assert sol.converged
        assert sol.approach == pytest.approx(zeta, rel=1e-8)
        assert float(load @ sol.pressure) == pytest.approx(force, rel=1e-12)
        assert np.max(np.abs(sol.pressure - given.pressure)) <= 1e-6 * given.pressure.max()


def test_bordered_conjugate_gradients_on_a_large_active_set(monkeypatch):
    """Beyond the Cholesky size the bordered systems run projected CG (one Krylov sequence
    per active set); the size lowered here so that a small problem takes that path."""
    from pillar_xval.contact import _active_set

    monkeypatch.setattr(_active_set, "CHOLESKY_MAX", 100)
    n = 600
    x = np.linspace(-1.0, 1.0, n)
    A, gap, load = 1.0 / (np.abs(x[:, None] - x[None, :]) + 0.001) / n, x**2, np.full(n, 0.7)
    zeta = 1.2
    given = solve_active_set(A, gap - zeta * load, scale=zeta)
    assert np.count_nonzero(given.pressure) > 4 * _active_set.CHOLESKY_MAX
    sol = solve_active_set(A, gap, scale=zeta, force=float(load @ given.pressure), load=load)
    assert sol.converged and sol.approach == pytest.approx(zeta, rel=1e-10)
    assert np.max(np.abs(sol.pressure - given.pressure)) <= 1e-9 * given.pressure.max()


def test_secant_after_a_cycle_and_approach_for_force():
    """The active set's fallback (a bracketing secant over indentation solves) meets the force
    too, and the secant alone inverts a monotone force law."""
    from pillar_xval.contact._active_set import _force_by_secant

    A, gap, load = _problem()
    given = solve_active_set(A, gap - 0.1 * load, scale=0.1)
    force = float(load @ given.pressure)
    sol = _force_by_secant(A, gap, 0.1, None, None, 1e-8, 100, force, load, 0)
    assert sol.converged and sol.approach == pytest.approx(0.1, rel=1e-7)
    zeta, answer, met = approach_for_force(lambda z: (z**1.5, z), 8.0, guess=1.0, rtol=1e-12)
    assert met and zeta == pytest.approx(4.0, rel=1e-11) and answer == zeta


def test_a_model_without_force_control_solves_by_an_outer_secant(monkeypatch):
    """A model registered without a thought for force control still answers a force: the
    registry finds the indentation that carries it by solves under indentations."""
    from dataclasses import replace

    from validation.registry import MODELS

    monkeypatch.setitem(MODELS, "bem", replace(MODELS["bem"], force_control="outer"))
    scene = load_scene(*LATTICE)
    given = run_model("bem", scene, elements_per_diameter=5)
    back = run_model("bem", scene.at_force(given.total_force_N), elements_per_diameter=5)
    assert back.diagnostics["force_control"] == "secant over solves"
    assert back.indentation_m == pytest.approx(scene.indentation_m, rel=1e-7)


def test_cached_force_result_is_verified(tmp_path):
    """A cached force-controlled result that does not carry its case's force is recomputed."""
    from validation.engine import Case, CaseStore, Engine

    scene = load_scene("hertz", ["load.force_uN=3"])
    case = Case("hertz", scene, {})
    with Engine("serial", quiet=True) as engine:
        engine.run([case], tmp_path)
    store = CaseStore(tmp_path)
    record, _ = store.load(case)
    assert record is not None
    record["result"]["total_force_N"] *= 1.01
    reason = store._check(case, record)
    assert "the case's force" in reason

