"""Validation and cost of the elastic-pillar BEM on one pillar:
``python -m validation.bench.elastic_pillar --out DIR [--quick]``.

For E_p/E_l in {1e-3, 0.1, 1, 10, 1e6} and h/d in {0.25, 1, 4} on the ``single-pillar``
scene (E_s = E_l = 1.6 MPa, every nu = 0.5, zeta = 0.3 um, d = 4 um): the dense BEM with the
Hooke and the elastic pillar at P = 21 and 41 (and their first-order Richardson estimate in
1/P, as ``bem-richardson``), and fem-axisym at mesh_size 1 and 0.5.  Writes
``elastic_pillar.json`` and ``elastic_pillar.csv`` (F_T, sigma0, their relative differences
against fem-axisym at mesh_size 0.5, wall times) and prints a table; the compliance build
time of each pillar kind is recorded (uncached: the cache goes to DIR/cache).
With ``--modes-study`` it also measures F_T, sigma0 and a ring force against the number of
Fourier modes and the compliance mesh on a lattice; ``--lattice`` compares the Hooke and
elastic BEMs with fem-3d on Phi = 0.2 instead (``elastic_lattice.json``).
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
    from pillar_xval.scenes import load_scene

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
    from fem_reference.axisym import solve as solve_axisymmetric

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


def modes_study(ratios=(10.0, 0.1), meshes=(4.0, 2.0, 1.0), P=21) -> list:
    """F_T, sigma0 and the first ring's force of the dense elastic BEM on Phi = 0.2 against
    the highest Fourier mode kept (one build with n <= 12 per mesh, truncated) and the
    compliance mesh (its number of P2 points on the top)."""
    from bem_solver import solve_dense
    from fem_reference import ModalCompliance, PillarKind, modal_compliance
    from pillar_xval.scenes import load_scene

    rows = []
    for ratio in ratios:
        scene = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                                 f"pillars.E_Pa={ratio * 1.6e6!r}"])
        kind = PillarKind.of_scene(scene)
        for mesh in meshes:
            full, t = _timed(modal_compliance, kind, 12, mesh)
            for n in (0, 1, 2, 4, 8, 12):
                m = ModalCompliance(kind, n, mesh, full.r_top, full.pillar[:n + 1],
                                    full.halfspace[:n + 1], {}, full.base_moments)
                r = solve_dense(scene, P, pillars="elastic", compliance=m)
                rows.append({"E_p/E_l": ratio, "mesh_size": mesh, "top_points": len(full.r_top),
                             "modes": n, "F_T": r.total_force_N,
                             "sigma0": r.centre_pressure_Pa,
                             "ring1": _rings(r).get(1), "build_s": t})
                print(json.dumps(rows[-1]), flush=True)
    return rows


def lattice(ratios=(0.1, 10.0), phi=0.2, fem_sizes=(2.83, 2.0), P=21, N=32) -> list:
    """Hooke BEM, elastic BEM (dense P, FFT N) and fem-3d (two mesh levels) on
    ``paper-fig3-sparse`` at surface fraction ``phi`` (E_s = E_l = 1.6 MPa)."""
    from bem_solver import solve_dense, solve_fft
    from bem_solver._elastic_pillar import scene_compliance
    from fem_reference.solid3d import solve as solve_fem3d
    from pillar_xval.scenes import load_scene

    rows = []
    for ratio in ratios:
        scene = load_scene("paper-fig3-sparse", [f"pillars.surface_fraction={phi!r}",
                                                 f"pillars.E_Pa={ratio * 1.6e6!r}"])
        modal, t_build = _timed(scene_compliance, scene)
        row = {"E_p/E_l": ratio, "Phi": phi, "compliance_s": t_build}
        for name, fn in (("hooke_dense", lambda: solve_dense(scene, P)),
                         ("elastic_dense", lambda: solve_dense(scene, P, pillars="elastic")),
                         ("hooke_fft", lambda: solve_fft(scene, N)),
                         ("elastic_fft", lambda: solve_fft(scene, N, pillars="elastic"))):
            r, t = _timed(fn)
            row.update({f"{name}_F_T": r.total_force_N, f"{name}_sigma0": r.centre_pressure_Pa,
                        f"{name}_s": t, f"{name}_converged": r.converged,
                        f"{name}_rings": _rings(r)})
        for ms in fem_sizes:
            r, t = _timed(solve_fem3d, scene, ms)
            row.update({f"fem3d_m{ms:g}_F_T": r.total_force_N,
                        f"fem3d_m{ms:g}_sigma0": r.centre_pressure_Pa,
                        f"fem3d_m{ms:g}_s": t, f"fem3d_m{ms:g}_rings": _rings(r),
                        f"fem3d_m{ms:g}_converged": r.converged})
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def _rings(result) -> dict:
    """Force per pillar, averaged over each lattice ring (N), keyed by ring."""
    rings = {}
    for p in result.pillar_forces:
        ring = max(abs(p.n), abs(p.m), abs(p.n - p.m))
        rings.setdefault(ring, []).append(p.force_N)
    return {k: sum(v) / len(v) for k, v in sorted(rings.items())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--quick", action="store_true", help="h/d = 1 only, E_p/E_l 0.1 and 10")
    ap.add_argument("--modes-study", action="store_true")
    ap.add_argument("--lattice", action="store_true",
                    help="only the lattice scene (Phi = 0.2) against fem-3d")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    os.environ["PILLAR_XVAL_CACHE"] = str(args.out / "cache")
    doc = {}
    if args.lattice:
        doc["lattice"] = lattice()
        (args.out / "elastic_lattice.json").write_text(json.dumps(doc, indent=1))
        return 0
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
