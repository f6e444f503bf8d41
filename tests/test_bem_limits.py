"""The dense BEM against closed-form limits, the paper's Fig. 3 and its own refinement."""

import math

import numpy as np
import pytest

from bem_solver import solve_dense
from pillar_xval.scenes import analytic as an
from pillar_xval.scenes import load_scene

# Rigid flat punch with covered cells, measured: force error -2.4 % (P = 11), -1.37 % (21),
# -0.79 % (41), falling monotonically ~ P^-0.8 (the 1/sqrt edge singularity); centre
# pressure +2.5 %, +1.7 %, +1.2 %.
RTOL_PUNCH_P21 = 0.02
# Hertz (flat scene): force +0.28 % (P = 11), +0.066 % (21), +0.011 % (41), second order.
RTOL_HERTZ_P21 = 0.002


def test_rigid_punch_limit():
    scene = load_scene("single-pillar", ["pillars.rigid=true", "substrate.rigid=true"])
    punch = an.rigid_punch(scene)
    r = solve_dense(scene, 21)
    assert r.converged and r.pillars_in_contact == 1
    assert r.total_force_N == pytest.approx(punch.force, rel=RTOL_PUNCH_P21)
    assert r.centre_pressure_Pa == pytest.approx(punch.centre_pressure, rel=RTOL_PUNCH_P21)
    assert r.real_contact_area_m2 == pytest.approx(math.pi * 4e-12, rel=1e-12)
    # Stiff pillars and substrate approach the same limit.
    stiff = solve_dense(load_scene("single-pillar", ["pillars.E_Pa=1.6e15",
                                                     "substrate.E_Pa=1.6e15"]), 21)
    assert stiff.total_force_N == pytest.approx(r.total_force_N, rel=1e-6)


def test_hertz_limit():
    scene = load_scene("hertz")
    hz = an.hertz(scene)
    r = solve_dense(scene, 21)
    assert r.pillars_in_contact == 0 and r.pillar_forces == []
    assert r.total_force_N == pytest.approx(hz.force, rel=RTOL_HERTZ_P21)
    assert r.centre_pressure_Pa == pytest.approx(hz.centre_pressure, rel=RTOL_HERTZ_P21)
    b = 2 * hz.contact_radius / 21
    assert abs(r.contact_radius_m - hz.contact_radius) < b  # resolved to one element
    prof = r.pillar_top_profile
    inner = np.array(prof["r_m"]) < 0.8 * hz.contact_radius
    assert np.allclose(np.array(prof["pressure_Pa"])[inner],
                       hz.pressure(np.array(prof["r_m"])[inner]), rtol=0.01)


@pytest.mark.parametrize("E_p", [1e3, 1.6e5, 1.6e6, 1.6e7, 1e12])
def test_soft_flat_punch_limit_across_stiffness(E_p):
    # A Hooke pillar shortens uniformly, so under a flat lens the half-spaces see a flat punch:
    # the spring model is then the exact continuum answer and the BEM error is the punch's
    # discretisation error.  (At R = 2 mm the lens sag over the pillar top, 1 nm, is not
    # negligible against the half-space share of zeta when E_p << E_l: the BEM is then right
    # and the spring model off by up to 3 %.)  R = 2 m, one pillar within the overlap radius.
    scene = load_scene("single-pillar", [f"pillars.E_Pa={E_p}", f"substrate.E_Pa={E_p}",
                                         "lens.radius_mm=2000",
                                         "pillars.surface_fraction=1e-5"])
    model = an.spring_model(scene)
    r = solve_dense(scene, 21)
    assert r.total_force_N == pytest.approx(model.force, rel=RTOL_PUNCH_P21)
    assert r.centre_pressure_Pa == pytest.approx(model.centre_pressure, rel=RTOL_PUNCH_P21)


