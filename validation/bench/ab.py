"""Interleaved before/after timing of solves against another checkout of the toolkit:
``python -m validation.bench.ab --baseline DIR --out DIR [--case dense] [--case fft:58] ...``.

Each run is one solve in a fresh interpreter (as ``pillar-xval solve`` runs it: imports
excluded, first-call costs included) whose ``PYTHONPATH`` is this checkout or the baseline
(a read-only checkout of the old code, e.g. ``git archive main | tar -x -C DIR``); the runs
alternate between the two (ABBA order), so that the load of a shared machine weighs on both
alike.  Per case and side: the median and the spread of the solve's wall time and CPU time
(``time.process_time``, both threads), the iterations, and the answers F_T, sigma0 and a with
their largest relative difference between the sides; for the FFT, the operator applications
and the fine level's solve time per iteration over the bare FFT pair (scipy.fft rfft2 + irfft2,
on the solver's threads, as :func:`validation.bench.fft.fft_floor`, timed right after the solve): wall over
wall on the model's own padded grid, wall over wall on the 2 n - 1 zero-padded grid (the
same yardstick for two sides that pad differently), and the fine CG's CPU time over the
pair's (both threads; steadier than wall times on a loaded machine).  With ``--warm`` each
interpreter solves twice and the second solve is timed.  Prints the table and writes it with the runs
and the load averages to ``DIR/bench_ab.md`` and ``DIR/bench_ab.json``.

Cases: ``dense`` (the dense BEM at its default P = 11 on paper-fig3-dense, zeta = 0.5 um),
``fft:N`` and ``elastic-fft:N`` (the FFT BEM with Hooke or elastic pillars at N cells per
diameter on paper-fig3-dense), optionally ``@tol`` (the FFT's tolerance), e.g. ``fft:58@1e-12``;
``fem3d:PHI:MESH_SIZE`` (fem-3d on paper-fig3-sparse with surface fraction PHI, the lattice
study's scene at zeta = 0.3 um), whose rows add the median time of each phase of the solve and
the interpreter's peak RSS (its own, since each run is a fresh process);
``floor3d:PHI:MESH_SIZE`` (fem-3d on the floor validation's lattice of surface fraction PHI,
its floor touched: :data:`validation.studies.floor_check.POINTS`), whose rows add the
elements and the floor's contact area; ``floor:H`` (the FFT BEM on the floor benchmark's
timed scene with pillars H um tall: ``floor:1`` mixed, ``floor:20`` suspended).  ``--rounds``
runs every case in each repeat, so that the ratio of two cases' medians (printed for two
``floor:`` cases) is measured under one load.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

SCENE = ("paper-fig3-dense", ["load.indentation_um=0.5"])
FEM3D_SCENE = "paper-fig3-sparse"
# The phases fem-3d times (its diagnostics' time_s), in the order they run.
FEM3D_PHASES = ("mesh", "assemble", "factorise", "contact", "post")
# The fine level's solve per iteration over the bare FFT pair: wall over wall on the model's
# own padded grid; wall over wall on the 2 n - 1 padded grid (one yardstick for both sides
# when their padding differs); CPU over CPU (both threads: steadier on a loaded machine).
PER_ITERATION = ("per_iteration_over_fft_pair", "per_iteration_over_2n1_pair",
                 "cpu_per_iteration_over_cpu_pair")
ROOT = Path(__file__).resolve().parents[2]
# The answers compared between the sides (the floor's two: 0 without a floor).
ANSWERS = ("F_T", "sigma0", "a", "F_floor", "A_floor")

WORKER = r"""
import json, os, sys, time
case, warm = json.loads(sys.argv[1]), sys.argv[2] == "1"
from pillar_xval.scenes import load_scene
scene = load_scene(case["scene"], case["overrides"])
if case["model"] == "dense":
    from bem_solver import solve_dense as solve
elif case["model"] == "fem3d":
    from fem_reference.solid3d import solve
else:
    from bem_solver import solve_fft as solve
if case["model"] == "fft" and case["pillars"] == "elastic":
    from bem_solver._elastic_pillar import scene_compliance
    scene_compliance(scene)  # the cached compliance, read outside the timing
