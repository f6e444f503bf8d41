"""Force control against indentation control, at the same resolution, in one run.

    python -m validation.bench.force --out DIR [--repeats 5] [--fem-repeats 2]
                                     [--only bem-fft,bem,...] [--fem3d-levels 2.83,2,1.41]

The cases: ``paper-fig3-dense`` with bem-fft at N = 32 and 64, the dense bem at P = 11 and
fem-3d at its compare levels (mesh_size 2.83, 2, 1.41); fem-axisym, which holds one pillar,
on ``single-pillar`` at its compare levels (mesh_size 2, 1, 0.5).  For each: the solve under
the scene's indentation gives its force F0; the solve under F0 is the force-controlled one.
After an untimed warm-up of both (imports, caches), the two are timed alternately, A B A B
..., in this process: medians of the repeats, the ratio of the medians beside the median of
the pairs' ratios, and the load average before and after (the machine may be shared).  Also
recorded: the force met, |F - F0| / F0; the round trip, the indentation found against the
given one; the iterations of both solves and the force-controlled solve's design rounds (each
mesh or grid built for a design indentation, fem-3d's coarse level's included).  Targets: at
most 1.5x for the BEMs, 2x for the FEMs.  Prints a table and writes ``bench_force.json`` and ``bench_force.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

# (label, model, options, preset, target ratio)
CASES = (
    ("bem-fft N=32", "bem-fft", {"cells_per_diameter": 32}, "paper-fig3-dense", 1.5),
    ("bem-fft N=64", "bem-fft", {"cells_per_diameter": 64}, "paper-fig3-dense", 1.5),
    ("bem P=11", "bem", {"elements_per_diameter": 11}, "paper-fig3-dense", 1.5),
    ("fem-axisym S=2", "fem-axisym", {"mesh_size": 2.0}, "single-pillar", 2.0),
    ("fem-axisym S=1", "fem-axisym", {"mesh_size": 1.0}, "single-pillar", 2.0),
    ("fem-axisym S=0.5", "fem-axisym", {"mesh_size": 0.5}, "single-pillar", 2.0),
)
FEM3D_LEVELS = (2.83, 2.0, 1.41)
FEMS = ("fem-axisym", "fem-3d")


def _solve(model: str, scene, options: dict):
    from validation.registry import run_model

    t0 = time.perf_counter()
    result = run_model(model, scene, **options)
    return result, time.perf_counter() - t0


def _iterations(result) -> int:
    d = result.diagnostics
    return int(d.get("cg_iterations", result.iterations))


def run_case(label: str, model: str, options: dict, preset: str, target: float,
             repeats: int) -> dict:
    """One case of the benchmark (module docstring): timings, ratio, force and round trip."""
    from pillar_xval.scenes import load_scene

    scene = load_scene(preset)
    given, _ = _solve(model, scene, options)  # warm-up, and the force to give
    loaded = scene.at_force(given.total_force_N)
    forced, _ = _solve(model, loaded, options)
    times = {"indentation": [], "force": []}
    for _ in range(repeats):
        for control, at in (("indentation", scene), ("force", loaded)):
            result, seconds = _solve(model, at, options)
            times[control].append(seconds)
            if control == "force":
                forced = result
    t_ind, t_force = (statistics.median(times[k]) for k in ("indentation", "force"))
    pairs = [f / i for i, f in zip(times["indentation"], times["force"])]
    return {"label": label, "model": model, "options": options, "scene": preset,
            "target_ratio": target, "repeats": repeats, "times_s": times,
            "median_indentation_s": t_ind, "median_force_s": t_force,
            "ratio_of_medians": t_force / t_ind, "median_pair_ratio": statistics.median(pairs),
            "within_target": t_force / t_ind <= target,
            "force_N": given.total_force_N,
            "force_met": abs(forced.total_force_N - given.total_force_N) / given.total_force_N,
            "indentation_given_m": scene.indentation_m, "indentation_found_m":
                forced.indentation_m,
            "round_trip": forced.indentation_m / scene.indentation_m - 1.0,
            "sigma0_change": forced.centre_pressure_Pa / given.centre_pressure_Pa - 1.0,
            "iterations": {"indentation": _iterations(given), "force": _iterations(forced)},
            "design_rounds": len(forced.diagnostics.get("design_rounds", [])),
            "converged": bool(given.converged and forced.converged)}


def table(rows: list[dict]) -> str:
    head = ("| case | scene | indentation (s) | force (s) | ratio (medians) | pair ratios "
            "(median) | target | force met | round trip | iterations (ind./force) | "
            "design rounds |")
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        lines.append(
            f"| {r['label']} | {r['scene']} | {r['median_indentation_s']:.3g} | "
            f"{r['median_force_s']:.3g} | {r['ratio_of_medians']:.2f} | "
            f"{r['median_pair_ratio']:.2f} | {r['target_ratio']:g}x "
            f"{'yes' if r['within_target'] else 'NO'} | {r['force_met']:.1e} | "
            f"{r['round_trip']:+.1e} | {r['iterations']['indentation']}/"
            f"{r['iterations']['force']} | {r['design_rounds']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m validation.bench.force",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=Path("out/bench-force"))
    parser.add_argument("--repeats", type=int, default=5,
                        help="timed pairs per BEM case (default 5)")
    parser.add_argument("--fem-repeats", type=int, default=2,
                        help="timed pairs per FEM case (default 2: fem-3d takes minutes)")
    parser.add_argument("--only", default="",
                        help="comma-separated models to run (default: every case)")
    parser.add_argument("--fem3d-levels", default=",".join(f"{v:g}" for v in FEM3D_LEVELS),
                        help="fem-3d's mesh sizes on paper-fig3-dense (default 2.83,2,1.41; "
                             "empty: none)")
    args = parser.parse_args(argv)
    only = {m for m in args.only.split(",") if m}
    cases = list(CASES) + [(f"fem-3d S={v:g}", "fem-3d", {"mesh_size": v}, "paper-fig3-dense",
                            2.0) for v in (float(t) for t in args.fem3d_levels.split(",") if t)]
    cases = [c for c in cases if not only or c[1] in only]
    args.out.mkdir(parents=True, exist_ok=True)
    load_start = [round(v, 2) for v in os.getloadavg()]
    rows = []
    for label, model, options, preset, target in cases:
        repeats = args.fem_repeats if model in FEMS else args.repeats
        print(f"{label} on {preset}: {repeats} pairs ...", flush=True)
        rows.append(run_case(label, model, options, preset, target, repeats))
        r = rows[-1]
        print(f"  indentation {r['median_indentation_s']:.3g} s, force {r['median_force_s']:.3g}"
              f" s, ratio {r['ratio_of_medians']:.2f}, round trip {r['round_trip']:+.1e}",
              flush=True)
        _write(args.out, rows, load_start, argv)  # each case kept as it finishes
    print(_write(args.out, rows, load_start, argv))
    return 0


def _write(out: Path, rows: list, load_start: list, argv) -> str:
    """bench_force.json and bench_force.md of the cases so far; the table's text."""
    from pillar_xval.outcome import write_atomic

    doc = {"rows": rows, "load_average_start": load_start,
           "load_average_end": [round(v, 2) for v in os.getloadavg()],
           "cpus": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
           "command": "python -m validation.bench.force " + " ".join(
               sys.argv[1:] if argv is None else argv)}
    text = (f"{table(rows)}\n\nload average {doc['load_average_start']} -> "
            f"{doc['load_average_end']} on {doc['cpus']} CPUs")
    write_atomic(out / "bench_force.json", json.dumps(doc, indent=2))
    write_atomic(out / "bench_force.md", text + "\n")
    return text


if __name__ == "__main__":
    raise SystemExit(main())
