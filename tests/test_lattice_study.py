"""The multi-pillar cross-validation study (pillar-xval lattice): its bookkeeping, one cheap
real point, and input refused before any solve."""

from __future__ import annotations

import pytest

from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.scenes import InputError
from validation.engine import Engine
from validation.studies import lattice as study

# Hooke pillars against elastic pillars at E_p = E_l, Phi = 0.03: the spring model misses the
# elastic pillar's non-uniform top pressure but not its total force; the lead measured the
# Richardson totals 0.6-3 % apart (coarse levels, which add a few % of discretisation).
RTOL_MODEL_FORCE = 0.06


def _result(forces: dict) -> ContactResult:
    pillars = [PillarForce(n, m, 0.0, 0.0, f) for (n, m), f in forces.items()]
    return ContactResult("x", {}, {}, sum(forces.values()), 1.0, 1.0, 1.0, len(pillars),
                         pillars, True, 1, 0.0)


def test_ring_ratios_group_pillars_by_lattice_ring():
    fem = _result({(0, 0): 2.0, (1, 0): 1.1, (1, 1): 0.9, (2, 1): 0.3})
    bem = _result({(0, 0): 1.0, (1, 0): 1.0, (1, 1): 1.0, (3, 0): 0.2})
    rings = {r["ring"]: r for r in study.ring_ratios(fem, bem)}
    assert rings[0]["ratio_mean"] == 2.0 and rings[0]["pillars"] == 1
    assert rings[1]["ratio_min"] == pytest.approx(0.9) and rings[1]["ratio_max"] == 1.1
    assert rings[1]["ring_force_ratio"] == pytest.approx(1.0)
    # (2, 1) is loaded by the FEM only, (3, 0) by the BEM only: counted, never divided.
    assert rings[2]["fem_only"] == 1 and rings[2]["ratio_mean"] is None
    assert rings[3]["bem_only"] == 1 and rings[3]["ring_force_ratio"] == 0.0
    assert sum(r["fem_force_N"] for r in rings.values()) == pytest.approx(fem.total_force_N)


@pytest.fixture
def coarse_compliance(monkeypatch, tmp_path_factory):
    """The elastic pillar's compliance at the tests' coarse discretisation (mesh_size 4, n <= 2:
    seconds; the default takes about 20 s per pillar kind), in a cache of the test's own."""
    import fem_reference

    monkeypatch.setenv("PILLAR_XVAL_CACHE", str(tmp_path_factory.mktemp("compliance")))
    full = fem_reference.modal_compliance
    monkeypatch.setattr(fem_reference, "modal_compliance",
                        lambda kind, modes, mesh_size, progress=None: full(kind, 2,
                                                                           mesh_size=4.0))


def test_one_point_of_the_study_on_the_real_models(tmp_path, coarse_compliance):
    point = study.LatticePoint(0.03, 1.0)
    levels = {"fem_levels": study.QUICK_FEM_LEVELS, "bem_levels": study.QUICK_BEM_LEVELS,
              "dense_levels": study.QUICK_DENSE_LEVELS, "fft_rungs": study.QUICK_FFT_RUNGS}
    with Engine("serial", quiet=True) as engine:
        report = study.lattice_study(tmp_path, engine=engine, points=[point], **levels)
        row = report["rows"][0]
        assert row["status"] == "ok", row["status"]
        f_t = row["quantities"]["F_T"]
        assert f_t["fem"] == pytest.approx(f_t["bem"], rel=RTOL_MODEL_FORCE)
        # Both models load the centre pillar and its first ring (7 pillars, Fig. 3a).
        assert row["pillars_in_contact"]["fem"] == row["pillars_in_contact"]["bem"] == 7
        ring_sum = sum(r["bem_force_N"] for r in row["rings"])
        assert ring_sum == pytest.approx(row["bem_levels"][-1]["F_T"], rel=1e-12)
        assert {r["ring"] for r in row["rings"]} == {0, 1}
        # the elastic BEM: its own ladder, the same pillars, E_p = E_l close to the FEM
        assert row["pillars_in_contact"]["elastic"] == 7
        assert [lv["cells_per_diameter"] for lv in row["elastic_levels"]] == [8, 16]
        e = row["elastic_quantities"]["F_T"]
        assert e["fem"] == f_t["fem"] and e["bem"] == pytest.approx(e["fem"],
                                                                  rel=RTOL_MODEL_FORCE)
        assert {r["ring"] for r in row["ring_forces"]} == {0, 1} and row["profile"]
        # the dense elastic BEM (P = 11, the planner's rung) close to the FEM too
        (dense,) = row["elastic_dense_levels"]
        assert dense["converged"] and dense["F_T"] == pytest.approx(f_t["fem"],
                                                                   rel=RTOL_MODEL_FORCE)
        assert row["targets"]["F_T"]["met"] is not None
        names = study.write_report(report, tmp_path)
        assert all((tmp_path / n).exists() for n in names)
        # A rerun reads every case back: nothing is computed twice.
        outcomes = engine.run(study.cases(point, **levels), tmp_path / "cases")
        assert all(o.cached for o in outcomes)