if case["model"] == "fft":  # the fine level's CG is the last one a solve runs
    import bem_solver._fft as fft_module
    cg_of_module, fine = fft_module.constrained_cg, {}
    def timed_cg(*a, **k):
        t, c = time.perf_counter(), time.process_time()
        res = cg_of_module(*a, **k)
        fine.update(wall=time.perf_counter() - t, cpu=time.process_time() - c)
        return res
    fft_module.constrained_cg = timed_cg
args = (case["cells"],) if case["model"] != "dense" else ()
kw = {"pillars": case["pillars"], **case["options"]} if case["model"] == "fft" else {}
for _ in range(2 if warm else 1):
    t, c = time.perf_counter(), time.process_time()
    r = solve(scene, *args, **kw)
    wall, cpu = time.perf_counter() - t, time.process_time() - c
out = {"wall_s": wall, "cpu_s": cpu, "iterations": r.iterations, "converged": r.converged,
       "F_T": r.total_force_N, "sigma0": r.centre_pressure_Pa, "a": r.contact_radius_m,
       "F_floor": getattr(r, "floor_force_N", 0.0),
       "A_floor": getattr(r, "floor_contact_area_m2", 0.0)}
if case["model"] == "fem3d":
    import resource
    out["elements"] = r.discretisation["elements"]
    # None on a baseline from before the floor contact (e.g. 13c5f52, the fem-3d speed
    # work's reference)
    out["floor_area_m2"] = getattr(r, "floor_contact_area_m2", None)
    out["phases"] = r.diagnostics["time_s"]
    out["peak_rss_GiB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
if case["model"] == "fft":  # the fine level's time per iteration over the bare FFT pair
    import statistics
    import numpy as np
    import scipy.fft as sfft
    # The solver's threads (pillar_xval.threads, read here without it: a baseline may lack it).
    W = int(os.environ.get("PILLAR_XVAL_THREADS") or len(os.sched_getaffinity(0)))
    def pair(shape, repeats=7):  # validation.bench.fft.fft_floor, wall and CPU (all threads)
        a = np.random.default_rng(0).random(tuple(shape))
        sfft.irfft2(sfft.rfft2(a, workers=W), s=a.shape, workers=W)
        walls, cpus = [], []
        for _ in range(repeats):
            t, c = time.perf_counter(), time.process_time()
            sfft.irfft2(sfft.rfft2(a, workers=W), s=a.shape, workers=W)
            walls.append(time.perf_counter() - t)
            cpus.append(time.process_time() - c)
        return statistics.median(walls), statistics.median(cpus)
    d = r.diagnostics
    iters = max(r.iterations, 1)
    own, own_cpu = pair(d["fft_shape"])
    # The same yardstick on both sides: the pair on the 2 n - 1 zero-padded grid.
    common = [sfft.next_fast_len(2 * k - 1, real=True) for k in d["grid_shape"]]
    ref = own if list(common) == list(d["fft_shape"]) else pair(common)[0]
    out["applications"] = d["operator_applications"]
    out["fft_shape"] = d["fft_shape"]
    out["per_iteration_over_fft_pair"] = d["timings_s"]["solve"] / iters / own
    out["per_iteration_over_2n1_pair"] = d["timings_s"]["solve"] / iters / ref
    out["cpu_per_iteration_over_cpu_pair"] = fine["cpu"] / iters / own_cpu
print(json.dumps(out))
"""


def parse_case(text: str) -> dict:
    if text.startswith(("fem3d:", "floor3d:")):
        return _parse_fem3d(text)
    if text.startswith("floor:"):
        return _parse_floor(text)
    name, _, tol = text.partition("@")
    model, _, cells = name.partition(":")
    if model not in ("dense", "fft", "elastic-fft") or (model != "dense") != bool(cells):
        raise argparse.ArgumentTypeError(f"{text!r}: expected dense, fft:N, elastic-fft:N or "
                                         "fem3d:PHI:MESH_SIZE (floor3d:PHI:MESH_SIZE)")
    options = {"tol": float(tol)} if tol else {}
    return {"label": text, "model": "dense" if model == "dense" else "fft",
            "pillars": "elastic" if model == "elastic-fft" else "hooke",
            "cells": int(cells) if cells else None, "options": options,
            "scene": SCENE[0], "overrides": SCENE[1]}


def _parse_fem3d(text: str) -> dict:
    parts = text.split(":")
    try:
        phi, mesh_size = float(parts[1]), float(parts[2])
        if len(parts) != 3:
            raise ValueError
    except (IndexError, ValueError):
        raise argparse.ArgumentTypeError(f"{text!r}: expected {parts[0]}:PHI:MESH_SIZE, e.g. "
                                         f"{parts[0]}:0.4:2") from None
    case = {"label": text, "model": "fem3d", "cells": mesh_size, "options": {},
            "scene": FEM3D_SCENE, "overrides": [f"pillars.surface_fraction={phi}"]}
    if parts[0] == "floor3d":
        from validation.studies.floor_check import POINTS

        point = next((p for p in POINTS if p.surface_fraction == phi and not p.single), None)
        if point is None:
            raise argparse.ArgumentTypeError(
                f"{text!r}: PHI must be one of the floor validation's lattices, " + ", ".join(
                    f"{p.surface_fraction:g}" for p in POINTS if not p.single))
        case.update(overrides=point.overrides())
    return case


def _parse_floor(text: str) -> dict:
    """``floor:H``: the floor benchmark's timed scene (:mod:`validation.bench.floor`, rigid
    pillars, 1e6 candidate cells) with pillars H um tall (1: the floor touched; 20: not)."""
    from validation.bench.floor import PERF_N, PERF_SCENE, TOL

    try:
        height = float(text.split(":", 1)[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected floor:H (pillar height in um, "
                                         "e.g. floor:1 or floor:20)") from None
    return {"label": text, "model": "fft", "pillars": "hooke", "cells": PERF_N,
            "options": {"tol": TOL}, "scene": "paper-fig3-sparse",
            "overrides": PERF_SCENE + [f"pillars.height_um={height:g}"]}


def run_once(root: Path, case: dict, warm: bool, worker: str = WORKER) -> dict:
    """One run of ``worker`` (this module's solve by default) on ``case`` in a fresh
    interpreter whose PYTHONPATH is the checkout ``root``: its JSON line."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    out = subprocess.run([sys.executable, "-c", worker, json.dumps(case), "1" if warm else "0"],
                         env=env, cwd=root, capture_output=True, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def interleaved(cases, sides: dict, repeats: int, summarise, *, warm: bool = False,
                worker: str = WORKER, rounds: bool = False) -> tuple[list, dict, list]:
    """Run each case ``repeats`` times a side, the sides alternating (ABBA): (the rows of
    ``summarise(case, runs)``, the runs by case label, the load averages before and after
    each case).  ``rounds``: every case in each repeat (ratios between cases then see the
    same load), the load averages after each round."""
    load = [os.getloadavg()]
    raw = {case["label"]: {"baseline": [], "this": []} for case in cases}

    def one(case, k):
        order = ("baseline", "this") if k % 2 == 0 else ("this", "baseline")
        for side in order:
            raw[case["label"]][side].append(run_once(sides[side], case, warm, worker))

    for outer in (range(repeats) if rounds else cases):
        for inner in (cases if rounds else range(repeats)):
            one(*((inner, outer) if rounds else (outer, inner)))
        load.append(os.getloadavg())
    rows = [row for case in cases for row in summarise(case, raw[case["label"]])]
    return rows, raw, load


def case_ratios(rows, over: str, under: str) -> str:
    """Each side's ratio of the median walls of the cases ``over`` and ``under``."""
    wall = {(r["case"], r["side"]): r["wall_median_s"] for r in rows}
    return "; ".join(f"{side}: {over} / {under} = "
                     f"{wall[over, side] / wall[under, side]:.3f}"
                     for side in ("baseline", "this"))


def load_text(load: list) -> str:
    return ("load average (1, 5, 15 min) before and after each case: "
            + ", ".join("(" + ", ".join(f"{x:.2f}" for x in la) + ")" for la in load))


def _rel(a, b):
    return abs(a - b) / max(abs(a), abs(b), 1e-300)


def summarise(case, runs) -> list[dict]:
    rows = []
    for side in ("baseline", "this"):
        rs = runs[side]
        wall = [r["wall_s"] for r in rs]
        cpu = [r["cpu_s"] for r in rs]
        rows.append({"case": case["label"], "side": side, "repeats": len(rs),
                     "wall_median_s": statistics.median(wall), "wall_min_s": min(wall),
                     "wall_max_s": max(wall), "cpu_median_s": statistics.median(cpu),
                     "iterations": rs[-1]["iterations"], "converged": rs[-1]["converged"],
                     **{q: rs[-1].get(q) for q in ANSWERS},
                     "applications": rs[-1].get("applications"),
                     **{key: statistics.median([r.get(key, float("nan")) for r in rs])
                        for key in PER_ITERATION}})
        if "phases" in rs[-1]:
            rows[-1]["phases_median_s"] = {k: statistics.median([r["phases"][k] for r in rs])
                                           for k in FEM3D_PHASES}
            rows[-1]["peak_rss_median_GiB"] = statistics.median([r["peak_rss_GiB"] for r in rs])
            rows[-1]["elements"] = rs[-1].get("elements")
            rows[-1]["floor_area_m2"] = rs[-1].get("floor_area_m2")
    base, this = rows
    this["speed-up"] = base["wall_median_s"] / this["wall_median_s"]
    # with the floor's force and area where both sides report them
    this["max_rel_diff"] = max(_rel(base[q], this[q]) for q in ANSWERS
                               if base.get(q) is not None and this.get(q) is not None)
    return rows


def table(rows) -> str:
    head = ("| case | side | wall median s (min-max) | CPU median s | iterations "
            "(applications) | iteration / FFT pair (own grid; 2n-1 grid; CPU) | F_T N | "
            "sigma0 Pa | a m | speed-up | max rel diff |")
    lines = [head, "|" + "---|" * 11]
    for r in rows:
        apps = "" if r["applications"] is None else f" ({r['applications']})"
        lines.append(
            f"| {r['case']} | {r['side']} | {r['wall_median_s']:.3f} ({r['wall_min_s']:.3f}-"
            f"{r['wall_max_s']:.3f}) | {r['cpu_median_s']:.3f} | {r['iterations']}{apps} | "
            + "; ".join(f"{r[key]:.2f}" for key in PER_ITERATION) + " | "
            f"{r['F_T']:.10g} | {r['sigma0']:.10g} | {r['a']:.10g} | "
            f"{r.get('speed-up', float('nan')):.2f} | {r.get('max_rel_diff', float('nan')):.2e} |")
    phased = [r for r in rows if "phases_median_s" in r]
    if phased:
        lines += ["", "| case | side | " + " | ".join(f"{k} s" for k in FEM3D_PHASES)
                  + " | peak RSS GiB | elements | floor area um^2 |",
                  "|" + "---|" * (len(FEM3D_PHASES) + 5)]
        lines += [f"| {r['case']} | {r['side']} | "
                  + " | ".join(f"{r['phases_median_s'][k]:.1f}" for k in FEM3D_PHASES)
                  + f" | {r['peak_rss_median_GiB']:.2f} | {r.get('elements') or '-'} | "
                  + ("-" if r.get("floor_area_m2") is None else f"{r['floor_area_m2'] * 1e12:.1f}")
                  + " |" for r in phased]
    return "\n".join(lines)


def side_arguments(ap: argparse.ArgumentParser, files: str) -> None:
    """--baseline, --this and --out (the folder for ``files``) of an A/B benchmark."""
    ap.add_argument("--baseline", type=Path, required=True,
                    help="checkout of the old code (its root: bem_solver/, pillar_xval/, ...)")
    ap.add_argument("--this", type=Path, default=ROOT,
                    help="checkout of the new code (default: this one)")
    ap.add_argument("--out", type=Path, required=True, help=f"folder for {files}")


def write_results(out: Path, stem: str, text: str, sides: dict, rows: list, raw: list,
                  load, **extra) -> None:
    """An A/B benchmark's table ``text`` and its rows, runs and load averages as
    ``out/stem.md`` and ``out/stem.json`` (each written whole, atomically)."""
    from pillar_xval.outcome._files import write_atomic

    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / f"{stem}.md", text)
    write_atomic(out / f"{stem}.json", json.dumps(
        {"baseline": str(sides["baseline"]), "this": str(sides["this"]), "rows": rows,
         "runs": raw, "load_average": load, **extra}, indent=1))


