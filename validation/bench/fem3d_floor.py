"""fem-3d with the floor against a suspended run at the same mesh size:
``python -m validation.bench.fem3d_floor --out DIR [--mesh-size 4] [--repeats 3]``.

The scene is paper-fig3-sparse with short pillars (h = 0.5 um): suspended at zeta = 0.45 um
(below the floor's onset bound h + g(d/2); fewer pillars in reach), mixed at zeta = 2 um (the
floor carries about a third of the force); and suspended at the same zeta = 2 um on pillars
of h = 2 um (the same pillars in reach, no floor).  Each run is ``pillar-xval solve --model
fem-3d --json`` in a fresh interpreter, the cases in rotating order, so the load of a
shared machine weighs on all alike.  Per case: the medians of the wall time, of each phase
(the result's ``time_s``) and of the peak RSS, the CG iterations and the floor's share; the
mixed case's medians over each suspended case's.  Prints the table and writes it with the
runs and the load averages to ``DIR/bench_fem3d_floor.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

SCENE = "paper-fig3-sparse"
# case: (pillar height, indentation), um
CASES = {"suspended": (0.5, 0.45), "suspended-h2": (2.0, 2.0), "mixed": (0.5, 2.0)}
PHASES = ("mesh", "assemble", "factorise", "contact", "post")


def run_once(case: tuple, mesh_size: float) -> dict:
    """One solve in a fresh interpreter: its wall time, phases, peak RSS and answers."""
    h_um, zeta_um = case
    cmd = [sys.executable, "-m", "validation.cli", "solve", "--model", "fem-3d", "--scene",
           SCENE, "--set", f"pillars.height_um={h_um}", "--set",
           f"load.indentation_um={zeta_um}", "--mesh-size", str(mesh_size), "--json"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        raise SystemExit(f"fem-3d at (h, zeta) = {case} um exited {done.returncode}: "
                         + done.stderr.strip().splitlines()[-1:][0] if done.stderr.strip()
                         else f"fem-3d at (h, zeta) = {case} um exited {done.returncode}")
    doc = json.loads(done.stdout)
    d = doc["diagnostics"]
    return {"wall_s": doc["wall_time_s"], **{p: d["time_s"].get(p, 0.0) for p in PHASES},
            "peak_rss_GiB": d["peak_rss_GiB"], "cg_iterations": d["cg_iterations"],
            "F_T_N": doc["total_force_N"],
            "floor_share": doc.get("floor_force_N", 0.0) / doc["total_force_N"],
            "regime": doc.get("regime", ""), "load": os.getloadavg()[0]}


def table(runs: dict) -> list[str]:
    """Markdown rows: the medians per case and the mixed case's over each suspended one."""
    keys = ("wall_s", *PHASES, "peak_rss_GiB", "cg_iterations")
    med = {c: {k: statistics.median(r[k] for r in rs) for k in keys} for c, rs in runs.items()}
    lines = ["| case | " + " | ".join(keys) + " | floor share | load |",
             "|---" * (len(keys) + 3) + "|"]
    for c, rs in runs.items():
        lines.append(f"| {c} | " + " | ".join(f"{med[c][k]:.3g}" for k in keys)
                     + f" | {rs[0]['floor_share']:.3f} | "
                     + f"{statistics.median(r['load'] for r in rs):.1f} |")
    a = med["mixed"]
    for c in ("suspended", "suspended-h2"):
        b = med[c]
        lines.append(f"| mixed / {c} | " + " | ".join(
            f"{a[k] / b[k]:.2f}" if b[k] else "-" for k in keys) + " | | |")
    return lines


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--mesh-size", type=float, default=4.0)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    runs = {c: [] for c in CASES}
    order = list(CASES)
    for i in range(args.repeats):
        for c in order[i % len(order):] + order[:i % len(order)]:
            runs[c].append(run_once(CASES[c], args.mesh_size))
            print(f"{c}: {runs[c][-1]['wall_s']:.3g} s", flush=True)
    lines = [f"fem-3d on {SCENE}, mesh_size {args.mesh_size:g}, (h, zeta) in um: "
             + ", ".join(f"{c} {v}" for c, v in CASES.items())
             + f"; medians of {args.repeats}, rotating order:", "", *table(runs)]
    print("\n".join(lines))
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "bench_fem3d_floor.md").write_text("\n".join(lines) + "\n")
    (args.out / "bench_fem3d_floor.json").write_text(json.dumps(runs, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
