"""Interleaved before/after timing of fem-3d's assemble phase alone against another checkout:
``python -m validation.bench.assembly3d_ab --baseline DIR --out DIR [--case 0.82:2] ...``.

Each run meshes fem-3d's sector of the A/B benchmark's scene (:data:`.ab.FEM3D_SCENE` at
surface fraction PHI, ``--case PHI:MESH_SIZE``) in a fresh interpreter whose ``PYTHONPATH`` is
the checkout, then times what a solve's assemble phase runs (``assemble_sector`` and
``contact_faces``); the sides alternate (ABBA, :func:`.ab.interleaved`).  Per case and side:
the medians of the phase's CPU time (user and system apart: the system time is the kernel's
fresh pages, which vary most from run to run on a loaded machine) and wall time, the
phase's own peak resident memory (the high-water mark reset after the mesh, where Linux
allows), and whether the two sides built the same scaled matrix bit for bit (SHA-256 of its
arrays and its scale).  Run it on one core and one thread for figures that compare with a
lattice study's cases (``PILLAR_XVAL_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 taskset -c
0 python -m ...``).  Prints the table and writes it with the runs and the load averages to
``DIR/bench_assembly3d_ab.md`` and ``.json``.
"""

from __future__ import annotations

import statistics
import sys

from .ab import median_of, phase_main, phase_rows
from .mesh3d_ab import parse_case

WORKER = r"""
import hashlib, json, math, resource, sys, time
import numpy as np
case = json.loads(sys.argv[1])
from pillar_xval.scenes import load_scene
from fem_reference.solid3d.contact import contact_faces
from fem_reference.solid3d.driver import BLOCK_FACTOR, _setup
from fem_reference.solid3d.system import assemble_sector
from meshes import build_wedge_mesh
scene = load_scene(case["scene"], case["overrides"])
setup = _setup(scene, case["mesh_size"], math.pi / 6, BLOCK_FACTOR, 1.0, {})
mesh = build_wedge_mesh(setup["geometry"]).to_skfem().scaled([1.0 / setup["ell"]] * 3)
def peak():  # the resident high-water mark, GiB
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 2**20
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
try:
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # resets VmHWM: the phase's own peak from here
    reset = True
except OSError:
    reset = False
r0, t = resource.getrusage(resource.RUSAGE_SELF), time.perf_counter()
system = assemble_sector(mesh, setup["materials"], sector_angle=math.pi / 6,
                         clamp_pillar_base=setup["clamp_pillar_base"],
                         rigid_pillars=setup["rigid_pillars"])
contact_faces(mesh, system, lens_meshed=setup["lens_meshed"], lower=setup["lower"],
              floor=setup["floor"])
wall, r1 = time.perf_counter() - t, resource.getrusage(resource.RUSAGE_SELF)
high = peak()  # before the digest below
digest = hashlib.sha256()
for a in (system.K.data, system.K.indices, system.K.indptr, system.scale):
    digest.update(np.ascontiguousarray(a))
print(json.dumps({"wall_s": wall, "user_s": r1.ru_utime - r0.ru_utime,
                  "system_s": r1.ru_stime - r0.ru_stime, "peak_GiB": high,
                  "peak_reset": reset, "elements": int(mesh.t.shape[1]),
                  "unknowns": int(system.K.shape[0]), "entries": int(system.K.nnz),
                  "sha256": digest.hexdigest()}))
"""


def summarise(case: dict, runs: dict) -> list[dict]:
    def cpu(rs):
        return [r["user_s"] + r["system_s"] for r in rs]

    return phase_rows(case, runs, {"cpu_s": cpu, **{f"{k}_median": median_of(k) for k in (
        "wall_s", "user_s", "system_s", "peak_GiB")},
        "cpu_median_s": lambda rs: statistics.median(cpu(rs))},
        ("elements", "unknowns", "entries", "sha256", "peak_reset"), "same_matrix")


def table(rows: list[dict]) -> str:
    lines = ["| case | side | CPU median s (runs) | user s | system s | wall s | CPU speed-up "
             "| peak GiB | elements | unknowns | same matrix |", "|" + "---|" * 11]
    for r in rows:
        lines.append(f"| {r['case']} | {r['side']} | {r['cpu_median_s']:.2f} ("
                     + ", ".join(f"{c:.2f}" for c in r["cpu_s"]) + f") | "
                     f"{r['user_s_median']:.2f} | {r['system_s_median']:.2f} | "
                     f"{r['wall_s_median']:.2f} | {r.get('cpu_speed-up', float('nan')):.2f} | "
                     f"{r['peak_GiB_median']:.3f} | {r['elements']} | {r['unknowns']} | "
                     f"{r.get('same_matrix', '')} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    return phase_main(argv, __doc__, "bench_assembly3d_ab", parse_case,
                      "PHI:MESH_SIZE (repeatable; default: Phi = 0.82 at mesh_size 2 and "
                      "1.41, Phi = 0.2 at 1.41)", ("0.82:2", "0.82:1.41", "0.2:1.41"), 5,
                      summarise, table, WORKER)


if __name__ == "__main__":
    sys.exit(main())
