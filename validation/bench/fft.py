"""Benchmark of the FFT boundary-element model against its floor and its peer
(``python -m validation.bench.fft --out DIR``, ``make bench-fft``).

Side by side with ContactMechanics (Polonsky-Keer CG on its free-boundary FFT half-space), on
the same discrete problem: paper-fig3-dense (Phi = 0.82), a rigid substrate, the lens a
half-space of compliance gamma_l, the same grid of square cells (ours: pillar-top cells within
the disk g(r) <= zeta; ContactMechanics: the same cells as the unmasked points of a masked
topography), Love's uniform-pressure cell kernel in both, and the same tolerance on the gap
(1e-8 zeta).  Two pillar cases: rigid pillars, and elastic pillars as Hooke springs (the
preset's E_p, c = 4 h / (pi d^2 E_p) per pillar), given to ContactMechanics as a substrate
whose displacement adds c times each pillar's force to its cells (its CG is unchanged).  Our
solver runs with ``edge_correction=False`` (edge cells loaded and collocated at their
centres: exactly the masked-grid problem); our default model (edge cells as equivalent
squares at their centroids) runs on the same grid too and is reported beside it (its F_T
differs by its smaller discretisation error), and so does the same solver in float64
throughout (``precision="double"``: the model before mixed precision), so that before and
after come from one run.

For each case: grid cells; our CG iterations on the finest grid (and on the coarser
warm-start levels); our time per fine iteration against the floor, the bare FFT pair
(scipy.fft rfft2 + irfft2, on the solver's threads) on our padded grid timed in the same process before and
after the solve, as scipy.fft's own calls (fresh output arrays, page faults included) and as
the same transforms into kept arrays (the transforms' work alone, as the solver runs them);
convolutions per fine iteration; our wall time and ContactMechanics', their ratio, ContactMechanics' iterations and
the relative difference of F_T.  Each solve runs in a fresh interpreter (its peak resident
memory is its own); the repeats are interleaved (ours, peer, default model at every level, then
again) and every column is the median over the repeats.  Prints the table and writes it with
the runs to ``bench_fft.json`` and ``bench_fft.md``.  ContactMechanics is the optional
``[bench]`` extra (``pip install -e '.[bench]'``); without it the peer's columns are skipped and
the reason printed.  ``--scaling`` adds our default model alone over a ladder of grids.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

from validation.bench import median_time

SCENE = "paper-fig3-dense"
PILLARS = {
    "rigid": ("pillars.rigid=true", "substrate.rigid=true", "substrate.nu=0.5"),
    "elastic": ("substrate.rigid=true", "substrate.nu=0.5"),
}
SCALING_LEVELS = (8, 12, 16, 24, 32, 48, 64)
# 32 and 58 cells per diameter give bounding grids of 3.1e5 and 1.0e6 cells on this scene.
CM_LEVELS = (32, 58)
TOL = 1e-8
FLOOR_REPEATS = 7


def fft_floor(shape, workers=None, repeats=FLOOR_REPEATS) -> float:
    """Median wall time (s) of the bare FFT pair, rfft2 then irfft2 with scipy.fft on a float64
    array of ``shape``: what one convolution on that padded grid cannot go below.  scipy.fft
    returns fresh arrays: on grids of 1e6 points each call page-faults some 30-60 MB in,
    which this time includes (see :func:`fft_floor_kept`).  ``workers``: the solver's own
    (:func:`pillar_xval.threads.thread_count`) unless given."""
    import numpy as np
    import scipy.fft as sfft

    from pillar_xval.threads import thread_count

    workers = thread_count() if workers is None else workers

    a = np.random.default_rng(0).random(tuple(shape))

    def pair():
        sfft.irfft2(sfft.rfft2(a, workers=workers), s=a.shape, workers=workers)

    pair()  # warm-up
    return median_time(pair, repeats)[0]


def fft_floor_kept(shape, workers=None, repeats=FLOOR_REPEATS) -> float | None:
    """The same pair as :func:`fft_floor` (the same pocketfft transforms scipy.fft runs, its
    default norm) written into arrays kept between calls: the transforms' own work, without
    the page faults of fresh arrays, as the solver runs them.  None where scipy's layout
    lacks the kernels."""
    import numpy as np

    from pillar_xval.threads import thread_count

    try:
        from scipy.fft._pocketfft import pypocketfft as pocketfft
    except ImportError:
        return None
    workers = thread_count() if workers is None else workers
    ny, nx = (int(v) for v in shape)
    a = np.random.default_rng(0).random((ny, nx))
    spec = np.empty((ny, nx // 2 + 1), dtype=np.complex128)
    out = np.empty((ny, nx))

    def pair():
        pocketfft.r2c(a, (0, 1), True, 0, spec, workers)
        pocketfft.c2r(spec, (0, 1), nx, False, 2, out, workers)

    pair()  # warm-up
    return median_time(pair, repeats)[0]


def _ours(scene_name, overrides, n, tol, edge_correction=True, precision="mixed"):
    from pillar_xval.scenes import load_scene

    from bem_solver._fft import solve_fft

    from bem_solver._fft_grid import build_grid
    from bem_solver._fft_operator import padded_length
    from bem_solver._xp import NumpyDevice

    scene = load_scene(scene_name, list(overrides))
    # The floors are timed before and after the solve (the machine's load moves).
    ny, nx = build_grid(scene, n).shape
    fast = NumpyDevice().next_fast_len  # the plan's own choice of lengths
    padded = (padded_length(ny, fast), padded_length(nx, fast))
    before = (fft_floor(padded), fft_floor_kept(padded))
    start = time.perf_counter()
    res = solve_fft(scene, n, tol=tol, edge_correction=edge_correction,
                    precision=precision)
    wall = time.perf_counter() - start
    d = res.diagnostics
    after = (fft_floor(d["fft_shape"]), fft_floor_kept(d["fft_shape"]))
    floor = statistics.median([before[0], after[0]])
    kept = None if before[1] is None else statistics.median([before[1], after[1]])
    name = ("bem-fft" if edge_correction else "bem-fft-grid") \
        + ("-double" if precision == "double" else "")
    solve = d["timings_s"]["solve"]
    return {"solver": name, "cells_per_diameter": n, "wall_time_s": wall,
            "iterations": res.iterations, "operator_applications": d["operator_applications"],
            # Nested iteration: work on the coarser levels (each 1/4 of the next one's cells).
            "warm_start_iterations": sum(v["iterations"] for v in d["warm_start_levels"]),
            "timings_s": d["timings_s"], "candidate_cells": d["candidate_cells"],
            "grid_cells": d["grid_shape"][0] * d["grid_shape"][1],
            "fft_shape": d["fft_shape"], "total_force_N": res.total_force_N,
            "converged": res.converged, "contact_residual": d["contact_residual"],
            "preconditioner": d["preconditioner"],
            "time_per_iteration_s": solve / max(res.iterations, 1),
            "time_per_application_s": solve / max(d["operator_applications"], 1),
            "fft_pair_s": floor, "fft_pair_kept_s": kept}


def _contactmechanics(scene_name, overrides, n, tol):
    import numpy as np
    from ContactMechanics import FreeFFTElasticHalfSpace
    from ContactMechanics.Optimization import constrained_conjugate_gradients
    from SurfaceTopography import Topography

    from pillar_xval.scenes import load_scene

    from bem_solver._fft_grid import build_grid
    from pillar_xval.scenes.analytic import lens_gap

    scene = load_scene(scene_name, list(overrides))
    grid = build_grid(scene, n)  # the same cells; setup time excluded for both codes' grids
    ny, nx = grid.shape
    L = grid.cell_size
    zeta = scene.indentation_m
    heights = np.zeros(ny * nx)
    outside = np.ones(ny * nx, dtype=bool)
    # Rigid lens surface -g(r) at the cell centres (the collocation points of both codes here).
    heights[grid.flat_index] = -lens_gap(scene.lens.radius_m, np.hypot(grid.x, grid.y))
    outside[grid.flat_index] = False
    masked = np.ma.masked_array(heights.reshape(ny, nx), mask=outside.reshape(ny, nx))
    spring = scene.pillar_spring_compliance  # m/N; 0 for rigid pillars
    owner = np.full(ny * nx, -1)
    owner[grid.flat_index] = grid.pillar
    start = time.perf_counter()
    # ContactMechanics' "young" is the contact modulus E* with u = (1 / (pi E*)) int p / r.
    args = ((ny, nx), 1.0 / scene.half_space_compliance, (ny * L, nx * L))
    substrate = FreeFFTElasticHalfSpace(*args)
    if spring > 0.0:
        _add_hooke_term(substrate, owner, spring, (ny, nx))
    topography = Topography(masked, physical_sizes=(ny * L, nx * L))
    # Forces: tolerate a tensile pixel force of tol times a mean contact pixel force
    # (F ~ d zeta / gamma per pillar over ~ (d/L)^2 cells).
    pixel_force = zeta * L / scene.half_space_compliance
    res = constrained_conjugate_gradients(substrate, topography, offset=zeta,
                                          pentol=tol * zeta, forcetol=tol * pixel_force,
                                          thermotol=tol, maxiter=20000)
    wall = time.perf_counter() - start
    return {"solver": "contactmechanics", "cells_per_diameter": n, "wall_time_s": wall,
            "iterations": int(res.nit), "operator_applications": int(res.nfev),
            "candidate_cells": grid.n_cells, "grid_cells": ny * nx,
            "total_force_N": float(np.sum(res.jac)), "converged": bool(res.success)}


def _add_hooke_term(substrate, owner, spring, shape):
    """Give ContactMechanics' free-boundary half-space the Hooke shortening of each pillar:
    u = (half-space) + spring * (force on the cell's pillar) on the pillar cells (our
    operator's Hooke term; ``owner`` is the pillar index of each point of the (ny, nx) grid,
    -1 off the tops).  Its CG passes arrays on the padded grid, the physical one in the
    corner [:ny, :nx].  (An instance attribute: the class checks its own exact type.)"""
    import numpy as np

    ny, nx = shape
    on_top = (owner >= 0).reshape(ny, nx)
    labels = owner[owner >= 0]
    n_pillars = int(labels.max()) + 1 if labels.size else 0
    half_space = substrate.evaluate_disp

    def evaluate_disp(forces, *args, **kwargs):
        disp = half_space(forces, *args, **kwargs)
        f = -np.asarray(forces)[:ny, :nx][on_top]  # its convention: u = K(-forces)
        shortening = spring * np.bincount(labels, weights=f, minlength=n_pillars)
        disp[:ny, :nx][on_top] += shortening[labels]
        return disp

    substrate.evaluate_disp = evaluate_disp
    return substrate


def _worker(spec: dict) -> dict:
    args = (spec["scene"], spec["overrides"], spec["n"], spec["tol"])
    if spec["solver"] == "contactmechanics":
        out = _contactmechanics(*args)
    else:
        out = _ours(*args, edge_correction=spec["solver"] == "bem-fft",
                    precision="double" if spec["solver"].endswith("-double") else "mixed")
    # ru_maxrss is in KiB on Linux.
    out["peak_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    out["pillars"] = spec.get("pillars")
    return out


def run_case(solver, scene, overrides, n, tol=TOL, timeout=3600, pillars=None) -> dict:
    """One solve in a fresh interpreter; returns its measurements or {'error': ...}."""
    spec = {"solver": solver, "scene": scene, "overrides": list(overrides), "n": n, "tol": tol,
            "pillars": pillars}
    return run_worker("validation.bench.fft", spec, timeout)


# Characters of a failed worker's stderr kept in its record (its traceback, for the report).
STDERR_KEPT = 3000


def run_worker(module: str, spec: dict, timeout: float, cwd=None) -> dict:
    """``python -m module --worker SPEC`` in a fresh interpreter (in ``cwd``: another
    checkout's module), the JSON it prints last, or ``{**spec, 'error': ...}`` (also used by
    validation.bench.gpu and .threads)."""
    try:
        proc = subprocess.run([sys.executable, "-m", module, "--worker", json.dumps(spec)],
                              capture_output=True, text=True, timeout=timeout, cwd=cwd)
    except subprocess.TimeoutExpired:
        return {**spec, "error": f"timed out after {timeout} s"}
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return {**spec, "error": tail, "stderr_tail": proc.stderr[-STDERR_KEPT:]}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def contactmechanics_available() -> str:
    """'' when ContactMechanics imports, else the reason."""
    try:
        import ContactMechanics  # noqa: F401
        from ContactMechanics import FreeFFTElasticHalfSpace  # noqa: F401
    except Exception as exc:  # any import failure is a reason to skip, reported verbatim
        return f"ContactMechanics not importable ({type(exc).__name__}: {exc}); " \
               "install the optional extra: pip install -e '.[bench]'"
    return ""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m validation.bench.fft", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", type=Path, default=Path("out/bench-fft"))
    ap.add_argument("--cm-levels", type=int, nargs="*", default=list(CM_LEVELS),
                    help="cells per diameter of the side-by-side table (default 32 58)")
    ap.add_argument("--pillars", nargs="*", default=list(PILLARS), choices=list(PILLARS),
                    help="pillar cases of the side-by-side table (default rigid elastic)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="interleaved repeats of every run; columns are medians (default 3)")
    ap.add_argument("--levels", type=int, nargs="*", default=[],
                    help="cells per diameter of an optional scaling study of our default "
                         f"model alone (e.g. {' '.join(map(str, SCALING_LEVELS))})")
    ap.add_argument("--no-peer", action="store_true",
                    help="leave ContactMechanics out (our columns and the floors only: a "
                         "minute instead of half an hour)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(_worker(json.loads(args.worker))))
        return 0
    reason = "left out (--no-peer)" if args.no_peer else contactmechanics_available()
    solvers = ["bem-fft-grid"] + ([] if reason else ["contactmechanics"]) + ["bem-fft"] \
        + ["bem-fft-grid-double"]
    runs = []
    for rep in range(args.repeats):
        for n in args.cm_levels:
            for pillars in args.pillars:
                for solver in solvers:
                    print(f"bench-fft: repeat {rep + 1}/{args.repeats}: {solver} N = {n} "
                          f"({pillars} pillars)", file=sys.stderr, flush=True)
                    runs.append(run_case(solver, SCENE, PILLARS[pillars], n, pillars=pillars))
    scaling = []
    for n in args.levels:
        print(f"bench-fft: scaling N = {n}", file=sys.stderr, flush=True)
        scaling.append(_median([run_case("bem-fft", SCENE, (), n, pillars="preset")
                                for _ in range(args.repeats)]))
    meta = {"scene": SCENE, "pillars": {k: list(PILLARS[k]) for k in args.pillars},
            "tolerance": TOL, "repeats": args.repeats, "fft_workers": _threads(),
            "python": platform.python_version(), "machine": platform.machine(),
            "load_average": _load(), "contactmechanics": _version("contactmechanics"),
            "contactmechanics_skipped": reason}
    table = write_report(args.out, runs, scaling, meta)
    print(table)
    return 0


def _threads() -> int:
    from pillar_xval.threads import thread_count

    return thread_count()


def _load() -> list:
    import os

    return [round(v, 2) for v in os.getloadavg()]


def _version(dist: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(dist)
    except PackageNotFoundError:
        return ""


def side_by_side(runs: list) -> list:
    """One row per (pillars, N): medians over the repeats of every column; the ratio of the
    peer's time to ours is the median of the ratios of runs made in the same repeat."""
    rows = []
    keys = sorted({(r.get("pillars"), r.get("cells_per_diameter", r.get("n"))) for r in runs},
                  key=lambda k: (k[1], str(k[0])))
    for pillars, n in keys:
        mine = [r for r in runs if r.get("pillars") == pillars
                and r.get("cells_per_diameter", r.get("n")) == n]

        def ok(solver):
            return [r for r in mine if r.get("solver") == solver and "error" not in r]

        ours, cm, default = ok("bem-fft-grid"), ok("contactmechanics"), ok("bem-fft")
        double = ok("bem-fft-grid-double")
        errors = [f"{r['solver']}: {r['error']}" for r in mine if "error" in r]
        row = {"pillars": pillars, "cells_per_diameter": n, "errors": errors}
        if ours:
            row.update(_our_columns(ours, ""))
        if default:
            row.update(_our_columns(default, "default_"))
        if double:
            row.update(_our_columns(double, "double_"))
            if ours:
                row["double_over_mixed"] = statistics.median(
                    d["time_per_iteration_s"] / o["time_per_iteration_s"]
                    for o, d in zip(ours, double))
        if cm:
            row.update({"cm_s": _med(cm, "wall_time_s"), "cm_iterations": _med(cm, "iterations"),
                        "cm_applications": _med(cm, "operator_applications"),
                        "cm_rss_MB": _med(cm, "peak_rss_MB"),
                        "cm_force_N": cm[0]["total_force_N"],
                        "cm_converged": all(r["converged"] for r in cm)})
        if ours and cm:
            pairs = list(zip(ours, cm))  # same order: one of each per repeat
            row["ratio_cm_over_ours"] = statistics.median(
                c["wall_time_s"] / o["wall_time_s"] for o, c in pairs)
            row["force_rel_diff"] = (row["total_force_N"] - row["cm_force_N"]) \
                / abs(row["cm_force_N"])
        if default and cm:
            row["default_ratio_cm_over_ours"] = statistics.median(
                c["wall_time_s"] / o["wall_time_s"] for o, c in zip(default, cm))
            row["default_force_rel_diff"] = (row["default_total_force_N"] - row["cm_force_N"]) \
                / abs(row["cm_force_N"])
        rows.append(row)
    return rows


