"""Thread scaling: solves on 1, 2, ... threads, and the FFT iteration against its floor
(``python -m validation.bench.threads --out DIR``, ``make bench-threads``).

1. Scaling.  Each case solved in a fresh interpreter with ``PILLAR_XVAL_THREADS`` = each
   count of ``--threads`` (default 1 up to the CPUs this process may use), the counts
   interleaved over ``--repeats``: the median wall time, CPU seconds per wall second, the
   speed-up over one thread, and the answers' largest relative difference from one thread's
   (F_T, sigma0, a: threads must change nothing beyond round-off).  Cases: ``fft`` (bem-fft
   on paper-fig3-dense at N = 58, a 1005 x 1005 grid: 1.0e6 cells), ``dense`` (the dense BEM
   at P = 11 on paper-fig3-dense), ``fem3d`` (fem-3d on paper-fig3-sparse with Phi = 0.2 at
   mesh_size 2.83; ``--fem3d-mesh`` and ``--fem3d-phi`` for the dense Phi = 0.82 at 2).
2. The FFT iteration.  The fine level's CG of bem-fft (a rigid substrate, rigid or Hooke
   pillars, cells collocated at their centres: validation/bench/fft.py's "ours") at N = 32
   and 58 (3.1e5 and 1.0e6 cells) on one thread, its CPU time split into the pocketfft
   transforms, the elementwise work the numpy path runs in chunks on the transforms' threads
   (``bem_solver._xp.in_chunks``: the operator's scatter, spectrum product and gather, the
   preconditioner's and the CG's vector passes, the pillar sums) and the rest (the CG's dot
   products, the pillar values spread to their cells, Python), each per iteration over the
   float64 FFT pair's CPU time on the same padded grid (kept arrays, one thread); and the
   2-thread wall time per iteration over the pair on 2 threads they predict, transforms and
   chunked work halved, the rest not (R_fft + R_chunks + 2 R_rest): on a machine others
   load, CPU times stay where wall times do not.  With ``--split-threads 1,2``, the same
   iteration's measured wall time over the pair's, on the threads given.  With ``--baseline
   DIR`` (another checkout, e.g. ``git archive main | tar -x -C DIR``) the same split of that
   checkout's iteration, each of its runs right after this one's (its own chunks'
   definition); ``--cases ''`` measures the split alone.  With ``--edge-correction`` the
   iteration of the default solve instead, edge cells at their centroids (the near-field
   correction's sparse product in the operator, the rest of the split unchanged).

Prints the tables and writes them with the runs and the load averages to ``bench_threads.md``
and ``bench_threads.json``, both rewritten after every run (a run stopped by a time limit
keeps the runs it finished).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

from validation.bench.fft import PILLARS, run_worker

CASES = {
    "fft": ("bem-fft", "paper-fig3-dense", [], {"cells_per_diameter": 58}),
    "dense": ("bem", "paper-fig3-dense", [], {"elements_per_diameter": 11}),
    "fem3d": ("fem-3d", "paper-fig3-sparse", ["pillars.surface_fraction=0.2"],
              {"mesh_size": 2.83}),
}
SPLIT_LEVELS = (32, 58)
PAIR_REPEATS = 7


def _solve(spec: dict) -> dict:
    """One case on this process's threads: wall and CPU seconds and the answers."""
    from pillar_xval.scenes import load_scene
    from pillar_xval.threads import thread_count
    from validation.registry import run_model

    model, scene_name, overrides, options = spec["case"]
    scene = load_scene(scene_name, overrides)
    start, cpu = time.perf_counter(), time.process_time()
    r = run_model(model, scene, **options)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu
    return {"threads": thread_count(), "wall_s": wall, "cpu_s": cpu, "converged": r.converged,
            "F_T": r.total_force_N, "sigma0": r.centre_pressure_Pa, "a": r.contact_radius_m,
            "iterations": r.iterations}


