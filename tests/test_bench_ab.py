"""The before/after benchmark's table (validation.bench.ab) from recorded runs, without
solving."""

from __future__ import annotations

import argparse

import pytest

from validation.bench import ab


def _run(wall, per_iteration, force):
    return {"wall_s": wall, "cpu_s": 2 * wall, "iterations": 10, "converged": True,
            "F_T": force, "sigma0": 1.0, "a": 2.0, "applications": 15,
            "per_iteration_over_fft_pair": per_iteration,
            "per_iteration_over_2n1_pair": 0.9 * per_iteration,
            "cpu_per_iteration_over_cpu_pair": 1.1 * per_iteration}


def test_summary_has_medians_of_the_three_ratios_and_the_answer_difference():
    case = ab.parse_case("fft:58")
    runs = {"baseline": [_run(4.0, 2.0, 1.0), _run(5.0, 1.0, 1.0), _run(6.0, 3.0, 1.0)],
            "this": [_run(2.0, 1.5, 1.0 + 1e-9), _run(3.0, 1.2, 1.0 + 1e-9),
                     _run(1.0, 1.3, 1.0 + 1e-9)]}
    base, this = ab.summarise(case, runs)
    assert base["wall_median_s"] == 5.0 and this["wall_median_s"] == 2.0
    assert this["speed-up"] == pytest.approx(2.5)
    assert base["per_iteration_over_fft_pair"] == 2.0
    assert this["per_iteration_over_fft_pair"] == 1.3
    assert this["per_iteration_over_2n1_pair"] == pytest.approx(0.9 * 1.3)
    assert this["cpu_per_iteration_over_cpu_pair"] == pytest.approx(1.1 * 1.3)
    assert this["max_rel_diff"] == pytest.approx(1e-9, rel=1e-6)
    text = ab.table([base, this])
    assert "| fft:58 | this | 2.000 (1.000-3.000) |" in text
    assert "| 1.30; 1.17; 1.43 |" in text and "| 2.50 |" in text


def test_cases_parse_and_refuse():
    assert ab.parse_case("elastic-fft:32@1e-10")["options"] == {"tol": 1e-10}
    import argparse

    with pytest.raises(argparse.ArgumentTypeError, match="dense, fft:N, elastic-fft:N or"):
        ab.parse_case("fft")
    case = ab.parse_case("fem3d:0.82:2")
    assert case["model"] == "fem3d" and case["cells"] == 2.0
    assert case["overrides"] == ["pillars.surface_fraction=0.82"]
    for bad in ("fem3d:0.82", "fem3d:x:2", "fem3d:0.2:2:1"):
        with pytest.raises(argparse.ArgumentTypeError, match="fem3d:PHI:MESH_SIZE"):
            ab.parse_case(bad)


def test_fem3d_rows_carry_the_median_of_each_phase():
    case = ab.parse_case("fem3d:0.2:2.83")

    def run(wall, factorise):
        phases = {"mesh": 1.0, "assemble": 2.0, "factorise": factorise, "contact": 4.0,
                  "post": 0.5}
        return {"wall_s": wall, "cpu_s": wall, "iterations": 30, "converged": True,
                "F_T": 1.0, "sigma0": 2.0, "a": 3.0, "phases": phases, "peak_rss_GiB": 1.5}

    runs = {"baseline": [run(9.0, 3.0), run(11.0, 5.0), run(10.0, 4.0)],
            "this": [run(3.0, 1.0), run(4.0, 2.0), run(5.0, 3.0)]}
    base, this = ab.summarise(case, runs)
    assert base["phases_median_s"]["factorise"] == 4.0
    assert this["phases_median_s"]["factorise"] == 2.0 and this["speed-up"] == 2.5
    text = ab.table([base, this])
    assert "| fem3d:0.2:2.83 | this | 1.0 | 2.0 | 2.0 | 4.0 | 0.5 | 1.50 |" in text


def test_floor3d_cases_are_the_floor_validations_lattices_with_elements_and_area():
    import argparse

    case = ab.parse_case("floor3d:0.4:1.41")
    assert case["model"] == "fem3d" and case["cells"] == 1.41
    assert "pillars.surface_fraction=0.4" in case["overrides"]
    assert "load.indentation_um=7.0" in case["overrides"]
    with pytest.raises(argparse.ArgumentTypeError, match="floor validation's lattices, 0.03"):
        ab.parse_case("floor3d:0.5:2")
    phases = dict.fromkeys(ab.FEM3D_PHASES, 1.0)
    run = {"wall_s": 5.0, "cpu_s": 5.0, "iterations": 30, "converged": True, "F_T": 1.0,
           "sigma0": 2.0, "a": 3.0, "phases": phases, "peak_rss_GiB": 1.5,
           "elements": 1234, "floor_area_m2": 650.4e-12}
    rows = ab.summarise(case, {"baseline": [run], "this": [run]})
    assert "| 1.50 | 1234 | 650.4 |" in ab.table(rows)


