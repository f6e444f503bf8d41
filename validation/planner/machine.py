"""The machine's speed: a short calibration that carries the planner's seconds to it.

The cost fits (:mod:`.tables`) are seconds measured on one machine at one thread count.
Three reference workloads, a few seconds in all, measure this machine at the thread count
a solve gets (:func:`pillar_xval.threads.thread_count`):

- ``fft``: scipy.fft's rfft2 + irfft2 of a 1024 x 1024 float64 array on that many workers
  (the FFT BEM's transforms);
- ``factorisation``: MKL PARDISO (:class:`fem_reference._pardiso.Pardiso`, the 3D FEM's
  solver) factorising a 7-point Laplacian on a 22^3 grid and solving once;
- ``assembly``: a P1 stiffness matrix assembled as the FEM assembles, vectorised over 20,250
  tetrahedra (local matrices by einsum, then a sparse sum of duplicates); numpy's own work,
  on one thread.

Each is the median of :data:`REPEATS` runs: the machine as a solve meets it, its other users
included (the fastest run would be the machine alone, which a solve on a shared machine
seldom gets: on this 2-core machine under a load average of 5-6, predictions from the
fastest runs came out 2.7-4x short of the solves, from the medians 1.1-1.6x).
A fit names the workloads its time follows (its ``workload`` shares) and carries the
reference seconds of the machine it was measured on (``machine``); its prediction here is
its time times the sum over workloads of share x (seconds here / reference seconds).

The calibration is cached per machine and thread count under ``$PILLAR_XVAL_CACHE/machine``
(default ``~/.cache/pillar-xval/machine``) and verified when read: a file that does not
parse, is of another format, machine, thread count or library version, or whose digest does
not match its content is measured again and replaced (atomically).  ``PILLAR_XVAL_MACHINE=
reference`` plans with the fits' own seconds (no calibration): the same plan on every
machine.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import statistics
import time
from pathlib import Path

from pillar_xval.outcome import cache_root, write_atomic
from pillar_xval.scenes import InputError
from pillar_xval.threads import cpu_count, limited, thread_count, threads_override

__all__ = ["FORMAT", "MACHINE_ENV", "MODES", "WORKLOADS", "cache_folder", "calibration",
           "identity", "measure", "mode", "seconds_here", "speed_factor"]

FORMAT = "pillar-xval machine calibration 1"
WORKLOADS = ("fft", "factorisation", "assembly")
REPEATS = 5
MACHINE_ENV = "PILLAR_XVAL_MACHINE"
MODES = ("here", "reference")
# Sizes of the reference workloads (module docstring): each run takes some 10-100 ms here.
FFT_SIDE = 1024
LAPLACIAN_SIDE = 22
ASSEMBLY_CUBES = 15


def mode() -> str:
    """``PILLAR_XVAL_MACHINE``: "here" (default, this machine's calibration) or "reference"
    (the fits' own seconds)."""
    value = os.environ.get(MACHINE_ENV, "").strip() or "here"
    if value not in MODES:
        raise InputError(f"{MACHINE_ENV} = {value!r}: choose one of {', '.join(MODES)}")
    return value


def _fft(threads: int):
    import numpy as np
    import scipy.fft as sfft

    a = np.random.default_rng(0).random((FFT_SIDE, FFT_SIDE))
    return lambda: sfft.irfft2(sfft.rfft2(a, workers=threads), s=a.shape, workers=threads)


def _laplacian(side: int):
    """The 7-point Laplacian on a side^3 grid (CSR, symmetric positive definite)."""
    import scipy.sparse as sp

    line = sp.diags([-1.0, 2.0, -1.0], [-1, 0, 1], shape=(side, side))
    eye = sp.identity(side)
    return (sp.kron(sp.kron(line, eye), eye) + sp.kron(sp.kron(eye, line), eye)
            + sp.kron(sp.kron(eye, eye), line)).tocsr()


def _factorisation(threads: int):
    import numpy as np

    from fem_reference._pardiso import Pardiso, PardisoHandle

    K = _laplacian(LAPLACIAN_SIDE)
    b = np.ones(K.shape[0])
    solver = PardisoHandle()  # made once: MKL is found then
    return lambda: Pardiso(K, solver).solve(b)


def _tetrahedra(cubes: int):
    """Nodes (n, 3) and tetrahedra (m, 4) of a cubes^3 block, six tetrahedra a cube."""
    import numpy as np

    s = cubes + 1
    g = np.arange(s)
    nodes = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3).astype(float)
    i, j, k = (a.reshape(-1) for a in np.meshgrid(*(np.arange(cubes),) * 3, indexing="ij"))
    corner = [((i + a) * s + (j + b)) * s + (k + c)
              for a, b, c in ((0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0),
                              (0, 0, 1), (1, 0, 1), (0, 1, 1), (1, 1, 1))]
    # Kuhn's six tetrahedra of a cube, all sharing its main diagonal 0-7.
    paths = ((1, 3), (1, 5), (2, 3), (2, 6), (4, 5), (4, 6))
    tets = [np.stack([corner[0], corner[a], corner[b], corner[7]], -1) for a, b in paths]
    return nodes, np.concatenate(tets)


def _assembly(threads: int):
    import numpy as np
    import scipy.sparse as sp

    nodes, tets = _tetrahedra(ASSEMBLY_CUBES)
    n = nodes.shape[0]

    def run():
        x = nodes[tets]                                  # (m, 4, 3)
        jac = x[:, 1:] - x[:, :1]                        # (m, 3, 3)
        inv = np.linalg.inv(jac)
        ref = np.array([[-1.0, -1.0, -1.0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        grads = np.einsum("aj,mij->mai", ref, inv)      # (m, 4, 3)
        volume = np.abs(np.linalg.det(jac)) / 6.0
        local = np.einsum("mai,mbi,m->mab", grads, grads, volume)
        rows = np.repeat(tets, 4, axis=1).reshape(-1)
        cols = np.tile(tets, (1, 4)).reshape(-1)
        return sp.coo_matrix((local.reshape(-1), (rows, cols)), shape=(n, n)).tocsr()

    return run


_BUILDERS = {"fft": _fft, "factorisation": _factorisation, "assembly": _assembly}


def measure(threads: int | None = None, repeats: int = REPEATS) -> dict:
    """Seconds of each reference workload on ``threads`` threads (default
    :func:`pillar_xval.threads.thread_count`): the median of ``repeats`` runs after one
    unmeasured run (first-call costs: library loading, plans)."""
    threads = thread_count() if threads is None else int(threads)
    seconds = {}
    with threads_override(threads):
        for name in WORKLOADS:
            run = _BUILDERS[name](threads)
            with limited(threads):
                run()
                times = []
                for _ in range(repeats):
                    start = time.perf_counter()
                    run()
                    times.append(time.perf_counter() - start)
            seconds[name] = statistics.median(times)
    return seconds


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def identity(threads: int) -> dict:
    """What a calibration holds for: the host, its CPU, the CPUs this process may use, the
    thread count, and the versions of the libraries the workloads run."""
    import numpy
    import scipy

    return {"host": platform.node(), "cpu": _cpu_model(), "cpus": cpu_count(),
            "threads": int(threads), "numpy": numpy.__version__, "scipy": scipy.__version__,
            "python": platform.python_version()}


def cache_folder() -> Path:
    return cache_root("machine")


def _digest(body: dict) -> str:
    return hashlib.sha256(json.dumps(body, sort_keys=True).encode()).hexdigest()


def _verified(path: Path, ident: dict) -> dict | None:
    """The seconds of the calibration at ``path`` if it is whole, this format, this machine
    and thread count, and its digest matches; None otherwise."""
    try:
        doc = json.loads(path.read_text())
        body = {k: doc[k] for k in ("format", "identity", "seconds", "repeats", "created")}
        ok = (doc["format"] == FORMAT and doc["identity"] == ident
              and doc["digest"] == _digest(body)
              and all(isinstance(doc["seconds"].get(w), (int, float))
                      and math.isfinite(doc["seconds"][w]) and doc["seconds"][w] > 0
                      for w in WORKLOADS))
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None
    return {w: float(doc["seconds"][w]) for w in WORKLOADS} if ok else None


def calibration(threads: int | None = None, fresh: bool = False) -> dict:
    """This machine's calibration at ``threads`` (default :func:`thread_count`): read from
    the cache when a verified one is there (``fresh``: measured again), else measured and
    cached.  ``{"threads", "seconds", "cached", "path"}``."""
    threads = thread_count() if threads is None else int(threads)
    ident = identity(threads)
    path = cache_folder() / f"{_digest(ident)[:20]}.json"
    seconds = None if fresh else _verified(path, ident)
    cached = seconds is not None
    if seconds is None:
        seconds = measure(threads)
        body = {"format": FORMAT, "identity": ident, "seconds": seconds, "repeats": REPEATS,
                "created": time.strftime("%Y-%m-%dT%H:%M:%S")}
        try:
            write_atomic(path, json.dumps({**body, "digest": _digest(body)}, indent=1))
        except OSError:  # a read-only cache: measured each time, the plan unchanged
            pass
    return {"threads": threads, "seconds": seconds, "cached": cached, "path": str(path)}


def seconds_here() -> dict | None:
    """This machine's seconds per workload at :func:`thread_count` threads, None where the
    planner plans with the fits' own seconds (``PILLAR_XVAL_MACHINE=reference``)."""
    if mode() == "reference":
        return None
    return calibration()["seconds"]


def speed_factor(workload: dict, reference: dict, here: dict | None) -> float:
    """Time here over time on the reference machine of a fit whose time follows
    ``workload`` (shares summing to 1): sum of share x here / reference seconds; 1 without a
    calibration here or a reference."""
    if not here or not workload or not reference:
        return 1.0
    ref = reference["seconds"]
    return float(sum(share * here[w] / ref[w] for w, share in workload.items()))
