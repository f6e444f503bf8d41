"""Benchmark of the FFT boundary-element solver: cells vs time vs memory, and a side-by-side run
against ContactMechanics (Polonsky-Keer CG on its free-boundary FFT half-space).

Run as ``python -m validation.bench.fft --out DIR`` (``make bench-fft``).  Each solve runs in
its own subprocess, so the peak resident memory (``ru_maxrss``) belongs to that solve alone.

The side-by-side problem is the same discrete problem for both codes: rigid pillars and a rigid
substrate (no Hooke term), the lens a half-space of compliance gamma_l, the same grid of square
cells (ours: pillar-top cells within the disk g(r) <= zeta; ContactMechanics: the same cells as
the unmasked points of a masked topography), Love's uniform-pressure cell kernel in both, and
the same tolerance on the gap (1e-8 zeta).  For that run our solver is called with
``edge_correction=False`` (edge cells loaded and collocated at their centres, exactly the
masked-grid problem); our default model, whose edge cells act as equivalent squares at their
centroids, runs on the same grid too and is reported beside it (its F_T differs from both by
its smaller discretisation error).  ContactMechanics is an optional benchmark extra
(``pip install -e '.[bench]'``); without it the comparison is skipped and the reason printed.
"""

from __future__ import annotations

import argparse
import json
import platform
import resource
import subprocess
import sys
import time
from pathlib import Path

SCENE = "paper-fig3-dense"
RIGID = ("pillars.rigid=true", "substrate.rigid=true", "substrate.nu=0.5")
SCALING_LEVELS = (8, 12, 16, 24, 32, 48, 64)
# 32 and 58 cells per diameter give bounding grids of 3.1e5 and 1.0e6 cells on this scene.
CM_LEVELS = (32, 58)
TOL = 1e-8


def _ours(scene_name, overrides, n, tol, edge_correction=True):
    from scenes import load_scene

    from bem_solver._fft import solve_fft

    scene = load_scene(scene_name, list(overrides))
    start = time.perf_counter()
    res = solve_fft(scene, n, tol=tol, edge_correction=edge_correction)
    wall = time.perf_counter() - start
    d = res.diagnostics
    name = "bem-fft" if edge_correction else "bem-fft-grid"
    return {"solver": name, "cells_per_diameter": n, "wall_time_s": wall,
            "iterations": res.iterations, "operator_applications": d["operator_applications"],
            # Nested iteration: work on the coarser levels (each 1/4 of the next one's cells).
            "warm_start_iterations": sum(v["iterations"] for v in d["warm_start_levels"]),
            "candidate_cells": d["candidate_cells"],
            "grid_cells": d["grid_shape"][0] * d["grid_shape"][1],
            "fft_shape": d["fft_shape"], "total_force_N": res.total_force_N,
            "converged": res.converged, "contact_residual": d["contact_residual"]}


def _contactmechanics(scene_name, overrides, n, tol):
    import numpy as np
    from ContactMechanics import FreeFFTElasticHalfSpace
    from ContactMechanics.Optimization import constrained_conjugate_gradients
    from SurfaceTopography import Topography

    from scenes import load_scene

    from bem_solver._fft_grid import build_grid
    from scenes.analytic import lens_gap

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
    start = time.perf_counter()
    # ContactMechanics' "young" is the contact modulus E* with u = (1 / (pi E*)) int p / r.
    substrate = FreeFFTElasticHalfSpace((ny, nx), 1.0 / scene.half_space_compliance,
                                        (ny * L, nx * L))
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


