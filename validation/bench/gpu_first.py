"""Where a GPU solve's first call in a fresh interpreter spends the time it does not spend
again: the CUDA libraries' loads, the kernels' loads, the cuFFT plans of its sizes.

Run as ``python -m validation.bench.gpu_first --out DIR`` on a machine with a GPU.  Scene:
paper-fig3-dense, ``--pillars`` rigid or Hooke, N cells per diameter (``--n``, default 58:
1e6 cells).  Each case runs in a fresh interpreter (the kernels' binaries are on cupy's disk
cache: a warm-up run fills it first) and times, in order: cupy's import, the backend (the
CUDA context), one small FFT (cuFFT's load), then the solve twice ('first', 'again'); with
``prime``, a small solve (N = 8: every kernel of the solve loaded, plans of other sizes)
runs before the timed pair, so that first - again splits into what a process pays once
(libraries and kernels) and what each new grid size pays (its plans).  The first solve runs
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

SCENE = "paper-fig3-dense"
PILLARS = {"rigid": ("pillars.rigid=true",), "hooke": ()}
TOL = 1e-8
PRIME_N = 8


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
    warm = run_worker("validation.bench.gpu_first",
                      {"pillars": args.pillars[0], "n": PRIME_N, "prime": False}, args.timeout)
    rows = []
    for pillars in args.pillars:
        for prime in (False, True):
            spec = {"pillars": pillars, "n": args.n, "prime": prime}
            rows.append({**spec, **run_worker("validation.bench.gpu_first", spec,
                                              args.timeout)})
    keys = ("import_cupy_s", "backend_s", "small_fft_s", "prime_s", "first_s", "again_s")
    lines = [f"{'pillars':>7} {'prime':>5} " + " ".join(f"{k[:-2]:>11}" for k in keys)]
    for r in rows:
        lines.append(f"{r['pillars']:>7} {r['prime']!s:>5} " + " ".join(
            f"{r[k]:>11.3f}" if isinstance(r.get(k), float) else f"{'-':>11}" for k in keys))
    lines.append(f"seconds; first = the first solve of N = {args.n} in the interpreter (under "
                 "cProfile), again = the next")
    table = "\n".join(lines)
    print(table)
    meta = {"scene": SCENE, "n": args.n, "python": platform.python_version(),
            "warm_up": {k: warm.get(k) for k in ("first_s", "error") if k in warm},
            "command": "python -m validation.bench.gpu_first " + " ".join(sys.argv[1:])}
    write_record(args.out, "bench_gpu_first.json", meta, rows, table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
