"""``pillar-xval figures --pillars hooke|elastic|both``: the option, the two-column
figures.md, the verdicts on the paper's claims (constructed data that makes each hold or
fail), and the ``pillars`` column of every CSV.  Fast: the study is stubbed or its documents
constructed; one real quick ``both`` run is behind the ``slow`` marker."""

from __future__ import annotations

import copy
import csv
import json
import types

import numpy as np
import pytest

from validation.cli import main
from validation.studies.figures.claims import CLAIMS, claim_rows, write_claims_csv
from validation.studies.figures.fits import master_curve
from validation.studies.figures.report import write_report
from validation.studies.figures.scenes import FIG5_PHI, FigureGrid, table1_scene

ZETAS = (0.1, 0.2, 0.3)
RATIOS = (1e-3, 1.0, 1e6)
PHIS = tuple(np.geomspace(2.3e-3, 0.82, 8))


# --- the option -----------------------------------------------------------------------------
@pytest.fixture
def stubbed(monkeypatch):
    """run_figures replaced: records its keywords, returns an empty document."""
    from validation.studies import figures

    calls = []

    def stub(out, grid, **kw):
        calls.append(kw)
        return {"timing": {"unique_cases": 0, "cases_computed": 0, "threshold_solves": 0,
                           "total_s": 0.0, "scenes_s": 0.0, "threshold_bisection_s": 0.0,
                           "analysis_and_plots_s": 0.0, "executor": "serial"},
                "failed": [], "claims": []}

    monkeypatch.setattr(figures, "run_figures", stub)
    return calls


@pytest.mark.parametrize("value, expected", [
    (None, None), ("hooke", None), ("elastic", ("elastic",)), ("both", ("hooke", "elastic")),
    ("elastic,hooke", ("hooke", "elastic"))])
def test_pillars_values_reach_the_study(tmp_path, stubbed, value, expected):
    argv = ["figures", "--quick", "--executor", "serial", "--out", str(tmp_path / "f")]
    if value is not None:
        argv += ["--pillars", value]
    assert main(argv) == 0
    # hooke (the default) calls the study exactly as before: no pillars keyword at all.
    assert stubbed[-1].get("pillars") == expected


@pytest.mark.parametrize("bad", ["nope", "", "Hooke", "hooke,hooke", "both,elastic", "1"])
def test_bad_pillars_is_one_clear_line(tmp_path, stubbed, capsys, bad):
    code = main(["figures", "--pillars", bad, "--out", str(tmp_path / "f")])
    err = capsys.readouterr().err
    assert code == 2 and not stubbed
    assert "Traceback" not in err
    line = err.strip().splitlines()[-1]
    assert "--pillars" in line and repr(bad) in line
    assert all(word in line for word in ("hooke", "elastic", "both")), line


# --- constructed documents ----------------------------------------------------------------
def _curve(ratio, zeta_um, phi_s, phi_h, n=3.0, band=0.5):
    phi = np.array(PHIS)
    star = master_curve(phi, phi_s, phi_h, n)
    s_h, s_s = 8e3, 30e3
    return {"ratio": ratio, "zeta_um": zeta_um, "zeta_h": zeta_um / 2.0, "phi": phi.tolist(),
            "sigma0_Pa": (s_h + (s_s - s_h) * star).tolist(), "star": star.tolist(),
            "sigma0_hertz_Pa": s_h, "sigma0_single_Pa": s_s, "sigma0_single_closed_Pa": s_s,
            "single_from": "solver", "phi_s_fit": phi_s, "phi_h_fit": phi_h,
            "fit_rms": 0.01, "phi_h_band": band, "band_stays": True, "band_lowest": 0.95}


