"""``pillar-xval compare`` on fake models with known errors (and the real models, slow)."""

import importlib
import json

import pytest

from scenes import analytic, load_scene
from validation import models
from validation.cli import main
from validation.studies.compare import closed_form, compare_rows

from test_converge import C_BEM, C_FEM, fakes  # noqa: F401  (fixture)


def _run(tmp_path, scene, *extra):
    out = tmp_path / scene
    rc = main(["compare", "--scene", scene, "--out", str(out), *extra])
    return rc, out, json.loads((out / "report.json").read_text())


def test_compare_single_pillar_on_fakes(fakes, tmp_path, capsys):  # noqa: F811
    rc, out, report = _run(tmp_path, "single-pillar", "--no-render", "--fem-coarsest", "1",
                           "--bem-levels", "1")
    assert rc == 0
    for name in ("summary.md", "profiles.png", "profiles.csv", "fem_finest.vtu"):
        assert (out / name).stat().st_size > 0
    rows = {r["quantity"]: r for r in report["rows"]}
    spring = analytic.spring_model(load_scene("single-pillar"))
    f_t = rows["F_T"]
    # fake FEM: spring (1 + C h^2), h = 1, 1/2, 1/4: Richardson recovers the spring force
    assert f_t["fem_order"] == pytest.approx(2.0, abs=1e-9)
    assert f_t["fem_richardson"] == pytest.approx(spring.force, rel=1e-12)
    assert f_t["fem"] == pytest.approx(spring.force * (1 + C_FEM / 16))
    assert f_t["bem"] == pytest.approx(spring.force * (1 + C_BEM / 121))
    assert f_t["u_fem"] == pytest.approx(1.25 * spring.force * C_FEM * 3 / 16 / 3)
    assert f_t["exceeds"] is True and f_t["u_fem_is_gci"]
    # contact radius is d/2 on every level: zero difference, round-off status, not exceeding
    assert rows["a"]["fem_status"] == "round-off" and rows["a"]["exceeds"] is False
    assert "sigma(r=0.5)" in rows and rows["sigma(r=0.5)"]["fem_order"] == pytest.approx(2.0)
    assert "skipped" in report["render"]
    text = capsys.readouterr().out
    assert "F_T [uN]" in text and "exceeds U" in text and "report:" in text


def test_compare_refined_bem_adds_its_band(fakes, tmp_path):  # noqa: F811
    rc, out, report = _run(tmp_path, "hertz", "--no-render")  # defaults: 3 BEM, 3 FEM levels
    assert rc == 0
    row = next(r for r in report["rows"] if r["quantity"] == "F_T")
    assert row["u_bem"] > 0 and row["uncertainty"] == pytest.approx(
        (row["u_fem"] ** 2 + row["u_bem"] ** 2) ** 0.5)
    assert report["closed_form"]["name"] == "Hertz"
    assert report["bem"]["levels"][-1]["value"] == 47
    assert [lv["value"] for lv in report["fem"]["levels"]] == [2.0, 1.0, 0.5]


def test_compare_render_never_fails_the_run(fakes, tmp_path):  # noqa: F811
    rc, out, report = _run(tmp_path, "single-pillar")
    assert rc == 0
    assert report["render"].startswith(("rendered", "not rendered"))
    if report["render"].startswith("rendered"):
        assert (out / "fem_stress_3d.png").stat().st_size > 0


def test_compare_rows_verdicts():
    fem_st = {"F_T": {"gci": {"status": "ok", "uncertainty": 0.1, "fallback_uncertainty": 0.1,
                              "f_exact": 1.0, "order": 2.0}},
              "sigma0": {"gci": {"status": "oscillatory", "uncertainty": None,
                                 "fallback_uncertainty": 0.5, "f_exact": None, "order": None}}}
    rows = {r["quantity"]: r for r in compare_rows(
        {"F_T": 1.2, "sigma0": 2.2}, {"F_T": 1.05, "sigma0": 2.0}, None, fem_st, {})}
    assert rows["F_T"]["exceeds"] is True and rows["F_T"]["u_fem_is_gci"]
    assert rows["sigma0"]["exceeds"] is False and not rows["sigma0"]["u_fem_is_gci"]
    assert rows["a"]["exceeds"] is None  # nothing to compare


def test_closed_form_columns():
    name, ref = closed_form(load_scene("hertz"))
    hz = analytic.hertz(load_scene("hertz"))
    assert name == "Hertz" and ref["sigma(r=0.5)"] == pytest.approx(hz.centre_pressure * 0.75**0.5)
    name, ref = closed_form(load_scene("single-pillar"))
    assert name == "spring model" and ref["a"] == pytest.approx(2e-6)


def _real_models() -> str | None:
    for module in ("bem_solver", "fem_reference"):
        try:
            importlib.import_module(module)
        except ImportError as exc:
            return f"{module} not importable yet ({exc})"
    for name in ("bem", "fem-axisym"):
        if name not in models.MODELS:
            return f"model {name!r} not registered in validation.models yet"
    return None


@pytest.mark.slow
@pytest.mark.parametrize("scene", ["single-pillar", "hertz"])
def test_real_compare(scene, tmp_path):
    """BEM and FEM agree where the BEM's assumptions hold (Hertz; a stiff pillar)."""
    reason = _real_models()
    if reason:
        pytest.skip(reason)
    rc, out, report = _run(tmp_path, scene)
    assert rc == 0
    rows = {r["quantity"]: r for r in report["rows"]}
    if scene == "hertz":  # both models solve the same problem: no real difference
        assert not rows["F_T"]["exceeds"] and not rows["sigma0"]["exceeds"]
    else:  # E_p = E_l: the Hooke pillar's force is off by -0.55 % (Gecit study), its
        # centre pressure by -37 %; bound the force at 2 %, 4x the measured gap
        assert abs(rows["F_T"]["relative_difference"]) < 0.02
    assert (out / "summary.md").exists()