@pytest.mark.parametrize("argv, words", [
    (["--surface-fractions", "0.95"], "surface_fraction"),
    (["--ratios", "0"], "--ratios"),
    (["--ratios", "1e-12"], "pillars.E_Pa"),
    (["--paper-scenes", "0.2"], "PHI:RATIO"),
    (["--paper-scenes", "0.95:10"], "surface_fraction"),
    (["--zeta-um", "0"], "--zeta-um"),
    (["--zeta-um", "nan"], "--zeta-um"),
    (["--zeta-um", "1e6"], "indentation"),
])
def test_bad_points_are_refused_before_any_solve(cli, tmp_path, argv, words):
    code, out, err = cli("lattice", *argv, "--out", tmp_path / "o", "--executor", "serial")
    assert code == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "o" / "cases").exists()


def test_paper_scenes_grid_is_every_grid_point_but_the_shared_one():
    from validation.cli.lattice import GRID, _pairs, paper_pairs

    assert _pairs("grid") == GRID and _pairs("none") == [] and _pairs("0.2:10") == [(0.2, 10)]
    assert paper_pairs(GRID, [0.1, 0.2], [0.1, 1.0, 10.0]) == [
        (0.1, 0.1), (0.1, 10.0), (0.2, 0.1), (0.2, 10.0)]
    assert paper_pairs(None, [0.1], [1.0]) is None


# --- the elastic-pillar BEM's column, the E_s = E_p scenes and the targets -----------------
# Fake models with exact second-order errors, so three levels give exact Richardson estimates
# and narrow bands: fem-3d f (1 + C h^2) with h = mesh_size, bem-fft f (1 + C / N^2); the
# Hooke BEM is off by HOOKE_OFF, the elastic BEM by ELASTIC_OFF[scene] on every quantity,
# ring force and profile point.
C_FEM, C_BEM = 1e-4, 1e-2
HOOKE_OFF = 0.10
ELASTIC_OFF = {0.1: 0.004, 0.2: 0.02}  # by Phi: within every target, then F_T's 1 % missed
FORCES = {(0, 0): 4.0, (1, 0): 1.0, (0, 1): 1.0, (2, 1): 0.25}  # ring 0, 1, 1, 2 (shares)
FAKE_LEVELS = {"fem_levels": (2.0, 1.41, 1.0), "bem_levels": (8, 16, 32),
               "dense_levels": (11, 21), "fft_rungs": (12, 24)}


def _fake_result(model, scene, factor, disc):
    from fakes import _profile

    d = scene.pillars.diameter_m
    f = 1e-6 * factor * scene.substrate.E_Pa / 1.6e6  # the substrate's modulus shows
    total = sum(FORCES.values())
    pillars = [PillarForce(n, m, 0.0, 0.0, f * s / total) for (n, m), s in FORCES.items()]
    r, p = _profile(scene)
    return ContactResult(model, scene.to_dict(), disc, f, 1e3 * factor, 0.3 * d * factor,
                         d * d * factor, len(pillars), pillars, True, 1, 0.01,
                         pillar_top_profile={"r_m": r.tolist(),
                                             "pressure_Pa": (p * factor).tolist()})


def fake_fem3d(scene, mesh_size=2.0):
    return _fake_result("fem-3d", scene, 1.0 + C_FEM * mesh_size**2, {"mesh_size": mesh_size})


