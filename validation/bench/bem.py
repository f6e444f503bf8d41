"""Benchmark of the dense BEM: ``python -m validation.bench.bem --out DIR`` (``make bench-bem``).

Times one solve (median of ``--repeats``) against the elements per diameter P on the dense
Fig. 3 scene, and against the number of pillars in contact up to Phi = 0.82, zeta = 0.5 um,
with the D6-reduced operator and, while it fits in memory, the unreduced one on the same
elements.  Peak memory is measured by tracemalloc in a separate run.  Writes bench_bem.json
and bench_bem.png and prints a table.
"""

from __future__ import annotations

import argparse
import json
import sys
import tracemalloc
from pathlib import Path

import numpy as np

from bem_solver import discretise, full_operator, lens_gap, solve_dense
from pillar_xval.contact import solve_active_set as solve_contact
from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import load_scene
from validation.bench import median_time
from validation.output.report import figure_png

UNREDUCED_MAX_ELEMENTS = 9000  # 650 MB for the full operator


def _peak_mb(fn):
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def _unreduced(scene, result):
    disc = discretise(scene, result.discretisation["elements_per_diameter"],
                      result.discretisation["cells"], result.diagnostics["candidate_radius_m"])
    K = full_operator(scene, disc)
    zeta = scene.indentation_m
    sol = solve_contact(K, lens_gap(scene, disc.img_x, disc.img_y) - zeta, scale=zeta)
    return float(sol.pressure.sum())


def bench_case(label, scene, P, repeats, log):
    t_red, res = median_time(lambda: solve_dense(scene, P), repeats)
    row = {"case": label, "P": P, "surface_fraction": scene.pillars.surface_fraction,
           "indentation_um": scene.indentation_m * 1e6,
           "pillars_in_contact": res.pillars_in_contact,
           "unknowns_reduced": res.diagnostics["unknowns"],
           "elements": res.diagnostics["elements"],
           "time_reduced_s": t_red,
           "peak_memory_reduced_MB": _peak_mb(lambda: solve_dense(scene, P)),
           "total_force_N": res.total_force_N, "time_unreduced_s": None,
           "force_unreduced_rel_diff": None}
    if res.diagnostics["elements"] <= UNREDUCED_MAX_ELEMENTS:
        t_full, f_full = median_time(lambda: _unreduced(scene, res), max(1, repeats // 2))
        row["time_unreduced_s"] = t_full
        row["force_unreduced_rel_diff"] = abs(f_full / res.total_force_N - 1)
    log(f"{label:>28s}  P={P:3d}  pillars={row['pillars_in_contact']:4d}  "
        f"unknowns={row['unknowns_reduced']:5d}  elements={row['elements']:6d}  "
        f"reduced {t_red:7.3f} s  {row['peak_memory_reduced_MB']:7.1f} MB  "
        + (f"unreduced {row['time_unreduced_s']:7.3f} s" if row["time_unreduced_s"] else
           "unreduced  (too large)"))
    return row


def run(out: Path, repeats: int = 3, quick: bool = False) -> dict:
    log = lambda msg: print(msg, file=sys.stderr, flush=True)  # noqa: E731
    rows = []
    dense = load_scene("paper-fig3-dense")
    for P in ([5, 11] if quick else [5, 7, 11, 15, 21]):
        rows.append(bench_case("vs P: fig3-dense", dense, P, repeats, log))
    cases = [(0.03, 0.3), (0.1, 0.3), (0.3, 0.3), (0.82, 0.3), (0.82, 0.5)]
    for phi, zeta in (cases[:2] if quick else cases):
        scene = load_scene("paper-fig3-dense", [f"pillars.surface_fraction={phi}",
                                                f"load.indentation_um={zeta}"])
        rows.append(bench_case(f"vs pillars: Phi={phi} zeta={zeta}", scene, 11, repeats, log))
    report = {"benchmark": "dense BEM", "repeats": repeats, "rows": rows,
              "note": "median wall time of one solve_dense call (discretise, operator, contact, "
                      "result); unreduced = full operator and LCP on the same elements"}
    out.mkdir(parents=True, exist_ok=True)
    write_atomic(out / "bench_bem.json", json.dumps(report, indent=2) + "\n")
    write_atomic(out / "bench_bem.png", _figure(rows))
    log(f"written {out / 'bench_bem.json'} and {out / 'bench_bem.png'}")
    return report


def _figure(rows) -> bytes:

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    byP = [r for r in rows if r["case"].startswith("vs P")]
    byN = [r for r in rows if r["case"].startswith("vs pillars")]
    for ax, sel, key, xlabel in ((a1, byP, "P", "elements per diameter P"),
                                 (a2, byN, "pillars_in_contact", "pillars in contact")):
        x = np.array([r[key] for r in sel])
        ax.loglog(x, [r["time_reduced_s"] for r in sel], "o-", label="D6-reduced")
        full = [(r[key], r["time_unreduced_s"]) for r in sel if r["time_unreduced_s"]]
        if full:
            ax.loglog(*zip(*full), "s--", label="unreduced")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("wall time per solve (s)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    a1.set_title("Phi = 0.82, zeta = 0.3 um")
    a2.set_title("P = 11, Phi and zeta up to 0.82, 0.5 um")
    return figure_png(fig, 110)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m validation.bench.bem", description=__doc__)
    p.add_argument("--out", type=Path, default=Path("out/bench-bem"))
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--quick", action="store_true", help="a few small cases (for tests)")
    args = p.parse_args(argv)
    run(args.out, args.repeats, args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
