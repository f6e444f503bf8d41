"""Where a GPU solve's first call in a fresh interpreter spends the time it does not spend
again: the CUDA libraries' loads, the kernels' loads, the cuFFT plans of its sizes.

Run as ``python -m validation.bench.gpu_first --out DIR`` on a machine with a GPU.  Scene:
paper-fig3-dense, ``--pillars`` rigid or Hooke, N cells per diameter (``--n``, default 58:
1e6 cells).  Each case runs in a fresh interpreter (the kernels' binaries are on cupy's disk
cache: a warm-up run fills it first) and times, in order: cupy's import, the backend (the
CUDA context), one small FFT (cuFFT's load), then the solve twice ('first', 'again'); with
``prime``, a small solve (N = 32, the smallest level whose grid the device builds: every
kernel of the solve loaded, plans of other sizes) runs before the timed pair, so that
first - again splits into what a process pays once (libraries and kernels) and what each new
grid size pays (its plans, its memory); with ``pool``, cupy's memory pool is first grown to
the size two solves left it at (one block, freed: the pool splits it), which says what the
pool's growth costs a first call.  The first solve runs
under cProfile: its 25 costliest functions (own time) are kept.  Prints a table and writes
``bench_gpu_first.json``.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import platform
import pstats
import sys
import time
from pathlib import Path

from . import write_record
from .fft import run_worker
from .gpu_parts import PILLARS, SCENE, TOL  # the same scene, pillars and tolerance

PRIME_N = 32


def _case(spec: dict) -> dict:
    """One fresh interpreter's figures (the ``--worker`` side)."""
    lap = time.perf_counter()
    import cupy

    out = {"import_cupy_s": time.perf_counter() - lap}
    from bem_solver._fft import solve_fft
    from bem_solver._xp import select_backend
    from pillar_xval.scenes import load_scene

    lap = time.perf_counter()
    be = select_backend("gpu")
    be.synchronize()
    out["backend_s"] = time.perf_counter() - lap
    lap = time.perf_counter()
    be.rfft2(cupy.ones((8, 8)))
    be.synchronize()
    out["small_fft_s"] = time.perf_counter() - lap
    scene = load_scene(SCENE, list(PILLARS[spec["pillars"]]))
    pool = cupy.get_default_memory_pool()
    if spec.get("pool_bytes"):  # the memory pool sized once, before the solve
        lap = time.perf_counter()
        block = cupy.empty(int(spec["pool_bytes"]), dtype=cupy.uint8)
        del block
        be.synchronize()
        out["pool_s"] = time.perf_counter() - lap
    if spec["prime"]:
        lap = time.perf_counter()
        solve_fft(scene, PRIME_N, tol=TOL, backend=be)
        out["prime_s"] = time.perf_counter() - lap
    profile = cProfile.Profile()
    lap = time.perf_counter()
    profile.enable()
    first = solve_fft(scene, spec["n"], tol=TOL, backend=be)
    profile.disable()
    out["first_s"] = time.perf_counter() - lap
    lap = time.perf_counter()
    again = solve_fft(scene, spec["n"], tol=TOL, backend=be)
    out["again_s"] = time.perf_counter() - lap
    out["first_timings_s"] = first.diagnostics["timings_s"]
    out["again_timings_s"] = again.diagnostics["timings_s"]
    out["iterations"] = first.iterations
    out["pool_bytes"] = int(pool.total_bytes())
    text = io.StringIO()
    pstats.Stats(profile, stream=text).sort_stats("tottime").print_stats(25)
    out["profile_tottime"] = text.getvalue().splitlines()[-40:]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.gpu_first",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-gpu-first"))
    ap.add_argument("--pillars", nargs="+", default=list(PILLARS), choices=list(PILLARS))
    ap.add_argument("--n", type=int, default=58, help="cells per pillar diameter")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds per case")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(_case(json.loads(args.worker))))
        return 0
    if args.n < 4:
        ap.error(f"--n {args.n}: at least 4")
    from bem_solver import available_devices

    reason = available_devices()["gpu"]
    if reason:
        print(f"bench-gpu-first: no GPU here ({reason})", file=sys.stderr)
        return 2
    # The warm-up at the timed size: every kernel of the solve on the disk cache, and the
    # memory pool's size after two solves (for the 'pool' cases).
    warm = run_worker("validation.bench.gpu_first",
                      {"pillars": args.pillars[0], "n": args.n, "prime": False}, args.timeout)
    rows = []
    for pillars in args.pillars:
        for prime, pool in ((False, False), (True, False), (False, True)):
            if pool and not warm.get("pool_bytes"):
                continue
            spec = {"pillars": pillars, "n": args.n, "prime": prime,
                    "pool_bytes": warm["pool_bytes"] if pool else 0}
            rows.append({**spec, **run_worker("validation.bench.gpu_first", spec,
                                              args.timeout)})
    keys = ("import_cupy_s", "backend_s", "small_fft_s", "pool_s", "prime_s", "first_s",
            "again_s")
    lines = [f"{'pillars':>7} {'prime':>5} {'pool GB':>7} "
             + " ".join(f"{k[:-2]:>11}" for k in keys)]
    for r in rows:
        pool_gb = r.get("pool_bytes", 0) / 1e9
        lines.append(f"{r['pillars']:>7} {r['prime']!s:>5} {pool_gb:>7.2f} "
                     + " ".join(f"{r[k]:>11.3f}" if isinstance(r.get(k), float)
                                else f"{'-':>11}" for k in keys))
    lines.append(f"seconds; first = the first solve of N = {args.n} in the interpreter (under "
                 "cProfile), again = the next")
    table = "\n".join(lines)
    print(table)
    meta = {"scene": SCENE, "n": args.n, "python": platform.python_version(),
            "warm_up": {k: warm.get(k) for k in ("first_s", "pool_bytes", "error")
                        if k in warm},
            "command": "python -m validation.bench.gpu_first " + " ".join(sys.argv[1:])}
    write_record(args.out, "bench_gpu_first.json", meta, rows, table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
