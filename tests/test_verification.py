"""Roache/Celik GCI against the NPARC worked example and closed-form sequences."""

import math

import numpy as np
import pytest

from validation.analysis.verification import (
    gci_three, gci_two, loglog_order, observed_order_lsq, study)

# The NPARC example is quoted to 4-5 significant digits.
RTOL_QUOTED = 5e-4
# Exact sequences f0 + C h^p are reproduced to round-off of the logarithms.
RTOL_EXACT = 1e-9


def test_nparc_example():
    g = gci_three([1.0, 2.0, 4.0], [0.97050, 0.96854, 0.96178])
    assert g.status == "ok"
    assert g.order == pytest.approx(1.7862, rel=RTOL_QUOTED)
    assert g.f_exact == pytest.approx(0.971300, rel=1e-6)
    assert 100 * g.gci_fine == pytest.approx(0.1031, rel=RTOL_QUOTED * 5)
    assert 100 * g.gci_coarse == pytest.approx(0.3562, rel=RTOL_QUOTED * 5)
    assert g.asymptotic and g.asymptotic_ratio == pytest.approx(1.0, abs=0.01)
    assert g.fs == 1.25
    assert g.uncertainty == pytest.approx(g.gci_fine * 0.97050)


@pytest.mark.parametrize("p", [0.5, 1.0, 2.0, 3.3])
@pytest.mark.parametrize("h", [(1.0, 2.0, 4.0), (0.1, 0.13, 0.2), (1.0, 1.5, 2.7)])
def test_synthetic_power_law_recovers_order(p, h):
    f0, c = 2.5, -0.7
    f = [f0 + c * x**p for x in h]
    g = gci_three(h, f)
    assert g.status == "ok"
    assert g.order == pytest.approx(p, rel=RTOL_EXACT)
    assert g.f_exact == pytest.approx(f0, rel=RTOL_EXACT)
    # exact power law: the GCI band is Fs times the true error of the fine grid
    assert g.uncertainty == pytest.approx(1.25 * abs(c) * h[0] ** p, rel=1e-7)
    # GCI_23 is relative to f2 and GCI_12 to f1: the ratio is exactly f1/f2
    assert g.asymptotic_ratio == pytest.approx(abs(f[0] / f[1]), rel=1e-7)


def test_oscillatory_sequence_reports_status_and_band():
    g = gci_three([1, 2, 4], [1.0, 1.01, 0.99])
    assert g.status == "oscillatory"
    assert g.order is None and g.f_exact is None and g.gci_fine is None
    assert g.fallback_uncertainty == pytest.approx(3 * 0.02)
    assert "oscillatory" in g.note


def test_round_off_sequence():
    g = gci_three([1, 2, 4], [3.0, 3.0 * (1 + 1e-14), 3.0])
    assert g.status == "round-off"
    assert g.order is None and g.gci_fine is None
    assert g.f_exact == 3.0
    assert math.isfinite(g.fallback_uncertainty) and g.fallback_uncertainty < 1e-12


def test_divergent_and_degenerate_sequences_never_nan():
    cases = {
        "divergent": [1.0, 1.1, 1.15],          # differences grow under refinement
        "fine-pair-equal": [1.0, 1.0, 1.2],
    }
    for status, f in cases.items():
        g = gci_three([1, 2, 4], f)
        assert g.status == status
        for value in g.to_dict().values():
            if isinstance(value, float):
                assert math.isfinite(value)
    assert gci_three([1, 2, 4], [1.0, 1.1, 1.1]).status == "divergent"


def test_zero_fine_value_keeps_absolute_band():
    h = [1.0, 2.0, 4.0]
    f = [0.0, 0.3, 1.5]  # f = 0.1 (h^2 - 1): f1 = 0
    g = gci_three(h, f)
    assert g.status == "ok" and g.order == pytest.approx(2.0)
    assert g.gci_fine is None and g.uncertainty == pytest.approx(1.25 * 0.3 / 3)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="grow"):
        gci_three([1, 1, 2], [1, 2, 3])
    with pytest.raises(ValueError, match="finite"):
        gci_three([1, 2, 4], [1, float("nan"), 3])
    with pytest.raises(ValueError):
        gci_two([1, 2], [1, 2], order=0)


def test_two_grid_gci_uses_fs_3():
    g = gci_two([1, 2], [1.0, 1.04], order=2.0)
    assert g.fs == 3.0 and g.status == "two-grid"
    assert g.uncertainty == pytest.approx(3 * 0.04 / 3)
    assert g.f_exact == pytest.approx(1.0 - 0.04 / 3)


def test_loglog_order_over_levels():
    h = np.array([1, 0.5, 0.25, 0.125])
    fit = loglog_order(h, 0.3 * h**1.5)
    assert fit.status == "ok" and fit.n == 4
    assert fit.order == pytest.approx(1.5, abs=1e-12) and fit.r_squared == pytest.approx(1.0)
    assert loglog_order(h[:2], h[:2]).status.startswith("too few")
    # without a reference, differences of f0 + C h^p decay with the same order
    lsq = observed_order_lsq(h, 4.0 + 0.3 * h**1.5)
    assert lsq.order == pytest.approx(1.5, abs=1e-9)
    assert observed_order_lsq(h, 4.0 + 0.3 * h**1.5, f_ref=4.0).order == pytest.approx(1.5)
    wobble = observed_order_lsq(h, 4.0 + 0.3 * h**1.5 * np.array([1, -1, 1, -1]))
    assert wobble.status.startswith("oscillatory")


def test_study_sorts_levels_and_handles_two():
    h = [0.25, 1.0, 0.5]
    d = study(h, [1 + x**2 for x in h])
    assert d["h"] == [0.25, 0.5, 1.0] and d["gci"]["order"] == pytest.approx(2.0)
    two = study([1.0, 0.5], [1.0, 1.1])
    assert two["gci"]["status"] == "two-grid" and two["gci"]["order"] is None
    assert two["gci"]["fallback_uncertainty"] == pytest.approx(0.3)
