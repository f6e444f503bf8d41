"""MKL PARDISO on a symmetric indefinite matrix, called through ctypes on MKL's runtime.

Why PARDISO: measured ~10x faster than SuperLU on these P2/P1 tetrahedral saddle-point
systems (3 s against 30 s at 54k unknowns; SuperLU > 600 s at 190k; ``python -m
validation.bench.fem3d --compare-solvers 2.83`` measures it again), and it
installs as a wheel (pypardiso + mkl).  The runtime is loaded from the environment's library
folder where the ``mkl`` wheel puts it (pypardiso's own search, its fallback, scans the whole
environment: ~0.4-0.9 s a process).  The symmetric indefinite mode (mtype -2, upper
triangle, Bunch-Kaufman pivots) stores half the factor of pypardiso's default unsymmetric
mode.  Solves call the library directly with the factors (phase 33): pypardiso's ``solve``
would rebuild the 1-based index arrays and compare the whole matrix with the factorised one
on every call.

Ordering.  By default PARDISO orders the unknowns by METIS nested dissection after a
symmetric weighted matching, which MKL advises for saddle points: the matching pairs each
pressure, whose diagonal vanishes at nu = 1/2, with a displacement for a 2x2 pivot.  A caller
that knows its mesh may give the elimination order instead (``order``): the 3D model's
(:func:`.solid3d.system.elimination_order`) follows METIS's nested dissection of the mesh's
vertex graph (:func:`metis_positions`) and puts each pressure after the displacements around
its vertex, so that its pivot carries the Schur complement -B A^-1 B^T of those
displacements and no matching is needed.  Eliminating the unknowns mesh node by mesh node
this way (paper-fig3-sparse, Phi = 0.82, mesh_size 2.83, 179k unknowns; load 7-12) took
4.3-4.4 s with the analysis against 7-15 s for the matching's ordering, with 2.6 % fewer
factor entries, no perturbed pivot and the same residual (7.6e-15 against 7.8e-15).  Should a
pivot still be perturbed, the matrix is factorised again the default way.

Precision.  ``single=True`` factorises and solves in float32 (MKL's iparm[27]): half the
factor's memory, the numeric factorisation 1.55x and a solve 1.26x faster in CPU time at
mesh_size 2 (335k unknowns, medians of 3 interleaved); a solve is then accurate to ~1e-5,
and the caller refines it against the float64 matrix (:mod:`.solid3d.system`).  Every call
runs on :func:`pillar_xval.threads.thread_count` threads (MKL's, held through threadpoolctl
once the library is loaded), but a back-substitution of at most :data:`SERIAL_SOLVE_COLUMNS`
columns runs on one: it streams the factor once, bound by memory, and a second thread gained
nothing (1, 3 and 32 columns at 6e4 unknowns, one solve after another), while holding MKL to
two threads around each of the contact phase's back-substitutions (where OpenBLAS runs between
them) made each 2.3x as long and as costly in CPU time on a shared 2-core machine
(``validation/bench/measured/fem3d_ab.md``).
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os
import sys

import numpy as np
import scipy.sparse as sp

from pillar_xval.threads import limiter

from ._reduced import SolveError

# iparm entries (0-based, as MKL's C interface numbers them) set for every factorisation.
_IPARM = {0: 1,    # we supply iparm
          1: 2,    # METIS nested dissection
          7: 0,    # no internal refinement: ours runs against the full matrix
          9: 13,   # pivot perturbation 1e-13
          17: -1,  # report the factor's non-zeros
          20: 1}   # Bunch-Kaufman 1x1 and 2x2 pivots
# The default ordering's symmetric scaling and weighted matching (advised for saddle points).
_MATCHING = {10: 1, 12: 1}
# Back-substitutions of up to this many columns run on one thread (see the module docstring).
SERIAL_SOLVE_COLUMNS = 32


class Pardiso:
    """Factorisation of the symmetric indefinite ``A`` (its upper triangle is used);
    ``solve(b)`` for one or several right-hand sides (float64 in and out);
    ``factor_nonzeros``, ``perturbed_pivots``, ``ordering`` ("given" or "matching") and
    ``single`` (the factor is float32) reported."""

    def __init__(self, A: sp.csr_matrix, solver=None, order: np.ndarray | None = None,
                 single: bool = False):
        """``solver``: a :class:`PardisoHandle` to reuse; it then holds one
        factorisation at a time (default: a handle of its own, MKL found once per process).
        ``order``: the unknowns in the order they are eliminated (a permutation of
        0..n-1; see the module docstring), factorised without a matching where no pivot is
        perturbed, else as with None: METIS after a weighted matching.  ``single``:
        factorise and solve in float32 (MKL's iparm[27]; half the factor's memory, its
        solves ~1e-6 of the exact ones: the caller refines them against ``A``)."""
        self._solver = PardisoHandle() if solver is None else solver
        self._threads = limiter()  # MKL is loaded by now
        self._serial = None  # limiter(1), made at the first few-column solve
        self._solver.msglvl = 0
        self.n = A.shape[0]
        self.single = bool(single)
        self._dtype = np.float32 if self.single else np.float64
        # PARDISO's arrays: the triangle's own, its indices 1-based in place
        upper = upper_triangle(A, self._dtype)
        self._a = np.ascontiguousarray(upper.data)
        self._ia = upper.indptr.astype(np.int32)
        self._ja = upper.indices.astype(np.int32, copy=False)
        del upper
        self._ia += 1
        self._ja += 1
        self._perm = np.zeros(self.n, dtype=np.int32)
        self._mtype = -2
        self._factorised = False
        self.ordering = "matching"
        if order is not None:
            self._perm = (np.asarray(order) + 1).astype(np.int32)  # the k-th eliminated at k
            self._factorise(user_ordering=True)
            if self.perturbed_pivots == 0:
                self.ordering = "given"
                return
            self._release()
            self._perm = np.zeros(self.n, dtype=np.int32)
        self._factorise(user_ordering=False)

    def _factorise(self, user_ordering: bool) -> None:
        iparm = self._solver.iparm
        iparm[:] = 0
        for k, v in _IPARM.items():
            iparm[k] = v
        iparm[27] = int(self.single)
        if user_ordering:
            iparm[4] = 1  # our permutation, in perm
        else:
            for k, v in _MATCHING.items():
                iparm[k] = v
        self._call(12, np.zeros((self.n, 1), dtype=self._dtype, order="F"))
        self._factorised = True
        self.factor_nonzeros = int(iparm[17])
        self.perturbed_pivots = int(iparm[13])

    def solve(self, b: np.ndarray) -> np.ndarray:
        b2 = np.asfortranarray(b.reshape(self.n, -1), dtype=self._dtype)
        serial = b2.shape[1] <= SERIAL_SOLVE_COLUMNS
        if serial and self._serial is None:
            self._serial = limiter(1)
        return self._call(33, b2, serial).astype(float, copy=False).reshape(b.shape)

    def _call(self, phase: int, b: np.ndarray, serial: bool = False) -> np.ndarray:
        with (self._serial if serial else self._threads)():
            return _pardiso(self._solver, self._mtype, phase, self._a, self._ia, self._ja,
                            self._perm, b)

    def _release(self) -> None:
        if self._factorised:
            self._factorised = False
            self._call(-1, np.zeros((self.n, 1), dtype=self._dtype, order="F"))

    def __del__(self):
        try:
            self._release()
        except Exception:
            pass


class PardisoHandle:
    """One factorisation's PARDISO handle (``pt``) and parameters (``iparm``), with MKL's
    ``pardiso`` found once per process (:func:`_library`)."""

    def __init__(self):
        self._mkl_pardiso, self._pt_type = _library()
        self.pt = np.zeros(64, dtype=self._pt_type[1])
        self.iparm = np.zeros(64, dtype=np.int32)
        self.msglvl = 0


# Where an environment's MKL runtime lies below its prefix (Linux and macOS; Windows).
_MKL_GLOBS = ("lib/libmkl_rt.so*", "lib/libmkl_rt*.dylib", "Library/bin/mkl_rt*.dll")


def mkl_runtime_path() -> str | None:
    """The MKL runtime this process loads PARDISO from: ``PYPARDISO_MKL_RT`` where set (the
    override pypardiso honours), else the shortest-named ``mkl_rt`` library directly in the
    environment's library folder (where the ``mkl`` wheel puts it), else None (pypardiso's
    own search then runs: ``find_library`` and a recursive scan of ``sys.prefix``, ~1 s)."""
    override = os.environ.get("PYPARDISO_MKL_RT")
    if override:
        return override
    for pattern in _MKL_GLOBS:
        found = sorted(glob.glob(os.path.join(sys.prefix, pattern)), key=len)
        if found:
            return found[0]
    return None


@functools.lru_cache(maxsize=1)
def _library():
    """MKL's ``pardiso`` function and the handle's integer type (ctypes, numpy), found once:
    loaded from :func:`mkl_runtime_path`, or through pypardiso's search where that finds
    nothing loadable."""
    path = mkl_runtime_path()
    function = None
    if path is not None:
        try:
            function = ctypes.CDLL(path).pardiso
        except (OSError, AttributeError):
            function = None
    if function is None:
        try:
            from pypardiso import PyPardisoSolver
        except ImportError as exc:
            raise SolveError(f"pypardiso is not installed ({exc}); it is a dependency of "
                             "the 3D FEM") from None
        return PyPardisoSolver(mtype=-2)._mkl_pardiso, _PT_TYPE
    function.argtypes = [ctypes.POINTER(_PT_TYPE[0])] + [ctypes.POINTER(ctypes.c_int32)] * 5 \
        + [ctypes.c_void_p] + [ctypes.POINTER(ctypes.c_int32)] * 6 \
        + [ctypes.c_void_p] * 2 + [ctypes.POINTER(ctypes.c_int32)]
    function.restype = None
    return function, _PT_TYPE


# The handle's entries are pointers: 64-bit integers on a 64-bit process.
_PT_TYPE = (ctypes.c_int64, np.int64) if ctypes.sizeof(ctypes.c_void_p) == 8 else \
    (ctypes.c_int32, np.int32)


# Separators METIS tries at each bisection of :func:`metis_positions` (the fewest flops
# of 1-5 on the lattice study's levels).
METIS_SEPARATORS = 2
# Rows per pass of :func:`upper_triangle`.
TRIANGLE_ROWS = 8192


def upper_triangle(A: sp.csr_matrix, dtype=None) -> sp.csr_matrix:
    """The upper triangle of the CSR matrix ``A``, its rows' columns sorted, its values cast
    to ``dtype`` (default: A's): the entries picked by one mask built a few thousand rows at
    a time (scipy's ``triu`` goes through a coordinate copy; arrays of A's entries' rows and
    running counts were 0.3 GB of fresh pages at Phi = 0.2, mesh_size 1.41)."""
    A = sp.csr_matrix(A)
    n = A.shape[0]
    keep = np.empty(A.nnz, dtype=bool)
    counts = np.zeros(n, dtype=np.int64)  # entries kept in each row
    for r0 in range(0, n, TRIANGLE_ROWS):
        r1 = min(r0 + TRIANGLE_ROWS, n)
        lo, hi = A.indptr[r0], A.indptr[r1]
        rows = np.repeat(np.arange(r0, r1, dtype=A.indices.dtype), np.diff(A.indptr[r0:r1 + 1]))
        np.greater_equal(A.indices[lo:hi], rows, out=keep[lo:hi])
        counts[r0:r1] = np.bincount(rows[keep[lo:hi]] - r0, minlength=r1 - r0)
    indptr = np.zeros(n + 1, dtype=A.indptr.dtype)
    np.cumsum(counts, out=indptr[1:])
    data = A.data[keep].astype(A.dtype if dtype is None else dtype, copy=False)
    upper = sp.csr_matrix((data, A.indices[keep], indptr), shape=A.shape)
    upper.sort_indices()
    return upper


def metis_positions(graph: sp.csr_matrix) -> np.ndarray:
    """The place of each vertex of ``graph`` (a symmetric pattern; any values, any
    triangle, the diagonal ignored) in METIS's nested-dissection order (METIS 5 through
    pymetis, :data:`METIS_SEPARATORS` separators tried at each bisection).

    PARDISO's own METIS (its analysis with iparm[1] = 2, the order used before) asked 7-16 %
    more factorisation work on the lattice study's levels (iparm[18], MFLOP, one analysis
    each: Phi = 0.2 at mesh_size 2 and 1.41, 1.81e4 and 7.17e4 against 1.56e4 and 6.44e4;
    Phi = 0.82 at 2.83, 2 and 1.41, 4.66e4, 1.50e5 and 6.03e5 against 4.24e4, 1.33e5 and
    5.62e5) for 2-5 % more factor entries; METIS's default of one separator, 2-8 % more
    than two, and three to five no fewer than two.  Where pymetis cannot be imported (a
    lent machine's kit carries pure-Python packages only) PARDISO's analysis orders the
    graph as before."""
    try:
        import pymetis
    except ImportError:
        return _analysis_positions(graph)

    nn = graph.shape[0]
    edges = sp.coo_matrix(graph)
    off = edges.row != edges.col
    row, col = edges.row[off], edges.col[off]
    pattern = sp.csr_matrix((np.ones(2 * len(row)), (np.concatenate([row, col]),
                                                      np.concatenate([col, row]))),
                            shape=(nn, nn))  # both triangles; duplicates summed
    options = pymetis.Options()
    options.nseps = METIS_SEPARATORS
    perm, _ = pymetis.nested_dissection(pymetis.CSRAdjacency(pattern.indptr, pattern.indices),
                                        options=options)
    position = np.empty(nn, dtype=np.int64)
    position[np.asarray(perm, dtype=np.int64)] = np.arange(nn)
    return position


def _analysis_positions(graph: sp.csr_matrix) -> np.ndarray:
    """:func:`metis_positions` from PARDISO's analysis (its METIS, one separator)."""
    solver = PardisoHandle()
    nn = graph.shape[0]
    pattern = sp.csr_matrix((np.ones(graph.nnz), graph.indices, graph.indptr), shape=(nn, nn))
    # the upper triangle of the symmetric pattern, with the diagonal (a lone vertex has none)
    upper = sp.triu(pattern + pattern.T + sp.eye(nn, format="csr"), format="csr")
    upper.sort_indices()
    # Any positive definite values with this pattern: only the analysis runs.
    upper.data[:] = -1.0 / nn
    upper.setdiag(2.0)
    a = np.ascontiguousarray(upper.data)
    ia = (upper.indptr + 1).astype(np.int32)
    ja = (upper.indices + 1).astype(np.int32)
    iparm = solver.iparm
    iparm[:] = 0
    for k, v in ((0, 1), (1, 2), (4, 2)):  # METIS, and return its permutation in perm
        iparm[k] = v
    perm = np.zeros(nn, dtype=np.int32)
    b = np.zeros((nn, 1), order="F")
    with limiter()():
        _pardiso(solver, 2, 11, a, ia, ja, perm, b)
        _pardiso(solver, 2, -1, a, ia, ja, perm, b)
    position = np.empty(nn, dtype=np.int64)
    position[perm - 1] = np.arange(nn)
    return position


def _pardiso(solver, mtype: int, phase: int, a, ia, ja, perm, b: np.ndarray) -> np.ndarray:
    """One call of MKL's pardiso on ``solver``'s handle and iparm (raises SolveError)."""
    s = solver
    n = len(ia) - 1
    x = np.zeros_like(b, order="F")
    err = ctypes.c_int32(0)
    i32 = ctypes.POINTER(ctypes.c_int32)
    real = ctypes.POINTER(ctypes.c_float if b.dtype == np.float32 else ctypes.c_double)
    s._mkl_pardiso(s.pt.ctypes.data_as(ctypes.POINTER(s._pt_type[0])),
                   ctypes.byref(ctypes.c_int32(1)), ctypes.byref(ctypes.c_int32(1)),
                   ctypes.byref(ctypes.c_int32(mtype)), ctypes.byref(ctypes.c_int32(phase)),
                   ctypes.byref(ctypes.c_int32(n)), a.ctypes.data_as(real),
                   ia.ctypes.data_as(i32), ja.ctypes.data_as(i32),
                   perm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(b.shape[1])),
                   s.iparm.ctypes.data_as(i32), ctypes.byref(ctypes.c_int32(0)),
                   b.ctypes.data_as(real), x.ctypes.data_as(real), ctypes.byref(err))
    if err.value != 0:
        raise SolveError(f"MKL PARDISO failed in phase {phase} with error {err.value} "
                         f"({n} unknowns)")
    return x
