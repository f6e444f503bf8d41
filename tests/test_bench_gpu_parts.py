"""The per-part benchmark of a CG iteration (validation.bench.gpu_parts), on the CPU: its
record reads back, its solve is the model's own, and every part was timed."""

import json
import math

from bem_solver._fft import solve_fft
from pillar_xval.scenes import load_scene
from validation.bench import gpu_parts


def test_the_parts_record_reads_back_with_the_models_answer(tmp_path):
    assert gpu_parts.main(["--device", "cpu", "--pillars", "rigid", "--n", "8",
                           "--repeats", "2", "--out", str(tmp_path)]) == 0
    record = json.loads((tmp_path / "bench_gpu_parts.json").read_text())
    (row,) = record["rows"]
    scene = load_scene(gpu_parts.SCENE, list(gpu_parts.PILLARS["rigid"]))
    ours = solve_fft(scene, 8, tol=gpu_parts.TOL, warm_start=False)
    assert row["total_force_N"] == ours.total_force_N
    assert row["iterations"] == ours.iterations and row["converged"]
    assert row["per_iteration_s"] > 0.0
    assert set(row["parts_s"]) >= {"apply_float64", "apply_float32", "precondition"}
    assert all(math.isfinite(v) and v > 0.0 for v in row["parts_s"].values())
