"""Devices of the FFT model: an array backend (:mod:`pillar_xval.contact._xp`) plus FFTs, sparse matrices
and the size limit of the padded FFT grid.

``select_backend("cpu" | "gpu" | "auto")`` gives the backend :func:`bem_solver.solve_fft`
runs on: numpy and scipy.fft on the CPU (the default), cupy and cuFFT on a CUDA GPU.
``available_devices()`` lists what this machine offers (for the CLI's ``--device``).
"""

from __future__ import annotations

import functools
import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from pillar_xval.contact._xp import CupyArrays, NumpyArrays
from pillar_xval.scenes import InputError
from pillar_xval.threads import thread_count

from ._fft_grid import MAX_FFT_POINTS
from ._limits import DEVICES

GPU_INSTALL = "pip install -e '.[gpu]' (cupy-cuda12x; with CUDA 13, pip install cupy-cuda13x)"
# GPU: device bytes per padded FFT point at the peak of an operator application (kernel
# spectrum 4, complex column transforms 16 + 8, cuFFT work area ~16, vectors) with a margin;
# the limit is the free device memory over this.
GPU_BYTES_PER_FFT_POINT = 64
# The elastic pillar's term on a GPU, per padded FFT point: per top cell ~440 bytes (kept: 13
# trigonometric columns 104, its two projections' 6 entries 72, base moments 24, order and
# position 16, diagonal and owner 16; in an application, two cells x 13 temporaries 208), at
# most one top cell per 4 padded points, with a margin.
GPU_ELASTIC_BYTES_PER_FFT_POINT = 128


def fft_point_limit(be, elastic: bool) -> int:
    """The padded FFT points a solve on ``be`` may take: its ``max_fft_points``, on a GPU
    shared with the elastic pillar's term where ``elastic``."""
    if not elastic or isinstance(be, NumpyDevice):
        return be.max_fft_points
    return be.max_fft_points * GPU_BYTES_PER_FFT_POINT \
        // (GPU_BYTES_PER_FFT_POINT + GPU_ELASTIC_BYTES_PER_FFT_POINT)


# Elementwise work of the numpy path on fewer elements than this runs in one piece: below it
# handing chunks to threads costs more than it saves.
CHUNK_MIN = 1 << 16
# The numpy path's scalar products are summed over blocks of this many entries, each block's
# product whole and the blocks' sums added exactly (math.fsum): the blocks are shared among the
# FFT threads, and the bits do not depend on how many there are.
DOT_BLOCK = 1 << 15

_POOLS: dict = {}


