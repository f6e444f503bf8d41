"""``pillar-xval converge`` against fake models with known convergence (and the real ones,
slow).  The fakes live here and are shared with test_compare.py and test_gecit.py."""

import csv
import importlib
import json
import math
import sys
import types

import numpy as np
import pytest

from scenes import ContactResult, PillarForce, analytic, load_scene
from validation import models
from validation.cli import main
from validation.engine import Case, Engine, case_key
from validation.ladders import LADDERS
from validation.studies.converge import converge_study

CALLS: list[tuple] = []
# Fake discretisation errors: f = f_exact (1 + C_FEM h^2) (FEM, h = mesh_size) and
# f_exact (1 + C_BEM / P^2) (BEM): both second order by construction.
C_FEM, C_BEM = 0.02, 0.5


def edge_exponent_of(scene) -> float:
    """The fake FEM's edge exponent: 1/2 for a rigid pillar, falling to 0 for a soft one."""
    ratio = scene.pillars.material.E_Pa / scene.lens.material.E_Pa
    return 0.5 * ratio / (1.0 + ratio)


def _profile(scene, n: int = 60):
    """Nodes graded towards the edge and sigma_0 (1 - (2r/d)^2)^(-lambda)."""
    if scene.is_flat:
        hz = analytic.hertz(scene)
        r = hz.contact_radius * np.linspace(0, 1, n)
        return r, hz.pressure(r)
    d = scene.pillars.diameter_m
    r = 0.5 * d * (1.0 - np.geomspace(1e-4, 1.0, n)[::-1])
    r[0] = 0.0
    r = np.append(r, 0.5 * d)
    s = analytic.spring_model(scene).centre_pressure
    inner = np.clip(1 - (2 * r / d) ** 2, 1e-4 * 2e-4, None)
    return r, s * inner ** (-edge_exponent_of(scene))


def _result(model, scene, factor, disc):
    if scene.is_flat:
        ref = analytic.hertz(scene)
        f, s0, a, area = ref.force, ref.centre_pressure, ref.contact_radius, ref.contact_area
    else:
        ref = analytic.spring_model(scene)
        d = scene.pillars.diameter_m
        f, s0, a, area = ref.force, ref.centre_pressure, d / 2, math.pi * d * d / 4
    r, p = _profile(scene)
    forces = [] if scene.is_flat else [PillarForce(0, 0, 0.0, 0.0, f * factor)]
    return ContactResult(
        model=model, scene=scene.to_dict(), discretisation=disc, total_force_N=f * factor,
        centre_pressure_Pa=s0 * factor, contact_radius_m=a, real_contact_area_m2=area,
        pillars_in_contact=0 if scene.is_flat else 1, pillar_forces=forces, converged=True,
        iterations=1, wall_time_s=0.01,
        pillar_top_profile={"r_m": r.tolist(), "pressure_Pa": (p * factor).tolist()})


def fake_fem(scene, mesh_size=1.0, *, vtu_path=None):
    CALLS.append(("fem", mesh_size))
    if vtu_path is not None:
        import meshio

        pts = np.array([[0, 0, 0], [1e-5, 0, 0], [1e-5, 1e-5, 0], [0, 1e-5, 0]], dtype=float)
        meshio.write(str(vtu_path), meshio.Mesh(
            pts, [("triangle", np.array([[0, 1, 2], [0, 2, 3]]))],
            point_data={"von_mises_Pa": np.array([1.0, 2.0, 3.0, 4.0])}))
    return _result("fem-axisym", scene, 1.0 + C_FEM * mesh_size**2, {"mesh_size": mesh_size})


def fake_bem(scene, elements_per_diameter=11, cells="covered", contact="exact"):
    CALLS.append(("bem", elements_per_diameter))
    return _result("bem", scene, 1.0 + C_BEM / elements_per_diameter**2,
                   {"elements_per_diameter": elements_per_diameter, "cells": cells})


@pytest.fixture
def fakes(monkeypatch):
    """Register the fake 'bem' and 'fem-axisym' in the model registry."""
    mod = types.ModuleType("xval_fakes")
    mod.fake_fem, mod.fake_bem = fake_fem, fake_bem
    monkeypatch.setitem(sys.modules, "xval_fakes", mod)
    monkeypatch.setitem(models.MODELS, "fem-axisym", ("xval_fakes", "fake_fem", ("mesh_size",)))
    monkeypatch.setitem(models.MODELS, "bem", ("xval_fakes", "fake_bem",
                                               ("elements_per_diameter", "cells", "contact")))
    CALLS.clear()
    return CALLS


def test_ladders_refine_as_documented():
    assert [LADDERS["bem"].value(k) for k in range(4)] == [11, 23, 47, 95]
    assert [LADDERS["fem-axisym"].value(k) for k in range(3)] == [1.0, 0.5, 0.25]
    assert [LADDERS["bem-fft"].value(k) for k in range(3)] == [32, 64, 128]
    assert LADDERS["bem"].size(11) == pytest.approx(1 / 11)
    assert LADDERS["bem"].options(1) == {"cells": "covered", "elements_per_diameter": 23}


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


def test_cli_converge_bad_input_exits_2(fakes, tmp_path, capsys):
    assert main(["converge", "--scene", "hertz", "--model", "bem", "--levels", "1",
                 "--out", str(tmp_path)]) == 2
    assert "--levels 1" in capsys.readouterr().err
    assert main(["converge", "--scene", "nowhere", "--out", str(tmp_path)]) == 2


def _available(module: str) -> bool:
    try:
        importlib.import_module(module)
        return True
    except ImportError:
        return False


@pytest.mark.slow
@pytest.mark.skipif(not _available("fem_reference"), reason="fem_reference not importable yet")
def test_real_fem_converges_on_single_pillar(tmp_path):
    """Observed order of the real axisymmetric FEM on the single-pillar scene."""
    if "fem-axisym" not in models.MODELS:
        pytest.skip("fem-axisym not registered in validation.models yet")
    # mesh_size 2, 1, 0.5 (0.25 alone costs minutes with the current FEM)
    data = converge_study("fem-axisym", load_scene("single-pillar"), 3, tmp_path, coarsest=2.0)
    gci = data["studies"]["F_T"]["gci"]
    assert data["all_converged"]
    assert gci["status"] in ("ok", "round-off")
    if gci["status"] == "ok":
        assert gci["gci_fine"] < 0.01  # the finest of three levels within 1 % in force


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
