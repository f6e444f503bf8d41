"""The multi-pillar cross-validation study (pillar-xval lattice): its bookkeeping, one cheap
real point, and input refused before any solve."""

from __future__ import annotations

import pytest

from outcome import ContactResult, PillarForce
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


def test_one_point_of_the_study_on_the_real_models(tmp_path):
    point = study.LatticePoint(0.03, 1.0)
    levels = {"fem_levels": (4.0, 2.83), "bem_levels": (8, 16)}
    with Engine("serial", quiet=True) as engine:
        report = study.lattice_study(tmp_path, engine=engine, points=[point], **levels)
        row = report["rows"][0]
        assert row["status"] == "ok", row["status"]
        f_t = row["quantities"]["F_T"]
        assert f_t["fem"] == pytest.approx(f_t["bem"], rel=RTOL_MODEL_FORCE)
        # Both models load the centre pillar and its first ring (7 pillars, Fig. 3a).
        assert row["pillars_in_contact"] == {"fem": 7, "bem": 7}
        ring_sum = sum(r["bem_force_N"] for r in row["rings"])
        assert ring_sum == pytest.approx(row["bem_levels"][-1]["F_T"], rel=1e-12)
        assert {r["ring"] for r in row["rings"]} == {0, 1}
        names = study.write_report(report, tmp_path)
        assert all((tmp_path / n).exists() for n in names)
        # A rerun reads every case back: nothing is computed twice.
        outcomes = engine.run(study.cases(point, **levels), tmp_path / "cases")
        assert all(o.cached for o in outcomes)


@pytest.mark.parametrize("argv, words", [
    (["--surface-fractions", "0.95"], "surface_fraction"),
    (["--ratios", "0"], "--ratios"),
    (["--ratios", "1e-12"], "pillars.E_Pa"),
])
def test_bad_points_are_refused_before_any_solve(cli, tmp_path, argv, words):
    code, out, err = cli("lattice", *argv, "--out", tmp_path / "o", "--executor", "serial")
    assert code == 2 and words in err and "Traceback" not in err
    assert not (tmp_path / "o" / "cases").exists()
