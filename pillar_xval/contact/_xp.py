"""Array backends: the few primitives the contact solvers need beyond the array API standard.

Solvers written against an array namespace ``xp`` (numpy, cupy, or any library implementing
the Python array API standard) run unchanged on the CPU or a GPU.  The standard leaves out a
handful of operations the solvers need; a backend supplies them:

- ``dot(a, b)``: the scalar product of two vectors, as a Python float;
- ``segment_sum(index, weights, n)``: sums of ``weights`` per integer label (numpy's bincount);
- ``segments(index, n)``: the same sums as a function of ``weights`` alone, for an ``index``
  used again and again (set up once: numpy sums runs of equal consecutive labels);
- ``spreader(index)``: ``(values, lo=0, hi=None) -> values[index[lo:hi]]`` (one value per
  label out to every entry of that label) for an ``index`` used again and again (numpy
  repeats each run's value; a range, for a chunk of entries);
- ``chunks(work, n, size=1)``: ``work(lo, hi)`` over contiguous pieces of [0, n) that cover
  it, at once where the backend has threads for it (elementwise work and exact reductions,
  the same bits in any split; ``size`` elements per unit of n); in one piece here;
- ``put(target, index, values)``: ``target[index] = values`` on a 1-D array (the standard
  has integer-array gathers, ``xp.take``, but no scatters); returns the updated array;
- ``asarray`` / ``to_numpy``: to and from host numpy arrays.

:class:`NumpyArrays` is the default everywhere (the FEM's contact solves use it unchanged);
:class:`CupyArrays` needs the optional ``[gpu]`` extra.  Everything is float64.

References
----------
.. [1] Consortium for Python Data API Standards, "Python array API standard", 2023.12,
   https://data-apis.org/array-api/
"""

from __future__ import annotations

import numpy as np


def one_piece(work, n: int, size: int = 1) -> None:
    """``chunks`` of a backend without threads for it: ``work(0, n)``."""
    work(0, n)


