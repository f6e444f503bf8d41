"""``pillar-xval check SPEC.toml``: 0 when every check passes, 1 when one fails (with the
message a pytest check gives, in the table and in the JUnit report), 2 on a bad spec."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

EXAMPLE = Path(__file__).resolve().parents[1] / "validation" / "examples" / "checks.toml"


def _spec(tmp_path, text: str) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(text)
    return path


def test_the_example_passes_and_its_junit_report_lists_every_check(tmp_path, cli):
    junit = tmp_path / "report" / "junit.xml"
    code, out, err = cli("check", EXAMPLE, "--out", tmp_path / "o", "--junit-xml", junit,
                         "--executor", "serial")
    assert code == 0, err
    assert "2 passed, 0 failed" in out
    suite = ET.parse(junit).getroot().find("testsuite")
    assert suite.get("tests") == "2" and suite.get("failures") == "0"
    assert [tc.get("name") for tc in suite.iter("testcase")] == [
        "dense BEM reaches Hertz", "dense BEM against fem-axisym, rigid punch"]
    doc = json.loads((tmp_path / "o" / "check.json").read_text())
    assert doc["passed"] == 2 and all(r["passed"] for r in doc["checks"])


def test_a_failing_check_exits_1_with_its_reason(tmp_path, cli):
    text = EXAMPLE.read_text().replace("rtol = 0.03", "rtol = 0.005")
    junit = tmp_path / "junit.xml"
    code, out, _ = cli("check", _spec(tmp_path, text), "--out", tmp_path / "o",
                       "--junit-xml", junit, "--executor", "serial")
    assert code == 1
    assert "1 passed, 1 failed" in out
    assert "rtol 0.005; source: measured 2.2 % at P = 11" in out
    failure = ET.parse(junit).getroot().find("testsuite/testcase/failure")
    assert failure is not None and "F_T: actual" in failure.text
    assert failure.get("message").startswith("assert_close")


@pytest.mark.parametrize("text, message", [
    ('[[check]]\nscene = "hertz"\nmodel = "bem"\nreference = "hertz"', "'rtol' is missing"),
    ('[[check]]\nscene = "hertz"\nmodel = "nope"\nreference = "hertz"\nrtol = 0.1',
     "unknown model"),
    ('[[check]]\nscene = "hertz"\nmodel = "bem"\nreference = "hertz"\nrtol = -1',
     "rtol = -1"),
    ('[[check]]\nscene = "hertz"\nmodel = "bem"\nreference = "hertz"\nrtol = 0.1\n'
     'quantities = ["force"]', "quantities"),
    ('[[check]]\nscene = "hertz"\nmodel = "bem"\noptions = { mesh_size = 1.0 }\n'
     'reference = "hertz"\nrtol = 0.1', "unknown option"),
    ('[[check]]\nscene = "hertz"\nmodel = "bem"\nreference = "hertz"\nrtol = 0.1\ncolour = 1',
     "unknown key"),
    ('[[check]]\nscene = "nowhere.toml"\nmodel = "bem"\nreference = "hertz"\nrtol = 0.1',
     "nowhere.toml"),
    ("check = 3", "at least one"),
    ("[[check]\n", "not valid TOML"),
])
def test_a_bad_spec_exits_2_naming_the_key(tmp_path, cli, text, message):
    code, out, err = cli("check", _spec(tmp_path, text), "--out", tmp_path / "o")
    assert code == 2
    assert message in err and "Traceback" not in err


# --- a spec is judged whole before anything is solved -------------------------------------
_LATTICE = 'scene = "paper-fig3-sparse"\n'
_FLAT = 'scene = "hertz"\n'


@pytest.mark.parametrize("body, message", [
    # a closed form that is no reference for the scene (found after solving, as exit 1)
    (_FLAT + 'model = "bem"\nreference = "punch"', "one pillar's: the scene is flat"),
    (_FLAT + 'model = "bem"\nreference = "spring"', "one pillar's: the scene is flat"),
    (_LATTICE + 'model = "bem"\nreference = "spring"', "a second pillar touches"),
    # Hertz ignores the pillars: refused on a lattice, not applied without a word
    (_LATTICE + 'model = "bem"\nreference = "hertz"', "Hertz is the flat substrate's solution"),
    # fem-axisym holds one pillar: refused on a lattice, naming fem-3d
    (_LATTICE + 'model = "fem-axisym"\nreference = "bem"', "fem-3d holds them"),
    (_LATTICE + 'model = "bem"\nreference = "fem-axisym"', "fem-3d holds them"),
    # auto's request (found after solving, as exit 1)
    (_FLAT + 'model = "auto"\noptions = { tolerance = 5 }\nreference = "hertz"',
     "--tolerance 5"),
    (_FLAT + 'model = "auto"\noptions = { budget = -1 }\nreference = "hertz"', "--budget -1"),
    (_FLAT + 'model = "auto"\noptions = { quantities = ["force"] }\nreference = "hertz"',
     "--quantities force: unknown"),
    (_FLAT + 'model = "auto"\noptions = { quantities = "F_T,,sigma0" }\nreference = "hertz"',
     "none empty"),
    (_FLAT + 'model = "auto"\noptions = { quantities = [] }\nreference = "hertz"',
     "none empty"),
    # NaN (exit 4 with a JSON error before)
    (_FLAT + 'model = "auto"\noptions = { tolerance = nan }\nreference = "hertz"',
     "tolerance = nan: expected a finite number"),
    (_FLAT + 'model = "bem"\nreference = "hertz"\natol = nan', "atol = nan"),
    # the elastic pillar on a flat scene (run as Hooke before)
    (_FLAT + 'model = "bem"\noptions = { pillars = "elastic" }\nreference = "hertz"',
     "the scene is flat"),
    (_FLAT + 'model = "bem"\nreference = "bem-fft"\nreference_options = { pillars = "elastic" }',
     "the scene is flat"),
    # a control character in a name (JUnit XML cannot carry it)
    ('name = "bell \\u0007"\n' + _FLAT + 'model = "bem"\nreference = "hertz"',
     "control character U+0007"),
])
def test_a_spec_is_refused_whole_before_any_solve(tmp_path, cli, body, message):
    code, out, err = cli("check", _spec(tmp_path, "[[check]]\nrtol = 0.1\n" + body),
                         "--out", tmp_path / "o", "--executor", "serial")
    assert code == 2, err
    assert message in err and "Traceback" not in err
    assert not (tmp_path / "o" / "cases").exists()  # nothing was solved


def test_output_paths_are_checked_before_any_solve(tmp_path, cli, monkeypatch):
    folder = tmp_path / "a-folder"
    folder.mkdir()
    code, _, err = cli("check", EXAMPLE, "--out", tmp_path / "o", "--junit-xml", folder)
    assert code == 2 and "--junit-xml" in err and "is a folder" in err
    assert not (tmp_path / "o" / "cases").exists()
    # a spec named '...toml' would send out/check/<stem> to out/ itself
    monkeypatch.chdir(tmp_path)
    (tmp_path / "...toml").write_text(EXAMPLE.read_text())
    code, _, err = cli("check", "...toml")
    assert code == 2 and "stem '..'" in err
    assert not (tmp_path / "out").exists()


def test_the_example_runs_from_any_folder_and_says_where_it_wrote(fakes, tmp_path, cli,
                                                                    monkeypatch):
    monkeypatch.chdir(tmp_path)  # not the repository: the toolkit's own example is read
    code, out, err = cli("check", "validation/examples/checks.toml", "--executor", "serial")
    assert code == 1 and "1 passed, 1 failed" in out, err  # the fakes' FEM is 8 % off
    assert "reading the toolkit's own" in err
    report = Path("out") / "check" / "checks" / "check.json"
    assert report.is_file() and f"written: {report}" in out


def test_junit_xml_is_well_formed_whatever_a_name_or_message_holds():
    from validation.studies.check import junit_xml

    rows = [{"name": "bell \a and escape \x1b[31m", "scene": "s\x00", "passed": False,
             "message": "first \x0b line\nsecond \ud800 line"},
            {"name": "fine", "scene": "hertz", "passed": True, "message": ""}]
    root = ET.fromstring(junit_xml(rows, "suite\x01", 1.0).split("\n", 1)[1])
    cases = list(root.iter("testcase"))
    assert cases[0].get("name") == "bell \\x07 and escape \\x1b[31m"
    assert "\\x0b" in cases[0].find("failure").text and cases[1].get("name") == "fine"