def test_convergence_in_P_with_covered_cells():
    scene = load_scene("single-pillar", ["pillars.rigid=true", "substrate.rigid=true"])
    exact = an.rigid_punch(scene).force
    Ps = [8, 16, 32]
    err = [abs(solve_dense(scene, P).total_force_N / exact - 1) for P in Ps]
    orders = np.diff(np.log(err)) / np.diff(np.log(Ps))
    assert err[0] > err[1] > err[2]
    # Observed order between 0.6 and 1.2 on each doubling (measured ~0.8 - 0.9).
    assert np.all((-orders > 0.6) & (-orders < 1.2)), orders


def test_paper_fig3_scenes():
    # The paper quotes two significant figures read from its figures (sigma_0 = 33 and 8 kPa,
    # F_T about 3 and 10 uN, 7 pillars at Phi = 0.03) with its P = 11 'centre' cells, whose
    # area alone is off by 2 %: 10 % on sigma_0 and 15 % on F_T cover rounding and that.
    sparse = solve_dense(load_scene("paper-fig3-sparse"), 11, "centre")
    dense = solve_dense(load_scene("paper-fig3-dense"), 11, "centre")
    assert sparse.pillars_in_contact == 7
    assert sparse.centre_pressure_Pa == pytest.approx(33e3, rel=0.10)
    assert dense.centre_pressure_Pa == pytest.approx(8e3, rel=0.10)
    assert sparse.total_force_N == pytest.approx(3e-6, rel=0.15)
    assert dense.total_force_N == pytest.approx(10e-6, rel=0.15)
    # Contact radii of the paper: a ~ e + d/2 (sparse) and ~ 5e + d/2 (dense).
    e_s, e_d = sparse.scene["pillars"]["pitch_m"], dense.scene["pillars"]["pitch_m"]
    assert sparse.contact_radius_m == pytest.approx(e_s + 2e-6, rel=0.05)
    # Dense: the paper says a ~ 5e + d/2 = 23 um; the outer edge of the ring-6 pillars on the
    # x axis (6e + d/2 = 27.2 um) lies beyond the contact, their inner part inside it.
    assert 5 * e_d + 2e-6 < dense.contact_radius_m < 6 * e_d + 2e-6


def test_paper_search_against_exact_complementarity():
    scene = load_scene("paper-fig3-sparse")
    exact = solve_dense(scene, 11, contact="exact")
    paper = solve_dense(scene, 11, contact="paper")
    assert paper.converged and paper.diagnostics["search_stopped"]
    for key in ("min_pressure_Pa", "max_interpenetration_m"):
        assert key in paper.diagnostics
    # On this scene every pillar in the overlap radius is fully pressed: the search and the
    # exact solver find the same contact set, hence the same linear solve (to round-off).
    assert paper.pillars_in_contact == exact.pillars_in_contact
    assert paper.total_force_N == pytest.approx(exact.total_force_N, rel=1e-9)
    assert paper.real_contact_area_m2 == pytest.approx(exact.real_contact_area_m2, rel=1e-12)


@pytest.mark.parametrize("overrides", [
    ["pillars.E_Pa=160"],                   # E_p / E_l = 1e-4
    ["pillars.E_Pa=1.6e15"],                # E_p / E_l = 1e9
    ["pillars.surface_fraction=0.002"],
    ["load.indentation_um=0.002"],           # zeta = 1e-3 h
    ["load.indentation_um=1.8", "pillars.surface_fraction=0.002"],  # zeta = 0.9 h
    ["load.indentation_um=0.002", "pillars.surface_fraction=0.9"],
])
def test_extremes_converge_and_stay_finite(overrides):
    r = solve_dense(load_scene("paper-fig3-sparse", overrides), 7)
    assert r.converged
    values = [r.total_force_N, r.centre_pressure_Pa, r.contact_radius_m, r.real_contact_area_m2]
    assert all(math.isfinite(v) and v > 0 for v in values)
    r.to_json()  # refuses NaN and inf
