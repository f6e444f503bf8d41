"""The force-control benchmark's arithmetic on a small case (its figures: make bench-force)."""

import json

import pytest

from validation.bench import force


def test_bench_force_times_both_controls_and_writes_its_files(tmp_path):
    assert force.main(["--out", str(tmp_path), "--only", "spring", "--repeats", "2"]) == 0
    row = force.run_case("bem P=5", "bem", {"elements_per_diameter": 5}, "single-pillar",
                         1.5, 2)
    assert len(row["times_s"]["indentation"]) == len(row["times_s"]["force"]) == 2
    assert row["ratio_of_medians"] == pytest.approx(
        row["median_force_s"] / row["median_indentation_s"])
    assert abs(row["round_trip"]) < 1e-8 and row["force_met"] < 1e-8 and row["converged"]
    assert "| bem P=5 | single-pillar |" in force.table([row])
    doc = json.loads((tmp_path / "bench_force.json").read_text())
    assert doc["rows"] == [] and (tmp_path / "bench_force.md").is_file()