def _worker(spec: dict) -> dict:
    args = (spec["scene"], spec["overrides"], spec["n"], spec["tol"])
    if spec["solver"] == "contactmechanics":
        out = _contactmechanics(*args)
    else:
        out = _ours(*args, edge_correction=spec["solver"] == "bem-fft")
    # ru_maxrss is in KiB on Linux.
    out["peak_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    return out


def run_case(solver, scene, overrides, n, tol=TOL, timeout=1800) -> dict:
    """One solve in a fresh interpreter; returns its measurements or {'error': ...}."""
    spec = {"solver": solver, "scene": scene, "overrides": list(overrides), "n": n, "tol": tol}
    return run_worker("validation.bench.fft", spec, timeout)


def run_worker(module: str, spec: dict, timeout: float) -> dict:
    """``python -m module --worker SPEC`` in a fresh interpreter: the JSON it prints last, or
    ``{**spec, 'error': ...}`` (also used by validation.bench.gpu)."""
    try:
        proc = subprocess.run([sys.executable, "-m", module, "--worker", json.dumps(spec)],
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {**spec, "error": f"timed out after {timeout} s"}
    if proc.returncode != 0:
        tail = (proc.stderr.strip().splitlines() or ["?"])[-1]
        return {**spec, "error": tail}
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
    ap.add_argument("--levels", type=int, nargs="*", default=list(SCALING_LEVELS),
                    help="cells per diameter of the scaling study")
    ap.add_argument("--cm-levels", type=int, nargs="*", default=list(CM_LEVELS),
                    help="cells per diameter of the ContactMechanics comparison")
    ap.add_argument("--repeats", type=int, default=1, help="repeats of each timing (median)")
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.worker:
        print(json.dumps(_worker(json.loads(args.worker))))
        return 0
    scaling = []
    for n in args.levels:
        print(f"bench-fft: scaling N = {n}", file=sys.stderr, flush=True)
        scaling.append(_median(
            [run_case("bem-fft", SCENE, (), n) for _ in range(args.repeats)]))
    side = []
    reason = contactmechanics_available()
    if not reason:
        for n in args.cm_levels:
            for solver in ("bem-fft-grid", "contactmechanics", "bem-fft"):
                print(f"bench-fft: {solver} N = {n} (rigid pillars)", file=sys.stderr,
                      flush=True)
                side.append(_median(
                    [run_case(solver, SCENE, RIGID, n) for _ in range(args.repeats)]))
    meta = {"scene": SCENE, "side_by_side_overrides": list(RIGID), "tolerance": TOL,
            "python": platform.python_version(), "machine": platform.machine(),
            "contactmechanics_skipped": reason}
    table = write_report(args.out, scaling, side, meta)
    print(table)
    return 0


def write_report(out: Path, scaling: list, side: list, meta: dict) -> str:
    """Write bench_fft.json and bench_fft.png into ``out``; return the printed table."""
    from outcome import write_atomic

    lines = ["scaling (bem-fft, scene %s, elastic pillars)" % meta["scene"],
             f"{'N':>4} {'cells':>9} {'grid':>9} {'time s':>8} {'iter':>5} {'FFTs':>5} "
             f"{'RSS MB':>7} {'F_T N':>12}"]
    for r in scaling:
        if "error" in r:
            lines.append(f"{r['n']:>4} error: {r['error']}")
            continue
        lines.append(f"{r['cells_per_diameter']:>4} {r['candidate_cells']:>9} "
                     f"{r['grid_cells']:>9} {r['wall_time_s']:>8.2f} {r['iterations']:>5} "
                     f"{r['operator_applications']:>5} {r['peak_rss_MB']:>7.0f} "
                     f"{r['total_force_N']:>12.6e}")
    lines.append("")
    comparison = _pairs(side)
    if meta["contactmechanics_skipped"]:
        lines.append("ContactMechanics comparison skipped: " + meta["contactmechanics_skipped"])
    else:
        lines.append("side by side (rigid pillars and substrate, same grid and equations, "
                     "tol 1e-8 zeta); ours = bem-fft with edge_correction=False; "
                     "iterations ours = fine + coarser warm-start levels")
        lines.append(f"{'N':>4} {'grid':>9} {'ours s':>8} {'CM s':>8} {'ratio':>6} "
                     f"{'it ours':>7} {'it CM':>6} {'FFT ours':>8} {'FFT CM':>6} "
                     f"{'RSS ours':>8} {'RSS CM':>7} {'dF_T rel':>9} "
                     f"{'default s':>9} {'dF_T def':>9}")
        for c in comparison:
            if "error" in c:
                lines.append(f"{c['cells_per_diameter']:>4} error: {c['error']}")
                continue
            lines.append(
                f"{c['cells_per_diameter']:>4} {c['grid_cells']:>9} {c['ours_s']:>8.2f} "
                f"{c['cm_s']:>8.2f} {c['time_ratio_cm_over_ours']:>6.2f} "
                f"{c['ours_iterations']:>7} {c['cm_iterations']:>6} {c['ours_ffts']:>8} "
                f"{c['cm_ffts']:>6} {c['ours_rss_MB']:>8.0f} {c['cm_rss_MB']:>7.0f} "
                f"{c['force_rel_diff']:>9.1e} "
                + (f"{c['default_s']:>9.2f} {c['default_force_rel_diff']:>9.1e}"
                   if c["default_s"] is not None else ""))
    table = "\n".join(lines)
    doc = {"meta": meta, "scaling": scaling, "side_by_side": side, "comparison": comparison,
           "table": table}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "bench_fft.json", json.dumps(doc, indent=2, allow_nan=False))
    _plot(out / "bench_fft.png", scaling, side)
    return table


def _pairs(side: list) -> list:
    """Match our run and ContactMechanics' at each level."""
    out = []
    levels = sorted({r.get("cells_per_diameter", r.get("n")) for r in side})
    for n in levels:
        rows = {r.get("solver"): r for r in side if r.get("cells_per_diameter", r.get("n")) == n}
        ours, cm = rows.get("bem-fft-grid"), rows.get("contactmechanics")
        default = rows.get("bem-fft") or {}
        if ours is None or cm is None or "error" in ours or "error" in cm:
            bad = ours if ours is None or "error" in ours else cm
            out.append({"cells_per_diameter": n,
                        "error": (bad or {}).get("error", "missing run")})
            continue
        out.append({
            "cells_per_diameter": n, "grid_cells": ours["grid_cells"],
            "candidate_cells": ours["candidate_cells"],
            "ours_s": ours["wall_time_s"], "cm_s": cm["wall_time_s"],
            "time_ratio_cm_over_ours": cm["wall_time_s"] / ours["wall_time_s"],
            "ours_iterations": f"{ours['iterations']}+{ours.get('warm_start_iterations', 0)}",
            "cm_iterations": cm["iterations"],
            "ours_ffts": ours["operator_applications"], "cm_ffts": cm["operator_applications"],
            "ours_rss_MB": ours["peak_rss_MB"], "cm_rss_MB": cm["peak_rss_MB"],
            "ours_force_N": ours["total_force_N"], "cm_force_N": cm["total_force_N"],
            "force_rel_diff": (ours["total_force_N"] - cm["total_force_N"])
            / abs(cm["total_force_N"]),
            "both_converged": bool(ours["converged"] and cm["converged"]),
            # Our default model (edge cells as equivalent squares) on the same grid: a
            # different, more accurate discretisation, so F_T differs at the O(L) level.
            "default_s": default.get("wall_time_s"),
            "default_force_rel_diff": (default["total_force_N"] - cm["total_force_N"])
            / abs(cm["total_force_N"]) if "total_force_N" in default else None})
    return out


def _plot(path: Path, scaling: list, side: list) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_t, ax_m) = plt.subplots(1, 2, figsize=(10, 4))
    ok = [r for r in scaling if "error" not in r]
    cells = [r["grid_cells"] for r in ok]
    ax_t.loglog(cells, [r["wall_time_s"] for r in ok], "o-", label="bem-fft (elastic)")
    ax_m.loglog(cells, [r["peak_rss_MB"] for r in ok], "o-", label="bem-fft (elastic)")
    for solver, mark in (("bem-fft-grid", "s"), ("contactmechanics", "^"),
                         ("bem-fft", "d")):
        rows = [r for r in side if r.get("solver") == solver and "error" not in r]
        if rows:
            label = f"{solver} (rigid, side by side)"
            ax_t.loglog([r["grid_cells"] for r in rows], [r["wall_time_s"] for r in rows],
                        mark + "--", label=label)
            ax_m.loglog([r["grid_cells"] for r in rows], [r["peak_rss_MB"] for r in rows],
                        mark + "--", label=label)
    ax_t.set(xlabel="grid cells", ylabel="wall time (s)", title="time")
    ax_m.set(xlabel="grid cells", ylabel="peak RSS (MB)", title="memory")
    for ax in (ax_t, ax_m):
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
