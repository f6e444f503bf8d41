"""The FFT benchmark's table (validation.bench.fft) from recorded runs, without solving."""

from __future__ import annotations

import json

import pytest

from validation.bench import fft as bench


def _run(solver, pillars, n, wall, force, it=20, rep=0):
    run = {"solver": solver, "pillars": pillars, "cells_per_diameter": n, "wall_time_s": wall,
           "iterations": it, "operator_applications": it + 5, "candidate_cells": 100,
           "grid_cells": 400, "total_force_N": force, "converged": True, "peak_rss_MB": 50.0}
    if solver != "contactmechanics":
        run.update({"warm_start_iterations": 7, "fft_shape": [45, 45],
                    "timings_s": {"solve": 0.5 * wall}, "time_per_iteration_s": 0.5 * wall / it,
                    "time_per_application_s": 0.5 * wall / (it + 5), "fft_pair_s": 0.01,
                    "fft_pair_kept_s": 0.005})
    return run


def test_table_has_medians_ratios_and_force_differences(tmp_path):
    runs = []
    for rep, (ours, cm) in enumerate([(1.0, 5.0), (2.0, 6.0), (1.5, 30.0)]):
        for pillars in ("rigid", "elastic"):
            runs += [_run("bem-fft-grid", pillars, 32, ours, 1.0),
                     _run("contactmechanics", pillars, 32, cm, 1.0 + 1e-8, it=90),
                     _run("bem-fft", pillars, 32, 2 * ours, 1.01),
                     _run("bem-fft-grid-double", pillars, 32, 1.6 * ours, 1.0)]
    runs.append({"solver": "contactmechanics", "pillars": "rigid", "n": 58,
                 "error": "timed out after 1 s"})
    meta = {"scene": "paper-fig3-dense", "tolerance": 1e-8, "repeats": 3,
            "load_average": [0.1, 0.1, 0.1], "contactmechanics": "1.8.3",
            "contactmechanics_skipped": ""}
    table = bench.write_report(tmp_path, runs, [], meta)
    rows = {(r["pillars"], r["cells_per_diameter"]): r for r in bench.side_by_side(runs)}
    row = rows[("rigid", 32)]
    assert row["wall_time_s"] == 1.5 and row["cm_s"] == 6.0
    # Median of the per-repeat ratios 5/1, 6/2, 30/1.5: 5.
    assert row["ratio_cm_over_ours"] == pytest.approx(5.0)
    assert row["force_rel_diff"] == pytest.approx(-1e-8, rel=1e-6)
    assert row["iteration_over_fft_pair"] == pytest.approx(0.5 * 1.5 / 20 / 0.01)
    assert row["iteration_over_kept_pair"] == pytest.approx(0.5 * 1.5 / 20 / 0.005)
    assert row["applications_per_iteration"] == pytest.approx(25 / 20)
    # The float64 run of the same solver, per iteration over the mixed-precision one: 1.6.
    assert row["double_over_mixed"] == pytest.approx(1.6)
    assert row["double_time_per_iteration_s"] == pytest.approx(0.5 * 1.6 * 1.5 / 20)
    assert rows[("rigid", 58)]["errors"] == ["contactmechanics: timed out after 1 s"]
    assert "| rigid | 4.00e+02 (d/32) | 20 + 7 |" in table and "5.0x" in table
    assert "| 10.0 / 5.0 (45x45) | 3.75 / 7.50 |" in table
    assert "| 60.0 (6.00), 2.40 |" in table  # float64: 0.5 * 2.4 / 20 s/it, pair 10 ms
    doc = json.loads((tmp_path / "bench_fft.json").read_text())
    assert doc["table"] == table == (tmp_path / "bench_fft.md").read_text().rstrip("\n")
