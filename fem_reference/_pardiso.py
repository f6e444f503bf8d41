"""MKL PARDISO on a symmetric indefinite matrix, through pypardiso's library handle.

Why PARDISO: measured ~10x faster than SuperLU on these P2/P1 tetrahedral saddle-point
systems (3 s against 30 s at 54k unknowns; SuperLU > 600 s at 190k; ``python -m
validation.bench.fem3d --compare-solvers 2.83`` measures it again), and it
installs as a wheel (pypardiso + mkl).  The symmetric indefinite mode (mtype -2, upper
triangle, Bunch-Kaufman pivots with symmetric weighted matching, as MKL advises for saddle
points) stores half the factor of pypardiso's default unsymmetric mode.  Solves call the
library directly with the factors (phase 33): pypardiso's ``solve`` would rebuild the 1-based
index arrays and compare the whole matrix with the factorised one on every call.  Every call
runs on :func:`pillar_xval.threads.thread_count` threads (MKL's, held through threadpoolctl
once the library is loaded).
"""

from __future__ import annotations

import ctypes

import numpy as np
import scipy.sparse as sp

from pillar_xval.threads import limiter

from ._reduced import SolveError


class Pardiso:
    """Factorisation of the symmetric indefinite ``A`` (its upper triangle is used);
    ``solve(b)`` for one or several right-hand sides; ``factor_nonzeros`` reported."""

    def __init__(self, A: sp.csr_matrix, solver=None):
        """``solver``: a ``PyPardisoSolver(mtype=-2)`` to reuse (its construction searches
        the file system for MKL, ~1 s); it then holds one factorisation at a time."""
        if solver is None:
            try:
                from pypardiso import PyPardisoSolver
            except ImportError as exc:
                raise SolveError(f"pypardiso is not installed ({exc}); it is a dependency "
                                 "of the 3D FEM") from None
            solver = PyPardisoSolver(mtype=-2)
        self._solver = solver
        self._threads = limiter()  # MKL is loaded by now
        self._solver.msglvl = 0
        iparm = self._solver.iparm
        iparm[:] = 0
        iparm[0] = 1    # we supply iparm
        iparm[1] = 2    # METIS nested dissection
        iparm[7] = 0    # no internal refinement: ours runs against the full matrix
        iparm[9] = 13   # pivot perturbation 1e-13
        iparm[10] = 1   # symmetric scaling and weighted matching: advised for saddle points
        iparm[12] = 1
        iparm[17] = -1  # report the factor's non-zeros
        iparm[20] = 1   # Bunch-Kaufman 1x1 and 2x2 pivots
        upper = sp.triu(A, format="csr")
        upper.sort_indices()
        self._a = np.ascontiguousarray(upper.data, dtype=float)
        self._ia = (upper.indptr + 1).astype(np.int32)
        self._ja = (upper.indices + 1).astype(np.int32)
        self.n = A.shape[0]
        self._call(12, np.zeros((self.n, 1), order="F"))
        self.factor_nonzeros = int(iparm[17])
        self.perturbed_pivots = int(iparm[13])

    def solve(self, b: np.ndarray) -> np.ndarray:
        b2 = np.asfortranarray(b.reshape(self.n, -1))
        return self._call(33, b2).reshape(b.shape)

    def _call(self, phase: int, b: np.ndarray) -> np.ndarray:
        with self._threads():
            return self._phase(phase, b)

    def _phase(self, phase: int, b: np.ndarray) -> np.ndarray:
        s = self._solver
        x = np.zeros_like(b, order="F")
        err = ctypes.c_int32(0)
        i32 = ctypes.POINTER(ctypes.c_int32)
        f64 = ctypes.POINTER(ctypes.c_double)
        s._mkl_pardiso(s.pt.ctypes.data_as(ctypes.POINTER(s._pt_type[0])),
                       ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
                       ctypes.byref(ctypes.c_int32(s.mtype)), ctypes.byref(ctypes.c_int32(phase)),
                       ctypes.byref(ctypes.c_int32(self.n)), self._a.ctypes.data_as(f64),
                       self._ia.ctypes.data_as(i32), self._ja.ctypes.data_as(i32),
                       s.perm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(b.shape[1])),
                       s.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)),
                       b.ctypes.data_as(f64), x.ctypes.data_as(f64), ctypes.byref(err))
        if err.value != 0:
            raise SolveError(f"MKL PARDISO failed in phase {phase} with error {err.value} "
                             f"({self.n} unknowns)")
        return x

    def __del__(self):
        try:
            self._call(-1, np.zeros((self.n, 1), order="F"))
        except Exception:
            pass