def fake_fft(scene, cells_per_diameter=16, pillars="hooke"):
    off = (HOOKE_OFF if pillars == "hooke"
           else ELASTIC_OFF[scene.pillars.surface_fraction])
    return _fake_result("bem-fft", scene, (1.0 + off) * (1.0 + C_BEM / cells_per_diameter**2),
                        {"cells_per_diameter": cells_per_diameter, "pillars": pillars})


def fake_dense(scene, elements_per_diameter=11, cells="covered", pillars="hooke"):
    off = (HOOKE_OFF if pillars == "hooke"
           else ELASTIC_OFF[scene.pillars.surface_fraction])
    return _fake_result("bem", scene, (1.0 + off) * (1.0 + C_BEM / elements_per_diameter**2),
                        {"elements_per_diameter": elements_per_diameter, "pillars": pillars})


@pytest.fixture
def fake_lattice_models(monkeypatch):
    import sys
    import types

    from fakes import register

    mod = types.ModuleType("xval_lattice_fakes")
    mod.fake_fem3d, mod.fake_fft, mod.fake_dense = fake_fem3d, fake_fft, fake_dense
    monkeypatch.setitem(sys.modules, "xval_lattice_fakes", mod)
    register(monkeypatch, "fem-3d", "xval_lattice_fakes:fake_fem3d", ("mesh_size",))
    register(monkeypatch, "bem-fft", "xval_lattice_fakes:fake_fft",
             ("cells_per_diameter", "pillars"))
    register(monkeypatch, "bem", "xval_lattice_fakes:fake_dense",
             ("elements_per_diameter", "cells", "pillars"))


@pytest.fixture
def fake_report(fake_lattice_models, tmp_path):
    points = [study.LatticePoint(0.1, 10.0), study.LatticePoint(0.2, 10.0, study.PILLAR)]
    with Engine("serial", quiet=True) as engine:
        report = study.lattice_study(tmp_path, engine=engine, points=points, **FAKE_LEVELS)
    return report


def test_the_scenes_say_their_substrate_convention():
    lens, paper = study.LatticePoint(0.2, 10.0), study.LatticePoint(0.2, 10.0, study.PILLAR)
    s = paper.scene()
    assert s.substrate.E_Pa == s.pillars.material.E_Pa == 10 * s.lens.material.E_Pa
    assert s.substrate.nu == s.pillars.material.nu
    s = lens.scene()
    assert s.substrate.E_Pa == s.lens.material.E_Pa and s.pillars.material.E_Pa == 1.6e7
    assert "Es=El" in lens.label and "Es=Ep" in paper.label
    assert paper.title.endswith("E_s = E_p") and lens.title.endswith("E_s = E_l")
    with pytest.raises(InputError, match="convention"):
        study.LatticePoint(0.2, 10.0, "E_s = 1")
    # the default study: the 16 E_s = E_l scenes, then at least four at E_s = E_p
    points = study.default_points()
    assert [p.substrate for p in points[:16]] == [study.LENS] * 16
    assert len([p for p in points if p.substrate == study.PILLAR]) >= 4
    assert study.default_points([0.03], study.RATIOS) == study.grid([0.03])


def test_a_study_at_another_indentation_says_so_and_keeps_one_zeta():
    point = study.LatticePoint(0.2, 10.0, zeta_um=0.05)
    assert point.scene().indentation_m == pytest.approx(0.05e-6)
    assert "zeta=0.05um" in point.label and point.title.endswith("zeta = 0.05 um")
    assert "zeta" not in study.LatticePoint(0.2, 10.0).label
    assert all(p.zeta_um == 0.05 for p in study.default_points(zeta_um=0.05))
    with pytest.raises(InputError, match="one zeta"):
        study.lattice_study("unused", points=[point, study.LatticePoint(0.2, 10.0)])


def test_both_bems_climb_the_same_ladder_and_hooke_keeps_its_keys():
    point = study.LatticePoint(0.2, 0.1)
    cs = study.cases(point)
    bem = [c for c in cs if c.model == study.BEM_MODEL]
    hooke = [c.options for c in bem if "pillars" not in c.options]
    elastic = [c.options for c in bem if c.options.get("pillars") == "elastic"]
    # the Hooke cases' options are what they were before the elastic column: same case keys
    assert hooke == [{"cells_per_diameter": n} for n in study.BEM_LEVELS]
    # the elastic ladder, then its single rungs between the ladder's levels
    assert [o["cells_per_diameter"] for o in elastic] == list(study.BEM_LEVELS + study.FFT_RUNGS)


