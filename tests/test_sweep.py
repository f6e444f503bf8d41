"""``pillar-xval sweep``: the spec format, the grid, the table (CSV and Parquet), resume and
the dry run.  Real solves use the dense BEM at small P."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from bem_solver import solve_dense
from pillar_xval.scenes import InputError, SceneError, load_scene
from validation.cli import main
from validation.engine import Engine, read_journal
from validation.studies.sweep import (ModelSpec, Sweep, crossed, linear, log, run_sweep,
                                      run_sweep_cases, table_rows, write_table, zipped)

EXAMPLE = Path(__file__).resolve().parents[1] / "validation" / "examples" / "sweep-phi-zeta.toml"


def _write(tmp_path, text: str) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(text)
    return path


def test_ranges_include_both_ends():
    assert linear(1.0, 3.0, 3) == [1.0, 2.0, 3.0]
    values = log(0.05, 0.5, 4)
    assert values[0] == 0.05 and values[-1] == 0.5
    ratios = [b / a for a, b in zip(values, values[1:])]
    assert ratios == pytest.approx([10 ** (1 / 3)] * 3, rel=1e-12)
    with pytest.raises(InputError, match="num"):
        linear(0, 1, 0)
    with pytest.raises(InputError, match="> 0"):
        log(0, 1, 3)


def test_grid_crosses_axes_and_zips_groups(tmp_path):
    spec = _write(tmp_path, """
        scene = "paper-fig3-sparse"
        [grid]
        pillars.surface_fraction = [0.01, 0.03]          # a dotted bare key
        "load.indentation_um" = { log = [0.1, 0.4], num = 3 }
        [[zip]]
        "pillars.E_Pa" = [1.6e5, 1.6e6]
        "substrate.E_Pa" = [1.6e6, 1.6e7]
        [[models]]
        name = "bem"
        elements_per_diameter = [5, 7]
        [[models]]
        name = "bem-fft"
        cells_per_diameter = 8
    """)
    sweep = Sweep.from_toml(spec)
    assert sweep.name == "spec" and len(sweep.points()) == 2 * 3 * 2
    assert sweep.keys == ["pillars.surface_fraction", "load.indentation_um", "pillars.E_Pa",
                          "substrate.E_Pa"]
    points = sweep.points()
    assert all(p["substrate.E_Pa"] == 10 * p["pillars.E_Pa"] for p in points)  # zipped
    assert {(p["pillars.surface_fraction"], p["load.indentation_um"]) for p in points} == {
        (phi, z) for phi in (0.01, 0.03) for z in log(0.1, 0.4, 3)}  # crossed
    cases, skipped = sweep.cases()
    assert len(cases) == 12 * 3 and not skipped
    first = cases[0]
    assert first.scene.pillars.surface_fraction == pytest.approx(0.01, rel=1e-12)
    assert first.scene.indentation_m == pytest.approx(0.1e-6, rel=1e-12)
    assert first.scene.substrate.E_Pa == 1.6e6 and first.scene.pillars.material.E_Pa == 1.6e5
    # elastic pillars: the elastic pillar by default, named in each case (and its key)
    assert [c.case.options for c in cases[:3]] == [
        {"elements_per_diameter": 5, "pillars": "elastic"},
        {"elements_per_diameter": 7, "pillars": "elastic"},
        {"cells_per_diameter": 8, "pillars": "elastic"}]


@pytest.mark.parametrize("text, message", [
    ('scene = "hertz"\n[[zip]]\n"lens.E_Pa" = [1.0, 2.0]\n"lens.nu" = [0.5]\n'
     '[[models]]\nname = "bem"', "equal lengths"),
    ('scene = "hertz"\n[[models]]\nname = "nope"', "unknown"),
    ('scene = "hertz"\n[[models]]\nname = "bem"\nmesh_size = 1.0', "unknown option"),
    ('scene = "hertz"', "at least one"),
    ('[[models]]\nname = "bem"', "'scene'"),
    ('scene = "hertz"\ngird = 1\n[[models]]\nname = "bem"', "unknown key"),
    ('scene = "hertz"\n[grid]\n"load.indentation_um" = { log = [0.1, 1], num = 0 }\n'
     '[[models]]\nname = "bem"', "num"),
    ('scene = "hertz"\n[grid]\n"load.indentation_um" = [1, 2]\n[[zip]]\n'
     '"load.indentation_um" = [1, 2]\n[[models]]\nname = "bem"', "given twice"),
    ('scene = "hertz"\n[grid]\n"load.depth_um" = [1, 2]\n[[models]]\nname = "bem"',
     "load.depth_um"),
    ("scene = ", "not valid TOML"),
    ('scene = "hertz"\nname = "../../etc/evil"\n[[models]]\nname = "bem"', "plain file name"),
    ('scene = "hertz"\nname = ".."\n[[models]]\nname = "bem"', "plain file name"),
    ('scene = "hertz"\n[grid]\n"pillars.surface_fraction" = [0.01, 0.01, 0.03]\n'
     '[[models]]\nname = "bem"', "more than once"),
    # auto's request and NaN (exit 4 with a JSON error before), before anything is solved
    ('scene = "hertz"\n[[models]]\nname = "auto"\ntolerance = nan', "finite"),
    ('scene = "hertz"\n[[models]]\nname = "auto"\ntolerance = 5', "--tolerance 5"),
    ('scene = "hertz"\n[[models]]\nname = "auto"\nquantities = "F_T,,sigma0"', "none empty"),
    # a model out of its scope at a point, and the elastic pillar on a flat scene
    ('scene = "paper-fig3-sparse"\n[[models]]\nname = "fem-axisym"', "fem-3d holds them"),
    ('scene = "hertz"\n[[models]]\nname = "bem"\npillars = "elastic"', "the scene is flat"),
])
def test_bad_specs_are_refused_with_the_reason(tmp_path, text, message, capsys):
    spec = _write(tmp_path, text)
    with pytest.raises(InputError, match=message):
        Sweep.from_toml(spec).cases()
    assert main(["sweep", str(spec), "--out", str(tmp_path / "o"), "--dry-run"]) == 2
    assert "error:" in capsys.readouterr().err


def test_a_point_the_scene_refuses_is_named_or_skipped(tmp_path):
    base = ('scene = "paper-fig3-sparse"\n{extra}\n[grid]\n'
            '"load.indentation_um" = [0.3, 300.0]\n[[models]]\nname = "bem"\n')
    with pytest.raises(SceneError, match="load.indentation_um=300"):
        Sweep.from_toml(_write(tmp_path, base.format(extra=""))).cases()
    cases, skipped = Sweep.from_toml(_write(tmp_path, base.format(
        extra='on_invalid = "skip"'))).cases()
    assert len(cases) == 1 and len(skipped) == 1 and skipped[0][0] == {"load.indentation_um": 300.0}


def test_python_sweep_table_matches_direct_solves(tmp_path):
    sweep = Sweep("paper-fig3-sparse",
                  axes=(crossed("load.indentation_um", linear(0.2, 0.4, 2)),
                        zipped({"pillars.E_Pa": [1.6e6, 1.6e7], "pillars.nu": [0.5, 0.3]})),
                  models=(ModelSpec("bem", {"elements_per_diameter": [3, 5],
                                            "pillars": "hooke"}),),
                  overrides=("lens.radius_mm=3",), name="api")
    rows = run_sweep(sweep, tmp_path, engine=Engine("serial", quiet=True))
    assert len(rows) == 8
    cols = list(rows[0])
    assert cols[:4] == ["load.indentation_um", "pillars.E_Pa", "pillars.nu", "lens.radius_mm"]
    assert cols[-1] == "case_key" and "option.elements_per_diameter" in cols
    for row in rows:
        sets = ["lens.radius_mm=3", f"load.indentation_um={row['load.indentation_um']!r}",
                f"pillars.E_Pa={row['pillars.E_Pa']!r}", f"pillars.nu={row['pillars.nu']!r}"]
        scene = load_scene("paper-fig3-sparse", sets)
        direct = solve_dense(scene, row["option.elements_per_diameter"])
        assert row["total_force_N"] == direct.total_force_N  # the same deterministic solve
        assert row["centre_pressure_Pa"] == direct.centre_pressure_Pa
        # file units, named as in a scene file: values as written, derived ones converted
        assert row["lens.radius_mm"] == 3.0 and row["pillars.diameter_um"] == 4.0
        assert row["pillars.pitch_um"] == pytest.approx(scene.pillars.pitch_m * 1e6, rel=1e-12)
        # the table reports the scene solved: the preset's own [substrate] (Table 1), which
        # an override of the pillars leaves alone
        assert row["substrate.E_Pa"] == scene.substrate.E_Pa == 1.6e6
        assert row["status"] == "ok" and row["converged"] is True
    paths = write_table(rows, tmp_path, "api")
    import pyarrow.parquet as pq

    table = pq.read_table(paths[1]).to_pylist()
    assert table == rows
    with open(paths[0]) as fh:
        back = list(csv.DictReader(fh))
    assert [float(r["total_force_N"]) for r in back] == [r["total_force_N"] for r in rows]


def test_cli_sweep_dry_run_run_and_resume(tmp_path, capsys):
    spec = _write(tmp_path, """
        name = "small"
        scene = "paper-fig3-sparse"
        [grid]
        "pillars.surface_fraction" = { linear = [0.02, 0.04], num = 3 }
        [[models]]
        name = "bem"
        elements_per_diameter = 3
        pillars = "hooke"
    """)
    out = tmp_path / "out"
    assert main(["sweep", str(spec), "--out", str(out), "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "3 cases (0 already in" in text and "estimated: ~" in text
    assert not (out / "small.csv").exists()
    assert main(["sweep", str(spec), "--out", str(out), "--executor", "serial"]) == 0
    assert "3 cases (0 failed, 0 not converged)" in capsys.readouterr().out
    with open(out / "small.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["pillars.surface_fraction"]) for r in rows] == [0.02, 0.03, 0.04]
    assert all(math.isfinite(float(r["total_force_N"])) for r in rows)
    assert (out / "small.parquet").stat().st_size > 0
    starts = sum(e["event"] == "start" for e in read_journal(out / "cases"))
    assert main(["sweep", str(spec), "--out", str(out)]) == 0  # resumed: all cached
    assert sum(e["event"] == "start" for e in read_journal(out / "cases")) == starts == 3
    assert main(["sweep", str(spec), "--out", str(out), "--dry-run"]) == 0
    assert "3 cases (3 already in" in capsys.readouterr().out


def test_example_spec_is_valid():
    sweep = Sweep.from_toml(EXAMPLE)
    cases, skipped = sweep.cases()
    assert sweep.name == "phi-zeta" and not skipped
    assert len(cases) == 4 * 3 * 2 * 3  # Phi x zeta x materials x (two P + one FFT)


def test_sweep_cases_give_results_and_pressure_maps(tmp_path):
    """What a figure needs: each case's result and, on request, its arrays."""
    sweep = Sweep("paper-fig3-sparse", axes=(crossed("pillars.surface_fraction", [0.03, 0.1]),),
                  models=(ModelSpec("bem", {"elements_per_diameter": 3, "pillars": "hooke"}),))
    pairs = run_sweep_cases(sweep, tmp_path, engine=Engine("serial", quiet=True), fields=True)
    assert [c.point for c, _ in pairs] == [{"pillars.surface_fraction": 0.03},
                                           {"pillars.surface_fraction": 0.1}]
    for case, outcome in pairs:
        arrays = outcome.field_arrays()
        total = (arrays["force_N"] * arrays["weight"]).sum()  # D6 orbits, weight each
        assert total == pytest.approx(outcome.result.total_force_N, rel=1e-12)
    assert [r["total_force_N"] for r in table_rows(sweep, pairs)] == \
        [o.result.total_force_N for _, o in pairs]