def _pair(shape, workers: int, clock) -> float:
    """Median ``clock`` seconds of the float64 FFT pair on ``shape`` into kept arrays."""
    import numpy as np
    from scipy.fft._pocketfft import pypocketfft as pocket

    ny, nx = (int(v) for v in shape)
    a = np.random.default_rng(0).random((ny, nx))
    spec = np.empty((ny, nx // 2 + 1), dtype=complex)
    out = np.empty((ny, nx))

    def pair():
        pocket.r2c(a, (0, 1), True, 0, spec, workers)
        pocket.c2r(spec, (0, 1), nx, False, 2, out, workers)

    pair()
    times = []
    for _ in range(PAIR_REPEATS):
        start = clock()
        pair()
        times.append(clock() - start)
    return statistics.median(times)


def _split(spec: dict) -> dict:
    """The fine CG's time per iteration split (module docstring, 2.) on this process's
    threads: CPU seconds of the transforms, of the chunked work and of the rest, and wall."""
    import bem_solver._fft as fft_model
    import bem_solver._fft_operator as operator
    import bem_solver._xp as devices
    from bem_solver._fft_grid import build_grid
    from pillar_xval.scenes import load_scene
    from pillar_xval.threads import thread_count

    scene = load_scene("paper-fig3-dense", list(PILLARS[spec["pillars"]]))
    n = spec["n"]
    cells = build_grid(scene, n).n_cells
    spent = {"fft": 0.0, "chunks": 0.0, "on": False}

    def timed(fn, key):
        def wrapper(*args, **kwargs):
            if not spent["on"]:
                return fn(*args, **kwargs)
            start = time.process_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent[key] += time.process_time() - start
        return wrapper

    pocket = operator._pocketfft
    operator._pocketfft = type("Timed", (), {
        name: staticmethod(timed(getattr(pocket, name), "fft")) for name in ("r2c", "c2c", "c2r")})
    # The operator's chunks and the backend's (the CG's and the preconditioner's passes):
    # each module's own name, so no call is timed twice.
    operator.in_chunks = timed(operator.in_chunks, "chunks")
    devices.in_chunks = timed(devices.in_chunks, "chunks")
    solve_cg, fine = fft_model.constrained_cg, {}

    def cg(*args, **kwargs):
        if args[1].shape[0] != cells:
            return solve_cg(*args, **kwargs)
        spent["on"] = True
        start, cpu = time.perf_counter(), time.process_time()
        try:
            return solve_cg(*args, **kwargs)
        finally:
            fine.update(wall=time.perf_counter() - start, cpu=time.process_time() - cpu)
            spent["on"] = False

    fft_model.constrained_cg = cg
    edges = bool(spec.get("edge_correction", False))
    r = fft_model.solve_fft(scene, n, edge_correction=edges)
    shape = r.diagnostics["fft_shape"]
    workers = thread_count()
    it = max(r.iterations, 1)
    return {"n": n, "pillars": spec["pillars"], "threads": workers, "edge_correction": edges,
            "iterations": r.iterations, "fft_shape": shape,
            "cells": cells, "grid_cells": r.diagnostics["grid_shape"][0]
            * r.diagnostics["grid_shape"][1],
            "cpu_per_iteration_s": fine["cpu"] / it, "wall_per_iteration_s": fine["wall"] / it,
            "fft_cpu_s": spent["fft"] / it, "chunks_cpu_s": spent["chunks"] / it,
            "pair_cpu_s": _pair(shape, workers, time.process_time),
            "pair_wall_s": _pair(shape, workers, time.perf_counter)}


def _run(kind: str, spec: dict, threads: int, root=None) -> dict:
    """One worker on ``threads`` threads, in this checkout or in ``root`` (a baseline)."""
    os.environ["PILLAR_XVAL_THREADS"] = str(threads)
    try:
        out = run_worker("validation.bench.threads", {**spec, "kind": kind}, 3600, root)
        return {**out, "side": "this" if root is None else "baseline"}
    finally:
        os.environ.pop("PILLAR_XVAL_THREADS", None)


def scaling_rows(runs: list) -> list:
    rows = []
    for case in dict.fromkeys(r["name"] for r in runs):
        mine = [r for r in runs if r["name"] == case and "error" not in r]
        one = [r for r in mine if r["threads"] == 1]
        base = statistics.median(r["wall_s"] for r in one) if one else None
        for t in sorted({r["threads"] for r in mine}):
            at = [r for r in mine if r["threads"] == t]
            wall = statistics.median(r["wall_s"] for r in at)
            diff = max((abs(r[q] - o[q]) / abs(o[q]) for r in at for o in one[:1]
                        for q in ("F_T", "sigma0", "a") if o[q]), default=None)
            rows.append({"case": case, "threads": t, "runs": len(at), "wall_s": wall,
                         "cpu_per_wall": statistics.median(r["cpu_s"] / r["wall_s"] for r in at),
                         "speedup": base / wall if base else None,
                         "answers_rel_diff": diff})
    return rows


def split_rows(splits: list) -> list:
    rows = []
    for side, n, pillars in dict.fromkeys((s.get("side", "this"), s["n"], s["pillars"])
                                          for s in splits):
        mine = [s for s in splits if s.get("side", "this") == side and s["n"] == n
                and s["pillars"] == pillars and "error" not in s]
        for t in sorted({s["threads"] for s in mine}):
            at = [s for s in mine if s["threads"] == t]

            def med(key, over="pair_cpu_s"):
                return statistics.median(s[key] / s[over] for s in at)

            rest = statistics.median((s["cpu_per_iteration_s"] - s["fft_cpu_s"]
                                      - s["chunks_cpu_s"]) / s["pair_cpu_s"] for s in at)
            row = {"side": side, "n": n, "pillars": pillars, "threads": t, "runs": len(at),
                   "grid_cells": at[0]["grid_cells"],
                   "R_fft": med("fft_cpu_s"), "R_chunks": med("chunks_cpu_s"), "R_rest": rest,
                   "wall_over_pair": med("wall_per_iteration_s", "pair_wall_s")}
            row["R_cpu"] = row["R_fft"] + row["R_chunks"] + rest
            row["R2_predicted"] = row["R_fft"] + row["R_chunks"] + 2.0 * rest \
                if t == 1 else None
            rows.append(row)
    return rows


def format_tables(scaling: list, split: list, meta: dict) -> str:
    def f(v, fmt):
        return "-" if v is None else format(v, fmt)

    lines = [f"Thread scaling ({meta['cpus']} CPUs this process may use; load average "
             f"{meta['load_before']} before, {meta['load_after']} after; medians of "
             f"{meta['repeats']} interleaved runs)", "",
             "| case | threads | wall s | CPU s / wall s | speed-up | answers vs 1 thread |",
             "|---|---|---|---|---|---|"]
    for r in scaling:
        lines.append(f"| {r['case']} | {r['threads']} | {r['wall_s']:.3g} | "
                     f"{r['cpu_per_wall']:.2f} | {f(r['speedup'], '.2f')} | "
                     f"{f(r['answers_rel_diff'], '.1e')} |")
    edges = " with the near-field correction" if meta.get("edge_correction") else ""
    lines += ["", f"FFT iteration (bem-fft, fine level{edges}) over the float64 FFT pair in "
              "kept arrays:", "", "| side | cells | pillars | threads | R_fft | R_chunks | "
              "R_rest | R (CPU) | predicted on 2 threads | measured wall / wall |",
              "|---|---|---|---|---|---|---|---|---|---|"]
    for r in split:
        lines.append(f"| {r['side']} | {r['grid_cells']:.2g} | {r['pillars']} | {r['threads']} | "
                     f"{r['R_fft']:.3f} | {r['R_chunks']:.3f} | {r['R_rest']:.3f} | "
                     f"{r['R_cpu']:.3f} | {f(r['R2_predicted'], '.3f')} | "
                     f"{r['wall_over_pair']:.3f} |")
    lines += ["", "R_*: CPU seconds per fine iteration over the pair's CPU seconds (transforms; "
              "elementwise work in chunks on the transforms' threads; the rest); predicted on "
              "2 threads: R_fft + R_chunks + 2 R_rest (transforms and chunked work halved, the "
              "rest not), from the 1-thread rows; measured: wall over wall on the row's "
              "threads (meaningful on an unloaded machine only)."]
    return "\n".join(lines)


def main(argv=None) -> int:
    from pillar_xval.outcome import write_atomic
    from pillar_xval.threads import cpu_count

    ap = argparse.ArgumentParser(prog="python -m validation.bench.threads", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-threads"))
    ap.add_argument("--threads", default=None,
                    help="comma-separated thread counts (default 1 up to the CPUs)")
    ap.add_argument("--cases", default="fft,dense",
                    help=f"among {', '.join(CASES)} (empty: the FFT iteration's split only)")
    ap.add_argument("--fem3d-mesh", type=float, default=None)
    ap.add_argument("--fem3d-phi", type=float, default=None)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--split-threads", default="1",
                    help="thread counts of the FFT iteration split (default 1; add 2 for "
                         "the measured wall ratio; empty: no split)")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another checkout (e.g. git archive main | tar -x -C DIR): its split "
                         "too, interleaved with this one's (its own chunks' definition)")
    ap.add_argument("--edge-correction", action="store_true",
                    help="split the default solve's iteration (edge cells corrected) instead "
                         "of the one with cells at their centres")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        spec = json.loads(args.worker)
        print(json.dumps(_split(spec) if spec["kind"] == "split" else _solve(spec)))
        return 0
    counts = [int(v) for v in args.threads.split(",")] if args.threads else \
        list(range(1, cpu_count() + 1))
    cases = dict(CASES)
    model, scene, overrides, options = cases["fem3d"]
    if args.fem3d_phi is not None:
        overrides = [f"pillars.surface_fraction={args.fem3d_phi:g}"]
    if args.fem3d_mesh is not None:
        options = {"mesh_size": args.fem3d_mesh}
    cases["fem3d"] = (model, scene, overrides, options)
    load_before = [round(v, 2) for v in os.getloadavg()]
    runs, splits = [], []

    def write() -> str:
        """The files as they stand (after every run: a run cut short keeps what it had)."""
        meta = {"cpus": cpu_count(), "repeats": args.repeats, "load_before": load_before,
                "edge_correction": args.edge_correction,
                "baseline": None if args.baseline is None else str(args.baseline),
                "load_after": [round(v, 2) for v in os.getloadavg()], "threads": counts}
        scaling, split = scaling_rows(runs), split_rows(splits)
        table = format_tables(scaling, split, meta)
        write_atomic(args.out / "bench_threads.json", json.dumps(
            {"meta": meta, "scaling": scaling, "split": split, "runs": runs,
             "splits": splits, "table": table}, indent=1))
        write_atomic(args.out / "bench_threads.md", table + "\n")
        return table

    for rep in range(args.repeats):
        for name in (v for v in args.cases.split(",") if v):
            for t in counts:
                print(f"bench-threads: {rep + 1}/{args.repeats} {name} on {t} thread(s)",
                      file=sys.stderr, flush=True)
                runs.append({"name": name, **_run("solve", {"case": cases[name]}, t)})
                write()
        for n in SPLIT_LEVELS:
            for pillars in ("rigid", "elastic"):
                for t in (int(v) for v in args.split_threads.split(",") if v):
                    for root in (None, args.baseline) if args.baseline else (None,):
                        splits.append(_run("split", {"n": n, "pillars": pillars,
                                                     "edge_correction": args.edge_correction},
                                           t, root))
                        write()
    print(write())
    return 0


if __name__ == "__main__":
    sys.exit(main())