def test_a_target_is_the_tolerance_or_both_bands_where_wider():
    j = study.judge(1.009, 0.0, 1.0, 0.0, 0.01)
    assert j["met"] and j["error"] == pytest.approx(0.009) and j["allowed"] == 0.01
    assert study.judge(1.011, 0.0, 1.0, 0.0, 0.01)["met"] is False
    assert study.judge(0.989, 0.0, 1.0, 0.0, 0.01)["met"] is False
    # bands wider than the target: 2 % off is within 1.5 % + 1 % of bands
    j = study.judge(1.02, 0.015, 1.0, 0.01, 0.01)
    assert j["met"] and j["allowed"] == pytest.approx(0.025)
    assert study.judge(1.03, 0.015, 1.0, 0.01, 0.01)["met"] is False
    assert study.judge(None, 0.0, 1.0, 0.0, 0.01)["met"] is None
    assert study.judge(0.0, 0.0, 0.0, 0.0, 0.01)["met"] is True


def _row(f_t=1.0, sigma0=1.0, ring=1.0, profile=1.0):
    """A row by hand: the FEM at 1 with no band, the elastic BEM at the given values."""
    q = {k: {"fem": 1.0, "fem_band": 0.0, "bem": v, "bem_band": 0.0}
         for k, v in (("F_T", f_t), ("sigma0", sigma0))}
    rings = [{"ring": k, "fem_N": 1.0, "fem_band_N": 0.0, "elastic_N": v,
              "elastic_band_N": 0.0} for k, v in ((0, 1.0), (1, ring))]
    prof = [{"r_over_radius": x, "fem_Pa": 1.0, "fem_band_Pa": 0.0, "elastic_Pa": v,
             "elastic_band_Pa": 0.0} for x, v in ((0.1, 1.0), (0.8, profile))]
    return {"elastic_quantities": q, "ring_forces": rings, "profile": prof}


@pytest.mark.parametrize("kw, missed", [
    ({}, None), ({"f_t": 1.011}, "F_T"), ({"sigma0": 0.969}, "sigma0"),
    ({"ring": 1.021}, "rings"), ({"profile": 0.949}, "profile"),
    ({"f_t": 1.0099, "sigma0": 1.0299, "ring": 0.9801, "profile": 1.0499}, None),
])
def test_each_target_can_fail_alone(kw, missed):
    t = study.evaluate_targets(_row(**kw))
    assert t["every"] is (missed is None)
    assert [k for k in study.TARGETS if not t[k]["met"]] == ([missed] if missed else [])
    if missed in ("rings", "profile"):
        assert t[missed]["worst_error"] == pytest.approx(kw["ring" if missed == "rings"
                                                            else "profile"] - 1.0)
    # a scene without an elastic column meets no target: not judged is not met
    empty = study.evaluate_targets({})
    assert not empty["every"] and empty["F_T"]["met"] is None and empty["rings"]["met"] is None


