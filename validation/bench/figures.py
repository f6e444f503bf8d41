"""Benchmark of ``pillar-xval figures``: ``python -m validation.bench.figures --out DIR``
(``make bench-figures``).

1. The resolution: on a seeded sample of the scenes behind Figs. 4-8, the error of F_T and
   sigma_0 of the figures' model (``bem-richardson``, P = 5 and 9) and of alternatives
   (plain dense BEM at P = 9, 11, 15; Richardson of P = 9, 11, the pair first proposed)
   against a finer reference: the FFT BEM at N = 32 and 48 cells per diameter, extrapolated
   at order 1 (both models converge at order 1 on pillar tops).  The reference's own
   uncertainty is estimated where N = 64 is affordable, as the change of the extrapolation
   from (32, 48) to (48, 64).
2. The time: the whole figure set (``run_figures``, every scene of Figs. 3-8 and the
   threshold bisection) in a fresh folder on the local pool, unless ``--skip-run``.

Prints a table and writes ``bench_figures.json``.  Every solve runs on the engine and is
cached under ``DIR/cases`` (a rerun resumes); timings on a shared machine are contended.
"""

from __future__ import annotations

import argparse
import json
import shutil
import time
from pathlib import Path

import numpy as np

from bem_solver._extrapolated import richardson
from pillar_xval.outcome import write_atomic
from validation.engine import Case, Engine
from validation.studies.figures import run_figures
from validation.studies.figures.scenes import FigureGrid, expected_pillars, figure_sweeps

SEED = 8  # the sample of figure scenes timed (any fixed seed: the same scenes every run)
SAMPLE = 40
REFERENCE_N = (32, 48)
CHECK_N = 64
CHECK_MAX_PILLARS = 40  # N = 64 only where it is affordable
TARGET = 0.01           # F_T and sigma_0 within 1 %


def figure_scenes(grid: FigureGrid) -> list:
    """The distinct scenes behind Figs. 4-8 (Fig. 3's two are drawn at a finer level)."""
    sweeps = figure_sweeps(grid, "bem-richardson", {"elements_per_diameter": 5})
    seen, scenes = set(), []
    for name, sweep in sweeps.items():
        if name == "fig3":
            continue
        for c in sweep.cases()[0]:
            if c.case.key not in seen:
                seen.add(c.case.key)
                scenes.append(c.scene)
    return scenes


def _candidates():
    """(label, cases to run, how to combine their (F_T, sigma_0))."""
    def dense(p):
        return ("bem", {"elements_per_diameter": p, "cells": "covered"})

    return [
        ("bem-richardson P=5 (5, 9)", [("bem-richardson", {"elements_per_diameter": 5})],
         lambda v: v[0]),
        ("bem-richardson P=7 (7, 13)", [("bem-richardson", {"elements_per_diameter": 7})],
         lambda v: v[0]),
        ("bem P=9", [dense(9)], lambda v: v[0]),
        ("bem P=11", [dense(11)], lambda v: v[0]),
        ("bem P=15", [dense(15)], lambda v: v[0]),
        ("Richardson of bem P=(9, 11)", [dense(9), dense(11)],
         lambda v: tuple(richardson(a, b, 9, 11) for a, b in zip(*v))),
    ]