def _med(runs, key):
    return statistics.median(r[key] for r in runs)


def _our_columns(runs: list, prefix: str) -> dict:
    first = runs[0]
    return {prefix + k: v for k, v in {
        "grid_cells": first["grid_cells"], "candidate_cells": first["candidate_cells"],
        "fft_shape": first["fft_shape"], "iterations": _med(runs, "iterations"),
        "warm_start_iterations": _med(runs, "warm_start_iterations"),
        "operator_applications": _med(runs, "operator_applications"),
        "wall_time_s": _med(runs, "wall_time_s"),
        "solve_s": statistics.median(r["timings_s"]["solve"] for r in runs),
        "time_per_iteration_s": _med(runs, "time_per_iteration_s"),
        "time_per_application_s": _med(runs, "time_per_application_s"),
        "fft_pair_s": _med(runs, "fft_pair_s"),
        # Each run's time per iteration over the floors timed in the same process.
        "iteration_over_fft_pair": statistics.median(
            r["time_per_iteration_s"] / r["fft_pair_s"] for r in runs),
        # Convolutions per fine iteration: one for the step, one more for a step that clips
        # more pressures than the kernel table updates directly, and the float64 refreshes
        # of the gap (mixed precision: about two a solve).
        "applications_per_iteration": statistics.median(
            r["operator_applications"] / max(r["iterations"], 1) for r in runs),
        **_kept_columns(runs),
        "rss_MB": _med(runs, "peak_rss_MB"), "total_force_N": first["total_force_N"],
        "converged": all(r["converged"] for r in runs),
        "wall_times_s": [r["wall_time_s"] for r in runs]}.items()}


