"""Invariants of the dense BEM operator: Love's formula, cells, symmetry reduction, scaling."""

import math

import numpy as np
import pytest
from scipy.integrate import dblquad

from pillar_xval.contact import solve_active_set as solve_contact
from bem_solver import (cell_pattern, discretise, disk_rectangle_area, expansion, full_operator,
                        lens_gap, love_rectangle, reduced_operator, solve_dense)
from bem_solver._love import (FAR_FIELD_RATIO, FAR_FIELD_RTOL, love_square_near,
                              unit_force_influence)
from pillar_xval.scenes import load_scene

RTOL_ROUNDOFF = 1e-12   # identities that hold exactly up to floating-point rounding
RTOL_QUADRATURE = 1e-9  # adaptive quadrature of the 1/r integral


@pytest.mark.parametrize("x, y", [(0.3, 0.1), (1.0, 0.0), (2.5, -1.2), (-0.5, 0.5), (0.2, 0.0)])
def test_love_matches_quadrature(x, y):
    a, b = 0.5, 0.3
    exact, _ = dblquad(lambda yy, xx: 1 / math.hypot(x - xx, y - yy), -a, a, -b, b,
                       epsabs=1e-12, epsrel=1e-12)
    assert love_rectangle(x, y, a, b) == pytest.approx(exact, rel=RTOL_QUADRATURE)


def test_love_self_term_and_far_field():
    L = 2.0
    assert love_rectangle(0, 0, L / 2, L / 2) == pytest.approx(4 * L * math.log(1 + math.sqrt(2)))
    theta = np.linspace(0, math.pi / 4, 40)
    r = FAR_FIELD_RATIO * 1.0001
    exact = love_rectangle(r * np.cos(theta), r * np.sin(theta), 0.5, 0.5)
    approx = unit_force_influence(r * np.cos(theta), r * np.sin(theta), 0.0, 0.0, 0.0, 1.0)
    assert np.max(np.abs(approx / exact - 1)) < FAR_FIELD_RTOL


def test_love_square_near_matches_corner_sum():
    # The regrouped corner sum of the operator's near pairs: every sign, zero distances to
    # the corner lines (x = +-h, y = +-h, and the axes), the self term, out to the far radius.
    rng = np.random.default_rng(1)
    h = rng.uniform(0.1, 0.5, 4000)
    x = rng.uniform(-FAR_FIELD_RATIO, FAR_FIELD_RATIO, h.size) * h
    y = rng.uniform(-FAR_FIELD_RATIO, FAR_FIELD_RATIO, h.size) * h
    x[:400], y[200:600] = 0.0, 0.0
    x[1000:1200], y[1100:1300], x[1400:1500] = h[1000:1200], -h[1100:1300], -h[1400:1500]
    exact = love_rectangle(x, y, h, h) / (4 * h * h)
    assert np.max(np.abs(love_square_near(x, y, h) / exact - 1)) < RTOL_ROUNDOFF


def test_cell_areas():
    # The paper's cells: 97 in the disk at P = 11 (54 in the half disk), and the area errors
    # of PHYSICS.md ("Boundary-element model of [P]"); the covered cells carry the exact area
    # for every P.
    assert len(cell_pattern(11, "centre").x) == 97
    for P, err in [(5, 7.0), (7, -3.9), (9, 8.5), (11, 2.1), (13, 3.2), (15, 0.2)]:
        area = cell_pattern(P, "centre").area.sum()
        assert 100 * (area / (math.pi / 4) - 1) == pytest.approx(err, abs=0.06)
        assert cell_pattern(P, "covered").area.sum() == pytest.approx(math.pi / 4, rel=1e-13)
    # A rectangle straddling the rim, against a fine midpoint rule.
    n = 4000
    xs = 0.3 + 0.3 * (np.arange(n) + 0.5) / n
    inner = np.clip(np.sqrt(np.clip(0.25 - xs**2, 0, None)), 0.2, 0.4) - 0.2
    assert disk_rectangle_area(0.3, 0.6, 0.2, 0.4, 0.5) == pytest.approx(inner.mean() * 0.3, rel=1e-6)


@pytest.fixture(scope="module")
def sparse_small():
    scene = load_scene("paper-fig3-sparse")
    disc = discretise(scene, 7, "covered", 26e-6)
    return scene, disc


