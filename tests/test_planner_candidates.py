"""The planner's elastic-pillar candidates and its requests: the elastic
BEM and fem-3d as candidates without the Hooke error, the pillar compliance's one-off cost,
fem-3d refused beyond memory, ``solve --model auto --tolerance --quantities``, ``plan
--budget`` with nothing inside it, and bad requests refused in one line."""

from __future__ import annotations

import importlib
import json

import pytest

from pillar_xval.scenes import load_scene
from validation.cli import main
from validation.planner import costs
from validation.planner.plan import plan, plan_text
from validation.planner.tables import PlannerData, ScaledCost, load_data

plan_module = importlib.import_module("validation.planner.plan")
LATTICE = ("paper-fig3-sparse", ["pillars.surface_fraction=0.2"])


def _lattice():
    return load_scene(*LATTICE)


@pytest.fixture
def cached(monkeypatch):
    """The pillar compliance counted as cached (or not: ``cached(False)``), whatever this
    machine's disk cache holds."""
    def set_(value=True):
        monkeypatch.setitem(costs.SETUPS, "pillar-compliance", lambda scene: value)
    set_(True)
    return set_


def _elastic(c):
    return c["physics"] == "elastic-pillar"


def test_lattice_sigma0_at_five_percent_takes_the_elastic_bem(cached):
    p = plan(_lattice(), 0.05, "sigma0")
    choice = p["choice"]
    assert choice["within_tolerance"], plan_text(p)
    assert choice["model"] in ("bem", "bem-fft") and choice["options"]["pillars"] == "elastic"
    assert choice["predicted_errors"]["sigma0"] <= 0.05
    by_label = {c["label"]: c for c in p["candidates"]}
    for c in by_label.values():
        if not c["eligible"] or c["model"] not in ("bem", "bem-fft"):
            continue
        parts = c["errors"]["sigma0"]["parts"]
        if _elastic(c):  # no Hooke error; the elastic rung's whole error against fem-3d,
            # from the lattice studies (0.1-0.6 % at this Phi and E_p / E_l, plus its margin)
            assert "hooke" not in parts and "elastic-coupling" not in parts
            assert 0.0 < parts["discretisation"] < 0.05
        else:  # the Hooke BEMs still carry theirs (46-60 % here): none within 5 %
            assert parts["hooke"] > 0.3 and c["errors"]["sigma0"]["total"] > 0.05
    # fem-3d is a candidate too, dearer here (its predicted time above the chosen BEM's)
    fem = [c for c in p["candidates"] if c["model"] == "fem-3d"]
    assert fem and all(c["eligible"] and c["time_s"] > choice["time_s"] for c in fem)
    assert "cheapest model predicted within 5 %" in p["reason"]


def test_the_compliance_build_is_charged_once_per_pillar_kind(cached):
    warm = {c["label"]: c for c in plan(_lattice(), 0.05, "sigma0")["candidates"]}
    cached(False)
    p = plan(_lattice(), 0.05, "sigma0")
    cold = {c["label"]: c for c in p["candidates"]}
    fit = load_data().costs["bem-fft pillars=elastic"]
    assert isinstance(fit, ScaledCost)
    build = fit.setup["time_s"]
    for label, c in cold.items():
        if _elastic(c) and c["model"] != "fem-3d":
            assert c["setup_s"] == build
            assert c["time_s"] == pytest.approx(warm[label]["time_s"] + build)
        else:
            assert c["setup_s"] == 0.0 and c["time_s"] == warm[label]["time_s"]
    assert "one-off set-up" in plan_text(p)
    # the Hooke FFT BEM's time times the measured ratio, when cached
    hooke, elastic = warm["bem-fft N=32"], warm["bem-fft N=32 elastic"]
    assert elastic["time_s"] == pytest.approx(fit.factor * hooke["time_s"])


def test_the_compliance_lookup_is_the_one_the_bem_makes(tmp_path, monkeypatch):
    import numpy as np

    import fem_reference
    from fem_reference import DEFAULT_MODES, ModalCompliance, PillarKind, _pillar_compliance
    from fem_reference._compliance_store import cache_key

    def build(kind, modes, mesh_size, progress=None):  # a synthetic operator: no solve
        r = np.linspace(0.0, 1.0, 9)
        c = np.tile(np.eye(9), (modes + 1, 1, 1))
        return ModalCompliance(kind, modes, mesh_size, r, c, c / 2, {}, np.tile(r * r, (2, 1)))

    monkeypatch.setattr(_pillar_compliance, "compute_modal_compliance", build)
    monkeypatch.setenv("PILLAR_XVAL_CACHE", str(tmp_path))
    scene = _lattice()
    assert not costs.compliance_cached(scene)
    path = tmp_path / "pillar-compliance" / \
        f"{cache_key(PillarKind.of_scene(scene), DEFAULT_MODES, 1.0)}.npz"
    fem_reference.modal_compliance(PillarKind.of_scene(scene), DEFAULT_MODES, 1.0)
    assert path.is_file() and costs.compliance_cached(scene)
    # A damaged file is no cached compliance: the BEM would rebuild it, so its time counts
    # (an empty file once made `solve --model auto` pick the elastic BEM, which then crashed).
    path.write_bytes(b"")
    assert not costs.compliance_cached(scene)
    # no pillar compliance to build: a flat scene, rigid pillars on a rigid substrate
    assert costs.compliance_cached(load_scene("hertz"))
    assert costs.compliance_cached(load_scene(
        "paper-fig3-sparse", ["pillars.rigid=true", "substrate.rigid=true"]))


