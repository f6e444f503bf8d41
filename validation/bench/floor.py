"""The floor between the pillars in bem-fft: its cost, its convergence and a peer code.

``python -m validation.bench.floor --out DIR [--only perf,convergence,peer] [--repeats 3]``

- perf: on one FFT grid (rigid pillars, the same lens, pitch, cells and box), a mixed solve
  (h = 1 um, the floor touched) against a suspended one (h = 20 um: the floor out of reach,
  the same pillar-top cells), timed alternately, medians of ``--repeats`` runs with the load average
  beside them; then the iterations against the floor's share of the load over a rising
  indentation.
- convergence: the floor force, floor contact area and radius (and F_T) over N = 8, 16, 32,
  64 on one mixed scene: observed order and GCI (:func:`validation.analysis.verification.study`).
- peer: ContactMechanics (the ``[bench]`` extra) on the same cells with the floor in its
  topography (heights -g on the pillar tops, -(g + h) on the floor, no mask), the same
  physics as the Hooke BEM with rigid pillars, on two scenes at two resolutions: F_T, the
  floor force and the floor contact area.

Writes ``bench_floor.json`` and ``bench_floor.md`` in DIR (each part as it finishes).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import time
from pathlib import Path

import numpy as np

from pillar_xval.outcome._files import write_atomic

PARTS = ("perf", "convergence", "peer")
# Rigid pillars on an elastic substrate and lens (the paper's moduli), d = 4 um.
BASE = ["pillars.rigid=true", "substrate.E_Pa=1.6e6", "substrate.nu=0.5"]
# perf: 1.0e6 candidate cells at N = 36 with the floor touched (R = 1 mm, Phi = 0.03, 3 um,
# h = 1 um); the suspended solve (h = 20 um) has the same tops and the same FFT box (both
# set by the lens's reach sqrt(2 R zeta)), without floor cells.
PERF_SCENE = BASE + ["lens.radius_mm=1", "pillars.surface_fraction=0.03",
                     "load.indentation_um=3"]
PERF_N = 36
PERF_HEIGHTS_UM = (1.0, 20.0)  # mixed, suspended
SHARE_ZETAS_UM = (1.1, 1.5, 2.0, 3.0, 4.0)
SHARE_N = 12
CONV_SCENE = BASE + ["lens.radius_mm=0.2", "pillars.surface_fraction=0.03",
                     "pillars.height_um=1", "load.indentation_um=2"]
CONV_LEVELS = (8, 16, 32, 64)
PEER_SCENES = {  # both with floor contact (at Phi = 0.1 and zeta = 2 h the lens is suspended)
    "Phi = 0.03, h/d = 0.25, zeta = 2 h": BASE + [
        "lens.radius_mm=0.2", "pillars.surface_fraction=0.03", "pillars.height_um=1",
        "load.indentation_um=2"],
    "Phi = 0.1, h/d = 0.25, zeta = 6 h": BASE + [
        "lens.radius_mm=0.2", "pillars.surface_fraction=0.1", "pillars.height_um=1",
        "load.indentation_um=6"],
}
PEER_LEVELS = (8, 16)
TOL = 1e-8


def _scene(overrides):
    from pillar_xval.scenes import load_scene

    return load_scene("paper-fig3-sparse", list(overrides))


def _solve(overrides, n, **kw):
    from bem_solver._fft import solve_fft

    start = time.perf_counter()
    r = solve_fft(_scene(overrides), n, tol=TOL, **kw)
    return r, time.perf_counter() - start


def perf(repeats: int) -> dict:
    """Mixed against suspended on one grid, alternately; iterations against the floor's share."""
    runs = {h: [] for h in PERF_HEIGHTS_UM}
    info = {}
    for _ in range(repeats):
        for h in PERF_HEIGHTS_UM:
            r, wall = _solve(PERF_SCENE + [f"pillars.height_um={h}"], PERF_N)
            runs[h].append(wall)
            info[h] = {"cells": r.discretisation["cells"], "iterations": r.iterations,
                       "floor_cells": r.diagnostics.get("floor_cells", 0),
                       "floor_share": r.floor_force_N / r.total_force_N,
                       "converged": r.converged, "regime": r.regime,
                       "left_out_floor_cells": r.diagnostics.get("left_out_floor_cells", 0),
                       "warm_start_iterations": sum(v["iterations"] for v in
                                                    r.diagnostics["warm_start_levels"])}
    mixed, suspended = PERF_HEIGHTS_UM
    out = {"scene": PERF_SCENE, "cells_per_diameter": PERF_N, "repeats": repeats,
           "load_average": os.getloadavg()[0],
           "mixed": {**info[mixed], "wall_s": runs[mixed],
                     "median_s": statistics.median(runs[mixed])},
           "suspended": {**info[suspended], "wall_s": runs[suspended],
                         "median_s": statistics.median(runs[suspended])}}
    out["ratio"] = out["mixed"]["median_s"] / out["suspended"]["median_s"]
    share = []
    for zeta in SHARE_ZETAS_UM:
        r, wall = _solve(BASE + ["lens.radius_mm=0.5", "pillars.surface_fraction=0.03",
                                 "pillars.height_um=1", f"load.indentation_um={zeta}"],
                         SHARE_N)
        share.append({"indentation_um": zeta, "floor_share": r.floor_force_N / r.total_force_N,
                      "iterations": r.iterations, "cells": r.discretisation["cells"],
                      "floor_cells": r.diagnostics.get("floor_cells", 0), "wall_s": wall})
    out["share"] = {"cells_per_diameter": SHARE_N, "rows": share}
    return out