def test_reduced_operator_is_the_projected_full_operator(sparse_small):
    scene, disc = sparse_small
    M, K, E = reduced_operator(scene, disc), full_operator(scene, disc), expansion(disc)
    assert np.array_equal(K, K.T) and np.array_equal(M, M.T)
    assert np.abs(M - E.T @ K @ E).max() < RTOL_ROUNDOFF * np.abs(M).max()
    # Every element belongs to exactly one orbit; orbit sizes are those of D6 and D2.
    assert E.sum() == disc.n_elements
    assert set(disc.rep_weight[~disc.rep_centre]) <= {6, 12}
    assert set(disc.rep_weight[disc.rep_centre]) <= {1, 2, 4}


def test_raw_collocation_is_symmetric_within_one_orientation():
    scene = load_scene("single-pillar")
    disc = discretise(scene, 9, "centre", 3e-6)  # centre pillar only: one orientation
    k = unit_force_influence(disc.img_x[:, None], disc.img_y[:, None], disc.img_x[None, :],
                             disc.img_y[None, :], disc.img_angle[None, :], disc.img_side[None, :])
    assert np.abs(k - k.T).max() < RTOL_ROUNDOFF * k.max()


def test_reduced_solution_equals_unreduced_solution(sparse_small):
    scene, disc = sparse_small
    M, K = reduced_operator(scene, disc), full_operator(scene, disc)
    zeta = scene.indentation_m
    full = solve_contact(K, lens_gap(scene, disc.img_x, disc.img_y) - zeta, scale=zeta)
    red = solve_contact(M, disc.rep_weight * (lens_gap(scene, disc.rep_x, disc.rep_y) - zeta),
                        scale=zeta, weights=disc.rep_weight)
    assert full.converged and red.converged
    # The unreduced problem is exactly D6-symmetric except for the centre pillar's square grid
    # (only D2-symmetric); its influence on other pillars differs from a D6-symmetric one by a
    # hexadecapole term ~ (b/r)^4: measured 1.5e-7 at P = 5 and 7e-8 at P = 7.
    assert full.pressure.sum() == pytest.approx((disc.rep_weight * red.pressure).sum(), rel=1e-10)
    assert np.abs(full.pressure - expansion(disc) @ red.pressure).max() \
        < 1e-6 * full.pressure.max()


def test_force_balance_and_unit_rescaling():
    base = solve_dense(load_scene("paper-fig3-sparse"), 7)
    pillar_sum = sum(p.force_N for p in base.pillar_forces)
    element_sum = float((base.fields["weight"] * base.fields["force_N"]).sum())
    assert pillar_sum == pytest.approx(base.total_force_N, rel=RTOL_ROUNDOFF)
    assert element_sum == pytest.approx(base.total_force_N, rel=RTOL_ROUNDOFF)
    assert len(base.pillar_forces) == base.pillars_in_contact == 7
    # Lengths x 10 and moduli x 1000: pressures x 1000, forces x 1e5, radii x 10.
    scaled = solve_dense(load_scene("paper-fig3-sparse", [
        "lens.radius_mm=20", "pillars.diameter_um=40", "pillars.height_um=20",
        "load.indentation_um=3", "lens.E_Pa=1.6e9", "pillars.E_Pa=1.6e9",
        "substrate.E_Pa=1.6e9"]), 7)
    assert scaled.total_force_N == pytest.approx(1e5 * base.total_force_N, rel=1e-10)
    assert scaled.centre_pressure_Pa == pytest.approx(1e3 * base.centre_pressure_Pa, rel=1e-10)
    assert scaled.contact_radius_m == pytest.approx(10 * base.contact_radius_m, rel=1e-10)


def test_odd_and_even_discretisations_agree():
    scene = load_scene("paper-fig3-sparse")
    odd, even = solve_dense(scene, 21), solve_dense(scene, 22)
    # Both are within the measured P = 21 discretisation error (1.4 % in force) of the limit.
    assert even.total_force_N == pytest.approx(odd.total_force_N, rel=0.01)
    assert even.centre_pressure_Pa == pytest.approx(odd.centre_pressure_Pa, rel=0.01)
