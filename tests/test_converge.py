"""``pillar-xval converge`` against fake models with known convergence (tests/fakes.py), and
the real ones (slow)."""

import csv
import json

import pytest

from pillar_xval.scenes import analytic, load_scene
from validation.cli import main
from validation.engine import Case, Engine, case_key
from validation.registry import ladders
from validation.studies.converge import converge_study

def test_ladders_refine_as_documented():
    assert [ladders()["bem"].value(k) for k in range(4)] == [11, 23, 47, 95]
    assert [ladders()["fem-axisym"].value(k) for k in range(3)] == [1.0, 0.5, 0.25]
    assert [ladders()["bem-fft"].value(k) for k in range(3)] == [32, 64, 128]
    assert ladders()["bem"].size(11) == pytest.approx(1 / 11)
    assert ladders()["bem"].options(1) == {"cells": "covered", "elements_per_diameter": 23}


def test_case_key_depends_on_physics_not_name():
    a = load_scene("single-pillar")
    b = a.replace(name="renamed")
    c = load_scene("single-pillar", ["load.indentation_um=0.2"])
    opts = {"mesh_size": 0.5}
    assert case_key("fem-axisym", a, opts) == case_key("fem-axisym", b, opts)
    assert case_key("fem-axisym", a, opts) != case_key("fem-axisym", c, opts)
    assert case_key("fem-axisym", a, opts) != case_key("fem-axisym", a, {"mesh_size": 0.25})
    assert case_key("fem-axisym", a, opts) != case_key("bem", a, opts)


def test_study_recovers_fake_order_and_resumes(fakes, tmp_path):
    scene = load_scene("single-pillar")
    data = converge_study("fem-axisym", scene, 4, tmp_path)
    assert [c[1] for c in fakes] == [1.0, 0.5, 0.25, 0.125]
    spring = analytic.spring_model(scene)
    gci = data["studies"]["F_T"]["gci"]
    assert gci["status"] == "ok" and gci["order"] == pytest.approx(2.0, abs=1e-9)
    assert gci["f_exact"] == pytest.approx(spring.force, rel=1e-12)
    assert data["studies"]["F_T"]["lsq"]["order"] == pytest.approx(2.0, abs=1e-9)
    # a and A do not change with the mesh: reported as round-off, never NaN
    assert data["studies"]["a"]["gci"]["status"] == "round-off"
    fakes.clear()
    again = converge_study("fem-axisym", scene, 4, tmp_path)
    assert fakes == [] and all(lv["cached"] for lv in again["levels"])
    assert again["studies"]["F_T"]["gci"] == gci


def test_engine_writes_vtu_when_model_can(fakes, tmp_path):
    scene = load_scene("single-pillar")
    engine = Engine("serial")
    out = engine.run_one(Case("fem-axisym", scene, {"mesh_size": 1.0}, vtu=True), tmp_path)
    assert len(list(tmp_path.glob("*.vtu"))) == 1 and len(list(tmp_path.glob("*.json"))) == 1
    assert out.files["fields.vtu"].exists()
    engine.run_one(Case("bem", scene, {"elements_per_diameter": 11}, vtu=True), tmp_path)
    assert len(list(tmp_path.glob("*.vtu"))) == 1  # the BEM has no VTU option


def test_cli_converge_writes_report(fakes, tmp_path, capsys):
    out = tmp_path / "conv"
    rc = main(["converge", "--scene", "hertz", "--model", "bem", "--levels", "3",
               "--out", str(out)])
    assert rc == 0
    for name in ("converge.json", "levels.csv", "gci.csv", "convergence.png"):
        assert (out / name).stat().st_size > 0
    report = json.loads((out / "converge.json").read_text())
    assert [lv["value"] for lv in report["levels"]] == [11, 23, 47]
    # P = 11, 23, 47 is not a constant ratio: the general-ratio order must still be 2
    assert report["studies"]["sigma0"]["gci"]["order"] == pytest.approx(2.0, abs=1e-8)
    rows = list(csv.DictReader((out / "gci.csv").open()))
    assert [r["quantity"] for r in rows] == ["F_T", "sigma0", "a", "A"]
    text = capsys.readouterr()
    assert "F_T" in text.out and "report:" in text.out and "[converge" in text.err


def test_cli_converge_bad_input_exits_2(fakes, tmp_path, cli):
    code, _, err = cli("converge", "--scene", "hertz", "--levels", "1", "--out", tmp_path,
                       "--executor", "serial")
    assert code == 2 and "--levels" in err and "'1'" not in err and "[2, 8]" in err
    assert cli("converge", "--scene", "nowhere", "--out", tmp_path)[0] == 2
    assert fakes == []