def convergence() -> dict:
    from validation.analysis.verification import study

    rows = []
    for n in CONV_LEVELS:
        r, wall = _solve(CONV_SCENE, n)
        rows.append({"cells_per_diameter": n, "F_T": r.total_force_N,
                     "F_floor": r.floor_force_N, "A_floor": r.floor_contact_area_m2,
                     "a_floor": r.floor_contact_radius_m, "cells": r.discretisation["cells"],
                     "iterations": r.iterations, "wall_s": wall, "converged": r.converged})
    h = [1.0 / row["cells_per_diameter"] for row in rows]
    studies = {}
    for key in ("F_T", "F_floor", "A_floor", "a_floor"):
        # The three finest levels for the GCI; the least-squares order over all four.
        s = study(h[::-1], [row[key] for row in rows][::-1])
        studies[key] = {"order": s["gci"]["order"], "gci_fine": s["gci"]["gci_fine"],
                        "f_exact": s["gci"]["f_exact"], "status": s["gci"]["status"],
                        "lsq_order": s["lsq"]["order"]}
    return {"scene": CONV_SCENE, "levels": rows, "studies": studies}


def _peer_one(overrides, n) -> dict:
    from ContactMechanics import FreeFFTElasticHalfSpace
    from ContactMechanics.Optimization import constrained_conjugate_gradients
    from SurfaceTopography import Topography

    from bem_solver._fft_grid import build_grid
    from pillar_xval.scenes.analytic import lens_gap

    scene = _scene(overrides)
    grid = build_grid(scene, n)
    ny, nx = grid.shape
    L = grid.cell_size
    zeta, h = scene.indentation_m, scene.pillars.height_m
    # Every point of the box: its centre on a pillar top (our top cells' positions with more
    # than half of the cell covered) or on the floor, -g or -(g + h); no mask.
    iy, ix = np.divmod(np.arange(ny * nx), nx)
    x0 = grid.x.min() - np.rint(grid.x.min() / L) * L  # 0: cells on multiples of L
    xs = (ix + np.rint(grid.x.min() / L)) * L + x0
    ys = (iy + np.rint(grid.y.min() / L)) * L
    top = np.zeros(ny * nx, dtype=bool)
    for px, py in grid.pillar_xy:
        top |= np.hypot(xs - px, ys - py) <= 0.5 * scene.pillars.diameter_m
    heights = -lens_gap(scene.lens.radius_m, np.hypot(xs, ys)) - np.where(top, 0.0, h)
    start = time.perf_counter()
    substrate = FreeFFTElasticHalfSpace((ny, nx), 1.0 / scene.half_space_compliance,
                                        (ny * L, nx * L))
    topography = Topography(heights.reshape(ny, nx), physical_sizes=(ny * L, nx * L))
    pixel_force = zeta * L / scene.half_space_compliance
    res = constrained_conjugate_gradients(substrate, topography, offset=zeta,
                                          pentol=TOL * zeta, forcetol=TOL * pixel_force,
                                          thermotol=TOL, maxiter=20000)
    wall = time.perf_counter() - start
    force = np.asarray(res.jac).reshape(-1)[:ny * nx] if np.size(res.jac) == ny * nx else \
        np.asarray(res.jac)[:ny, :nx].reshape(-1)
    floor = ~top
    return {"total_force_N": float(force.sum()), "floor_force_N": float(force[floor].sum()),
            "floor_contact_area_m2": float(np.count_nonzero(force[floor] > 0) * L * L),
            "iterations": int(res.nit), "converged": bool(res.success), "wall_s": wall}