def make_doc(pillars="hooke", *, phi_h=0.33, phi_s=0.011, exponent=3.0, rms_n3=0.02,
             area=0.7, fig5_dev=0.01, phi_h_rise=-0.1, soft_up=0.05, band=0.4):
    """A study document whose claims hold by default; each keyword moves one claim."""
    curves = []
    for ratio in RATIOS:
        shift = soft_up if ratio == min(RATIOS) else 0.0
        for k, z in enumerate(ZETAS):
            factor = (1 + phi_h_rise) ** k
            curves.append(_curve(ratio, z, phi_s * (1 - 0.1 * k), (phi_h + shift) * factor,
                                 band=band))
    fig4a = [c for c in curves if c["zeta_um"] == 0.3]
    exact = [{"zeta_um": z, "ratio": r, "phi_s": 0.0112, "phi_s_paper": 0.0123,
              "phi_s_rim": 0.011, "phi_s_large_zeta": 0.01, "lo": 0.011, "hi": 0.0113,
              "rel_halfwidth": 0.01, "solves": 9, "zeta_h": z / 2.0}
             for z in ZETAS for r in RATIOS]
    grid = FigureGrid.quick().to_dict()
    grid["dpi"] = 50
    rows = {"fig4a": [], "fig4b": [], "fig5": [], "master": [], "fig3": []}
    for c in fig4a:
        for phi, s0 in zip(c["phi"], c["sigma0_Pa"]):
            rows["fig4a"].append({"ratio": c["ratio"], "phi": phi, "zeta_m": 0.3e-6,
                                  "sigma0_Pa": s0, "a_m": 2.4e-5, "A_m2": phi * 1.8e-9,
                                  "F_N": 3e-6, "pillars": 7, "converged": True})
    for phi in (0.03, 0.3):
        for z in ZETAS:
            rows["fig4b"].append({"ratio": 1.0, "phi": phi, "zeta_m": z * 1e-6,
                                  "sigma0_Pa": 2e4, "a_m": 2e-5 * z, "A_m2": phi * 1.2e-9 * z,
                                  "F_N": 1e-6, "pillars": 5, "converged": True})
    for e in (1e3, 1.6e6, 1e12):
        rows["fig5"].append({"ratio": e / 1.6e6, "phi": FIG5_PHI, "zeta_m": 0.3e-6,
                             "E_p_Pa": e, "sigma0_Pa": 3e4, "converged": True})
    points = [{"ratio": c["ratio"], "zeta_m": c["zeta_um"] * 1e-6, "phi": phi,
               "phi_star": (phi - c["phi_s_fit"]) / c["phi_h_fit"], "sigma_star": s,
               "area_star": phi**area, "area_star_tops": phi**area}
              for c in curves for phi, s in zip(c["phi"], c["star"])]
    return {
        "pillars": pillars, "grid": grid, "model": "bem-richardson",
        "options": {"elements_per_diameter": 5}, "rows": rows, "fig4a_curves": fig4a,
        "thresholds": {
            "band": 0.1, "curves": curves, "exact": exact,
            "large_zeta": {"zeta_h": [z / 2.0 for z in ZETAS], "phi_s": [0.01] * 3},
            "zeta_t_over_h": {str(r): 0.01 for r in RATIOS},
            "common_exponent": {"exponent": exponent, "rms": rms_n3 * 0.9, "rms_n3": rms_n3,
                                "profile": [{"exponent": 3.0, "rms": rms_n3}]},
            "area_exponent": {"exponent": area, "rms": 0.01, "points": 20,
                              "tops": {"exponent": area, "rms": 0.01, "points": 20}}},
        "master_points": points, "fig3": [], "fig3_search": [],
        "fig5": [{"El_over_Ep": 1.6e6 / e, "E_p_Pa": e, "sigma0_Pa": 3e4 * (1 + fig5_dev),
                  "closed_form_Pa": 3e4} for e in (1e3, 1.6e6, 1e12)],
        "failed": []}


def _holds(doc) -> dict:
    return {r["key"]: r["x"]["holds"] for r in claim_rows({"x": doc})}


def test_every_claim_holds_on_data_built_to_hold():
    assert _holds(make_doc()) == {key: True for key, *_ in CLAIMS}


@pytest.mark.parametrize("change, key", [
    ({"fig5_dev": 0.05}, "fig5_spring_model"),
    ({"phi_s": 0.03}, "phi_s_fit"),
    ({"phi_h": 0.6}, "phi_h_fit"),
    ({"band": 0.7}, "phi_h_band"),
    ({"band": None}, "phi_h_band"),
    ({"exponent": 4.0}, "master_exponent"),
    ({"rms_n3": 0.08}, "master_collapse"),
    ({"area": 0.9}, "area_exponent"),
    ({"phi_h_rise": 0.1}, "thresholds_decrease"),
    ({"phi_h": 0.08, "phi_h_rise": -0.01}, "thresholds_separated"),
    ({"soft_up": -0.05}, "soft_shift"),
])
def test_each_claim_can_fail(change, key):
    holds = _holds(make_doc(**change))
    assert holds[key] is False, holds
    # The change breaks that claim; the Fig. 5 and area claims do not follow any other.
    assert holds["fig5_spring_model"] is (key != "fig5_spring_model")
    assert holds["area_exponent"] is (key != "area_exponent")


def test_exact_threshold_claim_fails_outside_the_widened_range():
    doc = make_doc()
    for e in doc["thresholds"]["exact"]:
        e["phi_s"] = 0.0135 * 1.25  # 25 % above the paper's upper end
    assert _holds(doc)["phi_s_exact"] is False


def test_missing_data_is_undecided_not_a_verdict():
    doc = make_doc()
    doc["fig5"] = []
    doc["fig4a_curves"] = []
    holds = _holds(doc)
    assert holds["fig5_spring_model"] is None and holds["phi_s_fit"] is None


