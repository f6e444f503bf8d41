"""Validation and cost of the elastic-pillar BEM on one pillar:
``python -m validation.bench.elastic_pillar --out DIR [--quick]``.

For E_p/E_l in {1e-3, 0.1, 1, 10, 1e6} and h/d in {0.25, 1, 4} on the ``single-pillar``
scene (E_s = E_l = 1.6 MPa, every nu = 0.5, zeta = 0.3 um, d = 4 um): the dense BEM with the
Hooke and the elastic pillar at P = 21 and 41 (and their first-order Richardson estimate in
1/P, as ``bem-richardson``), and fem-axisym at mesh_size 1 and 0.5.  Writes
``elastic_pillar.json`` and ``elastic_pillar.csv`` (F_T, sigma0, their relative differences
against fem-axisym at mesh_size 0.5, wall times) and prints a table; the compliance build
time of each pillar kind is recorded (uncached: the cache goes to DIR/cache).
With ``--modes-study`` it also measures F_T and sigma0 against the number of Fourier modes
and the compliance mesh on one kind.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from pathlib import Path

RATIOS = (1e-3, 0.1, 1.0, 10.0, 1e6)
ASPECTS = (0.25, 1.0, 4.0)
LEVELS = (21, 41)


def _scene(ratio, aspect):
    from scenes import load_scene

    return load_scene("single-pillar", [f"pillars.E_Pa={ratio * 1.6e6!r}",
                                        f"pillars.height_um={aspect * 4.0!r}"])


def _timed(fn, *args, **kw):
    t = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t


def _richardson(f1, f2, P1, P2):
    """First order in 1/P: f + (f2 - f1) / (P2/P1 - 1) extrapolated from P1 < P2."""
    return f2 + (f2 - f1) / (P2 / P1 - 1.0)


def run(out: Path, ratios=RATIOS, aspects=ASPECTS, levels=LEVELS) -> list:
    from bem_solver import solve_dense
    from bem_solver._elastic_pillar import scene_compliance
    from fem_reference import solve_axisymmetric

    rows = []
    for aspect in aspects:
        for ratio in ratios:
            scene = _scene(ratio, aspect)
            modal, t_build = _timed(scene_compliance, scene)
            row = {"E_p/E_l": ratio, "h/d": aspect, "compliance_s": t_build,
                   "reciprocity_asymmetry": modal.diagnostics["reciprocity_asymmetry"]}
            for pil in ("hooke", "elastic"):
                vals = []
                for P in levels:
                    r, t = _timed(solve_dense, scene, P, pillars=pil, compliance=None)
                    if not r.converged:
                        print(f"not converged: {pil} P={P}: {r.diagnostics['message']}")
                    vals.append((r.total_force_N, r.centre_pressure_Pa))
                    row[f"{pil}_P{P}_s"] = t
                for k, name in enumerate(("F_T", "sigma0")):
                    row[f"{pil}_{name}_P{levels[-1]}"] = vals[-1][k]
                    row[f"{pil}_{name}_rich"] = _richardson(vals[0][k], vals[1][k], *levels)
            for ms in (1.0, 0.5):
                f, t = _timed(solve_axisymmetric, scene, ms)
                row[f"fem_F_T_m{ms:g}"] = f.total_force_N
                row[f"fem_sigma0_m{ms:g}"] = f.centre_pressure_Pa
                row[f"fem_m{ms:g}_s"] = t
            for pil in ("hooke", "elastic"):
                for name in ("F_T", "sigma0"):
                    ref = row[f"fem_{name}_m0.5"]
                    row[f"d_{pil}_{name}_rich"] = row[f"{pil}_{name}_rich"] / ref - 1.0
                    row[f"d_{pil}_{name}_P{levels[-1]}"] = \
                        row[f"{pil}_{name}_P{levels[-1]}"] / ref - 1.0
            for name in ("F_T", "sigma0"):
                row[f"fem_band_{name}"] = row[f"fem_{name}_m1"] / row[f"fem_{name}_m0.5"] - 1
            rows.append(row)
            print(f"h/d {aspect:5g} E_p/E_l {ratio:8.0e}  elastic-FEM: F_T "
                  f"{100 * row['d_elastic_F_T_rich']:+.2f} %  sigma0 "
                  f"{100 * row['d_elastic_sigma0_rich']:+.2f} %  | hooke-FEM: F_T "
                  f"{100 * row['d_hooke_F_T_rich']:+.2f} %  sigma0 "
                  f"{100 * row['d_hooke_sigma0_rich']:+.2f} %  | fem 1 vs 0.5: "
                  f"{100 * row['fem_band_F_T']:+.2f} % {100 * row['fem_band_sigma0']:+.2f} %"
                  f"  | build {t_build:.1f} s, solve P{levels[-1]}: hooke "
                  f"{row[f'hooke_P{levels[-1]}_s']:.3f} s elastic "
                  f"{row[f'elastic_P{levels[-1]}_s']:.3f} s", flush=True)
    return rows


def modes_study(scene_overrides=("pillars.E_Pa=1.6e7",), P=31) -> list:
    """F_T and sigma0 of the elastic BEM against the modes and the compliance mesh."""
    from bem_solver import solve_dense
    from fem_reference import PillarKind, modal_compliance
    from scenes import load_scene

    scene = load_scene("single-pillar", list(scene_overrides))
    kind = PillarKind.of_scene(scene)
    rows = []
    for modes, mesh in ((2, 1.0), (4, 1.0), (8, 1.0), (12, 1.0), (16, 1.0), (12, 0.7),
                        (12, 0.5)):
        modal, t = _timed(modal_compliance, kind, modes, mesh)
        r = solve_dense(scene, P, pillars="elastic", compliance=modal)
        rows.append({"modes": modes, "mesh_size": mesh, "top_points": len(modal.r_top),
                     "F_T": r.total_force_N, "sigma0": r.centre_pressure_Pa,
                     "build_s": t})
        print(rows[-1], flush=True)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--quick", action="store_true", help="h/d = 1 only, E_p/E_l 0.1 and 10")
    ap.add_argument("--modes-study", action="store_true")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    os.environ["PILLAR_XVAL_CACHE"] = str(args.out / "cache")
    doc = {}
    if args.modes_study:
        doc["modes"] = modes_study()
    rows = run(args.out, (0.1, 10.0), (1.0,)) if args.quick else run(args.out)
    doc["single_pillar"] = rows
    (args.out / "elastic_pillar.json").write_text(json.dumps(doc, indent=1))
    with open(args.out / "elastic_pillar.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
