"""``pillar-xval curve``: the loading curve on the engine, its files, the user's data, and the
loads refused before anything is solved; force-controlled scenes in solve, sweeps, check
specs and the pytest plugin."""

from __future__ import annotations

import csv
import json

import pytest

from validation.cli import main
from validation.studies.curve import CSV_COLUMNS, read_data


def run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def test_curve_writes_its_files_and_resumes(tmp_path, capsys):
    out = tmp_path / "curve"
    args = ["curve", "--scene", "paper-fig3-sparse", "--forces-uN", "1,5,20", "--models",
            "bem,bem-fft", "--elements-per-diameter", "5", "--cells-per-diameter", "8",
            "--executor", "serial", "--out", str(out)]
    code, text, _ = run(args, capsys)
    assert code == 0, text
    with open(out / "curve.csv") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0]) == CSV_COLUMNS
    assert [r["model"] for r in rows] == ["bem"] * 3 + ["bem-fft"] * 3
    assert [float(r["force_N"]) for r in rows[:3]] == pytest.approx([1e-6, 5e-6, 2e-5],
                                                                     rel=1e-8)
    doc = json.loads((out / "curve.json").read_text())
    assert doc["control"] == "force" and doc["falls"] == {"bem": [], "bem-fft": []}
    assert set(doc["references"]) == {"hertz", "spring"}
    assert (out / "curve.png").stat().st_size > 10_000
    code, _, err = run(args, capsys)  # every case cached: nothing solved again
    assert code == 0 and "running" not in err


def test_curve_under_indentations_with_bands_and_data(tmp_path, capsys):
    data = tmp_path / "measured.csv"
    data.write_text("# a comment\nforce_uN,indentation_um,contact_radius_um\n"
                    "2,0.2,\n8,0.45,40\n")
    out = tmp_path / "curve"
    code, text, _ = run(["curve", "--scene", "single-pillar", "--indentations-um", "0.1,0.3",
                         "--models", "bem", "--elements-per-diameter", "5", "--levels", "2",
                         "--data", str(data), "--executor", "serial", "--out", str(out),
                         "--json"], capsys)
    assert code == 0
    doc = json.loads(text)
    assert doc["control"] == "indentation"
    assert all(set(r["bands"]) >= {"total_force_N", "centre_pressure_Pa"} for r in doc["rows"])
    assert len(doc["data"]["points"]) == 2
    assert doc["data"]["points"][0] == pytest.approx({"total_force_N": 2e-6,
                                                      "indentation_m": 2e-7})


@pytest.mark.parametrize("content,words", [
    ("force_uN,depth_um\n1,2\n", "line 1, column 2 'depth_um': unknown"),
    ("indentation_um\n0.3\n", "no force_uN column"),
    ("force_uN,indentation_um\n1,abc\n", "line 2, column indentation_um: 'abc' is not"),
    ("force_uN,indentation_um\n1,0.2\n2\n", "line 3: 1 cells"),
    ("force_uN\n-1\n", "line 2, column force_uN: -1 is out of range"),
    ("force_uN\nnan\n", "line 2, column force_uN: 'nan' is not a decimal"),
    ("force_uN,force_uN\n1,1\n", "given twice"),
    ("force_uN\n", "no data rows"),
    ("", "no header row"),
])
def test_malformed_data_is_refused_naming_file_line_and_column(tmp_path, content, words):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(Exception) as err:
        read_data(path)
    assert words in str(err.value) and str(path) in str(err.value)


@pytest.mark.parametrize("extra,words", [
    (["--forces-uN", "5,2"], "the loads must rise"),
    (["--forces-uN", "1,nan"], "expected a decimal number"),
    (["--forces-uN", "1", "--indentations-um", "0.1"], "not allowed with argument"),
    ([], "one of the arguments --forces-uN --indentations-um is required"),
    (["--forces-uN", "1,1e6"], "--forces-uN 1e6: implies an indentation of at least"),
    (["--forces-uN", "0"], "allowed range is (0, inf)"),
    (["--forces-uN", "1", "--data", "missing.csv"], "--data missing.csv: not a file"),
])
def test_bad_loads_are_refused_before_anything_is_solved(tmp_path, capsys, extra, words):
    code, _, err = run(["curve", "--scene", "paper-fig3-sparse", *extra, "--out",
                        str(tmp_path / "o")], capsys)
    assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "o" / "cases").exists()


