"""PARDISO's MKL runtime, loaded directly: the same library as pypardiso's search, held by
the toolkit's thread limits, and a solve that agrees with SuperLU.

Tolerance: RTOL_SOLVE, a float64 factorisation of a 600-unknown saddle-point system
(condition number 76) against SuperLU's solution, max norm: measured 1.2e-13 (PARDISO's
ordering) and 1.5e-13 (METIS's order of the unknowns' graph, given); 1e-12 is seven times
that.
"""

from __future__ import annotations

import ctypes.util
import os
import sys

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve

from fem_reference import _pardiso

RTOL_SOLVE = 1e-12


def _pypardiso_path() -> str:
    from pypardiso import PyPardisoSolver

    return os.path.realpath(PyPardisoSolver(mtype=-2).libmkl._name)


def test_the_runtime_is_the_one_pypardiso_finds(monkeypatch):
    """Where no system-wide MKL precedes it (pypardiso asks find_library first), pypardiso's
    scan of the environment ends at the library loaded directly."""
    monkeypatch.delenv("PYPARDISO_MKL_RT", raising=False)
    if ctypes.util.find_library("mkl_rt") is not None:
        pytest.skip("a system-wide mkl_rt comes first in pypardiso's search")
    path = _pardiso.mkl_runtime_path()
    assert path is not None, "the mkl wheel's runtime is not in the environment's lib folder"
    assert os.path.realpath(path) == _pypardiso_path()


def test_the_override_is_honoured(monkeypatch):
    monkeypatch.setenv("PYPARDISO_MKL_RT", "/elsewhere/libmkl_rt.so.2")
    assert _pardiso.mkl_runtime_path() == "/elsewhere/libmkl_rt.so.2"


def test_the_loaded_runtime_is_held_by_the_thread_limits():
    """threadpoolctl sees the MKL that PARDISO calls, so :func:`limiter` sets its threads."""
    from threadpoolctl import ThreadpoolController

    _pardiso._library()
    path = _pardiso.mkl_runtime_path()
    mkl = [m.filepath for m in ThreadpoolController().select(internal_api="mkl").lib_controllers]
    assert os.path.realpath(path) in {os.path.realpath(p) for p in mkl}


def _saddle(n_u: int = 450, n_p: int = 150, seed: int = 3):
    """[[A, B^T], [B, -C]] with A SPD (a shifted 1D Laplacian plus a random SPD part), B
    random sparse, C a small SPD block: symmetric indefinite, as the reduced systems are."""
    rng = np.random.default_rng(seed)
    lap = sp.diags([-np.ones(n_u - 1), 2.5 * np.ones(n_u), -np.ones(n_u - 1)], [-1, 0, 1])
    R = sp.random(n_u, n_u, density=0.01, random_state=seed)
    A = lap + 0.1 * (R @ R.T)
    B = sp.random(n_p, n_u, density=0.02, random_state=seed + 1)
    C = 1e-3 * sp.eye(n_p)
    K = sp.bmat([[A, B.T], [B, -C]], format="csr")
    return K, rng.standard_normal(n_u + n_p)


@pytest.mark.parametrize("given", [False, True])
def test_a_solve_agrees_with_superlu(given):
    K, b = _saddle()
    order = np.argsort(_pardiso.metis_positions(K)) if given else None
    factor = _pardiso.Pardiso(K, order=order)
    x = factor.solve(b)
    reference = spsolve(K.tocsc(), b)
    assert np.max(np.abs(x - reference)) <= RTOL_SOLVE * np.max(np.abs(reference))
    assert factor.ordering == ("given" if given else "matching")


