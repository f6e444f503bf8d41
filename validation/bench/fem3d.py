"""Benchmark of the 3D FEM reference (fem-3d): unknowns, time by phase, contact iterations and
peak memory over a mesh_size ladder, with the error of F_T against the Richardson estimate.

    python -m validation.bench.fem3d --out DIR [--levels 2,1.41,1] [--dense 2.83,2]
                                     [--compare-solvers 2.83]

The ladder runs on Phi = 0.2, zeta = 0.3 um, E_p = E_s = E_l (``paper-fig3-sparse`` with
``pillars.surface_fraction=0.2`` and ``substrate.E_Pa=1.6e6``).  Targets on the 2-core
machine: F_T within 2 % of the Richardson estimate in under 5 minutes and 12 GiB.  With
``--dense`` the densest paper scene (``paper-fig3-dense``, Phi = 0.82) runs at the given
levels; its error is the three-grid GCI (two grids: with the order observed on the
ladder).  Each level runs
in a fresh process, so its peak RSS is its own.  Prints a table and writes
``bench_fem3d.json``.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

LADDER_SCENE = ("paper-fig3-sparse", ["pillars.surface_fraction=0.2", "substrate.E_Pa=1.6e6"])
DENSE_SCENE = ("paper-fig3-dense", [])
TARGET_RTOL, TARGET_TIME_S, TARGET_RSS_GIB = 0.02, 300.0, 12.0
DENSE_RTOL, DENSE_TIME_S = 0.05, 900.0


def _run_level(preset: str, overrides: list, mesh_size: float) -> dict:
    """One solve in this (fresh) process; the figures of the benchmark table."""
    from fem_reference.solid3d import solve
    from pillar_xval.scenes import load_scene

    t0 = time.perf_counter()
    res = solve(load_scene(preset, overrides), mesh_size)
    d = res.diagnostics
    return {"mesh_size": mesh_size, "dofs": res.discretisation["dofs"],
            "elements": res.discretisation["elements"],
            "contact_unknowns": d["contact_vertices"], "pillars_meshed": len(d["pillars_meshed"]),
            "pillars_in_contact": res.pillars_in_contact, "F_T_N": res.total_force_N,
            "sigma0_Pa": res.centre_pressure_Pa, "cg_iterations": d["cg_iterations"],
            "time_s": d["time_s"], "wall_s": time.perf_counter() - t0,
            "peak_rss_GiB": d["peak_rss_GiB"], "converged": res.converged,
            "linear_residual": d["linear_residual"], "contact_residual": d["contact_residual"],
            "factor_nonzeros": d["factor_nonzeros"]}


def _compare_solvers(preset: str, overrides: list, mesh_size: float) -> dict:
    """Factorisation and one solve of the same reduced system by PARDISO and SuperLU."""
    import math

    import numpy as np
    from scipy.sparse.linalg import splu

    from fem_reference._pardiso import Pardiso
    from fem_reference.solid3d.driver import _setup
    from fem_reference.solid3d.system import assemble_sector
    from meshes import build_wedge_mesh
    from pillar_xval.scenes import load_scene

    setup = _setup(load_scene(preset, overrides), mesh_size, math.pi / 6, 1e4, 1.0, {})
    mesh = build_wedge_mesh(setup["geometry"]).to_skfem().scaled([1.0 / setup["ell"]] * 3)
    system = assemble_sector(mesh, setup["materials"], sector_angle=math.pi / 6,
                             clamp_pillar_base=False, rigid_pillars=[])
    Ks = system.K.tocsc()  # scaled
    b = np.random.default_rng(1).standard_normal(Ks.shape[0])
    out = {"mesh_size": mesh_size, "unknowns": int(Ks.shape[0])}
    for name, factor in (("pardiso", lambda: Pardiso(Ks.tocsr())),
                         ("superlu", lambda: splu(Ks, permc_spec="COLAMD",
                                                  diag_pivot_thresh=0.1))):
        t0 = time.perf_counter()
        f = factor()
        t1 = time.perf_counter()
        x = f.solve(b)
        t2 = time.perf_counter()
        out[name] = {"factorise_s": t1 - t0, "solve_s": t2 - t1,
                     "residual": float(np.linalg.norm(Ks @ x - b) / np.linalg.norm(b))}
        del f
    return out


def run_level(preset: str, overrides: list, mesh_size: float) -> dict:
    ctx = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
        return pool.submit(_run_level, preset, overrides, mesh_size).result()


def _table(rows: list, reference: float | None) -> str:
    head = (f"{'mesh_size':>9} {'dofs':>8} {'contact':>7} {'mesh':>6} {'assem':>6} "
            f"{'factor':>7} {'contact':>8} {'iters':>5} {'total':>7} {'RSS GiB':>7} "
            f"{'F_T (uN)':>10} {'err':>8}")
    lines = [head, "-" * len(head)]
    for r in rows:
        t = r["time_s"]
        err = "" if reference is None else f"{(r['F_T_N'] / reference - 1) * 100:+.2f}%"
        lines.append(f"{r['mesh_size']:>9.3g} {r['dofs']:>8d} {r['contact_unknowns']:>7d} "
                     f"{t['mesh']:>6.1f} {t['assemble']:>6.1f} {t['factorise']:>7.1f} "
                     f"{t['contact']:>8.1f} {r['cg_iterations']:>5d} {r['wall_s']:>7.1f} "
                     f"{r['peak_rss_GiB']:>7.2f} {r['F_T_N'] * 1e6:>10.5f} {err:>8}")
    return "\n".join(lines)


def main(argv=None) -> int:
    from validation.analysis.verification import gci_three, gci_two

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--levels", default="2,1.41,1",
                    help="mesh_size ladder, coarse to fine (default 2,1.41,1)")
    ap.add_argument("--compare-solvers", type=float, default=None, metavar="MESH_SIZE",
                    help="also time PARDISO against SuperLU on the ladder scene at this level")
    ap.add_argument("--dense", default="",
                    help="mesh sizes for paper-fig3-dense, coarse to fine (e.g. 2.83,2)")
    args = ap.parse_args(argv)
    levels = [float(s) for s in args.levels.split(",") if s]
    out = {"machine_note": "2-core machine shared with other jobs: timings are contended",
           "scene": {"preset": LADDER_SCENE[0], "overrides": LADDER_SCENE[1]}, "ladder": []}
    for ms in levels:
        row = run_level(*LADDER_SCENE, ms)
        out["ladder"].append(row)
        print(f"mesh_size {ms:g}: {row['dofs']} dofs, {row['wall_s']:.1f} s, "
              f"F_T = {row['F_T_N']:.6g} N", flush=True)
    rows = out["ladder"]
    reference = order = None
    if len(rows) >= 3:
        fine = rows[-3:][::-1]
        g = gci_three([r["mesh_size"] for r in fine], [r["F_T_N"] for r in fine])
        out["richardson"] = g.to_dict()
        reference, order = g.f_exact, g.order
    print(_table(rows, reference))
    if reference is not None:
        ok = [r for r in rows if abs(r["F_T_N"] / reference - 1) <= TARGET_RTOL
              and r["wall_s"] <= TARGET_TIME_S and r["peak_rss_GiB"] <= TARGET_RSS_GIB]
        out["target_met_by"] = [r["mesh_size"] for r in ok]
        print(f"Richardson F_T = {reference:.6g} N (order {order:.2f}); 2 % / 5 min / 12 GiB "
              f"met by mesh_size {out['target_met_by'] or 'none'}")
    dense_levels = [float(s) for s in args.dense.split(",") if s]
    if dense_levels:
        out["dense"] = [run_level(*DENSE_SCENE, ms) for ms in dense_levels]
        dense = out["dense"]
        g = None
        if len(dense) >= 3:
            fine = dense[-3:][::-1]
            g = gci_three([r["mesh_size"] for r in fine], [r["F_T_N"] for r in fine])
        if (g is None or g.gci_fine is None) and len(dense) >= 2 and order:
            g = gci_two([dense[-1]["mesh_size"], dense[-2]["mesh_size"]],
                        [dense[-1]["F_T_N"], dense[-2]["F_T_N"]], order)
        if g is None:
            print("paper-fig3-dense")
            print(_table(dense, None))
        else:
            out["dense_gci"] = g.to_dict()
            for r in dense:
                ref = g.f_exact
                r["error_vs_estimate"] = None if ref is None else r["F_T_N"] / ref - 1
            print("paper-fig3-dense")
            print(_table(dense, g.f_exact))
            a = dense[-1]
            band = (g.gci_fine if g.gci_fine is not None
                    else g.fallback_uncertainty / abs(a["F_T_N"]))
            print(f"dense: F_T = {a['F_T_N']:.6g} N at mesh_size {a['mesh_size']:g}, GCI "
                  f"{band * 100:.2f} % ({g.status}, order {g.order}), Richardson "
                  f"{g.f_exact}, {a['wall_s']:.0f} s, {a['peak_rss_GiB']:.2f} GiB")
    if args.compare_solvers:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=1, mp_context=ctx) as pool:
            cmp = pool.submit(_compare_solvers, *LADDER_SCENE, args.compare_solvers).result()
        out["solvers"] = cmp
        for name in ("pardiso", "superlu"):
            c = cmp[name]
            print(f"{name:8s} {cmp['unknowns']} unknowns: factorise {c['factorise_s']:.1f} s, "
                  f"solve {c['solve_s']:.2f} s, residual {c['residual']:.1e}")
    from pillar_xval.outcome import write_atomic

    path = write_atomic(args.out / "bench_fem3d.json", json.dumps(out, indent=2))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