class NumpyArrays:
    """numpy on the CPU."""

    name = "numpy"
    device = "cpu"
    xp = np
    numpy_like = np  # numpy's own API (beyond the standard), for code written against it

    def asarray(self, a, dtype=None):
        return np.asarray(a, dtype=dtype)

    def to_numpy(self, a) -> np.ndarray:
        return np.asarray(a)

    def dot(self, a, b) -> float:
        # einsum, not BLAS ddot: a threaded ddot wakes OpenBLAS threads that then spin against
        # the FFT worker threads (measured 0.04 to 8 ms for 2e5 cells, against a steady 0.1 ms).
        return float(np.einsum("i,i->", a, b))

    def segment_sum(self, index, weights, n: int):
        return np.bincount(index, weights=weights, minlength=n)

    def segments(self, index, n: int):
        """``weights -> segment_sum(index, weights, n)`` for a fixed ``index``.  Where the
        labels come in runs (a grid's pillar cells: a run per pillar and row), each run is
        summed by one ``np.add.reduceat`` and the runs by a bincount over the runs: a pass
        over contiguous memory instead of a scattered add per cell (0.3 against 3.1 ms on
        1.1e6 cells in 25e3 runs).  The sums differ from a bincount's by round-off only.  The
        runs are summed in the backend's ``chunks`` of runs (each run's reduceat over the
        same elements: the same bits in any split)."""
        index = np.asarray(index)
        starts = run_starts(index)
        if starts is None:
            return lambda weights: np.bincount(index, weights=weights, minlength=n)
        labels, ends = index[starts], np.append(starts[1:], index.size)
        per_run = max(index.size // starts.size, 1)

        def sums(weights):
            runs = np.empty(starts.size)

            def part(r0, r1):
                if r1 > r0:
                    lo = starts[r0]
                    np.add.reduceat(weights[lo:ends[r1 - 1]], starts[r0:r1] - lo,
                                    out=runs[r0:r1])

            self.chunks(part, starts.size, per_run)
            return np.bincount(labels, weights=runs, minlength=n)

        return sums

    def spreader(self, index):
        """``(values, lo=0, hi=None) -> values[index[lo:hi]]`` for a fixed ``index``: where the
        labels come in runs, each run's value repeated (``np.repeat``, a sequential write: 0.3
        against 0.7 ms for a gather of 6.8e5 cells in 1.5e4 runs), the runs cut at ``lo``
        and ``hi`` (a chunk of entries, spread by the thread that uses it); the same values
        as the gather."""
        index = np.asarray(index)
        starts = run_starts(index)
        if starts is None:
            return lambda values, lo=0, hi=None: np.take(values, index[lo:hi])
        labels = index[starts]
        lengths = np.diff(np.append(starts, index.size))

        def spread(values, lo=0, hi=None):
            lo, hi, _ = slice(lo, hi).indices(index.size)
            if lo == 0 and hi == index.size:
                return np.repeat(np.take(values, labels), lengths)
            if hi <= lo:
                return np.empty(0, dtype=np.result_type(values))
            r0 = int(np.searchsorted(starts, lo, "right")) - 1  # the runs that hold lo, hi - 1
            r1 = int(np.searchsorted(starts, hi, "left"))
            cut = lengths[r0:r1].copy()
            cut[0] -= lo - starts[r0]
            cut[-1] -= starts[r1 - 1] + lengths[r1 - 1] - hi
            return np.repeat(np.take(values, labels[r0:r1]), cut)

        return spread

    def put(self, target, index, values):
        target[index] = values
        return target

    chunks = staticmethod(one_piece)


def run_starts(index):
    """Positions where a run of equal consecutive labels of ``index`` begins, or None where
    the runs are too short to pay (fewer than ``RUNS_PAY`` labels on average) or there are
    none."""
    if index.size == 0:
        return None
    starts = np.flatnonzero(np.concatenate(([True], index[1:] != index[:-1])))
    return None if starts.size * RUNS_PAY > index.size else starts


# NumpyArrays.segments sums runs when they average at least this many labels.
RUNS_PAY = 4


class CupyArrays:
    """cupy on the current CUDA device (``pip install -e '.[gpu]'``)."""

    name = "cupy"
    device = "gpu"

    def __init__(self, fused: bool = True):
        import cupy

        self._cp = cupy
        self.numpy_like = cupy
        # The CG's passes as fused kernels (pillar_xval.contact._cuda), made on first use;
        # ``fused=False`` keeps the array passes (an A/B of the two; cupy stand-ins without
        # RawModule have only those).
        self.fused = fused and hasattr(cupy, "RawModule")
        self._passes = None
        try:  # the standard's names (asinh, concat, ...) on every cupy version
            import array_api_compat.cupy as xp
        except ImportError:  # cupy >= 14 mirrors numpy 2's namespace itself
            xp = cupy
        self.xp = xp

    def asarray(self, a, dtype=None):
        return self._cp.asarray(a, dtype=dtype)

    def to_numpy(self, a) -> np.ndarray:
        return self._cp.asnumpy(a)

    def dot(self, a, b) -> float:
        return float(self._cp.dot(a, b))

    def segment_sum(self, index, weights, n: int):
        # A scatter-add into n zeros, not cupy.bincount: that one reads max(index) back to
        # the host first, a synchronisation per call (0.6 ms each, 7 % of a 1e7-cell solve
        # on an H200).
        out = self._cp.zeros(n, dtype=weights.dtype)
        self._cp.add.at(out, index, weights)
        return out

    def segments(self, index, n: int):
        """``weights -> segment_sum(index, weights, n)`` for a fixed ``index``, as the product
        of the (n x len(index)) incidence matrix in CSR (cuSPARSE): one launch, each label's
        sum in a fixed order (the same bits on every run), where the scatter-add's atomics
        contend on few labels (a pillar's thousands of cells) in no fixed order."""
        m = int(index.shape[0])
        cp = self._cp
        incidence = self.sparse(cp.asarray(index), cp.arange(m), cp.ones(m, dtype=cp.float64),
                                n, m)
        return lambda weights: incidence @ weights

    def sparse(self, rows, cols, values, n: int, columns: int | None = None):
        """The CSR matrix (cupyx) of (row, column, value) triples, ``n`` rows and ``columns``
        (default ``n``) columns: COO with the entries in any order, then CSR for the
        products (the callers' entries are distinct)."""
        import cupyx.scipy.sparse as csp

        shape = (n, n if columns is None else columns)
        return csp.coo_matrix((values, (rows, cols)), shape=shape).tocsr()

    def spreader(self, index):
        return lambda values, lo=0, hi=None: self._cp.take(values, index[lo:hi])

    def put(self, target, index, values):
        target[index] = values
        return target

    @property
    def cg_passes(self):
        """The CG's passes fused into one kernel each, or None (``fused`` off)."""
        if self.fused and self._passes is None:
            from ._cuda import CudaPasses

            self._passes = CudaPasses(self._cp)
        return self._passes

    chunks = staticmethod(one_piece)


NUMPY = NumpyArrays()
