"""The byte-for-byte reproduction check: what it compares, what it leaves out, and (slow)
this checkout against HEAD."""

import json
import shutil

import pytest

from validation.reproduce import compare, main


def _side(root, fig3=b"phi,sigma0\n0.1,1.5\n", wall=0.1, seconds=2.0):
    (root / "figures" / "cases").mkdir(parents=True)
    (root / "figures" / "fig3.csv").write_bytes(fig3)
    (root / "figures" / "cases" / "x.json").write_text(str(wall))   # the engine's cache
    (root / "figures" / "figures.json").write_text(json.dumps(
        {"rows": [{"F_N": 1e-6, "wall_time_s": wall}], "paths": [str(root)]}))
    (root / "figures" / "timing.json").write_text(json.dumps({"total_s": seconds, "cases": 3}))
    (root / "figures" / "figures.md").write_text(
        f"# Figures\n\n40 scenes and 30 bisection solves in {seconds} s on serial.\nok\n")


def test_same_results_reproduce_whatever_the_run_took(tmp_path):
    _side(tmp_path / "a")
    _side(tmp_path / "b", wall=0.7, seconds=9.5)
    found = compare(tmp_path / "a", tmp_path / "b")
    assert found["differ"] == [] and found["missing"] == []
    assert set(found["same"]) == {"figures/fig3.csv", "figures/figures.json",
                                  "figures/timing.json", "figures/figures.md"}


def test_one_byte_a_result_or_a_count_differs(tmp_path):
    _side(tmp_path / "a")
    _side(tmp_path / "b", fig3=b"phi,sigma0\n0.1,1.6\n")
    (tmp_path / "b" / "figures" / "timing.json").write_text(
        json.dumps({"total_s": 2.0, "cases": 4}))
    (tmp_path / "b" / "figures" / "fig4.csv").write_text("")
    found = compare(tmp_path / "a", tmp_path / "b")
    assert found["differ"] == ["figures/fig3.csv", "figures/timing.json"]
    assert found["missing"] == ["figures/fig4.csv"]


def test_unknown_revision_and_used_folder_are_refused(tmp_path, capsys):
    assert main(["--against", "no-such-revision-xyz", "--out", str(tmp_path / "o")]) == 2
    (tmp_path / "used").mkdir()
    (tmp_path / "used" / "f").write_text("")
    assert main(["--against", "HEAD", "--out", str(tmp_path / "used")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "no-such-revision-xyz" in err[0] and "not empty" in err[1]


@pytest.mark.slow
def test_this_checkout_reproduces_head(tmp_path):
    """The working tree's figures (quick), lattice study and lattice tables against HEAD's
    (about 5 minutes on 2 cores): an uncommitted change that moves a result fails here."""
    if shutil.which("git") is None:
        pytest.skip("needs git")
    assert main(["--against", "HEAD", "--out", str(tmp_path / "r")]) == 0