def test_solve_answers_the_20_uN_question(capsys):
    code, out, _ = run(["solve", "--scene", "paper-fig3-sparse", "--set", "load.force_uN=20",
                        "--json"], capsys)
    result = json.loads(out)
    assert code == 0 and result["load_control"] == "force"
    assert result["total_force_N"] == pytest.approx(2e-5, rel=1e-8)
    assert 0.78e-6 < result["indentation_m"] < 0.84e-6  # the hand root-find: 0.81 um
    assert result["pillars_in_contact"] == 19


def test_solve_refuses_a_force_beyond_the_small_slope_limit_in_one_line(capsys):
    code, _, err = run(["solve", "--scene", "paper-fig3-sparse", "--set",
                        "load.force_uN=1e6"], capsys)
    assert code == 2 and "implies an indentation of at least" in err
    assert len(err.strip().splitlines()) == 1


def test_sweep_with_a_force_axis(tmp_path):
    from validation.studies.sweep import ModelSpec, Sweep, crossed, run_sweep

    sweep = Sweep("paper-fig3-sparse", axes=(crossed("load.force_uN", [2.0, 10.0]),),
                  models=(ModelSpec("bem", {"elements_per_diameter": 5}),))
    rows = run_sweep(sweep, tmp_path)
    assert [r["load_control"] for r in rows] == ["force", "force"]
    assert [r["load.force_uN"] for r in rows] == [2.0, 10.0]
    assert rows[0]["load.indentation_um"] is None
    assert rows[0]["indentation_m"] < rows[1]["indentation_m"]
    assert rows[1]["total_force_N"] == pytest.approx(1e-5, rel=1e-8)


def test_check_spec_compares_indentations_under_a_force(tmp_path, capsys):
    spec = tmp_path / "checks.toml"
    spec.write_text('[[check]]\nname = "hertz under 5 uN"\nscene = "hertz"\n'
                    'set = ["load.force_uN=5"]\nmodel = "bem-fft"\nreference = "hertz"\n'
                    'quantities = ["zeta", "sigma0", "a"]\nrtol = 0.002\n'
                    'source = "bem-fft N=32 against Hertz: zeta -0.008 %, sigma0 +0.026 %, '
                    'a +0.065 % measured"\n')
    code, out, _ = run(["check", str(spec), "--out", str(tmp_path / "o"), "--executor",
                        "serial"], capsys)
    assert code == 0, out


def test_pytest_fixture_accepts_force_controlled_scenes(xval):
    from validation.testing import assert_matches_closed_form

    scene = xval.scene("single-pillar", "pillars.E_Pa=1.6e5", "load.force_uN=1")
    # The spring model is the Hooke pillar's closed form: the BEM with Hooke pillars (the
    # fixture's default on this scene's elastic pillars is the elastic pillar).
    result = xval.run("bem-richardson", scene, elements_per_diameter=11, pillars="hooke")
    assert result.load_control == "force"
    assert_matches_closed_form(result, "spring", quantities=("zeta",), rtol=0.006,
                               source="spring model against the extrapolated BEM: +0.05 %")


def test_studies_take_force_controlled_scenes(tmp_path, capsys):
    """A study that reads a scene takes a force-controlled one: its levels under the force,
    the force itself at round-off, the indentation solved on each."""
    code, out, _ = run(["converge", "--scene", "hertz", "--set", "load.force_uN=5",
                        "--levels", "2", "--elements-per-diameter", "5", "--executor",
                        "serial", "--out", str(tmp_path / "o"), "--json"], capsys)
    doc = json.loads(out)
    assert code == 0 and all(lv["F_T"] == pytest.approx(5e-6, rel=1e-8)
                             for lv in doc["levels"])
