"""``pillar-xval solve``: one JSON document on stdout, report files a script can read back."""

import csv
import json

import pytest

from scenes import ContactResult
from validation.cli import main


def test_json_is_one_document_and_round_trips(tmp_path, capsys):
    code = main(["solve", "--scene", "paper-fig3-sparse", "--elements-per-diameter", "7",
                 "--json", "--out", str(tmp_path)])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)  # exactly one JSON document
    for key in ("model", "scene", "discretisation", "total_force_N", "centre_pressure_Pa",
                "contact_radius_m", "real_contact_area_m2", "pillars_in_contact",
                "pillar_forces", "converged", "iterations", "wall_time_s", "version"):
        assert key in doc
    back = ContactResult.from_json((tmp_path / "result.json").read_text())
    assert back.total_force_N == doc["total_force_N"] and back.pillars_in_contact == 7
    with open(tmp_path / "pillars.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 7
    assert sum(float(r["force_N"]) for r in rows) == pytest.approx(doc["total_force_N"], rel=1e-9)
    with open(tmp_path / "elements.csv") as fh:
        header = next(csv.reader(fh))
    assert {"x_m", "y_m", "pressure_Pa", "force_N", "weight"} <= set(header)
    assert (tmp_path / "pressure.png").read_bytes()[:4] == b"\x89PNG"


def test_paper_search_and_centre_cells_from_the_cli(capsys):
    assert main(["solve", "--scene", "single-pillar", "--contact", "paper", "--cells",
                 "centre", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["discretisation"]["contact"] == "paper"
    assert doc["discretisation"]["cells"] == "centre"
