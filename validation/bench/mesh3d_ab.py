"""Interleaved before/after timing of fem-3d's mesh phase alone against another checkout:
``python -m validation.bench.mesh3d_ab --baseline DIR --out DIR [--case 0.82:2] ...``.

Each run meshes fem-3d's sector of the A/B benchmark's scene (:data:`.ab.FEM3D_SCENE` at
surface fraction PHI, ``--case PHI:MESH_SIZE``) in a fresh interpreter whose ``PYTHONPATH`` is
the checkout, as a solve's mesh phase does (gmsh's mesh and its scikit-fem form, imports
excluded); the sides alternate (ABBA, :func:`.ab.interleaved`), so that the load of a shared
machine weighs on both alike.  Per case and side: the medians of the wall and CPU time (all
threads), the nodes, the tetrahedra and their mean-ratio quality (min, mean), and whether
the two sides made the same mesh (SHA-256 of the points and the tetrahedra).  Prints the
table and writes it with the runs and the load averages to ``DIR/bench_mesh3d_ab.md`` and
``.json``.
"""

from __future__ import annotations

import argparse
import sys

from .ab import FEM3D_SCENE, median_of, phase_main, phase_rows

WORKER = r"""
import hashlib, json, math, sys, time
import numpy as np
case = json.loads(sys.argv[1])
from pillar_xval.scenes import load_scene
from fem_reference.solid3d.driver import BLOCK_FACTOR, _setup
from meshes import build_wedge_mesh
scene = load_scene(case["scene"], case["overrides"])
geo = _setup(scene, case["mesh_size"], math.pi / 6, BLOCK_FACTOR, 1.0, {})["geometry"]
t, c = time.perf_counter(), time.process_time()
mesh = build_wedge_mesh(geo)
mesh.to_skfem()
wall, cpu = time.perf_counter() - t, time.process_time() - c
q = mesh.quality()
digest = hashlib.sha256(np.ascontiguousarray(mesh.points).tobytes()
                        + np.ascontiguousarray(mesh.tets, dtype=np.int64).tobytes()).hexdigest()
print(json.dumps({"wall_s": wall, "cpu_s": cpu, "nodes": int(mesh.points.shape[1]),
                  "elements": int(mesh.nelements), "min_quality": float(q.min()),
                  "mean_quality": float(q.mean()), "sha256": digest}))
"""


def parse_case(text: str) -> dict:
    try:
        phi, mesh_size = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected PHI:MESH_SIZE, e.g. 0.82:2") \
            from None
    return {"label": text, "scene": FEM3D_SCENE, "mesh_size": mesh_size,
            "overrides": [f"pillars.surface_fraction={phi}"]}


def summarise(case: dict, runs: dict) -> list[dict]:
    return phase_rows(case, runs, {"wall_median_s": median_of("wall_s"),
                                   "cpu_median_s": median_of("cpu_s")},
                      ("nodes", "elements", "min_quality", "mean_quality", "sha256"),
                      "same_mesh")


def table(rows: list[dict]) -> str:
    lines = ["| case | side | wall median s | CPU median s | CPU speed-up | nodes | elements | "
             "quality min / mean | same mesh |", "|" + "---|" * 9]
    for r in rows:
        lines.append(f"| {r['case']} | {r['side']} | {r['wall_median_s']:.3f} | "
                     f"{r['cpu_median_s']:.3f} | {r.get('cpu_speed-up', float('nan')):.2f} | "
                     f"{r['nodes']} | {r['elements']} | {r['min_quality']:.4f} / "
                     f"{r['mean_quality']:.4f} | {r.get('same_mesh', '')} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    return phase_main(argv, __doc__, "bench_mesh3d_ab", parse_case,
                      "PHI:MESH_SIZE (repeatable; default: the lattice study's levels at "
                      "Phi = 0.2 and 0.82 but 1.41)",
                      [f"{phi}:{h}" for phi in (0.2, 0.82) for h in (2.83, 2)], 4, summarise,
                      table, WORKER)


if __name__ == "__main__":
    sys.exit(main())