def _without(data: PlannerData, drop) -> PlannerData:
    return PlannerData([c for c in data.candidates if not drop(c)], data.tables, data.costs,
                       data.provenance, data.policy)


def test_fem3d_when_the_elastic_bem_is_out_or_the_tolerance_below_its_bound(cached):
    data = load_data()
    no_elastic_bem = _without(data, lambda c: c.get("physics") == "elastic-pillar"
                              and c["model"] != "fem-3d")
    p = plan(_lattice(), 0.05, "sigma0", data=no_elastic_bem)
    assert p["choice"]["model"] == "fem-3d" and p["choice"]["within_tolerance"], plan_text(p)
    # the cheapest rung within 5 %: the coarsest
    assert p["choice"]["options"] == {"mesh_size": 2.83}
    # below every elastic BEM's predicted sigma0 error (its coupling error, measured by the
    # lattice study, plus its discretisation) only fem-3d remains, its cheapest rung within
    wide = plan(_lattice(), 1.0, "sigma0", data=data)
    elastic = [c["errors"]["sigma0"]["total"] for c in wide["candidates"]
               if c["eligible"] and c["physics"] == "elastic-pillar" and c["model"] != "fem-3d"]
    fem = sorted((c["time_s"], c["errors"]["sigma0"]["total"], c["label"])
                 for c in wide["candidates"] if c["eligible"] and c["model"] == "fem-3d")
    tol = 0.9 * min(elastic)
    assert any(e <= tol for _, e, _ in fem), plan_text(wide)
    p = plan(_lattice(), tol, "sigma0", data=data)
    assert p["choice"]["within_tolerance"], plan_text(p)
    assert p["choice"]["label"] == next(label for _, e, label in fem if e <= tol), plan_text(p)
    # without any elastic-pillar candidate the Hooke error is unavoidable again, and said so
    hooke_only = _without(data, lambda c: c.get("physics") == "elastic-pillar")
    p = plan(_lattice(), 0.05, "sigma0", data=hooke_only)
    assert not p["choice"]["within_tolerance"]
    assert "hooke" in p["reason"] and "no elastic-pillar model is a candidate" in p["reason"]


def test_fem3d_is_refused_beyond_memory_with_the_reason():
    # a 1 km lens on the densest lattice reaches ~1e7 pillars (counted, not listed): fem-3d's
    # estimate is far beyond any machine (fem_reference.solid3d.estimate_memory, memory_short)
    huge = load_scene("paper-fig3-dense", ["lens.radius_mm=1e6"])
    p = plan(huge, 0.05, "F_T")
    fem = [c for c in p["candidates"] if c["model"] == "fem-3d"]
    assert len(fem) == 3
    for c in fem:
        assert not c["eligible"]
        assert c["why"].startswith("refused: needs ~") and "GiB" in c["why"]
        assert "more than 80%" in c["why"]
        assert c["memory_MB"] > 1e6  # the estimate is kept for the table
    assert p["choice"] is None or p["choice"]["model"] != "fem-3d"


def test_solve_auto_hands_tolerance_and_quantities_to_the_planner(monkeypatch, capsys):
    seen = []
    real = plan_module.plan

    def spy(scene, tolerance=plan_module.DEFAULT_TOLERANCE,
            quantities=plan_module.DEFAULT_QUANTITIES, budget=None, data=None):
        seen.append((tolerance, tuple(quantities), budget))
        return real(scene, tolerance, quantities, budget, data)

    monkeypatch.setattr(plan_module, "plan", spy)
    assert main(["solve", "--scene", "hertz", "--model", "auto", "--tolerance", "0.07",
                 "--quantities", "F_T,a", "--budget", "30", "--json"]) == 0
    assert seen == [(0.07, ("F_T", "a"), 30.0)]
    result = json.loads(capsys.readouterr().out)
    planned = result["diagnostics"]["plan"]
    assert planned["tolerance"] == 0.07 and planned["quantities"] == ["F_T", "a"]
    assert planned["choice"]["model"] == result["model"] and planned["reason"]
    # the text says which model was chosen and why
    seen.clear()
    assert main(["solve", "--scene", "hertz", "--model", "auto", "--quantities", "sigma0"]) == 0
    assert seen == [(0.01, ("sigma0",), None)]
    out = capsys.readouterr().out
    assert "auto: chose hertz: hertz is the cheapest model predicted within 1 %" in out
    # the request is the planner's: refused for any other model
    assert main(["solve", "--scene", "hertz", "--model", "bem", "--tolerance", "0.05"]) == 2
    err = capsys.readouterr().err
    assert "--tolerance 0.05: does not apply to --model bem (it is an option of auto)" in err


