"""The model registry: every model runs by one path (the CLI's, the engine's and the planner's),
a new model is one declaration, and the case key follows all the code that computes.

The small scene is the single-pillar preset (the flat hertz preset for a model the planner
keeps off single pillars: the Hertz-like limit refuses one pillar), each model at the coarsest
rung of its ladder; auto asks for a loose tolerance, so that it plans a cheap model."""

from __future__ import annotations

import dataclasses
import json
import shutil

import pytest

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import analytic, load_scene
from validation.engine import Case, Engine, case_key
from validation.planner.tables import load_data
from validation.registry import (MODELS, Ladder, Model, OptionSpec, check_option, get_model,
                                 ladders, option_vocabulary, run_model)

SCENE = "single-pillar"
AUTO_TOLERANCE = 0.5


def _scene(model: Model):
    return load_scene("hertz" if model.scopes and "single" not in model.scopes else SCENE)


def _cheap(model: Model) -> dict:
    """The coarsest rung of the model's ladder (no options without one)."""
    if model.name == "auto":
        return {"tolerance": AUTO_TOLERANCE}
    return {} if model.ladder is None else model.ladder.options_at(model.ladder.rungs[0])


@pytest.fixture(scope="module")
def direct():
    """Every registered model run once through :func:`run_model`."""
    return {name: run_model(name, _scene(model), **_cheap(model))
            for name, model in MODELS.items()}


def test_every_model_runs_through_the_one_path(direct):
    for name, result in direct.items():
        assert isinstance(result, ContactResult), name
        assert name in (result.model, "auto"), name
        assert result.total_force_N > 0, name
        assert result.scene == _scene(MODELS[name]).to_dict(), name


def test_every_model_runs_through_the_engine(direct, tmp_path):
    """The engine's worker (compute_case) runs the same path: equal inputs, equal answer."""
    cases = [Case(name, _scene(model), _cheap(model)) for name, model in MODELS.items()]
    with Engine("serial", quiet=True) as engine:
        outcomes = engine.run(cases, tmp_path / "cases")
    for case, outcome in zip(cases, outcomes):
        assert outcome.ok, (case.model, outcome.error)
        assert outcome.result.total_force_N == pytest.approx(
            direct[case.model].total_force_N, rel=1e-12), case.model


def test_every_candidate_model_is_planned_and_auto_runs_the_choice(direct):
    """Each model the planner may choose appears among the plan's candidates with the
    regimes of its declaration; ``auto`` runs the planned model with the planned options."""
    from validation.planner import plan

    scene = load_scene(SCENE)
    p = plan(scene, tolerance=AUTO_TOLERANCE)
    planned = {c["model"] for c in p["candidates"]}
    for name, model in MODELS.items():
        assert name in planned or not model.candidate, name
    # beyond the declarations' candidates, only hand entries of the data (fem-3d, the
    # elastic-pillar BEMs) until a recalibration measures them
    for c in load_data().candidates:
        if not MODELS[c["model"]].candidate or "pillars" in c["options"]:
            assert c["source"].startswith("hand"), c
    choice = p["choice"]
    assert choice is not None
    again = run_model(choice["model"], scene, **choice["options"])
    assert direct["auto"].total_force_N == pytest.approx(again.total_force_N, rel=1e-12)
    assert direct["auto"].diagnostics["plan"]["choice"]["label"] == choice["label"]


def test_option_specs_are_the_solvers_own():
    """A value inside a declared range is accepted by the solver, one outside is refused by
    both the registry and the solver: the ranges are the solvers' constants, not copies."""
    scene = load_scene("hertz")
    for name in ("bem", "bem-fft"):
        model = get_model(name)
        option = model.ladder.option
        spec = model.options[option]
        with pytest.raises(ValueError):
            check_option(option, spec.lo - 1, spec=spec)
        with pytest.raises(ValueError):
            run_model(name, scene, **{option: spec.lo - 1})
    with pytest.raises(ValueError, match=r"allowed range is \[0\.05, 4\]"):
        run_model("fem-3d", load_scene(SCENE), mesh_size=0.04)
    assert option_vocabulary()["mesh_size"].lo == get_model("fem-axisym").options["mesh_size"].lo


def test_fem3d_mesh_size_out_of_range_is_bad_input_like_fem_axisym(cli):
    """The same geometry check, the same error and exit status in both FEMs (2: bad input)."""
    for model, low in (("fem-axisym", 0.01), ("fem-3d", 0.04)):
        code, _, err = cli("solve", "--model", model, "--scene", SCENE, "--mesh-size", low)
        assert code == 2, (model, err)
        assert "mesh" in err and "allowed range" in err, err


# --- a new model: its declaration and its solver, nothing else ------------------------------
def solve_toy(scene, stiffness: float = 1.0, pillars: str = "hooke"):
    """A toy model: Hertz with the reduced modulus scaled by ``stiffness``; ``pillars`` is an
    option with choices like the elastic-pillar BEM's (``elastic`` halves the force)."""
    hz = analytic.hertz(scene)
    force = hz.force * stiffness * (0.5 if pillars == "elastic" else 1.0)
    return ContactResult(
        model="toy", scene=scene.to_dict(), discretisation={"stiffness": stiffness},
        total_force_N=force, centre_pressure_Pa=hz.centre_pressure,
        contact_radius_m=hz.contact_radius, real_contact_area_m2=hz.contact_area, pillars_in_contact=0, pillar_forces=[],
        converged=True, iterations=1, wall_time_s=0.0)


