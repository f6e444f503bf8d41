"""The thread-scaling benchmark's tables (validation.bench.threads) from recorded runs,
without solving: medians, speed-ups, the answers against one thread's, and the FFT
iteration's split with its 2-thread prediction."""

from __future__ import annotations

import json

import pytest

from validation.bench import threads as bench


def _solve(name, threads, wall, cpu, force=1.0):
    return {"name": name, "threads": threads, "wall_s": wall, "cpu_s": cpu, "F_T": force,
            "sigma0": 2.0, "a": 3.0, "converged": True, "iterations": 10}


def test_scaling_rows_take_medians_and_compare_answers():
    runs = [_solve("fft", 1, w, w) for w in (10.0, 12.0, 11.0)] + \
        [_solve("fft", 2, w, 1.8 * w, 1.0 + 1e-12) for w in (6.0, 5.0, 7.0)] + \
        [{"name": "fft", "threads": 2, "error": "timed out"}]
    rows = {r["threads"]: r for r in bench.scaling_rows(runs)}
    assert rows[1]["wall_s"] == 11.0 and rows[1]["speedup"] == 1.0
    assert rows[2]["wall_s"] == 6.0 and rows[2]["speedup"] == pytest.approx(11.0 / 6.0)
    assert rows[2]["cpu_per_wall"] == pytest.approx(1.8)
    assert rows[2]["answers_rel_diff"] == pytest.approx(1e-12)
    assert rows[2]["runs"] == 3  # the failed run is left out


def test_split_rows_predict_two_threads_from_one():
    def split(threads, fft, chunks, total):
        return {"n": 58, "pillars": "rigid", "threads": threads, "grid_cells": 1_010_025,
                "cpu_per_iteration_s": total, "wall_per_iteration_s": total / threads,
                "fft_cpu_s": fft, "chunks_cpu_s": chunks, "pair_cpu_s": 0.1,
                "pair_wall_s": 0.1 / threads}

    rows = bench.split_rows([split(1, 0.08, 0.02, 0.12), split(2, 0.08, 0.02, 0.12)])
    one, two = rows
    assert one["R_fft"] == pytest.approx(0.8) and one["R_chunks"] == pytest.approx(0.2)
    assert one["R_rest"] == pytest.approx(0.2) and one["R_cpu"] == pytest.approx(1.2)
    assert one["R2_predicted"] == pytest.approx(0.8 + 0.2 + 2 * 0.2)
    assert two["R2_predicted"] is None
    table = bench.format_tables([], rows, {"cpus": 2, "repeats": 1, "load_before": [0.0],
                                           "load_after": [0.0]})
    assert "| 1e+06 | rigid | 1 | 0.800 | 0.200 | 0.200 | 1.200 | 1.400 |" in table


def test_main_writes_the_runs_so_far_after_each(tmp_path, monkeypatch):
    """A run cut short (the lent machine's time limit) leaves the runs it finished."""
    done = []

    def run(kind, spec, threads, root=None):
        if len(done) == 2:
            raise KeyboardInterrupt  # stands for the time limit's signal
        done.append(threads)
        return _solve("fem3d", threads, 10.0 / threads, 10.0)

    monkeypatch.setattr(bench, "_run", run)
    with pytest.raises(KeyboardInterrupt):
        bench.main(["--out", str(tmp_path), "--cases", "fem3d", "--threads", "1,2,4",
                    "--repeats", "1", "--split-threads", ""])
    report = json.loads((tmp_path / "bench_threads.json").read_text())
    assert [r["threads"] for r in report["runs"]] == [1, 2]
    assert [r["speedup"] for r in report["scaling"]] == [1.0, 2.0]