def peer() -> dict:
    out = {}
    for name, overrides in PEER_SCENES.items():
        rows = []
        for n in PEER_LEVELS:
            ours, wall = _solve(overrides, n)
            theirs = _peer_one(overrides, n)
            rows.append({"cells_per_diameter": n,
                         "ours": {"total_force_N": ours.total_force_N,
                                  "floor_force_N": ours.floor_force_N,
                                  "floor_contact_area_m2": ours.floor_contact_area_m2,
                                  "iterations": ours.iterations, "wall_s": wall,
                                  "converged": ours.converged},
                         "contactmechanics": theirs})
        out[name] = {"overrides": overrides, "rows": rows}
    return out


def markdown(doc: dict) -> str:
    lines = ["# bem-fft with the floor between the pillars", ""]
    p = doc.get("perf")
    if p:
        lines += [f"Cost on one grid (N = {p['cells_per_diameter']}, load average "
                  f"{p['load_average']:.1f}, medians of {p['repeats']} alternate runs):", "",
                  "| solve | cells | floor cells | left out | floor share | iterations | "
                  "median |", "|---|---|---|---|---|---|---|"]
        for k in ("mixed", "suspended"):
            r = p[k]
            lines.append(f"| {k} | {r['cells']} | {r['floor_cells']} | "
                         f"{r.get('left_out_floor_cells', 0)} | "
                         f"{100 * r['floor_share']:.2f} % | {r['iterations']} | "
                         f"{r['median_s']:.3g} s |")
        per_iteration = (p["mixed"]["median_s"] / p["mixed"]["iterations"]) / (
            p["suspended"]["median_s"] / p["suspended"]["iterations"])
        lines += ["", f"Ratio mixed / suspended: {p['ratio']:.2f}; per iteration "
                  f"{per_iteration:.2f}", "",
                  f"Iterations against the floor's share (N = {p['share']['cells_per_diameter']}):",
                  "", "| zeta (um) | floor share | iterations | cells | floor cells |",
                  "|---|---|---|---|---|"]
        for r in p["share"]["rows"]:
            lines.append(f"| {r['indentation_um']:g} | {100 * r['floor_share']:.2f} % | "
                         f"{r['iterations']} | {r['cells']} | {r['floor_cells']} |")
        lines.append("")
    c = doc.get("convergence")
    if c:
        lines += ["Convergence (N = " + ", ".join(str(r["cells_per_diameter"])
                                                 for r in c["levels"]) + "):", "",
                  "| quantity | finest | order (3 finest) | lsq order | GCI fine | status |",
                  "|---|---|---|---|---|---|"]
        for key, s in c["studies"].items():
            fin = c["levels"][-1][key]
            order = "-" if s["order"] is None else f"{s['order']:.2f}"
            lsq = "-" if s["lsq_order"] is None else f"{s['lsq_order']:.2f}"
            gci = "-" if s["gci_fine"] is None else f"{100 * s['gci_fine']:.3g} %"
            lines.append(f"| {key} | {fin:.6g} | {order} | {lsq} | {gci} | {s['status']} |")
        lines.append("")
    peers = doc.get("peer")
    if peers:
        lines += ["Against ContactMechanics (rigid pillars, the floor in its topography):", "",
                  "| scene | N | F_T ours / CM - 1 | floor force ours / CM - 1 | "
                  "floor area ours / CM - 1 |", "|---|---|---|---|---|"]
        for name, s in peers.items():
            for r in s["rows"]:
                o, t = r["ours"], r["contactmechanics"]
                rel = [o[k] / t[k] - 1.0 if t[k] else float("nan") for k in
                       ("total_force_N", "floor_force_N", "floor_contact_area_m2")]
                lines.append(f"| {name} | {r['cells_per_diameter']} | "
                             + " | ".join(f"{100 * v:+.2f} %" for v in rel) + " |")
        lines.append("")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--only", default=",".join(PARTS))
    ap.add_argument("--repeats", type=int, default=5,
                    help="alternate runs of each solve for the medians (default 5)")
    args = ap.parse_args(argv)
    parts = [p for p in args.only.split(",") if p]
    unknown = [p for p in parts if p not in PARTS]
    if unknown or not parts:
        ap.error(f"--only = {args.only!r}: choose parts among {', '.join(PARTS)}")
    if args.repeats < 1:
        ap.error(f"--repeats = {args.repeats}: must be at least 1")
    args.out.mkdir(parents=True, exist_ok=True)
    path = args.out / "bench_floor.json"
    doc = json.loads(path.read_text()) if path.exists() else {}
    for part in parts:
        if part == "peer":
            from validation.bench.fft import contactmechanics_available

            why = contactmechanics_available()
            if why:
                print(f"peer: skipped: {why}")
                continue
        doc[part] = {"perf": lambda: perf(args.repeats), "convergence": convergence,
                     "peer": peer}[part]()
        write_atomic(path, json.dumps(doc, indent=2))
        write_atomic(args.out / "bench_floor.md", markdown(doc))
        print(markdown({part: doc[part]}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