def test_the_elastic_column_and_its_targets_on_fake_models(fake_report):
    report = fake_report
    assert report["elastic"]["pillars"] == "elastic" and report["substrates"] == [
        study.LENS, study.PILLAR]
    good, bad = report["rows"]
    assert good["substrate"] == study.LENS and bad["substrate"] == study.PILLAR
    assert bad["substrate_E_Pa"] == pytest.approx(1.6e7)
    for row, off in ((good, ELASTIC_OFF[0.1]), (bad, ELASTIC_OFF[0.2])):
        assert row["status"] == "ok"
        assert len(row["elastic_levels"]) == len(row["bem_levels"]) == 3
        for key in ("F_T", "sigma0", "a", "A"):
            # exact second order: both Richardson estimates exact, (FEM - BEM) / BEM
            hooke, elastic = row["quantities"][key], row["elastic_quantities"][key]
            assert hooke["difference"] == pytest.approx(1 / (1 + HOOKE_OFF) - 1, abs=1e-9)
            assert elastic["difference"] == pytest.approx(1 / (1 + off) - 1, abs=1e-9)
            assert elastic["fem"] == hooke["fem"] and elastic["bem_how"] == "richardson"
        assert [r["ring"] for r in row["ring_forces"]] == [0, 1, 2]
        assert {r["ring"] for r in row["elastic_rings"]} == {0, 1, 2}
        # the dense elastic BEM at the planner's rungs: each level as its model returned it
        scale = row["substrate_E_Pa"] / 1.6e6
        assert [lv["elements_per_diameter"] for lv in row["elastic_dense_levels"]] == [11, 21]
        for lv in row["elastic_dense_levels"]:
            n = lv["elements_per_diameter"]
            assert lv["converged"] and lv["F_T"] == pytest.approx(
                1e-6 * scale * (1 + off) * (1 + C_BEM / n**2), rel=1e-12)
        # the elastic bem-fft's single rungs between its ladder's levels, likewise
        assert [lv["cells_per_diameter"] for lv in row["elastic_fft_rungs"]] == [12, 24]
        for lv in row["elastic_fft_rungs"]:
            n = lv["cells_per_diameter"]
            assert lv["converged"] and lv["F_T"] == pytest.approx(
                1e-6 * scale * (1 + off) * (1 + C_BEM / n**2), rel=1e-12)
        assert row["zeta_um"] == study.ZETA_UM
        assert [p["r_over_radius"] for p in row["profile"]] == list(study.PROFILE_POINTS)
        t = row["targets"]
        for key in ("F_T", "sigma0"):
            assert t[key]["error"] == pytest.approx(off, abs=1e-9)
        assert t["rings"]["worst_error"] == pytest.approx(off, abs=1e-9)
        assert t["profile"]["worst_error"] == pytest.approx(off, rel=1e-6)
    assert good["targets"]["every"] and not bad["targets"]["every"]
    assert not bad["targets"]["F_T"]["met"] and bad["targets"]["sigma0"]["met"]
    assert report["targets_met"]["scenes"] == 1 and report["targets_met"]["of"] == 2
    text = study.table_text(report)
    assert "1 of 2 scenes meet every target" in text and "Es=Ep" in text


def test_the_report_files_round_trip(fake_report, tmp_path):
    import csv
    import json

    out = tmp_path / "report"
    names = study.write_report(fake_report, out)
    assert names[-1] == "lattice.json" and all((out / n).is_file() for n in names)
    assert json.loads((out / "lattice.json").read_text()) == json.loads(
        json.dumps(fake_report))
    rows = list(csv.DictReader((out / "lattice.csv").open()))
    assert [r["substrate"] for r in rows] == [study.LENS, study.PILLAR]
    for r, row in zip(rows, fake_report["rows"]):
        for q in ("F_T", "sigma0", "a", "A"):
            e = row["elastic_quantities"][q]
            unit = {"F_T": "N", "sigma0": "Pa", "a": "m", "A": "m^2"}[q]
            assert float(r[f"{q}_elastic_{unit}"]) == e["bem"]
            assert float(r[f"{q}_elastic_band_{unit}"]) == e["bem_band"]
            assert float(r[f"{q}_elastic_difference"]) == e["difference"]
            assert float(r[f"{q}_bem_{unit}"]) == row["quantities"][q]["bem"]
        assert r["targets_met"] == str(row["targets"]["every"])
        assert float(r["target_F_T_error"]) == row["targets"]["F_T"]["error"]
    rings = list(csv.DictReader((out / "rings.csv").open()))
    assert len(rings) == 6 and {"elastic_ring_force_ratio", "elastic_estimate_N",
                                "fem_band_N", "target_met"} <= set(rings[0])
    first = fake_report["rows"][0]["ring_forces"][0]
    assert float(rings[0]["elastic_estimate_N"]) == first["elastic_N"]
    prof = list(csv.DictReader((out / "profile.csv").open()))
    assert len(prof) == 2 * len(study.PROFILE_POINTS)
    assert float(prof[0]["elastic_Pa"]) == fake_report["rows"][0]["profile"][0]["elastic_Pa"]
    summary = (out / "summary.md").read_text()
    assert "1 of 2 scenes meet every target" in summary and "E_s = E_p" in summary