def median_of(key: str):
    """The median of ``key`` over a side's runs, as a :func:`phase_rows` column."""
    return lambda runs: statistics.median(r[key] for r in runs)


def phase_rows(case: dict, runs: dict, columns: dict, kept: tuple, same: str) -> list[dict]:
    """A phase benchmark's two rows (baseline, this) for ``case``: each ``columns[key](runs of
    the side)`` and the last run's ``kept`` values; on this side's row the CPU speed-up of
    the medians (``cpu_median_s``, a column) and ``same``: whether both sides' digests
    (``sha256``) agree."""
    rows = []
    for side in ("baseline", "this"):
        rs = runs[side]
        rows.append({"case": case["label"], "side": side, "repeats": len(rs),
                     **{k: f(rs) for k, f in columns.items()},
                     **{k: rs[-1][k] for k in kept}})
    base, this = rows
    this["cpu_speed-up"] = base["cpu_median_s"] / this["cpu_median_s"]
    this[same] = base["sha256"] == this["sha256"]
    return rows


def phase_main(argv, doc: str, stem: str, parse, cases_help: str, default_cases,
               repeats: int, summarise, table, worker: str) -> int:
    """The command of an A/B benchmark of one fem-3d phase (``--case`` parsed by ``parse``,
    ``default_cases`` without one, ``--repeats``, the sides' and ``--out``): runs ``worker``
    interleaved, prints ``table(rows)`` and writes ``DIR/stem.md`` and ``.json``."""
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    side_arguments(ap, f"{stem}.md/.json")
    ap.add_argument("--case", type=parse, action="append", help=cases_help)
    ap.add_argument("--repeats", type=int, default=repeats,
                    help=f"runs per side and case ({repeats})")
    args = ap.parse_args(argv)
    cases = args.case or [parse(c) for c in default_cases]
    sides = {"baseline": args.baseline.resolve(), "this": args.this.resolve()}
    rows, raw, load = interleaved(cases, sides, args.repeats, summarise, worker=worker)
    text = (table(rows) + f"\n\nrepeats {args.repeats} per side (interleaved ABBA); "
            + load_text(load) + "\n")
    print(text)
    write_results(args.out, stem, text, sides, rows, raw, load)
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    side_arguments(ap, "bench_ab.md/.json")
    ap.add_argument("--case", type=parse_case, action="append",
                    help="dense, fft:N, elastic-fft:N, optionally @tol, or "
                         "fem3d:PHI:MESH_SIZE (repeatable; default: dense)")
    ap.add_argument("--repeats", type=int, default=5, help="runs per side and case (5)")
    ap.add_argument("--warm", action="store_true", help="time a second solve per interpreter")
    ap.add_argument("--rounds", action="store_true",
                    help="every case in each repeat (the cases' ratios under one load); "
                         "with two floor:H cases, each side's ratio of their medians")
    args = ap.parse_args(argv)
    cases = args.case or [parse_case("dense")]
    sides = {"baseline": args.baseline.resolve(), "this": args.this.resolve()}
    rows, raw, load = interleaved(cases, sides, args.repeats, summarise, warm=args.warm,
                                  rounds=args.rounds)
    floors = [c["label"] for c in cases if c["label"].startswith("floor:")]
    ratio = "" if len(floors) != 2 else "\n\n" + case_ratios(rows, *floors)
    text = (table(rows) + ratio + f"\n\nrepeats {args.repeats} per side (interleaved ABBA"
            f"{', in rounds of every case' if args.rounds else ''}), "
            f"{'second (warm)' if args.warm else 'first (cold)'} solve per interpreter; "
            + load_text(load) + "\n")
    print(text)
    write_results(args.out, "bench_ab", text, sides, rows, raw, load, warm=args.warm)
    return 0


if __name__ == "__main__":
    sys.exit(main())