TOY = Model("toy", f"{__name__}:solve_toy", "a toy model",
            options={"stiffness": OptionSpec(float, 0.5, 4.0, family=True, metavar="K",
                                             help="toy: modulus factor"),
                     "pillars": OptionSpec(str, choices=("hooke", "elastic"),
                                           help="toy: Hooke or elastic pillars")},
            ladder=Ladder("stiffness", 1.0, 2.0, "float", -1.0, (1.0, 2.0, 4.0)))


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.setitem(MODELS, "toy", TOY)
    return TOY


def test_a_declared_model_joins_every_command(toy, cli, tmp_path):
    hertz = analytic.hertz(load_scene("single-pillar")).force
    code, out, err = cli("solve", "--model", "toy", "--scene", "single-pillar", "--stiffness",
                         "2", "--pillars", "elastic", "--json")
    assert code == 0, err
    assert json.loads(out)["total_force_N"] == pytest.approx(hertz * 2 * 0.5, rel=1e-12)
    # its options are checked with the name the user wrote, and refused for other models
    code, _, err = cli("solve", "--model", "toy", "--scene", "hertz", "--stiffness", "9")
    assert code == 2 and "--stiffness" in err
    code, _, err = cli("solve", "--model", "bem", "--scene", "hertz", "--stiffness", "2")
    assert code == 2 and "--stiffness 2: does not apply to --model bem" in err
    # an option two models share (the BEMs' --pillars) stays each model's own
    code, _, err = cli("solve", "--model", "fem-axisym", "--scene", "hertz", "--pillars",
                       "elastic")
    assert code == 2 and "does not apply to --model fem-axisym" in err
    # its ladder joins the studies
    assert "toy" in ladders()
    code, _, err = cli("converge", "--model", "toy", "--scene", "hertz", "--levels", "3",
                       "--executor", "serial", "--out", tmp_path / "converge")
    assert code == 0, err
    levels = json.loads((tmp_path / "converge" / "converge.json").read_text())["levels"]
    assert [lv["value"] for lv in levels] == [1.0, 2.0, 4.0]
    # and a sweep spec names it like any other model
    spec = tmp_path / "toy.toml"
    spec.write_text('scene = "single-pillar"\n[grid]\n"load.indentation_um" = [0.1, 0.2]\n'
                    '[[models]]\nname = "toy"\npillars = ["hooke", "elastic"]\n')
    code, _, err = cli("sweep", spec, "--out", tmp_path / "sweep", "--executor", "serial")
    assert code == 0, err


# --- the case key hashes all the code that computes ------------------------------------------
def test_a_change_to_the_planner_data_changes_autos_key(tmp_path, monkeypatch):
    """The planner and its data decide ``auto``'s result: an edit of its data gives ``auto``
    a new key (a faithful copy gives the same key), and leaves other models' keys alone."""
    from validation.engine import _case

    scene = load_scene(SCENE)
    planner = _case.package_root("validation.planner")
    assert (planner / "data" / "cost_models.json").is_file()
    copy = tmp_path / "planner"
    shutil.copytree(planner, copy, ignore=shutil.ignore_patterns("__pycache__"))
    real_root = _case.package_root

    def keys():
        _case.code_digest.cache_clear()
        _case.code_version.cache_clear()
        return case_key("auto", scene, {}), case_key("bem", scene, {})

    before = keys()
    monkeypatch.setattr(_case, "package_root",
                        lambda name: copy if name == "validation.planner" else real_root(name))
    assert keys() == before
    data = copy / "data" / "cost_models.json"
    doc = json.loads(data.read_text())
    doc["models"]["bem"]["coef"][0] *= 2.0  # a recalibration
    data.write_text(json.dumps(doc, indent=1))
    after = keys()
    assert after[0] != before[0]
    assert after[1] == before[1]
    monkeypatch.undo()
    _case.code_digest.cache_clear()
    _case.code_version.cache_clear()


def test_the_registry_is_in_every_key(tmp_path, monkeypatch):
    """Which options reach a solver is the registry's: an edit of it changes every key."""
    from validation.engine import _case

    scene = load_scene(SCENE)
    copy = tmp_path / "registry"
    shutil.copytree(_case.package_root("validation.registry"), copy,
                    ignore=shutil.ignore_patterns("__pycache__"))
    real_root = _case.package_root
    _case.code_digest.cache_clear()
    _case.code_version.cache_clear()
    before = case_key("bem", scene, {})
    (copy / "models.py").write_text((copy / "models.py").read_text() + "\n# edited\n")
    monkeypatch.setattr(_case, "package_root",
                        lambda name: copy if name == "validation.registry" else real_root(name))
    _case.code_digest.cache_clear()
    _case.code_version.cache_clear()
    assert case_key("bem", scene, {}) != before
    monkeypatch.undo()
    _case.code_digest.cache_clear()
    _case.code_version.cache_clear()


def test_the_studies_reference_models_come_from_the_registry(monkeypatch):
    """Each reference role is declared by exactly one model, and the studies take theirs from
    the registry: a role declared twice, or by none, is an error, not a silent choice."""
    from validation.registry import MODELS, REFERENCE_ROLES, reference_model
    from validation.studies import compare, gecit, lattice

    assert {role: reference_model(role) for role in REFERENCE_ROLES} == {
        "single-pillar": "fem-axisym", "lattice": "fem-3d"}
    assert (compare.FEM, compare.FEM_3D, gecit.FEM, lattice.FEM_MODEL) == (
        "fem-axisym", "fem-3d", "fem-axisym", "fem-3d")
    twice = dataclasses.replace(MODELS["fem-3d"], reference_for=("lattice", "single-pillar"))
    monkeypatch.setitem(MODELS, "fem-3d", twice)
    with pytest.raises(ValueError, match="'single-pillar': 2 models"):
        reference_model("single-pillar")
    with pytest.raises(ValueError, match="'floor': 0 models"):
        reference_model("floor")
