"""``validation.testing``: the assertions pass on exact data, fail on data off by a known
amount, and their messages carry the quantity, both values, the difference, the tolerance and
its source."""

from __future__ import annotations

import dataclasses

import pytest

from pillar_xval.scenes import analytic, load_scene
from pillar_xval.closed_forms import solve_hertz
from validation.testing import (assert_agree, assert_close, assert_converged,
                                assert_matches_closed_form, assert_order, checks_made)
from validation.analysis.verification import study


@pytest.fixture
def hertz():
    return solve_hertz(load_scene("hertz"))


def _off(result, factor):
    """The result with its force scaled by ``factor``."""
    return dataclasses.replace(result, total_force_N=result.total_force_N * factor)


def test_closed_form_of_its_own_scene_passes_and_a_1_percent_error_fails(hertz):
    exact = analytic.hertz(load_scene("hertz"))
    assert_matches_closed_form(hertz, "hertz", rtol=1e-12, quantities=("F_T", "sigma0", "a"))
    with pytest.raises(AssertionError) as err:
        assert_matches_closed_form(_off(hertz, 1.01), "hertz", rtol=1e-3,
                                   source="measured 1e-4 at mesh_size 1")
    text = str(err.value)
    assert "F_T" in text and f"{exact.force:.6g}" in text and f"{exact.force * 1.01:.6g}" in text
    assert "+1.000%" in text and "rtol 0.001" in text and "measured 1e-4 at mesh_size 1" in text
    assert "Hertz" in text


def test_close_takes_a_result_a_number_or_a_mapping(hertz):
    assert_close(_off(hertz, 1.0 + 1e-4), hertz, ("F_T", "sigma0"), rtol=2e-4)
    assert_close(hertz, hertz.total_force_N, "F_T", rtol=0)
    assert_close(hertz, {"a": hertz.contact_radius_m * 1.001}, "a", rtol=2e-3)
    with pytest.raises(AssertionError, match="1 of 2 quantities"):
        assert_close(_off(hertz, 1.01), hertz, ("F_T", "sigma0"), rtol=1e-3)
    with pytest.raises(ValueError, match="one quantity"):
        assert_close(hertz, 1.0, ("F_T", "a"), rtol=0.1)
    with pytest.raises(ValueError, match="quantities"):
        assert_close(hertz, hertz, ("force",), rtol=0.1)
    with pytest.raises(ValueError, match="rtol"):
        assert_close(hertz, hertz, rtol=-1)


def test_an_unconverged_result_fails_with_its_own_message(hertz):
    bad = dataclasses.replace(hertz, converged=False,
                              diagnostics={"message": "residual 3e-6 > 1e-8",
                                           "contact_residual": 3e-6})
    with pytest.raises(AssertionError, match="did not converge: residual 3e-6"):
        assert_converged(bad)
    with pytest.raises(AssertionError, match="contact_residual 3e-06"):
        assert_close(bad, hertz, rtol=1)


def _study(model, f_exact, c, p=2.0, h=(1.0, 0.5, 0.25, 0.125)):
    """A converge study of f = f_exact (1 + c h^p): Richardson recovers f_exact."""
    return {"model": model, "studies": {"F_T": study(list(h), [f_exact * (1 + c * x**p)
                                                               for x in h])}}


def test_agree_within_the_combined_bands_and_not_beyond():
    a = _study("bem", 1.0, 0.05)
    b = _study("fem", 1.0 + 1e-6, -0.02)
    assert_agree(a, b)
    far = _study("fem", 1.01, -0.02)
    with pytest.raises(AssertionError) as err:
        assert_agree(a, far)
    text = str(err.value)
    assert "bem 1 +-" in text and "fem 1.01 +-" in text and "GCI (Fs = 1.25)" in text


def test_order_fitted_over_the_levels():
    first = _study("bem", 2.0, 0.3, p=1.0)
    assert_order(first, 1.0, atol=0.01)
    with pytest.raises(AssertionError, match="observed 1, expected 2 \\+- 0.1"):
        assert_order(first, 2.0)


def test_every_check_is_recorded_for_the_summary(hertz):
    checks_made(clear=True)
    assert_close(hertz, hertz, ("F_T", "a"), rtol=1e-9, source="exact")
    with pytest.raises(AssertionError):
        assert_close(_off(hertz, 2.0), hertz, rtol=0.5)
    made = checks_made(clear=True)
    assert [(c.quantity, c.passed) for c in made] == [("F_T", True), ("a", True),
                                                      ("F_T", False)]
    assert made[0].source == "exact" and made[2].value == pytest.approx(2 * made[2].reference)
