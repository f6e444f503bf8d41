"""Where the FFT model's constrained CG spends an iteration, part by part, on a device.

Run as ``python -m validation.bench.gpu_parts --device gpu --out DIR`` (``--device cpu``
runs the same parts with numpy).  Scene: paper-fig3-dense (Phi = 0.82), rigid or Hooke
pillars (``--pillars``), N cells per diameter (``--n``, default 58: 1e6 cells).  It solves
once (the iterations and the CG's time per iteration), then builds the same operator and
preconditioner and times, each as the median of ``--repeats`` calls with the device
synchronised after each: the float64 and float32 operator applications, the preconditioner,
one dot product and one max reduction brought to the host (each a synchronisation), a
three-launch vector update, and the residual pass.  Their sum per iteration, against the
measured time per iteration, says how much of it is transforms, how much launches and
synchronisations: the figures that decide whether fusing the CG's vector work pays.
Prints a table and writes ``bench_gpu_parts.json``.
"""

from __future__ import annotations

import argparse
import platform
import statistics
import sys
import time
from pathlib import Path

from . import write_record

SCENE = "paper-fig3-dense"
PILLARS = {"rigid": ("pillars.rigid=true",), "hooke": ()}
TOL = 1e-8


def _timed(fn, be, repeats: int) -> float:
    """Median seconds of ``fn()`` with the device synchronised after each call (two calls
    first, untimed: plans made, kernels loaded)."""
    for _ in range(2):
        fn()
    be.synchronize()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        be.synchronize()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def measure(device: str, pillars: str, n: int, repeats: int, fused: bool = True) -> dict:
    """The solve's time per iteration and each part's median time (s); ``fused``: the CG's
    passes as fused kernels on a GPU (the backend's ``cg_passes``), else as array
    operations."""
    from bem_solver._fft import _Options, _prepare, solve_fft
    from bem_solver._xp import select_backend
    from pillar_xval.contact._cg import _residual
    from pillar_xval.contact._xp import one_piece
    from pillar_xval.scenes import load_scene

    scene = load_scene(SCENE, list(PILLARS[pillars]))
    be = select_backend(device)
    if device == "gpu":
        be.fused = fused
    xp = be.xp
    res = solve_fft(scene, n, tol=TOL, backend=be, warm_start=False)
    res = solve_fft(scene, n, tol=TOL, backend=be, warm_start=False)  # plans made
    timings = res.diagnostics["timings_s"]
    opts = _Options(TOL, None, be.workers if hasattr(be, "workers") else 1, False, True, None,
                    "circulant", "hooke", None, "mixed", False)
    setup = _prepare(scene, n, opts, be, None, time.perf_counter())
    plan, precondition = setup.plan, setup.precondition
    cells = setup.grid.n_cells
    q = be.asarray(res.fields["pressure_Pa"] * setup.grid.covered, dtype=xp.float64)
    gap = be.asarray(res.fields["gap_m"], dtype=xp.float64)
    active = q > 0.0
    free = active | (gap < 0.0)
    t, out = q + 0.0, q + 0.0
    parts = {
        "apply_float64": lambda: plan(q),
        "apply_float32": lambda: plan(q, single=True),
        "precondition": lambda: precondition(gap, free),
        "dot_to_host": lambda: float(be.dot(q, gap)),
        "max_to_host": lambda: float(xp.max(q)),
        "axpy_3_launches": lambda: (out.__setitem__(Ellipsis, t), out.__imul__(-0.5),
                                    out.__iadd__(q)),
        "residual_pass": lambda: _residual(xp, gap, active, None, cells,
                                           getattr(be, "chunks", one_piece), None),
    }
    passes = getattr(be, "cg_passes", None)
    if passes is not None:  # the fused kernels of the residual pass and of a step
        scratch = xp.zeros_like(active)
        parts["residual_fused"] = lambda: passes.residual(gap, active, cells, scratch)
        parts["step_fused"] = lambda: passes.step(out, q, 0.5, t, cells)
    measured = {name: _timed(fn, be, repeats) for name, fn in parts.items()}
    iterations = max(res.iterations, 1)
    return {"device": device, "pillars": pillars, "n": n, "cells": cells,
            "fused": passes is not None,
            "fft_shape": list(plan.fft_shape), "iterations": res.iterations,
            "operator_applications": res.diagnostics["operator_applications"],
            "single_precision_applications":
                res.diagnostics["single_precision_applications"],
            "solve_s": timings["solve"], "per_iteration_s": timings["solve"] / iterations,
            "timings_s": timings, "wall_time_s": res.wall_time_s, "parts_s": measured,
            "total_force_N": res.total_force_N, "converged": res.converged}


def report(rows: list) -> str:
    names = list(dict.fromkeys(k for r in rows for k in r["parts_s"]))
    lines = [f"{'device':>6} {'pillars':>7} {'fused':>5} {'cells':>9} {'it':>4} {'ms/it':>7} "
             + " ".join(f"{k[:14]:>14}" for k in names)]
    for r in rows:
        lines.append(f"{r['device']:>6} {r['pillars']:>7} {r['fused']!s:>5} "
                     f"{r['cells']:>9.3g} {r['iterations']:>4} "
                     f"{1e3 * r['per_iteration_s']:>7.3f} "
                     + " ".join(f"{1e3 * r['parts_s'][k]:>14.4f}" if k in r["parts_s"]
                                else f"{'-':>14}" for k in names))
    lines.append("parts in ms per call (median, device synchronised after each)")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.gpu_parts",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-gpu-parts"))
    ap.add_argument("--device", default="gpu", choices=["cpu", "gpu"])
    ap.add_argument("--pillars", nargs="+", default=list(PILLARS), choices=list(PILLARS))
    ap.add_argument("--n", type=int, default=58, help="cells per pillar diameter")
    ap.add_argument("--repeats", type=int, default=20, help="timed calls per part")
    ap.add_argument("--unfused", action="store_true",
                    help="on a GPU, also the rows with the CG's passes as array operations")
    args = ap.parse_args(argv)
    if args.n < 4 or args.repeats < 1:
        ap.error(f"--n {args.n} (at least 4), --repeats {args.repeats} (at least 1)")

    fusings = (True, False) if args.unfused and args.device == "gpu" else (True,)
    rows = [measure(args.device, p, args.n, args.repeats, fused) for p in args.pillars
            for fused in fusings]
    table = report(rows)
    print(table)
    meta = {"scene": SCENE, "tolerance": TOL, "python": platform.python_version(),
            "command": "python -m validation.bench.gpu_parts " + " ".join(sys.argv[1:])}
    write_record(args.out, "bench_gpu_parts.json", meta, rows, table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
