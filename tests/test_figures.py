"""``pillar-xval figures``: the extrapolated dense model, the master-curve fits, the
thresholds, the pressure maps, and a coarse version of every figure."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from bem_solver._extrapolated import fine_level, richardson, solve_dense_extrapolated
from pillar_xval.scenes import analytic as an
from pillar_xval.scenes import load_scene
from validation.cli import main
from validation.engine import Engine
from validation.studies.figures.fits import (fit_area_exponent, fit_common_exponent,
                                             fit_thresholds, hertz_band_entry, master_curve)
from validation.studies.figures.scenes import table1_scene
from validation.studies.figures.thresholds import (analytic_thresholds, bisect_single_pillar,
                                                   rim_contact_radius)

# Fits of noise-free synthetic data recover their parameters to the optimiser's tolerance.
RTOL_FIT = 1e-5
# The extrapolated dense model against the exact flat punch (R = 2 m): measured |error|
# <= 0.48 % over P = 5, 7, 9 and E_p/E_l = 1, 1e6 (the covered-cell pattern's wobble from
# one P to the next, times P/(P - 1)); either level alone is off by 1.2-2.8 %.
RTOL_EXTRAPOLATED = 0.006
# Flat scene (Hertz), second-order extrapolation: measured |error| <= 0.18 % for P = 5..11.
RTOL_EXTRAPOLATED_HERTZ = 0.003
# The bisected single-pillar threshold sits above the continuum one by at most one element
# side over the pitch (the ring's first contact is resolved to its innermost element's
# collocation point): at P = 21 and zeta = 0.3 um, b/e = 0.19/38 = 0.5 %; plus the bracket.
RTOL_THRESHOLD_P21 = 0.008
# Quick figures (P = 7, 3 halvings of a +-15 % bracket): 1.5 % + 1.8 %.
RTOL_THRESHOLD_QUICK = 0.035
RTOL_SPRING_MODEL = 0.02


# --- the extrapolated dense model ------------------------------------------------------
def test_richardson_of_exact_first_order_data_is_exact():
    f = {p: 3.0 + 2.0 / p for p in (5, 9)}
    assert richardson(f[5], f[9], 5, 9) == pytest.approx(3.0, rel=1e-14)
    g = {p: 3.0 + 2.0 / p**2 for p in (5, 9)}
    assert richardson(g[5], g[9], 5, 9, order=2.0) == pytest.approx(3.0, rel=1e-14)
    assert [fine_level(p) for p in (3, 5, 9)] == [5, 9, 17]


@pytest.mark.parametrize("E_p", [1.6e6, 1e12])
def test_extrapolation_beats_both_levels_on_the_exact_flat_punch(E_p):
    # A flat lens (R = 2 m) on one Hooke pillar: the spring model is exact.
    scene = load_scene("single-pillar", [f"pillars.E_Pa={E_p}", f"substrate.E_Pa={E_p}",
                                         "lens.radius_mm=2000", "pillars.surface_fraction=1e-5"])
    exact = an.spring_model(scene)
    r = solve_dense_extrapolated(scene, 5)
    assert r.converged and r.model == "bem-richardson" and r.pillars_in_contact == 1
    assert r.total_force_N == pytest.approx(exact.force, rel=RTOL_EXTRAPOLATED)
    assert r.centre_pressure_Pa == pytest.approx(exact.centre_pressure, rel=RTOL_EXTRAPOLATED)
    fine = r.diagnostics["levels"][1]
    assert fine["elements_per_diameter"] == 9
    assert abs(fine["total_force_N"] / exact.force - 1) > 2 * RTOL_EXTRAPOLATED
    assert r.real_contact_area_m2 == pytest.approx(math.pi * 4e-12, rel=1e-12)


def test_extrapolation_on_a_flat_scene_is_second_order():
    scene = load_scene("hertz")
    hz = an.hertz(scene)
    r = solve_dense_extrapolated(scene, 5)
    assert r.diagnostics["extrapolation"].startswith("Richardson, order 2")
    assert r.total_force_N == pytest.approx(hz.force, rel=RTOL_EXTRAPOLATED_HERTZ)
    assert r.centre_pressure_Pa == pytest.approx(hz.centre_pressure,
                                                 rel=RTOL_EXTRAPOLATED_HERTZ)


def test_pillar_forces_add_up_to_the_extrapolated_force():
    r = solve_dense_extrapolated(load_scene("paper-fig3-sparse"), 3)
    assert r.pillars_in_contact == 7 == len(r.pillar_forces)
    assert sum(p.force_N for p in r.pillar_forces) == pytest.approx(r.total_force_N, rel=1e-12)
    assert all(p.force_N > 0 for p in r.pillar_forces)
    assert json.loads(r.to_json())["discretisation"]["fine_elements_per_diameter"] == 5
    assert len(r.fields["pressure_Pa"]) == r.diagnostics["unknowns"]  # the fine level's map


# --- fits -------------------------------------------------------------------------------
def test_master_curve_formula():
    assert master_curve([0.01, 0.02, 0.11], 0.01, 0.1) == pytest.approx(
        [1.0, 1.1**-3, 2.0**-3], rel=1e-14)


def test_fit_recovers_the_thresholds_of_a_master_curve():
    phi = np.geomspace(2.3e-3, 0.82, 20)
    star = (1 + np.maximum(phi - 0.0123, 0) / 0.34) ** -3
    fit = fit_thresholds(phi, star)
    assert fit["phi_s"] == pytest.approx(0.0123, rel=RTOL_FIT)
    assert fit["phi_h"] == pytest.approx(0.34, rel=RTOL_FIT)
    free = fit_thresholds(phi, (1 + np.maximum(phi - 0.02, 0) / 0.3) ** -2.5, exponent=None)
    assert free["exponent"] == pytest.approx(2.5, rel=1e-4)


def test_common_exponent_of_several_curves():
    phi = np.geomspace(2.3e-3, 0.82, 20)
    curves = [(phi, (1 + np.maximum(phi - s, 0) / h) ** -4.0)
              for s, h in ((0.01, 0.3), (0.03, 0.4), (0.005, 0.25))]
    fit = fit_common_exponent(curves)
    assert fit["exponent"] == pytest.approx(4.0, rel=1e-4)
    assert fit["phi_h"] == pytest.approx([0.3, 0.4, 0.25], rel=1e-4)


def test_area_exponent_and_hertz_band():
    phi = np.geomspace(1e-3, 0.8, 15)
    assert fit_area_exponent(phi, phi**0.7)["exponent"] == pytest.approx(0.7, rel=1e-12)
    # sigma_0 / sigma_0H = 2 Phi^-0.5 crosses 1.1 at Phi = (2/1.1)^2, exactly on a power law.
    entry = hertz_band_entry(phi * 10, 2.0 * (phi * 10) ** -0.5, 1.0, 0.1)
    assert entry["phi"] == pytest.approx((2 / 1.1) ** 2, rel=1e-12)
    assert entry["stays"] is False  # it keeps falling below 0.9
    assert hertz_band_entry(phi, 5 + 0 * phi, 1.0, 0.1)["phi"] is None


# --- thresholds -------------------------------------------------------------------------
def test_rim_radius_solves_the_threshold_equation():
    scene = table1_scene(0.01, 0.3, 1.0)
    r = rim_contact_radius(scene)
    R, d, zeta = 2e-3, 4e-6, 0.3e-6
    big_pi = an.stiffness_number(scene)
    gap = R - math.sqrt(R * R - r * r) + (2 / big_pi * math.asin(d / (2 * r)) - 1) * zeta
    assert abs(gap) < 1e-12 * zeta
    # Where the paper's root exists (r_S >= d) it is the same root.
    assert r == pytest.approx(an.second_pillar_radius(scene), rel=1e-9)


def test_bisected_threshold_follows_the_rim_not_the_paper(tmp_path):
    """The exact solver's single-pillar threshold matches e_S = r_S + d/2 (the ring touches
    at its inner rim), not [P]'s e_S = r_S, which is 12 % higher in Phi at zeta = 0.3 um."""
    with Engine("serial", quiet=True) as engine:
        (out,) = bisect_single_pillar([(0.3, 1.0)], engine, tmp_path, 21, 6)
    closed = analytic_thresholds(0.3, 1.0)
    assert out["rel_halfwidth"] < 0.003
    assert out["phi_s"] == pytest.approx(closed["phi_s_rim"], rel=RTOL_THRESHOLD_P21)
    assert abs(out["phi_s"] / closed["phi_s_paper"] - 1) > 5 * RTOL_THRESHOLD_P21


