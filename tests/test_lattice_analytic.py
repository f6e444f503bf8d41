"""The hexagonal lattice and the analytic library, each against an independent computation."""

import math

import numpy as np
import pytest
from scipy.integrate import quad

from pillar_xval.scenes import analytic as an
from pillar_xval.scenes import lattice, load_scene


def test_rings_hold_6n_pillars_and_indices_invert():
    rows = lattice.pillars_within(20.5, 1.0)
    rings = [lattice.ring(int(n), int(m)) for n, m, _, _ in rows]
    for k in range(1, 8):
        assert rings.count(k) == 6 * k
    n, m = lattice.lattice_indices(rows[:, 2], rows[:, 3], 1.0)
    assert np.array_equal(n, rows[:, 0]) and np.array_equal(m, rows[:, 1])
    # Nearest neighbours are one pitch apart.
    assert np.sort(np.hypot(rows[:, 2], rows[:, 3]))[1] == pytest.approx(1.0)


def test_wedge_orbits_cover_the_plane_exactly_once():
    radius, pitch = 9.3, 1.0
    orbits = lattice.wedge_orbits(radius, pitch)
    assert all(0 <= o.angle <= math.pi / 6 + 1e-12 for o in orbits)
    covered = set()
    for o in orbits:
        x, y, _, _ = lattice.d6_images(o.x, o.y)
        n, m = lattice.lattice_indices(x, y, pitch)
        images = set(zip(n.tolist(), m.tolist()))
        assert len(images) == o.size  # orbit sizes 1, 6, 12 (the paper's K table)
        assert not images & covered
        covered |= images
    assert len(covered) == len(lattice.pillars_within(radius, pitch))


def test_hertz_force_is_the_integral_of_its_pressure():
    hz = an.hertz(load_scene("hertz"))
    a = hz.contact_radius
    # sigma_0 sqrt(1 - r^2/a^2) = sigma_0 sqrt(a + r) sqrt(a - r) / a: QUADPACK's 'alg' weight.
    force, _ = quad(lambda r: 2 * math.pi * r * hz.centre_pressure * math.sqrt(a + r) / a,
                    0, a, weight="alg", wvar=(0, 0.5))
    assert force == pytest.approx(hz.force, rel=1e-10)
    zeta = an.Hertz.indentation_for_force(hz.force, hz.radius, hz.compliance)
    assert zeta == pytest.approx(hz.indentation, rel=1e-12)


def test_flat_punch_force_is_the_integral_of_its_pressure():
    punch = an.rigid_punch(load_scene("single-pillar"))
    a = punch.diameter / 2
    # sigma_0 / sqrt(1 - r^2/a^2) has an integrable edge singularity: QUADPACK's 'alg' weight.
    force, _ = quad(lambda r: 2 * math.pi * r * punch.centre_pressure * a / math.sqrt(a + r),
                    0, a, weight="alg", wvar=(0, -0.5))
    assert force == pytest.approx(punch.force, rel=1e-10)
    assert punch.force == pytest.approx(punch.diameter * punch.indentation / punch.compliance)


def test_spring_model_limits():
    stiff = load_scene("single-pillar", ["pillars.E_Pa=1e12", "substrate.E_Pa=1e12"])
    soft = load_scene("single-pillar", ["pillars.E_Pa=1e3", "substrate.E_Pa=1e3"])
    rigid = load_scene("single-pillar", ["pillars.rigid=true", "substrate.rigid=true"])
    assert an.spring_model(rigid).centre_pressure == pytest.approx(an.rigid_punch(rigid).centre_pressure)
    assert an.spring_model(stiff).centre_pressure == pytest.approx(
        an.rigid_punch(stiff).centre_pressure, rel=1e-5)
    # Springs in series: 1/F = (gamma_l + gamma_s)/(d zeta) + (4h/(pi d^2 E_p))/zeta.
    s = load_scene("single-pillar")
    F = an.spring_model(s).force
    inv = s.half_space_compliance / (4e-6 * 0.3e-6) + s.pillar_spring_compliance / 0.3e-6
    assert 1 / F == pytest.approx(inv, rel=1e-12)
    assert an.spring_model(soft).centre_pressure < 1e-2 * an.rigid_punch(soft).centre_pressure


def test_second_pillar_radius_solves_its_equation_and_takes_the_outer_root():
    for E in (1e3, 1.6e6, 1e12):
        s = load_scene("single-pillar", [f"pillars.E_Pa={E}"])
        r = an.second_pillar_radius(s)
        R, d, zeta = 2e-3, 4e-6, 0.3e-6
        big_pi = an.stiffness_number(s)
        gap = R - math.sqrt(R * R - r * r) + (2 / big_pi * math.asin(d / (2 * r)) - 1) * zeta
        assert abs(gap) < 1e-12 * zeta
        grid = np.linspace(r * 1.0001, 5 * r, 200)  # no root further out
        assert np.all(R - np.sqrt(R * R - grid**2)
                      + (2 / big_pi * np.arcsin(d / (2 * grid)) - 1) * zeta > 0)
        # The paper's Fig. 5 fits give Phi_S in [0.0094, 0.0135] at zeta = 0.3 um.
        assert 0.0094 <= an.single_pillar_threshold(s) <= 0.0135


def test_large_indentation_limit_of_the_threshold():
    errors = []
    for zeta_um in (0.05, 0.3, 1.9):
        s = load_scene("single-pillar", [f"load.indentation_um={zeta_um}", "lens.radius_mm=20"])
        errors.append(abs(an.single_pillar_threshold(s)
                          / an.single_pillar_threshold_large_indentation(s) - 1))
    assert errors[0] > errors[1] > errors[2] and errors[2] < 0.05


def test_threshold_indentation_range_of_the_paper():
    # The paper: 0.004 <= zeta_T / h <= 0.014 over E_p in [1e3, 1e12] Pa.
    values = [an.threshold_indentation(load_scene("single-pillar", [
        f"pillars.E_Pa={E}", f"substrate.E_Pa={E}"])) / 2e-6 for E in (1e3, 1e6, 1e12)]
    assert min(values) == pytest.approx(0.004, abs=5e-4)
    assert 0.004 <= max(values) <= 0.0145


def test_master_curves_hit_their_limits():
    assert an.reduced_centre_pressure(0.0) == 1.0
    assert an.reduced_area(1.0) == 1.0
    assert an.master_centre_pressure(0.01, 0.01, 0.3, 5.0, 30.0) == pytest.approx(30.0)
    assert an.master_centre_pressure(100.0, 0.01, 0.3, 5.0, 30.0) == pytest.approx(5.0, rel=1e-3)
    a_s = math.pi * (4e-6) ** 2 / 4
    assert a_s == pytest.approx(1.26e-11, rel=3e-3)
    assert an.master_contact_area(0.0, 2e-3, 3e-7, 4e-6) == pytest.approx(a_s)