def test_plan_budget_with_no_candidate_inside_exits_2_in_one_line(capsys):
    p = plan(load_scene("hertz"), 0.01)
    cheapest = min((c for c in p["candidates"] if c["eligible"]), key=lambda c: c["time_s"])
    budget = cheapest["time_s"] / 2
    assert main(["plan", "--scene", "hertz", "--budget", f"{budget:.3g}"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"pillar-xval plan: error: --budget {float(f'{budget:.3g}'):g}:")
    assert f"the cheapest, {cheapest['label']}, is predicted to take" in lines[0]
    t = cheapest["time_s"]  # the plan writes times below 10 ms as "< 0.01 s"
    assert (f"{t:.2g} s" if t >= 0.01 else "< 0.01 s") in lines[0]
    # --json still prints the plan (no choice), then the same line and status
    assert main(["plan", "--scene", "hertz", "--budget", f"{budget:.3g}", "--json"]) == 2
    captured = capsys.readouterr()
    assert json.loads(captured.out)["choice"] is None and "--budget" in captured.err
    # a budget that leaves a candidate: the plan, status 0
    assert main(["plan", "--scene", "hertz", "--budget", "10"]) == 0
    assert "choice    hertz" in capsys.readouterr().out


@pytest.mark.parametrize("argv, words", [
    (["--tolerance", "2"], ["--tolerance", "2", "allowed range is (0, 1]"]),
    (["--tolerance", "0"], ["--tolerance", "0", "allowed range is (0, 1]"]),
    (["--tolerance", "abc"], ["--tolerance", "'abc'", "expected a decimal number"]),
    (["--tolerance", "nan"], ["--tolerance", "nan"]),
    (["--quantities", "F_T,nope"], ["--quantities nope", "allowed: F_T, sigma0, a, A"]),
    (["--quantities", ","], ["--quantities ','", "one or more of F_T, sigma0, a, A"]),
    (["--budget", "-1"], ["--budget", "-1", "allowed range is (0, inf)"]),
])
@pytest.mark.parametrize("command", [["plan"], ["solve", "--model", "auto"]])
def test_bad_requests_are_one_line_naming_option_value_and_range(command, argv, words, capsys):
    assert main(command + ["--scene", "hertz"] + argv) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "Traceback" not in captured.err
    assert len(captured.err.strip().splitlines()) == 1, captured.err
    for w in words:
        assert w in captured.err, captured.err


def test_a_recalibration_keeps_the_hand_entries(tmp_path):
    """calibrate does not measure fem-3d or the elastic BEMs yet: its new data keeps the
    installed hand entries instead of dropping the candidates."""
    from validation.planner.tables import DATA_FORMAT, data_dir
    from validation.studies.calibrate.hand import keep_hand_entries

    shipped_errors = json.loads((data_dir() / "error_models.json").read_text())
    shipped_costs = json.loads((data_dir() / "cost_models.json").read_text())

    def hand(entries, key="source"):
        return [e for e in entries if str(e.get(key, "")).startswith("hand")]

    measured = [c for c in shipped_errors["candidates"] if not hand([c])]
    errors = {"format": DATA_FORMAT, "provenance": {}, "candidates": measured,
              "tables": [t for t in shipped_errors["tables"] if not hand([t])]}
    costs = {"format": DATA_FORMAT, "provenance": {},
             "models": {k: v for k, v in shipped_costs["models"].items() if k != "fem-3d"}}
    keep_hand_entries(errors, costs)
    # the elastic bem-fft at N = 16, 24, 32, 48, 64 and bem at P = 11, 15, 21; fem-3d's three
    assert len(hand(errors["candidates"])) == len(hand(shipped_errors["candidates"])) == 11
    # 1 (the elastic BEM's bound on one pillar): the lattice studies measured the others (the
    # elastic BEMs' error at each rung and fem-3d's discretisation in lattices)
    assert len(hand(errors["tables"])) == len(hand(shipped_errors["tables"])) == 1
    # carried with the calibration of the machine its seconds were measured on
    assert costs["models"]["fem-3d"] == {"machine": shipped_costs["machine"],
                                         **shipped_costs["models"]["fem-3d"]}
    assert set(costs["variants"]) == {"bem pillars=elastic", "bem-fft pillars=elastic"}
    # written and read back: the planner sees them again
    (tmp_path / "error_models.json").write_text(json.dumps(errors))
    (tmp_path / "cost_models.json").write_text(json.dumps(costs))
    data = load_data(tmp_path)
    assert {c["label"] for c in data.candidates} == {
        c["label"] for c in shipped_errors["candidates"]}
    # nothing twice when the calibration already wrote an entry of the same label
    again = dict(errors, candidates=list(errors["candidates"]))
    keep_hand_entries(again, costs, tmp_path)
    labels = [c["label"] for c in again["candidates"]]
    assert len(labels) == len(set(labels))
    assert len(again["tables"]) == len(errors["tables"])
    # a hand table the calibration has measured since (here the lattice studies' elastic
    # rungs, which hold the coupling the bound stood for) stays out
    bound = {"kind": "model", "component": "elastic-coupling", "models": ["bem", "bem-fft"],
             "option": {"pillars": "elastic"}, "regimes": ["multi"], "features": [],
             "points": [[]], "errors": {"sigma0": [0.03]}, "loo": {}, "source": "hand: bound",
             "note": ""}
    old = dict(shipped_errors, tables=list(shipped_errors["tables"]) + [bound])
    (tmp_path / "error_models.json").write_text(json.dumps(old))
    keep_hand_entries(again, costs, tmp_path)
    coupling = [t for t in again["tables"] if t["component"] == "elastic-coupling"
                and "multi" in t["regimes"]]
    assert not [t for t in coupling if t["source"].startswith("hand")]
    # and a hand table nothing measured is carried over
    single = dict(bound, regimes=["single"], source="hand: one pillar")
    (tmp_path / "error_models.json").write_text(json.dumps(dict(old, tables=[single])))
    kept = dict(errors, tables=[t for t in errors["tables"] if not hand([t])])
    keep_hand_entries(kept, costs, tmp_path)
    assert single in kept["tables"]


def test_the_planner_validation_judges_only_measured_candidates():
    """validate-plan's Hooke-BEM reference (its scenes but the lattice-sigma0 ones): the
    hand-entered candidates (fem-3d, the elastic BEMs) stay out of the plans it judges there,
    and nothing else does."""
    from validation.studies.validate_plan import measured_only

    data = load_data()
    kept = measured_only(data)
    hand = [c for c in data.candidates if str(c.get("source", "")).startswith("hand")]
    assert hand and len(kept.candidates) == len(data.candidates) - len(hand)
    assert not any(c["model"] == "fem-3d" or c.get("options", {}).get("pillars") == "elastic"
                   for c in kept.candidates)
    p = plan(_lattice(), 0.05, "sigma0", data=kept)
    assert p["candidates"] and not any(
        c["model"] == "fem-3d" or c.get("options", {}).get("pillars") == "elastic"
        for c in p["candidates"])


def test_the_elastic_bems_rungs_are_as_close_in_time_as_the_hooke_bems(cached):
    """The validation's cost target counts a plan within 2x of the cheapest candidate within
    tolerance. A plan one rung finer than needed can meet it only if adjacent rungs are close
    in time. The elastic BEMs' rungs (bem-fft N = 16, 24, 32, 48, 64; bem P = 11, 15, 21) are
    as close as the Hooke BEMs' on a lattice: no step between adjacent rungs larger than the
    Hooke family's largest (1.8-2.6x here). Without the single rungs N = 24, 48 and P = 15
    the steps were 4x (N = 16 -> 32) and 3.6x (P = 11 -> 21)."""
    p = plan(_lattice(), 0.05, "sigma0")
    families = {}
    for c in p["candidates"]:
        if c["model"] not in ("bem", "bem-fft") or c["time_s"] is None:
            continue
        n = c["options"].get("cells_per_diameter") or c["options"]["elements_per_diameter"]
        families.setdefault((c["model"], _elastic(c)), []).append((n, c["time_s"]))

    def largest_step(rungs):
        times = [t for _, t in sorted(rungs)]
        return max(b / a for a, b in zip(times, times[1:]))

    for model in ("bem", "bem-fft"):
        elastic, hooke = families[(model, True)], families[(model, False)]
        assert len(elastic) >= 3
        assert largest_step(elastic) <= largest_step(hooke) * (1 + 1e-9), (
            model, sorted(elastic), sorted(hooke))
