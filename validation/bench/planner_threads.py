"""The planner's predicted seconds over measured ones, at several thread counts
(``python -m validation.bench.planner_threads --out DIR --threads 1,4,16``).

For each thread count, in a fresh interpreter with ``PILLAR_XVAL_THREADS`` set: this
machine's calibration measured afresh at that count (:mod:`validation.planner.machine`), then
the cases of the planner's calibrated-band test (bem-fft and dense bem on three calibration
lattices) solved once unmeasured and ``--repeats`` times measured; each case's predicted
seconds (the cost fit rescaled by the calibration) over its median measured seconds, and
their misfit in units of the fit's rms (the band is 2 rms).  A machine without MKL PARDISO
(the 3D FEM's solver) measures the factorisation workload as the reference machine's
seconds: no bem or bem-fft fit uses it, and the row says so.  Prints the table and writes
``bench_planner_threads.json`` and ``.md``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path

from pillar_xval.threads import cpu_count

from .fft import run_worker

# (lattice scene of the calibration set, model, options): the planner's band test's cases.
CASES = (("c10", "bem-fft", {"cells_per_diameter": 24}),
         ("c15", "bem-fft", {"cells_per_diameter": 16}),
         ("c20", "bem-fft", {"cells_per_diameter": 24}),
         ("c10", "bem", {"elements_per_diameter": 15}),
         ("c20", "bem", {"elements_per_diameter": 11}),
         ("c25", "bem", {"elements_per_diameter": 11}))
# The calibrated band: twice a fit's rms misfit in ln(time) over its calibration samples
# (bem-fft 0.51, bem 0.44: about 95 % of the fits' own samples lie within it).
BAND_RMS = 2.0


def case_rows(repeats: int) -> list:
    """The planner's prediction against the median of ``repeats`` measured solves (after one
    unmeasured) of each of :data:`CASES`, on this process's threads and calibration."""
    from validation.planner.plan import default_data
    from validation.registry import run_model
    from validation.studies.calibrate.run import CALIBRATION_SEED
    from validation.studies.calibrate.scenes import lattice_scenes

    scenes = {e["name"]: e["scene"] for e in lattice_scenes(40, CALIBRATION_SEED, "pillars", "c")}
    data = default_data()
    rows = []
    for name, model, options in CASES:
        scene = scenes[name]
        run_model(model, scene, **options)
        walls = []
        for _ in range(repeats):
            start = time.perf_counter()
            run_model(model, scene, **options)
            walls.append(time.perf_counter() - start)
        fit = data.costs[model]
        predicted = fit.predict(scene, options)[0]
        measured = statistics.median(walls)
        rows.append({"case": name, "model": model, "options": options,
                     "predicted_s": predicted, "measured_s": measured,
                     "ratio": predicted / measured,
                     "misfit_rms": math.log(predicted / measured) / fit.rms})
    return rows


def _worker(spec: dict) -> dict:
    """One thread count (this interpreter's PILLAR_XVAL_THREADS): calibration and cases."""
    from validation.planner import machine

    note = ""
    try:
        import pypardiso  # noqa: F401
    except ImportError:
        doc = Path(__file__).resolve().parents[1] / "planner" / "data" / "cost_models.json"
        ref_seconds = json.loads(doc.read_text())["machine"]["seconds"]["factorisation"]

        def stand_in(threads):
            return lambda: time.sleep(ref_seconds)

        machine._BUILDERS["factorisation"] = stand_in
        note = "no PARDISO here: factorisation workload = the reference's seconds"
    cal = machine.calibration(fresh=True)
    rows = case_rows(spec["repeats"])
    return {"threads": cal["threads"], "calibration_s": cal["seconds"], "note": note,
            "rows": rows,
            "mean_misfit_rms": statistics.mean(r["misfit_rms"] for r in rows)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.planner_threads",
                                 description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-planner-threads"))
    ap.add_argument("--threads", default=None,
                    help="comma-separated thread counts (default 1 and the CPUs)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per thread count")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(_worker(json.loads(args.worker))))
        return 0
    if args.repeats < 1:
        ap.error(f"--repeats {args.repeats}: must be at least 1")
    counts = [int(v) for v in args.threads.split(",")] if args.threads else \
        sorted({1, cpu_count()})
    results = []
    for t in counts:
        print(f"bench-planner-threads: {t} thread(s)", file=sys.stderr, flush=True)
        os.environ["PILLAR_XVAL_THREADS"] = str(t)
        os.environ["PILLAR_XVAL_MACHINE"] = "here"
        results.append({"threads_asked": t,
                        **run_worker("validation.bench.planner_threads",
                                     {"repeats": args.repeats}, args.timeout)})
    table = format_table(results)
    args.out.mkdir(parents=True, exist_ok=True)
    from pillar_xval.outcome import write_atomic

    meta = {"cpus": cpu_count(), "threads": counts, "repeats": args.repeats}
    write_atomic(args.out / "bench_planner_threads.json",
                 json.dumps({"meta": meta, "results": results, "table": table}, indent=1))
    write_atomic(args.out / "bench_planner_threads.md", table + "\n")
    print(table)
    return 0


def format_table(results: list) -> str:
    """Predicted over measured seconds per case and thread count."""
    lines = ["| threads | case | model | predicted s | measured s | predicted / measured | "
             "misfit (rms) |", "|---|---|---|---|---|---|---|"]
    for res in results:
        if "error" in res:
            lines.append(f"| {res['threads_asked']} | error: {res['error']} | | | | | |")
            continue
        for r in res["rows"]:
            lines.append(f"| {res['threads']} | {r['case']} | {r['model']} | "
                         f"{r['predicted_s']:.3g} | {r['measured_s']:.3g} | {r['ratio']:.2f} | "
                         f"{r['misfit_rms']:+.2f} |")
        lines.append(f"| {res['threads']} | mean | | | | | {res['mean_misfit_rms']:+.2f} "
                     f"(band +-{BAND_RMS:g}) |")
    notes = sorted({r.get("note") for r in results if r.get("note")})
    return "\n".join(lines + [f"note: {n}" for n in notes])


if __name__ == "__main__":
    sys.exit(main())
