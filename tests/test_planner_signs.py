"""The planner adds a discretisation error and a model error with their signs where both
signs are systematic (validation/planner/plan.py ``combined_error``, tables.py
``ErrorTable.sign``)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pillar_xval.scenes import load_scene
from validation.planner.plan import combined_error, plan, plan_text
from validation.planner.tables import (DEFAULT_POLICY, SIGN_MIN_POINTS, CostFit, ErrorTable,
                                       PlannerData, load_data)
from validation.studies.calibrate.run import _disc_tables


def _box_max(disc, factor, sign, model, n=41):
    """max |sign D + sum H| sampled densely over D in [disc/factor, disc*factor] and each
    H within value +- margin."""
    ds = np.linspace(disc / factor, disc * factor, n)
    hs = [np.linspace(v - m, v + m, 9) for v, m, _ in model]
    return max(abs(sign * d + sum(h)) for d in ds for h in itertools.product(*hs))


@pytest.mark.parametrize("seed", range(20))
def test_the_signed_bound_is_the_largest_error_of_its_box(seed):
    # The bound is a corner of the box; a dense sample of the box (corners included) reaches
    # it and never exceeds it.
    rng = np.random.default_rng(seed)
    disc, factor = rng.uniform(1e-3, 0.05), rng.uniform(1.0, 2.0)
    sign = int(rng.choice([-1, 1]))
    model = [(rng.uniform(-0.05, 0.05), rng.uniform(0.0, 0.01), -1)
             for _ in range(int(rng.integers(1, 3)))]
    bound = combined_error(disc, factor, sign, model)
    assert bound == pytest.approx(_box_max(disc, factor, sign, model), rel=1e-12)


def test_errors_of_one_sign_add_up_and_opposite_ones_cancel():
    # same sign: the plain sum of the bounds, d f + |h| + m
    assert combined_error(0.02, 1.25, +1, [(0.01, 0.002, +1)]) == pytest.approx(0.037)
    # opposite signs: D in [0.016, 0.025], H in [-0.017, -0.013]; the worst corner
    # is 0.025 - 0.013
    assert combined_error(0.02, 1.25, +1, [(-0.015, 0.002, -1)]) == pytest.approx(0.012)
    # a sign that is not systematic: no signed bound
    assert combined_error(0.02, 1.25, 0, [(-0.015, 0.002, -1)]) is None
    assert combined_error(0.02, 1.25, +1, [(-0.015, 0.002, 0)]) is None
    assert combined_error(0.02, 1.25, +1, []) is None


def _table(values, signed=True):
    pts = [[i / (len(values) - 1)] for i in range(len(values))]
    return ErrorTable("model", ["m"], ["single"], ["c_p"], pts, {"sigma0": list(values)},
                      signed=signed)


def test_a_sign_is_systematic_where_enough_points_share_it():
    share = DEFAULT_POLICY["sign_share"]
    n = 4 * SIGN_MIN_POINTS
    up = int(np.ceil(share * n))
    assert _table([0.01] * up + [-0.01] * (n - up)).sign("sigma0", share) == 1
    assert _table([-0.01] * up + [0.01] * (n - up)).sign("sigma0", share) == -1
    assert _table([0.01] * (up - 1) + [-0.01] * (n - up + 1)).sign("sigma0", share) == 0
    # a hand bound is not signed; too few points are not a system; zeros and holes are
    # not counted
    assert _table([0.01] * n, signed=False).sign("sigma0", share) == 0
    assert _table([0.01] * (SIGN_MIN_POINTS - 1)).sign("sigma0", share) == 0
    assert _table([0.01] * SIGN_MIN_POINTS + [0.0, None]).sign("sigma0", share) == 1
    assert _table([0.01] * n).sign("F_T", share) == 0


def _data(disc_sigma0, hooke_sigma0, hooke_signed=True):
    """Two candidates on single pillars: ``fast`` (its discretisation table 12 points of
    ``disc_sigma0`` along c_p, signed) and ``slow`` (0.1 %, 100x the time), both carrying
    a Hooke table of ``hooke_sigma0`` (constant, so no leave-one-out margin)."""
    n = 12
    pts = [[i / (n - 1)] for i in range(n)]
    cands = [{"model": m, "options": {"n": k}, "label": m, "regimes": ["single"]}
             for m, k in (("fast", 1), ("slow", 2))]
    tables = [ErrorTable("discretisation", [m], ["single"], ["c_p"], pts,
                         {"F_T": [-1e-3] * n, "sigma0": [e] * n}, option={"n": k},
                         signed=True)
              for m, k, e in (("fast", 1, disc_sigma0), ("slow", 2, 1e-3))]
    tables.append(ErrorTable("model", ["fast", "slow"], ["single"], ["c_p"], pts,
                             {"F_T": [0.0] * n, "sigma0": [hooke_sigma0] * n},
                             component="hooke", signed=hooke_signed))
    costs = {m: CostFit(m, "none", None, None, [0], [t])
             for m, t in (("fast", 0.01), ("slow", 1.0))}
    return PlannerData(cands, tables, costs)


def test_a_coarse_error_that_the_hooke_error_offsets_is_within_tolerance():
    scene = load_scene("single-pillar")
    # +2 % of discretisation, -1.5 % of Hooke error, both systematic: 0.5 % in all
    p = plan(scene, 0.01, ("sigma0",), data=_data(0.02, -0.015))
    fast = next(c for c in p["candidates"] if c["label"] == "fast")
    assert fast["errors"]["sigma0"]["total"] == pytest.approx(0.005)
    assert fast["errors"]["sigma0"]["signed"]
    assert p["choice"]["label"] == "fast"
    assert "errors added with their signs" in plan_text(p)
    # the parts are still each one's bound, so the report shows what offset what
    assert fast["errors"]["sigma0"]["parts"] == pytest.approx(
        {"discretisation": 0.02, "hooke": 0.015})
    # errors of one sign add up: 3.5 %, the slow candidate is needed
    p = plan(scene, 0.01, ("sigma0",), data=_data(0.02, 0.015))
    assert p["choice"]["label"] == "slow"
    # a Hooke error without a measured sign (a hand bound) is added as a magnitude
    p = plan(scene, 0.01, ("sigma0",), data=_data(0.02, -0.015, hooke_signed=False))
    fast = next(c for c in p["candidates"] if c["label"] == "fast")
    assert fast["errors"]["sigma0"]["total"] == pytest.approx(0.035)
    assert not fast["errors"]["sigma0"]["signed"] and p["choice"]["label"] == "slow"


def test_calibrate_keeps_the_sign_of_a_discretisation_error():
    rec = {"regime": "single", "features": {"w": 0.5, "log_sag": -2.0},
           "rows": [{"model": "bem", "value": 5, "converged": True,
                     "errors": {"F_T": -0.03, "sigma0": 0.02, "a": None, "A": None}}]}
    [table] = [t for t in _disc_tables([rec]) if t.models == ["bem"]]
    assert table.signed and table.errors["F_T"] == [-0.03] and table.errors["sigma0"] == [0.02]
    # its prediction is the magnitude, as before
    assert table.predict({"w": 0.5, "log_sag": -2.0}, "F_T")[0] == pytest.approx(0.03)


def test_the_shipped_tables_carry_the_signs_the_calibration_measured():
    # Every measured table is signed (the hand bounds are not).  The uniform-pressure
    # BEMs' coarse rungs put F_T low and sigma0 high on every calibration scene: if a
    # calibration lost those signs (magnitudes only), the planner would stop offsetting the
    # Hooke pillar's sigma0 error, which is mostly negative.
    data = load_data()
    share = data.policy["sign_share"]
    for t in data.tables:
        assert t.signed == (not t.source.startswith("hand")), t.source
    bem = [t for t in data.tables if t.kind == "discretisation" and t.source.startswith(
        "calibrate") and set(t.models) <= {"bem", "bem-fft"} and t.regimes != ["flat"]]
    assert len(bem) == 28  # 6 dense and 8 FFT rungs, single and multi
    for t in bem:
        assert (t.sign("F_T", share), t.sign("sigma0", share)) == (-1, 1), (t.models, t.option)
    hooke = [t for t in data.tables if t.component == "hooke"]
    assert {t.sign("sigma0", share) for t in hooke} == {-1}


@pytest.mark.parametrize("share", [0.5, 1.2, "most"])
def test_a_sign_share_outside_its_range_is_refused(tmp_path, share):
    import json
    import shutil

    from pillar_xval.scenes import InputError
    from validation.planner.tables import data_dir

    for name in ("error_models.json", "cost_models.json"):
        shutil.copyfile(data_dir() / name, tmp_path / name)
    doc = json.loads((tmp_path / "error_models.json").read_text())
    doc["policy"]["sign_share"] = share
    (tmp_path / "error_models.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match=r"sign_share .*\(0\.5, 1\]"):
        load_data(tmp_path)