# --- the pressure map -------------------------------------------------------------------
def test_pressure_map_is_the_element_field():
    from validation.studies.figures.maps import ElementMap

    r = solve_dense_extrapolated(load_scene("paper-fig3-sparse"), 3)
    f = r.fields
    emap = ElementMap(r, f["pressure_Pa"])
    # Each representative's collocation point lies in its own cell.
    assert emap.values(f["x_m"], f["y_m"]) == pytest.approx(f["pressure_Pa"], rel=1e-14)
    # The map over the plane carries the fine level's force (pixel-limited).
    reach = r.contact_radius_m * 1.05
    img, _ = emap.image((-reach, reach, -reach, reach), 700)
    pixel = (2 * reach / 700) ** 2
    fine = r.diagnostics["levels"][1]["total_force_N"]
    assert np.nansum(img) * pixel == pytest.approx(fine, rel=0.01)
    assert np.isnan(emap.values([11e-6], [0.0]))[0]  # between the pillars


# --- the command ------------------------------------------------------------------------
def test_quick_figures_command(tmp_path, capsys):
    out = tmp_path / "figs"
    code = main(["figures", "--quick", "--out", str(out), "--executor", "serial", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0 and not doc["failed"]
    for k in range(3, 9):
        assert (out / f"fig{k}.png").stat().st_size > 5_000
        with open(out / f"fig{k}.csv") as fh:
            assert len(list(csv.reader(fh))) > 2
    text = (out / "figures.md").read_text()
    assert "| quantity | paper | ours | difference |" in text and "E_s = E_p" in text
    sparse = next(p for p in doc["fig3"] if p["phi"] < 0.5)
    assert sparse["pillars"] == 7  # the paper's Fig. 3a
    # Fig. 5: the single pillar against the spring model, which ignores the lens sag over
    # the pillar top (a relative a^2 (1 + s)/(R zeta) <= 1.2 % at zeta = 0.3 um), plus the
    # model's 0.6 % discretisation error.
    with open(out / "fig5.csv") as fh:
        for row in csv.DictReader(fh):
            assert float(row["centre_pressure_Pa"]) == pytest.approx(
                float(row["closed_form_Pa"]), rel=RTOL_SPRING_MODEL)
    # Figs. 7-8: the bisected threshold (P = 7, 3 halvings) against the rim-corrected
    # closed form: one element side over the pitch (0.57/38 um) plus the bracket (1.8 %).
    for e in doc["exact_phi_s"]:
        assert e["phi_s"] == pytest.approx(e["phi_s_rim"], rel=RTOL_THRESHOLD_QUICK)
    assert doc["timing"]["cases_computed"] == doc["timing"]["unique_cases"]
    # A rerun resumes: nothing is computed again.
    assert main(["figures", "--quick", "--out", str(out), "--executor", "serial",
                 "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["timing"]["cases_computed"] == 0
    assert again["fig3"] == doc["fig3"]


def test_figures_refuses_other_models_and_bad_resolution(tmp_path, capsys):
    assert main(["figures", "--model", "bem-fft", "--out", str(tmp_path)]) == 2
    assert "--model" in capsys.readouterr().err
    assert main(["figures", "--elements-per-diameter", "1", "--out", str(tmp_path)]) == 2