def _kept_columns(runs: list) -> dict:
    kept = [r for r in runs if r.get("fft_pair_kept_s")]
    if not kept:
        return {}
    return {"fft_pair_kept_s": _med(kept, "fft_pair_kept_s"),
            "iteration_over_kept_pair": statistics.median(
                r["time_per_iteration_s"] / r["fft_pair_kept_s"] for r in kept)}


def format_table(rows: list, meta: dict) -> str:
    """The side-by-side table (markdown)."""
    peer = not meta["contactmechanics_skipped"]
    lines = ["FFT model (edge_correction=False) against the FFT pair floor"
             + (" and ContactMechanics " + meta["contactmechanics"] if peer else "")
             + f": {meta['scene']}, rigid substrate, same grid and equations, tol "
             f"{meta['tolerance']:g} zeta; medians of {meta['repeats']} interleaved runs; "
             f"load average {meta['load_average']}",
             "",
             "| pillars | cells | it ours (fine + coarse) | ms/it | conv/it | FFT pair ms, "
             "fresh / kept (padded) | it / pair, fresh / kept | ours s | CM it | CM s | "
             "CM / ours | F_T ours vs CM | default model s (it) | float64 ms/it (/ pair), s |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]

    def f(row, key, fmt, missing="-"):
        v = row.get(key)
        return missing if v is None else format(v, fmt)

    for r in rows:
        if "iterations" not in r:
            lines.append(f"| {r['pillars']} | N = {r['cells_per_diameter']} | error: "
                         + "; ".join(r["errors"]) + " |")
            continue
        shape = "x".join(str(v) for v in r["fft_shape"])
        kept = "-" if r.get("fft_pair_kept_s") is None else f"{1e3 * r['fft_pair_kept_s']:.1f}"
        lines.append(
            f"| {r['pillars']} | {r['grid_cells']:.2e} (d/{r['cells_per_diameter']}) | "
            f"{r['iterations']:g} + {r['warm_start_iterations']:g} | "
            f"{1e3 * r['time_per_iteration_s']:.1f} | "
            f"{f(r, 'applications_per_iteration', '.2f')} | "
            f"{1e3 * r['fft_pair_s']:.1f} / {kept} ({shape}) | "
            f"{r['iteration_over_fft_pair']:.2f} / {f(r, 'iteration_over_kept_pair', '.2f')} | "
            f"{r['wall_time_s']:.2f} | "
            f"{f(r, 'cm_iterations', 'g')} | {f(r, 'cm_s', '.2f')} | "
            f"{f(r, 'ratio_cm_over_ours', '.1f')}{'x' if 'ratio_cm_over_ours' in r else ''} | "
            f"{f(r, 'force_rel_diff', '.1e')} | {f(r, 'default_wall_time_s', '.2f')} "
            f"({f(r, 'default_iterations', 'g')}) | {_double_cell(r)} |")
        if r["errors"]:
            lines.append("|  | errors: " + "; ".join(r["errors"]) + " |")
    if not peer:
        lines.append("")
        lines.append("ContactMechanics comparison skipped: " + meta["contactmechanics_skipped"])
    lines += ["", "it ours: CG iterations on the finest grid + on the coarser warm-start levels "
              "(each a quarter of the next one's cells); ms/it: the finest level's solve time "
              "over its iterations (operator applications, preconditioner and CG vector work); "
              "conv/it: convolutions per fine iteration (one for the step, one more after a "
              "step that clips more pressures than the kernel table updates directly, and the "
              "float64 refreshes of the gap); "
              f"FFT pair: rfft2 + irfft2 (scipy.fft, {meta.get('fft_workers', '?')} workers) "
              "on our padded grid, timed in the same process before and after the solve (median of 2 x 7), fresh: scipy.fft's "
              "own calls, which page-fault their fresh output arrays in, kept: the same "
              "transforms into arrays kept between calls, as the solver runs them; ours s: the "
              "whole solve_fft call (grid, kernel table, "
              "warm-start levels, solve); CM s: from its substrate's construction on (the "
              "grid built before); CM / ours: median of the "
              "per-repeat ratios; default model: edge cells as equivalent squares (a different "
              "discretisation, F_T not comparable at 1e-8); float64: our solver with "
              "precision='double' (every FFT in float64, the model before mixed precision), "
              "its time per iteration, that over the fresh pair, and its wall time."]
    return "\n".join(lines)


def _double_cell(r: dict) -> str:
    if "double_time_per_iteration_s" not in r:
        return "-"
    return (f"{1e3 * r['double_time_per_iteration_s']:.1f} "
            f"({r['double_iteration_over_fft_pair']:.2f}), {r['double_wall_time_s']:.2f}")


def write_report(out: Path, runs: list, scaling: list, meta: dict) -> str:
    """Write bench_fft.json, bench_fft.md and bench_fft.png into ``out``; return the table."""
    from pillar_xval.outcome import write_atomic

    rows = side_by_side(runs)
    table = format_table(rows, meta)
    if scaling:
        table += "\n\nscaling (bem-fft default model, preset pillars)\n" + "\n".join(
            f"N = {r['cells_per_diameter']:>3}: {r['grid_cells']:>9} grid cells, "
            f"{r['wall_time_s']:7.2f} s, {r['iterations']} + {r['warm_start_iterations']} "
            f"iterations, {1e3 * r['time_per_iteration_s']:.1f} ms/it, FFT pair "
            f"{1e3 * r['fft_pair_s']:.1f} ms, {r['peak_rss_MB']:.0f} MB"
            if "error" not in r else f"N = {r.get('n')}: error: {r['error']}"
            for r in scaling)
    doc = {"meta": meta, "side_by_side": rows, "runs": runs, "scaling": scaling,
           "table": table}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "bench_fft.json", json.dumps(doc, indent=2, allow_nan=False))
    write_atomic(out / "bench_fft.md", table + "\n")
    _plot(out / "bench_fft.png", rows)
    return table