def test_the_calibration_places_each_substrate_convention_on_its_own_axis(fake_report):
    """The lattice tables gain an es_share axis (log E_s/E_l over log E_p/E_l) when a report
    holds E_s = E_p rows: the E_s = E_l row sits at 0, the E_s = E_p row at 1, and a row at
    E_p = E_l (the same scene under both conventions) at both ends; without E_s = E_p rows
    there is no such axis."""
    from validation.studies.calibrate import lattice_hooke_table
    from validation.studies.calibrate.lattice_tables import _lattice_features, _lattice_rows

    table = lattice_hooke_table(fake_report)
    assert table.features == ["phi", "c_p", "es_share"]
    c_p = 1.0 / (1.0 + 10.0)  # E_p = 10 E_l
    assert table.points == [pytest.approx([0.1, c_p, 0.0]), pytest.approx([0.2, c_p, 1.0])]
    row = {**fake_report["rows"][0], "ratio": 1.0}
    both = {"rows": [row, fake_report["rows"][1]]}
    (_, xs), _ = list(_lattice_rows(both, _lattice_features(both)))
    assert [x[-1] for x in xs] == [0.0, 1.0] and xs[0][:2] == pytest.approx([0.1, 0.5])
    assert _lattice_features({"rows": [fake_report["rows"][0]]}) == ["phi", "c_p"]


def test_csv_values_are_plain_numbers():
    """A band from the verification study is numpy's float64, whose repr is np.float64(...):
    every CSV cell must read back with float()."""
    import numpy as np

    from validation.studies.lattice.tables import _csv

    text = _csv(["a", "b", "c"], [{"a": np.float64(0.1), "b": None, "c": True}])
    assert text.splitlines()[1] == "0.1,,True"


@pytest.mark.slow
def test_the_elastic_bem_meets_its_force_target_on_real_scenes(tmp_path):
    """Two scenes at the study's quick levels on the real models (the default compliance, from
    the user's cache or built once per pillar kind): soft pillars at E_s = E_l and stiff ones
    at the paper's E_s = E_p.  The elastic BEM's F_T is within 1 % of fem-3d's, or within both
    bands (at two levels each band is 3 times the step, so this is a smoke test of the
    column; the full study judges the three-level estimates)."""
    points = [study.LatticePoint(0.1, 0.1), study.LatticePoint(0.2, 10.0, study.PILLAR)]
    with Engine("serial", quiet=True) as engine:
        report = study.lattice_study(tmp_path, engine=engine, points=points,
                                     fem_levels=study.QUICK_FEM_LEVELS,
                                     bem_levels=study.QUICK_BEM_LEVELS)
    for row in report["rows"]:
        assert row["status"] in ("ok", "not converged"), row["status"]
        assert row["targets"]["F_T"]["met"], (row["label"], row["targets"]["F_T"])
        # the elastic pillar is closer to fem-3d's than the Hooke pillar in sigma0
        assert abs(row["elastic_quantities"]["sigma0"]["difference"]) < abs(
            row["quantities"]["sigma0"]["difference"])
    study.write_report(report, tmp_path)
    assert report["targets_met"]["of"] == 2


def test_the_command_runs_the_paper_scenes_it_is_given(fake_lattice_models, cli, tmp_path):
    import json

    code, out, err = cli("lattice", "--surface-fractions", "0.1", "--ratios", "10",
                         "--paper-scenes", "0.2:10", "--quick", "--executor", "serial",
                         "--out", tmp_path)
    assert code == 0, err
    assert "Es=Ep" in out and "scenes meet every target" in out
    report = json.loads((tmp_path / "lattice.json").read_text())
    assert [(r["surface_fraction"], r["substrate"]) for r in report["rows"]] == [
        (0.1, study.LENS), (0.2, study.PILLAR)]
    assert {lv["cells_per_diameter"] for lv in report["rows"][1]["elastic_levels"]} == set(
        study.QUICK_BEM_LEVELS)
    # by default the E_s = E_p scenes are those of PAPER_SCENES inside the grid: none here
    code, out, err = cli("lattice", "--surface-fractions", "0.1", "--ratios", "10", "--quick",
                         "--executor", "serial", "--out", tmp_path / "grid")
    assert code == 0, err
    rows = json.loads((tmp_path / "grid" / "lattice.json").read_text())["rows"]
    assert [r["substrate"] for r in rows] == [study.LENS]
