"""Benchmark of the FFT boundary-element model on a GPU against the same model on the CPU, on
the same machine and in one run.

Run as ``python -m validation.bench.gpu --out DIR``.  Scene: paper-fig3-dense (Phi = 0.82),
``--pillars``: 'rigid' pillars, the preset's 'elastic' pillars as Hooke springs (the solver's
default model; the rows of the records in ``measured/``), and on request 'elastic-pillar',
the same pillars as the elastic pillar (``pillars="elastic"``: its finite-element
compliance, loaded or built before the clock and once before the cases, is not timed; its
term's set-up is, in the kernel table), edge correction on, tolerance 1e-8 zeta, from 3e5
to 2e7 grid cells (32 to 256 cells per pillar diameter).  For each case it reports the wall
time of each path, the time to build the kernel table (kernel block, its spectrum and the
near-field correction of the finest level) apart, the iterations, and the relative
difference of F_T between the paths.  Each case runs in its own interpreter, so its peak
host memory (``ru_maxrss``) is its own, and is solved there 1 + ``--again`` times: the first
solve is what a one-off call takes (cuFFT plans made, kernels loaded; the CUDA context is made
before the clock), the median of the others ('again') what each solve of a study in one
process takes.  Prints a
table and writes ``bench_gpu.json`` after every case, so that a run stopped at a lent
machine's limit keeps what it measured (``--budget-s`` starts no case after that many
seconds).  The runs on lent GPUs are kept in
``validation/bench/measured/``.

Without a usable GPU (no cupy, or cupy finds no device) it runs the CPU column on the smallest
levels only and says that the GPU column is pending.  The CPU path is given the machine's
cores as FFT threads and a padded-FFT limit from its memory, so that the large grids the GPU
solves are not refused on the CPU of a large machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import time
from pathlib import Path

from pillar_xval.threads import thread_count

from . import write_record
from .fft import run_worker

SCENE = "paper-fig3-dense"
PILLARS = {"rigid": ("pillars.rigid=true",), "elastic": (), "elastic-pillar": ()}
# The pillar model each choice solves with (solve_fft's ``pillars``).
PILLAR_MODEL = {"rigid": "hooke", "elastic": "hooke", "elastic-pillar": "elastic"}
DEFAULT_PILLARS = ("rigid", "elastic")
# Bounding-grid cells on this scene: 32 -> 3.1e5, 58 -> 1.0e6, 100 -> 3.0e6, 180 -> 9.8e6,
# 256 -> 2.0e7 (d/256).
LEVELS = (32, 58, 100, 180, 256)
CPU_ONLY_LEVELS = (32, 58)  # without a GPU: the CPU column on a small subset
TOL = 1e-8
# The GPU's variants (--gpu-variants): the grid's construction, the precision.
VARIANTS = {"host": "the grid on the host at every size",
            "windows": "the grid on the device, pillar window by pillar window",
            "double": "float64 throughout (precision='double')",
            "unfused": "the CG's passes as array operations, not fused kernels"}
# Cells per diameter of the untimed GPU run that compiles cupy's kernels first (with warm-start
# levels, so that their kernels are compiled too).
WARM_UP_N = 32
# Host bytes per padded FFT point for the CPU path's limit (the arrays of one operator
# application and the kernel table, with a margin).
CPU_BYTES_PER_FFT_POINT = 64


def _solve(spec: dict) -> dict:
    """The case solved 1 + ``again`` times in this interpreter (once again on the CPU):
    'first' as a one-off call pays for its cuFFT plans and kernel loads (CUDA context made
    before the clock), 'again' as the next solves of a study do not.  The measurements of
    the first, plus the times of the median of the others."""
    from bem_solver._fft import solve_fft
    from bem_solver._xp import NumpyDevice, select_backend
    from pillar_xval.scenes import load_scene

    scene = load_scene(SCENE, list(PILLARS[spec["pillars"]]))
    model = PILLAR_MODEL[spec["pillars"]]
    compliance = _compliance(scene) if model == "elastic" else None  # before the clock
    warm = spec.get("warm_start", True)
    if spec.get("variant") == "host":  # the variant that builds the grid on the host
        import bem_solver._fft as fft_module

        fft_module.GPU_GRID_MIN_POINTS = float("inf")
    elif spec.get("variant") == "windows":  # on the device, pillar window by pillar window
        import bem_solver._fft as fft_module
        import bem_solver._fft_grid as grid_module

        fft_module.GPU_GRID_MIN_POINTS = 0
        tops = grid_module._pillar_cells
        grid_module._pillar_cells = lambda *a, **k: tops(*a, **{**k, "dense": False})
    if spec["device"] == "cpu":
        backend = NumpyDevice(spec["workers"], max_fft_points=spec["cpu_max_fft_points"])
    else:
        backend = select_backend("gpu")
        backend.fused = spec.get("variant") != "unfused"
    runs = []
    # --again applies to the GPU's sub-second solves; the CPU's vary little (4.4-4.8 s at
    # 1e6 cells on the lent H200's host), and one repeat of each is enough there.
    for _ in range(1 + (spec.get("again", 1) if spec["device"] != "cpu" else 1)):
        start = time.perf_counter()
        res = solve_fft(scene, spec["n"], tol=TOL, workers=spec["workers"], backend=backend,
                        warm_start=warm, precision="double" if spec.get("variant") == "double"
                        else "mixed", pillars=model, compliance=compliance)
        runs.append((time.perf_counter() - start, res))
    later = sorted(runs[1:], key=lambda r: r[0])
    (wall, res), (again, res2) = runs[0], later[(len(later) - 1) // 2]  # the (lower) median
    d = res.diagnostics
    return {"wall_time_s": wall, "kernel_table_s": d["timings_s"]["kernel_table"],
            "grid_s": d["timings_s"]["grid"], "warm_start_s": d["timings_s"]["warm_start"],
            "solve_s": d["timings_s"]["solve"], "iterations": res.iterations,
            "warm_start_iterations": sum(v["iterations"] for v in d["warm_start_levels"]),
            "operator_applications": d["operator_applications"],
            "candidate_cells": d["candidate_cells"],
            "grid_cells": d["grid_shape"][0] * d["grid_shape"][1],
            "total_force_N": res.total_force_N, "converged": res.converged,
            "message": d["message"], "device": d["device"],
            "again_wall_time_s": again, "again_timings_s": res2.diagnostics["timings_s"],
            "again_runs_s": [r[0] for r in runs[1:]],
            "again_force_rel_diff": (res2.total_force_N - res.total_force_N)
            / abs(res.total_force_N)}


def _compliance(scene):
    """The elastic pillar's compliance of ``scene``'s pillar kind (built once, then read from
    its cache: $PILLAR_XVAL_CACHE)."""
    from bem_solver._elastic_pillar import scene_compliance

    return scene_compliance(scene)


def run_case(spec: dict, timeout: float) -> dict:
    """One solve in a fresh interpreter: the spec with its measurements, or an 'error'."""
    return {**spec, **run_worker("validation.bench.gpu", spec, timeout)}


def _median(runs: list) -> dict:
    """The run of median wall time, with the median of the repeated ('again') solves."""
    ok = sorted((r for r in runs if "error" not in r), key=lambda r: r["wall_time_s"])
    if not ok:
        return runs[0]
    best = dict(ok[len(ok) // 2])
    best["repeats"] = len(ok)
    best["wall_times_s"] = [r["wall_time_s"] for r in ok]
    again = sorted(r["again_wall_time_s"] for r in ok)
    best["again_wall_time_s"], best["again_wall_times_s"] = again[len(again) // 2], again
    return best


def _cpu_max_fft_points() -> int:
    memory = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    return int(memory // CPU_BYTES_PER_FFT_POINT)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.gpu", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-gpu"))
    ap.add_argument("--levels", type=int, nargs="*", default=None,
                    help="cells per pillar diameter (default: 32 58 100 180 256 with a GPU, "
                         "32 58 without)")
    ap.add_argument("--pillars", nargs="+", default=list(DEFAULT_PILLARS),
                    choices=list(PILLARS),
                    help="'rigid', 'elastic' (the preset's pillars as Hooke springs) and "
                         "'elastic-pillar' (the same as the elastic pillar); default: "
                         + " ".join(DEFAULT_PILLARS))
    ap.add_argument("--repeats", type=int, default=3, help="runs per case (median)")
    ap.add_argument("--cpu-max-cells", type=float, default=2.1e7,
                    help="skip the CPU path above this many grid cells")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per solve")
    ap.add_argument("--budget-s", type=float, default=None,
                    help="start no case after this many seconds (the rest are reported as "
                         "skipped), for a machine lent for a fixed time")
    ap.add_argument("--gpu-warm", type=int, nargs="*", default=[],
                    help="GPU variants with at most this many nested warm-start levels "
                         "(0: a cold start), beside the default (all levels)")
    ap.add_argument("--gpu-variants", nargs="*", default=[], choices=list(VARIANTS),
                    help="GPU variants beside the default (the grid on the device from "
                         "bem_solver._fft.GPU_GRID_MIN_POINTS points of the candidate "
                         "square, all tops at once; mixed precision): " + "; ".join(
                             f"'gpu-{k}' {v}" for k, v in VARIANTS.items()))
    ap.add_argument("--cpu-repeats", type=int, default=None,
                    help="runs per case of the CPU path (default: --repeats)")
    ap.add_argument("--again", type=int, default=1,
                    help="GPU solves after the first in each interpreter ('again': their "
                         "median; the CPU solves once again)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if min(args.repeats, args.again, args.cpu_repeats or 1) < 1:
        ap.error(f"--repeats {args.repeats}, --cpu-repeats {args.cpu_repeats}, --again "
                 f"{args.again}: each at least 1")
    if args.worker:
        out = _solve(json.loads(args.worker))
        out["peak_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
        print(json.dumps(out))
        return 0
    from bem_solver import available_devices

    gpu_reason = available_devices()["gpu"]
    levels = args.levels or list(LEVELS if not gpu_reason else CPU_ONLY_LEVELS)
    devices = ["cpu"] + ([] if gpu_reason else ["gpu"] + [f"gpu-w{k}" for k in args.gpu_warm]
                         + [f"gpu-{k}" for k in args.gpu_variants])
    base = {"workers": thread_count(), "cpu_max_fft_points": _cpu_max_fft_points(),
            "again": args.again}
    meta = {"scene": SCENE, "tolerance": TOL, "edge_correction": True,
            "python": platform.python_version(), "machine": platform.machine(),
            "cpu_workers": base["workers"], "cpu_max_fft_points": base["cpu_max_fft_points"],
            "gpu": gpu_reason or _gpu_name(), "gpu_pending": bool(gpu_reason),
            "levels_order": levels, "budget_s": args.budget_s}
    start = time.monotonic()
    if "elastic-pillar" in args.pillars:  # the compliance built here once, not in a case
        from pillar_xval.scenes import load_scene

        lap = time.perf_counter()
        _compliance(load_scene(SCENE, list(PILLARS["elastic-pillar"])))
        meta["elastic_compliance_s"] = time.perf_counter() - lap
    if not gpu_reason:  # fills cupy's kernel cache on disk, so that no timed run compiles
        # one run per pillar model asked for (the elastic pillar's term has kernels of its own)
        firsts = {PILLAR_MODEL[p]: p for p in reversed(args.pillars)}
        for model, pillars in sorted(firsts.items()):
            warm = run_case({**base, "device": "gpu", "pillars": pillars, "n": WARM_UP_N},
                            args.timeout)
            meta["warm_up" if model == "hooke" else f"warm_up_{model}"] = {
                k: warm.get(k) for k in ("wall_time_s", "error", "stderr_tail") if k in warm}
    rows = []
    table = write_report(args.out, rows, meta)
    for n in levels:  # in the order given: the cases that matter most first
        for pillars in args.pillars:
            row = {"pillars": pillars, "n": n}
            rows.append(row)
            for device in devices:
                spec = {**base, "device": device.split("-")[0], "pillars": pillars, "n": n}
                variant = device[len("gpu-"):] if device.startswith("gpu-") else ""
                if variant in VARIANTS:
                    spec["variant"] = variant
                elif variant:  # w<k>: at most k nested warm-start levels
                    spec["warm_start"] = int(variant[1:])
                elapsed = time.monotonic() - start
                if device == "cpu" and _too_big(rows, pillars, n, args.cpu_max_cells):
                    row[device] = {"error": f"skipped: over --cpu-max-cells "
                                            f"{args.cpu_max_cells:g}"}
                elif args.budget_s is not None and elapsed > args.budget_s:
                    row[device] = {"error": f"skipped: past --budget-s {args.budget_s:g} "
                                            f"({elapsed:.0f} s)"}
                else:
                    print(f"bench-gpu: {pillars} N = {n} on {device} ({elapsed:.0f} s)",
                          file=sys.stderr, flush=True)
                    repeats = (args.cpu_repeats if device == "cpu" else None) or args.repeats
                    row[device] = _median([run_case(spec, args.timeout)
                                           for _ in range(repeats)])
                # each finished case at once: a run stopped at its limit keeps the rest
                table = write_report(args.out, rows, meta)
    print(table)
    return 0


def _too_big(rows, pillars, n, limit) -> bool:
    """The CPU path's grid at N, estimated from a measured level (cells grow as N^2), else
    from the candidate square's side (the grid's bounding box is at most that square)."""
    done = [r for r in rows if r["pillars"] == pillars and "grid_cells" in r.get("cpu", {})]
    if not done:
        from bem_solver._fft_grid import candidate_side
        from pillar_xval.scenes import load_scene

        return candidate_side(load_scene(SCENE, list(PILLARS[pillars])), n) ** 2 > limit
    last = done[-1]
    return last["cpu"]["grid_cells"] * (n / last["n"]) ** 2 > limit


def _gpu_name() -> str:
    import cupy

    props = cupy.cuda.runtime.getDeviceProperties(cupy.cuda.Device().id)
    name = props["name"]
    return name.decode() if isinstance(name, bytes) else str(name)


def write_report(out: Path, rows: list, meta: dict) -> str:
    """Write bench_gpu.json into ``out``; return the printed table."""

    head = (f"{'pillars':>14} {'N':>4} {'cells':>9} {'CPU s':>8} {'again':>6} {'table':>6} "
            f"{'it':>4} {'GPU s':>8} {'again':>6} {'table':>6} {'it':>4} {'speed-up':>8} "
            f"{'again':>6} {'dF_T rel':>9}")
    rows = sorted(rows, key=lambda r: (r["pillars"] != "rigid", r["n"]))
    lines = [f"bem-fft on {meta['scene']} (Phi = 0.82), edge correction on, tol 1e-8 zeta; "
             f"median of runs; 'table' = kernel table of the finest level (s), included in "
             f"the total; 'again' = the same solve repeated in the same interpreter (cuFFT "
             f"plans and kernels loaded, as in a study)", head]
    for r in rows:
        cpu, gpu = r.get("cpu", {}), r.get("gpu")
        cells = cpu.get("grid_cells") or (gpu or {}).get("grid_cells") or 0
        lines.append(f"{r['pillars']:>14} {r['n']:>4} {cells:>9.3g} " + _cell(cpu) + " "
                     + (_cell(gpu) if gpu is not None else f"{'pending':>27}") + " "
                     + _ratio(cpu, gpu))
        r["force_rel_diff"] = _force_diff(cpu, gpu)
    for r in rows:  # the GPU's variants, against the CPU and the default GPU
        for path in sorted(k for k in r if k.startswith("gpu-")):
            v, cpu, gpu = r[path], r.get("cpu", {}), r.get("gpu", {})
            what = VARIANTS.get(path[4:], f"at most {path[5:]} nested levels")
            if "wall_time_s" in v:
                lines.append(
                    f"{r['pillars']} N = {r['n']} {path} ({what}; grid {v['grid_s']:.3f} s): "
                    f"{v['wall_time_s']:.2f} s, again {v['again_wall_time_s']:.2f} s, "
                    f"{v['iterations']} + {v['warm_start_iterations']} iterations; default GPU "
                    f"{gpu.get('wall_time_s', float('nan')):.2f} s (grid "
                    f"{gpu.get('grid_s', float('nan')):.3f} s); CPU over this "
                    f"{cpu.get('wall_time_s', float('nan')) / v['wall_time_s']:.1f}x; dF_T rel "
                    f"{_force_diff(cpu, v) if 'total_force_N' in cpu else float('nan'):.1e}")
    for r in rows:
        for path in [k for k in r if k in ("cpu", "gpu") or k.startswith("gpu-")]:
            if "error" in r.get(path, {}):
                lines.append(f"{r['pillars']} N = {r['n']} {path}: {r[path]['error']}")
    if meta["gpu_pending"]:
        lines.append(f"GPU column pending: {meta['gpu']}")
    else:
        lines.append(f"GPU: {meta['gpu']}; CPU: {meta['cpu_workers']} FFT threads")
    table = "\n".join(lines)
    write_record(out, "bench_gpu.json", meta, rows, table)
    return table


def _cell(r: dict) -> str:
    if "wall_time_s" not in r:
        return f"{'-':>8} {'-':>6} {'-':>6} {'-':>4}"
    return (f"{r['wall_time_s']:>8.2f} {r['again_wall_time_s']:>6.2f} "
            f"{r['kernel_table_s']:>6.2f} {r['iterations']:>4}")


def _ratio(cpu: dict, gpu) -> str:
    if gpu is None or "wall_time_s" not in cpu or "wall_time_s" not in gpu:
        return f"{'-':>8} {'-':>6} {'-':>9}"
    diff = _force_diff(cpu, gpu)
    return (f"{cpu['wall_time_s'] / gpu['wall_time_s']:>8.1f} "
            f"{cpu['again_wall_time_s'] / gpu['again_wall_time_s']:>6.1f} {diff:>9.1e}")


def _force_diff(cpu: dict, gpu):
    if not gpu or "total_force_N" not in cpu or "total_force_N" not in gpu:
        return None
    return (gpu["total_force_N"] - cpu["total_force_N"]) / abs(cpu["total_force_N"])


if __name__ == "__main__":
    sys.exit(main())