def test_mesh_phase_rows_say_whether_both_sides_made_the_same_mesh():
    from validation.bench import mesh3d_ab

    case = mesh3d_ab.parse_case("0.82:2")
    assert case["mesh_size"] == 2.0 and case["overrides"] == ["pillars.surface_fraction=0.82"]

    def run(cpu, digest):
        return {"wall_s": cpu + 0.1, "cpu_s": cpu, "nodes": 10, "elements": 20,
                "min_quality": 0.25, "mean_quality": 0.7, "sha256": digest}

    for digest, same in (("a", True), ("b", False)):
        runs = {"baseline": [run(4.0, "a"), run(6.0, "a")], "this": [run(2.0, digest),
                                                                       run(3.0, digest)]}
        base, this = mesh3d_ab.summarise(case, runs)
        assert base["cpu_median_s"] == 5.0 and this["cpu_speed-up"] == 2.0
        assert this["same_mesh"] is same
        assert f"| 0.82:2 | this | 2.600 | 2.500 | 2.00 | 10 | 20 | 0.2500 / 0.7000 | {same} |" \
            in mesh3d_ab.table([base, this])
    with pytest.raises(argparse.ArgumentTypeError, match="PHI:MESH_SIZE"):
        mesh3d_ab.parse_case("0.82")


def test_assembly_rows_say_whether_both_sides_built_the_same_matrix():
    from validation.bench import assembly3d_ab

    case = assembly3d_ab.parse_case("0.82:2")

    def run(user, system, digest):
        return {"wall_s": user + system, "user_s": user, "system_s": system, "peak_GiB": 1.5,
                "peak_reset": True, "elements": 20, "unknowns": 30, "entries": 40,
                "sha256": digest}

    for digest, same in (("a", True), ("b", False)):
        runs = {"baseline": [run(3.0, 1.0, "a"), run(4.0, 2.0, "a")],
                "this": [run(2.0, 0.0, digest), run(2.5, 0.5, digest)]}
        base, this = assembly3d_ab.summarise(case, runs)
        assert base["cpu_median_s"] == 5.0 and this["cpu_speed-up"] == 2.0
        assert this["same_matrix"] is same
        assert (f"| 0.82:2 | this | 2.50 (2.00, 3.00) | 2.25 | 0.25 | 2.50 | 2.00 | 1.500 | "
                f"20 | 30 | {same} |") in assembly3d_ab.table([base, this])


def test_the_assembly_worker_runs_a_small_case(tmp_path):
    """The assemble-phase benchmark's worker on the coarsest lattice level: the phase timed,
    its peak memory measured, the matrix's digest given."""
    from validation.bench import ab, assembly3d_ab

    case = assembly3d_ab.parse_case("0.2:2.83")
    run = ab.run_once(ab.ROOT, case, False, assembly3d_ab.WORKER)
    assert run["unknowns"] > 0 and run["user_s"] > 0 and 0 < run["peak_GiB"] < 8
    assert len(run["sha256"]) == 64


def test_results_are_written_whole_and_read_back(tmp_path):
    import json

    sides = {"baseline": tmp_path / "old", "this": tmp_path / "new"}
    rows, raw = [{"case": "dense", "side": "this"}], [{"wall_s": 1.0}]
    ab.write_results(tmp_path / "out", "bench_x", "table\n", sides, rows, raw, [0.5], warm=True)
    assert (tmp_path / "out" / "bench_x.md").read_text() == "table\n"
    doc = json.loads((tmp_path / "out" / "bench_x.json").read_text())
    assert doc == {"baseline": str(sides["baseline"]), "this": str(sides["this"]),
                   "rows": rows, "runs": raw, "load_average": [0.5], "warm": True}
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["bench_x.json",
                                                                    "bench_x.md"]


def test_floor_cases_run_in_rounds_and_give_each_sides_ratio(monkeypatch):
    """``floor:H`` is the floor benchmark's timed scene at pillar height H; in rounds every
    case runs in each repeat, both sides ABBA, and the ratio of the two cases' medians is
    each side's own."""
    from validation.bench.floor import PERF_N

    mixed, suspended = ab.parse_case("floor:1"), ab.parse_case("floor:20")
    assert mixed["cells"] == PERF_N and "pillars.height_um=1" in mixed["overrides"]
    assert "pillars.height_um=20" in suspended["overrides"]
    with pytest.raises(argparse.ArgumentTypeError, match="floor:H"):
        ab.parse_case("floor:tall")
    order = []
    walls = {("floor:1", "baseline"): 4.0, ("floor:20", "baseline"): 2.0,
             ("floor:1", "this"): 3.0, ("floor:20", "this"): 2.0}

    def fake(root, case, warm, worker):
        order.append((case["label"], str(root)))
        return {**_run(walls[case["label"], str(root)], 1.0, 1.0), "F_floor": 0.5,
                "A_floor": 0.0}

    monkeypatch.setattr(ab, "run_once", fake)
    rows, raw, load = ab.interleaved([mixed, suspended], {"baseline": "baseline",
                                                          "this": "this"}, 2, ab.summarise,
                                     rounds=True)
    assert order == [("floor:1", "baseline"), ("floor:1", "this"),
                     ("floor:20", "baseline"), ("floor:20", "this"),
                     ("floor:1", "this"), ("floor:1", "baseline"),
                     ("floor:20", "this"), ("floor:20", "baseline")]
    assert len(load) == 3 and len(raw["floor:1"]["this"]) == 2
    assert ab.case_ratios(rows, "floor:1", "floor:20") == \
        "baseline: floor:1 / floor:20 = 2.000; this: floor:1 / floor:20 = 1.500"
    assert rows[1]["F_floor"] == 0.5 and rows[1]["max_rel_diff"] == 0.0
