"""``pillar-xval extremes``: the verdicts, the invariants they rest on, a fast subset of the
corners, the outputs."""

from __future__ import annotations

import json

import pytest

from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.scenes import ScopeError, load_scene
from validation.engine import Case, Outcome
from validation.studies.extremes.report import STATUSES, counts, summary_text, write_outputs
from validation.studies.extremes.run import corner_scenes, judge, run_extremes


def _result(F=1e-6, pressures=(2.0, 1.0, 0.0), pen=0.0, converged=True, forces=None):
    scene = load_scene("single-pillar")
    return ContactResult(
        model="bem", scene=scene.to_dict(), discretisation={}, total_force_N=F,
        centre_pressure_Pa=pressures[0], contact_radius_m=2e-6, real_contact_area_m2=1e-11,
        pillars_in_contact=1,
        pillar_forces=[PillarForce(0, 0, 0.0, 0.0, F if forces is None else forces)],
        converged=converged, iterations=3, wall_time_s=0.01,
        pillar_top_profile={"r_m": [0.0, 1e-6, 2e-6], "pressure_Pa": list(pressures)},
        diagnostics={"message": "ok" if converged else "no convergence",
                     "contact_residual": 1e-9,
                     "max_gap_violation_m": pen * scene.indentation_m})


def _outcome(result=None, error=None):
    case = Case("bem", load_scene("single-pillar"), {"elements_per_diameter": 7})
    return Outcome(case, result, error, timing={"wall_time_s": 0.01})


ENTRY = {"label": "test corner", "stiffened": "E_p"}


@pytest.mark.parametrize("base, deeper, stiffer, status, word", [
    (_result(), _result(F=2e-6), _result(F=1.5e-6), "pass", ""),
    (_result(pressures=(2.0, -0.1, 0.0)), _result(F=2e-6), _result(F=2e-6), "fail",
     "pressure_nonnegative"),
    (_result(pen=1e-3), _result(F=2e-6), _result(F=2e-6), "fail", "no_interpenetration"),
    (_result(), _result(F=0.5e-6), _result(F=2e-6), "fail", "F_increases_with_zeta"),
    (_result(), _result(F=2e-6), _result(F=0.9e-6), "fail", "F_increases_with_E"),
    (_result(forces=0.9e-6), _result(F=2e-6), _result(F=2e-6), "fail", "force_balance"),
    (_result(converged=False), _result(F=2e-6), _result(F=2e-6), "not converged",
     "no convergence"),
])
def test_verdicts_rest_on_the_invariants(base, deeper, stiffer, status, word):
    rec = judge(ENTRY, "bem", _outcome(base), _outcome(deeper), _outcome(stiffer))
    assert rec["status"] == status and word in rec["reason"]


def test_refusals_and_crashes_are_told_apart():
    refused = judge(ENTRY, "bem", _outcome(error=ScopeError("too big")), None, None)
    assert refused["status"] == "refused" and "too big" in refused["reason"]
    crashed = judge(ENTRY, "bem", _outcome(error=IndexError("oops")), None, None)
    assert crashed["status"] == "error" and "IndexError" in crashed["reason"]


def test_corners_cover_the_extremes():
    labels = [c["label"] for c in corner_scenes()]
    assert len(labels) == len(set(labels))
    # 5 parameters x 2 extremes, 2^5 corners, 2 mismatched materials at 4 nu, 3 more nu at
    # the nominal scene, 5 past the pillar tops (the floor), 8 flat corners
    assert len(labels) == 1 + 10 + 32 + 2 * 4 + 3 + 5 + 8
    scenes = {c["label"]: c["scene"] for c in corner_scenes()}
    soft = scenes["Ep- Es+"].pillars.material.E_Pa / scenes["Ep- Es+"].substrate.E_Pa
    assert soft == pytest.approx(1e-9)
    assert scenes["R+"].lens.radius_m == pytest.approx(1.0)
    assert scenes["zeta+"].indentation_m == pytest.approx(0.99 * 2e-6)
    assert scenes["floor: zeta=10h"].indentation_m == pytest.approx(10 * 2e-6)
    assert scenes["floor: h/d=0.05 zeta=5h"].pillars.height_m == pytest.approx(0.05 * 4e-6)


def test_fast_subset_of_the_extremes(tmp_path):
    doc = run_extremes(tmp_path, quick=True)
    by = {(r["corner"], r["model"]): r for r in doc["records"]}
    assert all(r["status"] in STATUSES for r in doc["records"])
    # no model breaks an invariant or crashes on these corners
    assert not [r for r in doc["records"] if r["status"] in ("fail", "error")], \
        summary_text(doc)
    for model in ("bem", "bem-fft", "hertz"):
        assert by[("nominal", model)]["status"] == "pass"
    assert by[("zeta-", "spring")]["status"] == "pass"
    assert by[("nominal", "fem-axisym")]["status"] == "refused"
    assert by[("nominal", "fem-3d")]["status"] == "pass"  # its elastic pillars, mesh_size 4
    # pillars 1e9 times softer than the substrate (where the FFT model once failed): the models say
    # plainly whether they converged
    assert by[("Ep- Es+", "bem")]["status"] == "pass"
    assert by[("Ep- Es+", "bem-fft")]["status"] in ("pass", "not converged")
    names = write_outputs(doc, tmp_path)
    assert (tmp_path / "extremes.png").stat().st_size > 5000
    saved = json.loads((tmp_path / "extremes.json").read_text())
    assert len(saved["records"]) == len(doc["records"]) and "extremes.csv" in names
    assert sum(sum(c.values()) for c in counts(doc).values()) == len(doc["records"])
    # resumable: a second run reads every case from the cache
    again = run_extremes(tmp_path, quick=True)
    assert [r["status"] for r in again["records"]] == [r["status"] for r in doc["records"]]


def test_fem3d_is_skipped_for_cost_or_refused_on_wide_lattices():
    from validation.studies.extremes.run import FEM3D_MAX_DOFS, model_options, skip_reason

    scenes = {c["label"]: c["scene"] for c in corner_scenes()}
    opts = model_options()["fem-3d"]
    assert skip_reason("fem-3d", scenes["nominal"], opts) is None
    assert skip_reason("bem", scenes["R+"], model_options()["bem"]) is None
    why = skip_reason("fem-3d", scenes["R+"], opts)  # a 1 m lens: ~1e2-1e3 sector pillars
    assert why and "skipped for cost" in why and f"{FEM3D_MAX_DOFS:.2g}" in why