def in_chunks(work, n: int, workers: int, size: int = 1) -> None:
    """``work(lo, hi)`` over [0, n) in ``workers`` contiguous chunks at once (numpy releases
    the GIL in elementwise work, scatters, gathers and reductions): each element gets the
    same operations in any split, so results are bit-identical whatever ``workers`` is (a
    chunk may be empty).  ``size``: elements per unit of n (a row's length); one piece for
    one worker or fewer than :data:`CHUNK_MIN` elements."""
    if workers <= 1 or n * size < CHUNK_MIN:
        work(0, n)
        return
    key = (os.getpid(), workers)  # a pool's threads do not survive a fork
    pool = _POOLS.get(key)
    if pool is None:
        pool = _POOLS[key] = ThreadPoolExecutor(workers, thread_name_prefix="fft-chunks")
    bounds = [n * k // workers for k in range(workers + 1)]
    for _ in pool.map(lambda k: work(bounds[k], bounds[k + 1]), range(workers)):
        pass


class NumpyDevice(NumpyArrays):
    """numpy + scipy.fft (threaded: ``workers``, default
    :func:`pillar_xval.threads.thread_count`) + scipy.sparse on the CPU.  ``split_columns``
    (default True): the operator's column transforms in two halves
    (:class:`bem_solver._fft_operator.PrunedConvolution`); False gives the generic path's
    grid and bits (a reference for the array-API tests)."""

    def __init__(self, workers: int | None = None, max_fft_points: int = MAX_FFT_POINTS,
                 split_columns: bool = True):
        self.workers = thread_count() if workers is None else int(workers)
        self.max_fft_points = max_fft_points  # default ~1 GB of work arrays
        self.split_columns = bool(split_columns)

    def rfft2(self, a):
        import scipy.fft as sfft

        return sfft.rfft2(a, workers=self.workers)

    def irfft2(self, a, s):
        """The inverse of :meth:`rfft2` over the last two axes (a stack of boxes, or one),
        to real boxes of shape ``s``."""
        import scipy.fft as sfft

        return sfft.irfft2(a, s=s, workers=self.workers)

    def rfft(self, a, axis):
        import scipy.fft as sfft

        return sfft.rfft(a, axis=axis, workers=self.workers)

    def fft(self, a, n, axis):
        import scipy.fft as sfft

        return sfft.fft(a, n=n, axis=axis, workers=self.workers, overwrite_x=True)

    def ifft(self, a, axis):
        import scipy.fft as sfft

        return sfft.ifft(a, axis=axis, workers=self.workers, overwrite_x=True)

    def irfft(self, a, n, axis):
        import scipy.fft as sfft

        return sfft.irfft(a, n=n, axis=axis, workers=self.workers)

    def dot(self, a, b) -> float:
        """The scalar product of two vectors (a Python float), by blocks of
        :data:`DOT_BLOCK` entries in chunks on the FFT threads; one block: the whole
        product."""
        blocks = -(-int(a.shape[0]) // DOT_BLOCK)
        if blocks <= 1:
            return super().dot(a, b)
        sums = np.empty(blocks)

        def part(k0, k1):
            for k in range(k0, k1):
                lo = k * DOT_BLOCK
                sums[k] = np.einsum("i,i->", a[lo:lo + DOT_BLOCK], b[lo:lo + DOT_BLOCK])

        self.chunks(part, blocks, DOT_BLOCK)
        if not np.all(np.isfinite(sums)):  # fsum raises on inf - inf: NaN or inf, as einsum
            return float(np.sum(sums))
        return math.fsum(sums.tolist())

    def chunks(self, work, n: int, size: int = 1) -> None:
        """``work(lo, hi)`` over [0, n) in chunks on the FFT threads (:func:`in_chunks`); the
        runs' sums of :meth:`NumpyArrays.segments` go through it too."""
        in_chunks(work, n, self.workers, size)

    def next_fast_len(self, n: int) -> int:
        import scipy.fft as sfft

        return sfft.next_fast_len(n, real=True)

    def sparse(self, rows, cols, values, n: int, columns: int | None = None):
        """The CSR matrix of (row, column, value) triples, ``n`` rows and ``columns`` (default
        ``n``) columns; duplicates are summed."""
        import scipy.sparse as sp

        return sp.csr_matrix((values, (rows, cols)), shape=(n, n if columns is None else columns))

    def synchronize(self) -> None:
        pass


class CupyDevice(CupyArrays):
    """cupy + cuFFT + cupyx.scipy.sparse (:meth:`CupyArrays.sparse`) on the current CUDA
    device."""

    def __init__(self, fused: bool = True):
        super().__init__(fused)
        import cupyx.scipy.fft as cfft

        self._fft = cfft
        free, _total = self._cp.cuda.runtime.memGetInfo()
        self.max_fft_points = int(free // GPU_BYTES_PER_FFT_POINT)

    def rfft2(self, a):
        return self._fft.rfft2(a)

    def irfft2(self, a, s):
        return self._fft.irfft2(a, s=s)

    def rfft(self, a, axis):
        return self._fft.rfft(a, axis=axis)

    def fft(self, a, n, axis):
        return self._fft.fft(a, n=n, axis=axis, overwrite_x=True)

    def ifft(self, a, axis):
        return self._fft.ifft(a, axis=axis, overwrite_x=True)

    def irfft(self, a, n, axis):
        return self._fft.irfft(a, n=n, axis=axis)

    def next_fast_len(self, n: int) -> int:
        return self._fft.next_fast_len(n)

    def synchronize(self) -> None:
        self._cp.cuda.Device().synchronize()


@functools.lru_cache(maxsize=1)
def _gpu_reason() -> str:
    """'' when cupy imports and sees a CUDA device, else why not (one line)."""
    try:
        import cupy
    except Exception as exc:  # any import failure is a reason, reported verbatim
        return f"cupy is not installed ({type(exc).__name__}); install it with {GPU_INSTALL}"
    try:
        count = cupy.cuda.runtime.getDeviceCount()
    except Exception as exc:  # no driver, no device: the CUDA runtime's own words
        return f"cupy finds no CUDA GPU ({type(exc).__name__}: {exc})".splitlines()[0]
    return "" if count > 0 else "cupy finds no CUDA GPU (0 devices)"


def available_devices() -> dict:
    """{device: '' if usable here, else the reason}, for 'cpu' and 'gpu'."""
    return {"cpu": "", "gpu": _gpu_reason()}


def select_backend(device: str = "cpu", workers: int | None = None):
    """The backend for ``device``: 'cpu', 'gpu' (InputError with what to install when no GPU
    is usable) or 'auto' (the GPU when cupy finds one, else the CPU); ``workers``: the CPU's
    FFT threads (default :func:`pillar_xval.threads.thread_count`)."""
    if device not in DEVICES:
        raise InputError(f"device = {device!r}: choose one of {', '.join(DEVICES)}")
    if device == "cpu":
        return NumpyDevice(workers)
    reason = _gpu_reason()
    if reason:
        if device == "gpu":
            raise InputError(f"device = 'gpu': {reason}")
        return NumpyDevice(workers)
    return CupyDevice()