@pytest.mark.parametrize("rows", [None, 3])
def test_the_upper_triangle_is_scipys(rows, monkeypatch):
    """The masked upper triangle equals scipy's triu, columns sorted, on a matrix with empty
    rows, unsorted columns and an empty matrix, in one pass of rows and in passes of 3; cast
    to float32, its values are triu's cast."""
    if rows is not None:
        monkeypatch.setattr(_pardiso, "TRIANGLE_ROWS", rows)
    rng = np.random.default_rng(3)
    A = sp.random(40, 40, density=0.2, random_state=4, format="lil")
    A[7, :] = 0
    A[:, 0] = 0
    A = A.tocsr()
    A.eliminate_zeros()
    for k in range(A.shape[0]):  # scramble each row's column order
        lo, hi = A.indptr[k], A.indptr[k + 1]
        order = lo + rng.permutation(hi - lo)
        A.indices[lo:hi], A.data[lo:hi] = A.indices[order], A.data[order]
    A.has_sorted_indices = False
    for M in (A, sp.csr_matrix((5, 5))):
        U = _pardiso.upper_triangle(M)
        assert U.has_sorted_indices and (U != sp.triu(M)).nnz == 0
        assert all(np.all(np.diff(U.indices[U.indptr[k]:U.indptr[k + 1]]) > 0)
                   for k in range(U.shape[0]))
        single = _pardiso.upper_triangle(M, np.float32)
        assert single.dtype == np.float32 and np.array_equal(single.indices, U.indices)
        assert np.array_equal(single.data, U.data.astype(np.float32))


@pytest.mark.parametrize("pymetis", [True, False])
def test_metis_positions_are_a_nested_dissection(pymetis, monkeypatch):
    """On the 5-point Laplacian of a 60 x 60 grid (and a lone vertex without an edge, which
    is placed too) the positions are a permutation, and the factor in their order holds
    fewer than half the entries of the natural (banded) order's: measured 7.3e4 against
    2.2e5 (a random order's: 9.8e5); from pymetis and, where it cannot be imported, from
    PARDISO's analysis."""
    if not pymetis:
        monkeypatch.setitem(sys.modules, "pymetis", None)  # its import raises ImportError
    m = 60
    lap = sp.diags([-np.ones(m - 1), 4.0 * np.ones(m), -np.ones(m - 1)], [-1, 0, 1])
    grid = sp.kronsum(lap, sp.diags([-np.ones(m - 1), np.zeros(m), -np.ones(m - 1)],
                                    [-1, 0, 1]), format="csr")
    graph = sp.block_diag([grid, sp.csr_matrix((1, 1))], format="csr")
    position = _pardiso.metis_positions(graph)
    assert np.array_equal(np.sort(position), np.arange(m * m + 1))
    nested = _pardiso.Pardiso(grid, order=np.argsort(position[:-1]))
    banded = _pardiso.Pardiso(grid, order=np.arange(m * m))
    assert nested.ordering == banded.ordering == "given"
    assert nested.factor_nonzeros < 0.5 * banded.factor_nonzeros


def test_few_column_solves_run_on_one_thread(monkeypatch):
    """A back-substitution of up to SERIAL_SOLVE_COLUMNS columns holds MKL to one thread; a
    wider one, and the factorisation, to the toolkit's count (here 2, set)."""
    from threadpoolctl import ThreadpoolController

    monkeypatch.setenv("PILLAR_XVAL_THREADS", "2")
    K, b = _saddle()
    seen = []
    call = _pardiso._pardiso

    def spy(solver, mtype, phase, *rest):
        mkl = ThreadpoolController().select(internal_api="mkl").lib_controllers
        seen.append((phase, mkl[0].num_threads))
        return call(solver, mtype, phase, *rest)

    monkeypatch.setattr(_pardiso, "_pardiso", spy)
    factor = _pardiso.Pardiso(K)
    wide = _pardiso.SERIAL_SOLVE_COLUMNS + 1
    factor.solve(b)
    factor.solve(np.column_stack([b] * _pardiso.SERIAL_SOLVE_COLUMNS))
    factor.solve(np.column_stack([b] * wide))
    assert seen == [(12, 2), (33, 1), (33, 1), (33, 2)]