def test_figures_md_has_both_columns_and_the_verdicts(tmp_path):
    docs = {"hooke": make_doc("hooke"), "elastic": make_doc("elastic", fig5_dev=0.3,
                                                             area=0.95)}
    doc = {"pillars": ["hooke", "elastic"], "grid": docs["hooke"]["grid"],
           "model": "bem-richardson", "options": {"elements_per_diameter": 5},
           "variants": docs, "failed": [], "claims": claim_rows(docs),
           "timing": {"pillar_kinds": 1, "pillar_kinds_built": 0}}
    (path,) = write_report(tmp_path, doc)
    text = path.read_text()
    assert "| quantity | paper | ours, Hooke pillars | difference | ours, elastic pillars | " \
           "difference | note |" in text
    head = "| figure | the paper's claim | criterion | Hooke pillars | holds | elastic pillars " \
           "| holds |"
    assert head in text and "E_s = E_p" in text
    fig5 = next(line for line in text.splitlines() if line.startswith("| Fig. 5 |"))
    cells = [c.strip() for c in fig5.strip("|").split("|")]
    assert cells[4] == "**yes**" and cells[6] == "**no**"  # Hooke holds, elastic does not
    area = next(line for line in text.splitlines() if "| A* = Phi^0.7 |" in line)
    assert area.rstrip().endswith("| **yes** | 0.95 (rms 0.01 decades) | **no** |")
    assert "(Hooke pillars)" in text and "(elastic pillars)" in text
    # claims.csv: one line per claim and pillar model, readable by a script.
    write_claims_csv(tmp_path, doc["claims"], ["hooke", "elastic"])
    with open(tmp_path / "claims.csv") as fh:
        lines = list(csv.DictReader(fh))
    assert len(lines) == 2 * len(CLAIMS)
    assert {(r["key"], r["pillars"], r["holds"]) for r in lines} >= {
        ("fig5_spring_model", "hooke", "yes"), ("fig5_spring_model", "elastic", "no")}


def test_single_model_report_keeps_its_one_column(tmp_path):
    doc = make_doc("hooke")
    doc["claims"] = claim_rows({"hooke": doc})
    text = write_report(tmp_path, doc)[0].read_text()
    assert "| quantity | paper | ours | difference | note |" in text
    assert "| figure | the paper's claim | criterion | Hooke pillars | holds |" in text
    assert "elastic pillars |" not in text


def test_every_csv_names_the_pillar_model(tmp_path):
    from validation.studies.figures.files import write_figures

    docs = {v: make_doc(v) for v in ("hooke", "elastic")}
    scene5 = table1_scene(FIG5_PHI, 0.3, 1.0)
    pairs = {v: {"fig3": [], "fig5": [(types.SimpleNamespace(scene=scene5), None)]}
             for v in docs}
    write_figures(tmp_path, docs, pairs)
    for k in range(4, 9):
        with open(tmp_path / f"fig{k}.csv") as fh:
            reader = csv.DictReader(fh)
            assert reader.fieldnames[0] == "pillars"
            seen = {r["pillars"] for r in reader}
        assert seen == {"hooke", "elastic"}, k
    # One pillar model: the same columns, one value.
    one = tmp_path / "one"
    one.mkdir()
    write_figures(one, {"hooke": copy.deepcopy(docs["hooke"])}, {"hooke": pairs["hooke"]})
    with open(one / "fig5.csv") as fh:
        assert {r["pillars"] for r in csv.DictReader(fh)} == {"hooke"}


# --- one real run -------------------------------------------------------------------------
@pytest.mark.slow
def test_quick_figures_with_both_pillar_models(tmp_path, capsys):
    out = tmp_path / "both"
    code = main(["figures", "--quick", "--pillars", "both", "--out", str(out), "--executor",
                 "serial", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and doc["pillars"] == ["hooke", "elastic"]
    assert set(doc["variants"]) == {"hooke", "elastic"}
    assert doc["timing"]["pillar_kinds"] == 1  # E_s = E_p, h/d and nu fixed: one kind
    with open(out / "fig4.csv") as fh:
        assert {r["pillars"] for r in csv.DictReader(fh)} == {"hooke", "elastic"}
    # The elastic pillar's single-pillar sigma_0 at E_p = E_l is not the spring model's.
    with open(out / "fig5.csv") as fh:
        rows = [r for r in csv.DictReader(fh) if float(r["E_p_Pa"]) == 1.6e6]
    s = {r["pillars"]: float(r["centre_pressure_Pa"]) for r in rows}
    assert s["elastic"] > 1.2 * s["hooke"]