def resolution(scenes: list, engine: Engine, folder: Path) -> dict:
    """Errors of every candidate against the FFT reference on ``scenes``."""
    runs = {}
    for scene in scenes:
        for label, models, _ in _candidates():
            for model, opts in models:
                runs.setdefault((model, tuple(sorted(opts.items()))), []).append(scene)
        for n in REFERENCE_N:
            runs.setdefault(("bem-fft", (("cells_per_diameter", n),)), []).append(scene)
        if expected_pillars(scene) <= CHECK_MAX_PILLARS:
            runs.setdefault(("bem-fft", (("cells_per_diameter", CHECK_N),)), []).append(scene)
    cases = [Case(model, s, dict(opts), tag=f"Phi={s.pillars.surface_fraction:.3g} "
                  f"zeta={s.indentation_m * 1e6:.3g}um")
             for (model, opts), ss in runs.items() for s in ss]
    cases.sort(key=lambda c: -expected_pillars(c.scene))
    outcomes = {c.key: o for c, o in zip(cases, engine.run(cases, folder, label="resolution"))}

    def value(model, opts, scene):
        o = outcomes[Case(model, scene, dict(opts)).key]
        r = o.unwrap()
        if not r.converged:
            raise RuntimeError(f"{model} {opts} did not converge on {scene}")
        return (r.total_force_N, r.centre_pressure_Pa), o.timing["wall_time_s"]

    rows, uncertainty = [], []
    for s in scenes:
        (f32, _), (f48, _) = (value("bem-fft", (("cells_per_diameter", n),), s)
                              for n in REFERENCE_N)
        ref = tuple(richardson(a, b, *REFERENCE_N) for a, b in zip(f32, f48))
        row = {"phi": s.pillars.surface_fraction, "zeta_um": s.indentation_m * 1e6,
               "E_p_over_E_l": s.pillars.material.E_Pa / s.lens.material.E_Pa,
               "pillars_expected": expected_pillars(s), "reference": ref, "errors": {},
               "wall_time_s": {}}
        if expected_pillars(s) <= CHECK_MAX_PILLARS:
            (f64, _) = value("bem-fft", (("cells_per_diameter", CHECK_N),), s)
            check = tuple(richardson(a, b, REFERENCE_N[1], CHECK_N) for a, b in zip(f48, f64))
            row["reference_change"] = [abs(c / r - 1) for c, r in zip(check, ref)]
            uncertainty.append(row["reference_change"])
        for label, models, combine in _candidates():
            got = [value(m, tuple(sorted(o.items())), s) for m, o in models]
            est = combine([g[0] for g in got]) if len(got) > 1 else combine([got[0][0]])
            row["errors"][label] = [abs(e / r - 1) for e, r in zip(est, ref)]
            row["wall_time_s"][label] = sum(g[1] for g in got)
        rows.append(row)
    summary = {}
    for label, _, _ in _candidates():
        errs = np.array([r["errors"][label] for r in rows])
        summary[label] = {
            "max_F_T": float(errs[:, 0].max()), "max_sigma0": float(errs[:, 1].max()),
            "p95_F_T": float(np.percentile(errs[:, 0], 95)),
            "p95_sigma0": float(np.percentile(errs[:, 1], 95)),
            "median_sigma0": float(np.median(errs[:, 1])),
            "sample_time_s": float(sum(r["wall_time_s"][label] for r in rows)),
            "within_target": bool(errs.max() <= TARGET)}
    unc = np.array(uncertainty) if uncertainty else np.zeros((0, 2))
    return {"rows": rows, "summary": summary,
            "reference": f"bem-fft N = {REFERENCE_N}, Richardson order 1",
            "reference_uncertainty": {
                "scenes": len(unc),
                "max_F_T": float(unc[:, 0].max()) if len(unc) else None,
                "max_sigma0": float(unc[:, 1].max()) if len(unc) else None,
                "how": f"|Richardson(N = 48, {CHECK_N}) / Richardson(N = 32, 48) - 1| on the "
                       f"sample scenes with at most {CHECK_MAX_PILLARS} pillars expected"}}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out") / "bench-figures")
    parser.add_argument("--sample", type=int, default=SAMPLE)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--skip-run", action="store_true",
                        help="measure the resolution only, not the whole figure set's time")
    args = parser.parse_args(argv)
    out = args.out
    grid = FigureGrid.full()
    scenes = figure_scenes(grid)
    rng = np.random.default_rng(SEED)
    pick = sorted(rng.choice(len(scenes), size=min(args.sample, len(scenes)), replace=False))
    sample = [scenes[i] for i in pick]
    doc = {"seed": SEED, "scenes_behind_figs_4_8": len(scenes), "sample": len(sample)}
    with Engine("pool", workers=args.workers, label="bench") as engine:
        t0 = time.perf_counter()
        doc["resolution"] = resolution(sample, engine, out / "cases")
        doc["resolution_time_s"] = time.perf_counter() - t0
    if not args.skip_run:
        run_dir = out / "figures-run"
        shutil.rmtree(run_dir, ignore_errors=True)  # a fresh folder: nothing cached
        with Engine("pool", workers=args.workers, label="figures", quiet=True) as engine:
            t0 = time.perf_counter()
            figs = run_figures(run_dir, grid, engine=engine)
            doc["figure_set"] = {**figs["timing"], "wall_s": time.perf_counter() - t0,
                                 "target_s": 180.0}
    doc["out"] = str(out / "bench_figures.json")
    write_atomic(out / "bench_figures.json", json.dumps(doc, indent=1) + "\n")
    _print(doc)
    return 0


def _print(doc: dict) -> None:
    res = doc["resolution"]
    print(f"resolution: {doc['sample']} of the {doc['scenes_behind_figs_4_8']} scenes behind "
          f"Figs. 4-8 (seed {doc['seed']}); reference {res['reference']}")
    u = res["reference_uncertainty"]
    if u["scenes"]:
        print(f"  reference uncertainty (N = 48, 64 vs 32, 48 on {u['scenes']} scenes): "
              f"F_T {100 * u['max_F_T']:.2f} %, sigma0 {100 * u['max_sigma0']:.2f} %")
    print(f"  {'model':<30} {'max F_T':>8} {'max s0':>8} {'p95 s0':>8} {'time':>8}")
    for label, s in res["summary"].items():
        print(f"  {label:<30} {100 * s['max_F_T']:7.2f}% {100 * s['max_sigma0']:7.2f}% "
              f"{100 * s['p95_sigma0']:7.2f}% {s['sample_time_s']:7.1f}s")
    if "figure_set" in doc:
        f = doc["figure_set"]
        print(f"figure set: {f['unique_cases']} scenes + {f['threshold_solves']} bisection "
              f"solves in {f['wall_s']:.1f} s (target {f['target_s']:.0f} s; scenes "
              f"{f['scenes_s']:.1f} s, bisection {f['threshold_bisection_s']:.1f} s, fits and "
              f"plots {f['analysis_and_plots_s']:.1f} s) on {f['executor']}; contended "
              f"machine")
    print(f"written: {doc['out']}")


if __name__ == "__main__":
    raise SystemExit(main())