def _plot(path: Path, rows: list) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_t, ax_i) = plt.subplots(1, 2, figsize=(10, 4))
    for pillars, mark in (("rigid", "o"), ("elastic", "s")):
        sel = [r for r in rows if r["pillars"] == pillars and "iterations" in r]
        if not sel:
            continue
        cells = [r["grid_cells"] for r in sel]
        ax_t.loglog(cells, [r["wall_time_s"] for r in sel], mark + "-",
                    label=f"ours ({pillars})")
        ax_i.loglog(cells, [r["iterations"] for r in sel], mark + "-",
                    label=f"ours ({pillars})")
        peer = [r for r in sel if "cm_s" in r]
        if peer:
            ax_t.loglog([r["grid_cells"] for r in peer], [r["cm_s"] for r in peer],
                        mark + "--", label=f"ContactMechanics ({pillars})")
            ax_i.loglog([r["grid_cells"] for r in peer], [r["cm_iterations"] for r in peer],
                        mark + "--", label=f"ContactMechanics ({pillars})")
    ax_t.set(xlabel="grid cells", ylabel="wall time (s)", title="time")
    ax_i.set(xlabel="grid cells", ylabel="CG iterations", title="iterations")
    for ax in (ax_t, ax_i):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    from validation.output.report import save_figure

    save_figure(fig, path, 120)


def _median(runs: list[dict]) -> dict:
    ok = [r for r in runs if "error" not in r]
    if not ok:
        return runs[0]
    ok.sort(key=lambda r: r["wall_time_s"])
    best = dict(ok[len(ok) // 2])
    best["repeats"] = len(ok)
    return best


if __name__ == "__main__":
    sys.exit(main())