def test_converge_defaults_to_bem_like_solve(fakes, tmp_path, cli):
    code, out, _ = cli("converge", "--scene", "hertz", "--levels", "2", "--out", tmp_path,
                       "--executor", "serial")
    assert code == 0 and out.startswith("bem on hertz")
    assert {c[0] for c in fakes} == {"bem"}


@pytest.mark.parametrize("argv, message", [
    # integer options parse strictly: 5.5 is not rounded to 5
    (["--elements-per-diameter", "5.5"], "'5.5': expected an integer"),
    (["--coarsest", "5"], "unrecognized arguments: --coarsest 5"),
    (["--mesh-size", "0.5"], "--mesh-size 0.5: does not apply to --model bem"),
    (["--model", "fem-axisym", "--elements-per-diameter", "11"],
     "--elements-per-diameter 11: does not apply to --model fem-axisym"),
    # every level of the ladder is checked before the first solve: 200, 401, 803 > 400
    (["--elements-per-diameter", "200", "--levels", "3"], "level 2 would be"),
    (["--model", "fem-axisym", "--mesh-size", "0.05", "--levels", "3"], "level 3 would be"),
])
def test_converge_refuses_bad_options_before_any_solve(fakes, tmp_path, cli, argv, message):
    code, out, err = cli("converge", "--scene", "hertz", "--out", tmp_path,
                         "--executor", "serial", *argv)
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert fakes == []


def test_converge_coarsest_is_the_family_option(fakes, tmp_path, cli):
    code, _, _ = cli("converge", "--scene", "hertz", "--model", "fem-axisym", "--mesh-size",
                     "2", "--levels", "3", "--out", tmp_path, "--json", "--executor", "serial")
    assert code == 0 and [c[1] for c in fakes] == [2.0, 1.0, 0.5]


@pytest.mark.slow
def test_real_fem_converges_on_single_pillar(tmp_path):
    """Observed order of the real axisymmetric FEM on the single-pillar scene."""
    # mesh_size 2, 1, 0.5 (0.25 alone costs minutes with the current FEM)
    scene = load_scene("single-pillar")
    data = converge_study("fem-axisym", scene, 3, tmp_path, coarsest=2.0)
    assert data["all_converged"]
    gci = data["studies"]["F_T"]["gci"]
    # measured (single-pillar, mesh_size 2, 1, 0.5): order 3.4, GCI_fine 1.2e-5; the bounds
    # leave room for another grading but fail on a first-order or noisy sequence
    assert gci["status"] == "ok" and gci["order"] > 1.5 and gci["gci_fine"] < 1e-3
    # the contact radius of one pillar is its rim on every mesh: "round-off" because the
    # values are equal, which is checked, not assumed
    a = data["studies"]["a"]["gci"]
    assert a["status"] == "round-off"
    assert a["f"] == pytest.approx([scene.pillars.diameter_m / 2] * 3, rel=1e-12)


def test_unreadable_cache_entry_is_recomputed(fakes, tmp_path):
    scene = load_scene("single-pillar")
    case = Case("fem-axisym", scene, {"mesh_size": 1.0})
    Engine("serial").run_one(case, tmp_path)
    (entry,) = [p for p in tmp_path.glob("*.json")]
    entry.write_text('{"model": "fem-axisym"}')  # an older schema
    fakes.clear()
    out = Engine("serial").run_one(case, tmp_path)
    assert not out.cached and fakes == [("fem", 1.0)] and out.result.converged
    assert Engine("serial").run_one(case, tmp_path).cached


def test_convergence_figure_of_a_level_that_missed_is_stamped(fakes, tmp_path, monkeypatch):
    import sys

    from fakes import fake_bem
    from validation.output import plots

    def stuck_at_23(scene, elements_per_diameter=11, **options):
        result = fake_bem(scene, elements_per_diameter, **options)
        result.converged = elements_per_diameter != 23
        result.diagnostics["message"] = "stuck"
        return result

    monkeypatch.setattr(sys.modules["xval_fakes"], "fake_bem", stuck_at_23)
    figures = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: figures.append(fig))
    assert main(["converge", "--scene", "hertz", "--out", str(tmp_path), "--executor",
                 "serial"]) == 1
    texts = [t.get_text() for t in figures[0].texts]
    assert "NOT CONVERGED" in texts and any("elements_per_diameter=23: stuck" in t
                                            for t in texts)
