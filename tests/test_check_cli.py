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
