"""Matrix-free compliance operator of the cell grid: half-space kernel by zero-padded FFT plus
the Hooke shortening of each pillar.

The displacement (m) of cell i under smeared cell pressures q (Pa) is

    u_i = sum_j K(x_i - x_j) q_j  +  c_s L^2 sum_{j in pillar(i)} q_j,

with K = (gamma / pi) D, D Love's integral of 1/|x - x'| over a square cell (see
:mod:`bem_solver._love`), gamma = gamma_l + gamma_s, and c_s = 4 h / (pi d^2 E_p) the spring
compliance of a pillar (m/N).  The convolution is linear (free surface, not periodic): the grid
is zero-padded to at least 2 n - 2 points per axis, so no wrapped image of the kernel differs
from the true coefficient (K is even: :func:`padded_length`).  K is even in both axes, so its
spectrum is real and is stored as one real array.

Everything here is written against an array namespace and a device backend
(:mod:`bem_solver._xp`): the kernel table, its spectrum, the near-field correction (a sparse
matrix on the device) and the operator are built and applied on the CPU with numpy or on a GPU
with cupy by the same code.

References
----------
.. [1] S. Liu, Q. Wang, G. Liu, "A versatile method of discrete convolution and FFT (DC-FFT)
   for contact analyses", Wear 243 (2000) 101-111.
.. [2] A. E. H. Love, Phil. Trans. R. Soc. A 228 (1929) 377-420.
"""

from __future__ import annotations

import math

import numpy as np

from pillar_xval.contact._xp import one_piece

from ._limits import PRECISIONS
from ._love import FAR_FIELD_RATIO, love_far, love_rectangle, love_square_everywhere
from ._xp import NumpyDevice, in_chunks

try:  # scipy.fft's own transforms, which write into given arrays (scipy.fft has no out=)
    from scipy.fft._pocketfft import pypocketfft as _pocketfft
except ImportError:  # another scipy layout: the public scipy.fft path (fresh arrays per call)
    _pocketfft = None
try:  # scipy.sparse's own CSR product on a range of rows, y += A x (its GIL released)
    from scipy.sparse._sparsetools import csr_matvec as _csr_matvec
except ImportError:  # another scipy layout: the public product, whole
    _csr_matvec = None

# Half-width (in cells) of the stencil around a partly covered cell within which its grid
# coefficients are replaced by the equivalent-square ones.  Beyond it the two differ by a
# dipole of the O(L) centroid shift, ~ phi L^3 / r^2; tests/test_bem_fft.py shows the effect of
# the width on the answer.
NEAR_FIELD_CELLS = 3
# Offsets (in cells) within which the kernel table takes Love's exact form.
EXACT_CELLS = int(FAR_FIELD_RATIO) + 1
# CompliancePlan.apply_few takes the half-space part from the kernel table for at most
# FEW_COST_RATIO log2(M) M / G clipped cells (M padded FFT points, G grid cells): one scaled
# copy of the G-cell kernel table per cell against an application's pruned FFT pair
# (measured: one copy ~ 1/10-1/12 of the float64 convolution on 1005^2 and 555^2 grids,
# 2.0 and 0.55 ms); for more, one convolution.  The float32 convolution takes SINGLE_COST_SHARE
# of the float64 one (measured 0.64-0.66 on those grids), and its threshold shrinks with it.
FEW_COST_RATIO = 0.125
SINGLE_COST_SHARE = 0.65
# Error of the float32 convolution relative to the result's largest value: measured
# 1.9e-7 to 5.0e-7 on 1e6 cells (a Hertz-like pressure, white noise, a ring, scattered cells);
# four times the largest.
SINGLE_PRECISION_ERROR = 2e-6
# apply_few takes the near-field correction's rows of the given cells when they are at most
# 1/SPARSE_ROWS_FRACTION of all cells (a row slice of the sparse matrix), else its whole
# product.
SPARSE_ROWS_FRACTION = 16
# The near-field correction's pairs are evaluated in blocks of this many.
PAIR_BLOCK = 1 << 14


def kernel_block(shape, cell_size: float, compliance: float, xp=np):
    """K(i L, j L) for 0 <= i < ny, 0 <= j < nx in m/Pa (rows = y offsets), built in the
    array namespace ``xp`` (on the device): the far form everywhere, the exact form in the
    corner of offsets within ``FAR_FIELD_RATIO`` cells."""
    ny, nx = shape
    oy = xp.arange(ny, dtype=xp.float64) * cell_size
    ox = xp.arange(nx, dtype=xp.float64) * cell_size
    x, y = ox[None, :], oy[:, None]
    s2 = cell_size * cell_size
    block = love_far(x * x + y * y, s2, xp)
    k, m = min(ny, EXACT_CELLS), min(nx, EXACT_CELLS)
    cx, cy = x[:, :m], y[:k, :]
    h = 0.5 * cell_size
    near = cx * cx + cy * cy <= FAR_FIELD_RATIO**2 * s2
    block[:k, :m] = xp.where(near, love_rectangle(cx, cy, h, h, xp), block[:k, :m])
    return compliance / math.pi * block


def near_field_correction(grid, compliance: float, width: int = NEAR_FIELD_CELLS,
                          backend=None):
    """Sparse symmetric correction C (m/Pa) that turns the grid operator into the
    equivalent-square operator near partly covered cells.

    The force q_j L^2 of a partly covered cell acts as a uniform pressure on a square of side
    sqrt(phi_j) L centred on the centroid c_j of its covered part, and the cell is collocated
    at c_j (as in the dense model's ``covered`` cells).  For every pair (i, j) within ``width``
    cells of each other with i or j partly covered,

        C_ij = 1/2 [A'_ij + A'_ji] - K(x_i - x_j),
        A'_ij = (gamma / pi) D(c_i - c_j; sqrt(phi_j) L) / phi_j,

    symmetrised so that the constrained CG keeps a symmetric operator.  Built on the device of
    ``backend`` (default: numpy on the CPU) as that device's sparse matrix; ``None`` when every
    cell is fully covered.
    """
    be = NumpyDevice() if backend is None else backend
    xp = be.xp
    L = grid.cell_size
    n = grid.n_cells
    phi = be.asarray(grid.covered, dtype=xp.float64)
    cell = xp.arange(n, dtype=xp.int64)
    part = cell[phi < 1.0 - 1e-12]
    if part.shape[0] == 0:
        return None
    ny, nx = grid.shape
    flat = be.asarray(grid.flat_index, dtype=xp.int64)
    # One lookup per layer of unknowns: a rim cell with a floor holds two at its position.
    nu = int(getattr(grid, "n_unique", n))
    layers = [(0, nu)] + ([(nu, n)] if nu < n else [])
    lookups = [be.put(xp.full(ny * nx, -1, dtype=xp.int64), flat[a:b], cell[a:b])
               for a, b in layers]
    flat_part = xp.take(flat, part)
    iy, ix = flat_part // nx, flat_part % nx
    offs = xp.arange(-width, width + 1, dtype=xp.int64)
    dy, dx = (xp.reshape(a, (-1,)) for a in xp.meshgrid(offs, offs, indexing="ij"))
    jy, jx = iy[:, None] + dy[None, :], ix[:, None] + dx[None, :]
    inside = (jy >= 0) & (jy < ny) & (jx >= 0) & (jx < nx)
    neighbour = xp.clip(jy, 0, ny - 1) * nx + xp.clip(jx, 0, nx - 1)
    pairs_i, pairs_j = [], []
    for lookup in lookups:
        j = xp.reshape(xp.take(lookup, xp.reshape(neighbour, (-1,))), neighbour.shape)
        j = xp.where(inside, j, -1)
        i = xp.broadcast_to(part[:, None], j.shape)
        ok = j >= 0
        pairs_i.append(i[ok])
        pairs_j.append(j[ok])
    i, j = (pairs_i[0], pairs_j[0]) if len(lookups) == 1 else \
        (xp.concat(pairs_i), xp.concat(pairs_j))
    # Each unordered pair once: (partial, full) pairs, and (partial, partial) with i <= j.
    full_j = xp.take(phi, j) >= 1.0 - 1e-12
    keep = full_j | (i <= j)
    i, j = i[keep], j[keep]
    cx = be.asarray(grid.colloc_x, dtype=xp.float64)
    cy = be.asarray(grid.colloc_y, dtype=xp.float64)
    side = xp.sqrt(phi) * L
    k = compliance / math.pi
    # Grid coefficients of the pairs: a (width + 1)^2 table of integer offsets.
    table = xp.reshape(kernel_block((width + 1, width + 1), L, compliance, xp), (-1,))

    def values(i, j):
        dxc = xp.take(cx, i) - xp.take(cx, j)
        dyc = xp.take(cy, i) - xp.take(cy, j)
        a_ij = k * love_square_everywhere(dxc, dyc, xp.take(side, j), xp) / xp.take(phi, j)
        a_ji = k * love_square_everywhere(-dxc, -dyc, xp.take(side, i), xp) / xp.take(phi, i)
        fi, fj = xp.take(flat, i), xp.take(flat, j)
        offset = xp.abs(fi // nx - fj // nx) * (width + 1) + xp.abs(fi % nx - fj % nx)
        return 0.5 * (a_ij + a_ji) - xp.take(table, offset)

    chunks = getattr(be, "chunks", None)
    if chunks is None:
        value = values(i, j)
    else:  # elementwise per pair: blocks of pairs in the backend's chunks (the FFT threads)
        value = xp.empty(i.shape, dtype=xp.float64)
        m = int(i.shape[0])

        def part(b0, b1):  # blocks small enough that the temporaries stay in the cache
            for lo in range(b0 * PAIR_BLOCK, min(b1 * PAIR_BLOCK, m), PAIR_BLOCK):
                hi = min(lo + PAIR_BLOCK, m)
                value[lo:hi] = values(i[lo:hi], j[lo:hi])

        chunks(part, -(-m // PAIR_BLOCK), PAIR_BLOCK)
    off = i != j
    rows = xp.concat([i, j[off]])
    cols = xp.concat([j, i[off]])
    vals = xp.concat([value, value[off]])
    return be.sparse(rows, cols, vals, n)


def smooth_length(n: int) -> int:
    """Smallest 2^a 3^b 5^c >= n (scipy.fft.next_fast_len(n, real=True)), the same on every
    backend, so that the preconditioner, hence the iterates, do not depend on the device."""
    best = 1 << max(int(n) - 1, 0).bit_length()
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def padded_length(n: int, next_fast_len) -> int:
    """FFT length for the linear convolution of n-point sequences with an *even* kernel:
    2 n - 2 points suffice (not the 2 n - 1 of a general kernel).  On a ring of M points the
    offsets d and d - M of the table K(min(k, M - k)) coincide only at k = n - 1 when
    M = 2 n - 2, where both hold K((n - 1) L) as K is even: no wrapped image differs from the
    true coefficient.  (1297 cells per side: 2592 = 2^5 3^4 points instead of 2700.)"""
    return next_fast_len(max(2 * int(n) - 2, 1))


def padded_rows(n: int, be) -> int:
    """Rows of the operator's zero-padded grid for ``n`` rows of cells on backend ``be``:
    on numpy (``split_columns``), twice the smallest 2^a 3^b 5^c >= n
    (:class:`PrunedConvolution` then splits its column transforms in two halves; at least
    the 2 n - 2 points of :func:`padded_length`; lengths with factors 7 or 11 transformed
    slower: an application at 3e5 cells took 6.4 ms on 1120 rows against 6.2 on 1152, and
    at 4.8e5 cells 11.2 ms on 1386 against 10.6 on 1440); elsewhere :func:`padded_length`."""
    if _pocketfft is None or not getattr(be, "split_columns", False):
        return padded_length(n, be.next_fast_len)
    return 2 * be.next_fast_len(int(n))


def _zero(a: np.ndarray) -> None:
    """Zeros into the numpy array ``a`` (rows contiguous: a view, never a copy), as bytes:
    numpy fills bytes with memset, complex elements with its own loop (8.3 MB of complex64
    in 0.09 against 0.30 ms when in cache, 0.29 against 0.55 ms when not)."""
    a.view(np.uint8).fill(0)


class TransformWorkspace:
    """Work arrays of the numpy path's transforms, shared by convolutions that run one after
    the other: a plan's two precisions, its preconditioner and the warm start's coarser
    levels.  Each call overwrites its spectrum and output arrays whole before reading them,
    so they can be one memory: a solve at 1e6 cells peaks at 362 MB resident against 417 MB
    with arrays of their own (medians of 8 fresh interpreters).  ``take`` gives a view of the
    given shape and dtype at the start of the named block, grown when too small (views given
    out before keep the old block alive)."""

    def __init__(self):
        self._blocks = {}

    def take(self, name: str, shape, dtype) -> np.ndarray:
        dtype = np.dtype(dtype)
        nbytes = math.prod(shape) * dtype.itemsize
        block = self._blocks.get(name)
        if block is None or block.nbytes < nbytes:
            block = np.empty(-(-nbytes // 16), dtype=np.complex128)  # 16-byte aligned
            self._blocks[name] = block
        return block.view(np.uint8)[:nbytes].view(dtype).reshape(shape)


class PrunedConvolution:
    """Linear convolution of a field on the candidate cells with a kernel given by its
    real spectrum on an (my, mx) grid that holds the (ny, nx) box (zero padding or a
    periodic box), returned on the candidate cells.

    Only the first ny rows of the input are non-zero and only the first ny rows of the
    output are needed: the row transforms run on ny rows, the column transforms zero-pad to
    my (a pruned 2D FFT, 0.6-0.7 of rfft2 + irfft2 on the (my, mx) grid).  The scatter
    buffer is kept between calls; outside the candidate cells it stays zero.  With numpy, the
    same four scipy.fft transforms write into arrays kept between calls (the same
    floating-point operations as the generic path: identical results, no page faults of
    fresh 10-60 MB arrays per call).

    On numpy, where my = 2 M with M >= ny (:func:`padded_rows`) and the spectrum's products
    are kept in pairs (every call but the mixed plan's rare float64 ones), the column
    transforms are split in two (decimation in frequency, the zero half never
    transformed): the even output rows are the M-point transform of the ny rows, the odd ones
    that of the rows times exp(-i pi n / M); each half is multiplied by its own rows of the
    spectrum (halved: exact), transformed back on M points, and the first ny rows are the
    even half's plus the odd half's times exp(i pi n / M).  Two M-point transforms cost less
    than one of 2 M points: the operator's application at 1e6 cells ~10 % less.  The
    same result to round-off, not the generic path's bits.

    ``single=True`` runs the same transforms in float32 (complex64), 0.6-0.65 of the float64
    time, with a relative error of a few 1e-7 of the result's scale
    (:data:`SINGLE_PRECISION_ERROR`); the result is returned in float64.  The arrays of each
    of ``precisions`` are made with the object, those of another on its first call; on numpy
    the spectrum and output arrays are views of ``workspace`` (:class:`TransformWorkspace`,
    default: the object's own), which every convolution that runs in turn may share.
    """

    def __init__(self, shape, fft_shape, flat_index, spectrum, backend,
                 precisions=("double",), workspace=None, n_unique=None):
        be = backend
        xp = be.xp
        ny, nx = shape
        self.backend = be
        self.shape = (ny, nx)
        self.fft_shape = tuple(fft_shape)
        flat = be.asarray(flat_index, dtype=xp.int64)
        self.padded_index = (flat // nx) * self.fft_shape[1] + flat % nx
        # The unknowns past n_unique (floor parts of rim cells) share a grid position with one
        # before them: their values are added to the scattered field, not written.
        n = int(flat.shape[0])
        self.n_unique = n if n_unique is None or n_unique >= n else int(n_unique)
        self._extra_index = self.padded_index[self.n_unique:]
        self.spectrum = spectrum
        self._pocket = _pocketfft is not None and isinstance(be, NumpyDevice)
        self.workspace = workspace if workspace is not None else TransformWorkspace()
        self._arrays = {}  # "single"/"double" -> (buffer, spectrum or None, work or None)
        # With both precisions (mixed), float64 serves only the exact refreshes, two a level:
        # on numpy it multiplies by the real spectrum itself (3 ms more a call at 1e6 cells)
        # instead of keeping its own pairs (33 MB to fill with every level's plan).
        self._double_is_rare = set(precisions) == {"single", "double"}
        my = self.fft_shape[0]
        self._split = self._pocket and be.split_columns and my % 2 == 0 and my // 2 >= ny
        if self._split:  # exp(-i pi n / M) for the ny rows, then its conjugate
            shift = np.exp(-1j * np.pi * np.arange(ny) / (my // 2))[:, None]
            self._twiddles = (shift, np.conj(shift))
        for precision in precisions:  # made now, with the plan, not in the first solve's call
            self._state(precision)
        # Cells of the box whose values every float64 call also gathers (watch_at), and
        # the last such call's (q, values).
        self._watch, self.watched = None, None

    def watch_at(self, flat_index) -> None:
        """From now on, every float64 call of this object also keeps a copy of its ``q``
        and its result at the cells ``flat_index`` of the (ny, nx) box, as ``watched`` =
        (q, values) (a copy and a gather more a call)."""
        self._watch = self._padded(flat_index)
        self.watched = None

    def _padded(self, flat):
        """Positions in the padded (my, mx) grid of the box's flat indices ``flat``."""
        nx = self.shape[1]
        return (flat // nx) * self.fft_shape[1] + flat % nx

    def _state(self, precision):
        """The kept scatter buffer, the spectrum (generic path) and the kept work arrays
        (numpy path) of ``precision``, "single" or "double": made once per precision."""
        state = self._arrays.get(precision)
        if state is None:
            be = self.backend
            xp = be.xp
            ny = self.shape[0]
            my, mx = self.fft_shape
            real = xp.float64 if precision == "double" else xp.float32
            spectrum, work, twiddles = None, None, None
            if not self._pocket:
                spectrum = xp.astype(self.spectrum, real)
            else:
                complex_ = np.complex128 if precision == "double" else np.complex64
                if precision == "double" and self._double_is_rare:
                    factor = xp.astype(self.spectrum, real, copy=False)
                else:
                    # The real spectrum twice over, as the (re, im) pairs of the complex
                    # spectrum: one float product of equal arrays (half the time of numpy's
                    # complex-by-real product, which widens the real factor; the same
                    # values).
                    source = self.spectrum
                    if self._split:  # the even rows, then the odd ones, halved (exact)
                        source = 0.5 * np.concatenate((source[0::2], source[1::2]))
                    pairs = np.empty((my, mx // 2 + 1, 2), dtype=real)
                    pairs[..., 0] = source
                    pairs[..., 1] = source
                    factor = pairs.reshape(my, 2 * (mx // 2 + 1))
                    if self._split:
                        twiddles = tuple(t.astype(complex_) for t in self._twiddles)
                work = (self.workspace.take("spectrum", (my, mx // 2 + 1), complex_),
                        self.workspace.take("output", (ny, mx), real), factor, twiddles)
            state = (xp.zeros(ny * mx, dtype=real), spectrum, work)
            self._arrays[precision] = state
        return state

    def __call__(self, q, single: bool = False, at=None):
        """The convolution of ``q`` (on the candidate cells) on those cells, or with ``at``
        (flat indices into the (ny, nx) box) on those cells of the box instead."""
        be = self.backend
        xp = be.xp
        key = "single" if single else "double"
        out_index = self.padded_index if at is None else self._padded(at)
        buffer, spectrum, work = self._state(key)
        nu = self.n_unique
        shared = nu < self.padded_index.shape[0]
        if work is not None:
            index = self.padded_index

            def scatter(lo, hi):  # cast first: a scatter that also converts takes twice as long
                part = q[lo:hi]
                buffer[index[lo:hi]] = part if part.dtype == buffer.dtype else \
                    part.astype(buffer.dtype)

            in_chunks(scatter, nu, self.backend.workers)
            if shared:  # the floor parts of rim cells add to their top part's position
                buffer[self._extra_index] += q[nu:].astype(buffer.dtype, copy=False)
            watch = None if single else self._watch
            result = self._numpy_call(buffer, work, out_index, watch)
            if watch is None:
                return result
            result, values = result
            self.watched = (q.copy(), values)
            return result
        else:
            ny = self.shape[0]
            my, mx = self.fft_shape
            given = q
            q = xp.astype(q, buffer.dtype)
            if shared:
                buffer = be.put(buffer, self.padded_index[:nu], q[:nu])
                buffer = be.put(buffer, self._extra_index,
                                xp.take(buffer, self._extra_index) + q[nu:])
            else:
                buffer = be.put(buffer, self.padded_index, q)
            self._arrays[key] = (buffer, spectrum, work)
            spec = be.fft(be.rfft(xp.reshape(buffer, (ny, mx)), axis=1), n=my, axis=0)
            spec *= spectrum
            rows = be.ifft(spec, axis=0)[:ny, :]
            field = xp.reshape(be.irfft(rows, n=mx, axis=1), (-1,))
            if self._watch is not None and not single:
                self.watched = (xp.asarray(given, copy=True), xp.take(field, self._watch))
            out = xp.take(field, out_index)
        return xp.astype(out, xp.float64) if single else out

    def few(self, index, values, single: bool = False):
        """The convolution of the field that is ``values`` on the cells ``index`` and zero on
        the others: the same result as ``self(q)`` for that field (on numpy, the scatter
        buffer cleared and the few values put in it, instead of a whole field built and
        scattered)."""
        be = self.backend
        xp = be.xp
        buffer, _, work = self._state("single" if single else "double")
        if work is None:
            n = self.padded_index.shape[0]
            return self(be.put(xp.zeros(n, dtype=xp.float64), index, values), single)
        # Only the rows that hold a given cell are cleared, filled and transformed along
        # x: the others' transforms are zeros (written as such), and the whole calls that
        # follow overwrite every candidate cell (elsewhere the buffer stays zero).
        at = self.padded_index[index]
        mx = self.fft_shape[1]
        rows = (int(at.min()) // mx, int(at.max()) // mx + 1) if at.shape[0] else (0, 0)
        held = buffer[rows[0] * mx:rows[1] * mx]
        in_chunks(lambda lo, hi: _zero(held[lo:hi]), held.shape[0], be.workers)
        if self.n_unique < self.padded_index.shape[0]:  # two unknowns may share a position
            np.add.at(buffer, at, values.astype(buffer.dtype))
        else:
            buffer[at] = values.astype(buffer.dtype)
        return self._numpy_call(buffer, work, rows=rows)

    def _numpy_call(self, buffer, work, index=None, watch=None, rows=None):
        """The generic path's transforms (scipy.fft's rfft, fft, ifft, irfft are these
        pocketfft calls, with the default norm) of the scattered ``buffer`` into the kept
        arrays, and the result on the candidate cells (or at the padded positions ``index``)
        in float64; the elementwise work in chunks on the transforms' threads
        (:func:`in_chunks`).  With ``watch`` (padded positions): (result, the values
        there).  With ``rows`` = (r0, r1): the buffer is zero outside those rows, whose
        transforms along x are then zeros, written without transforming."""
        ny = self.shape[0]
        my, mx = self.fft_shape
        spec, out, factor, twiddles = work
        workers = self.backend.workers
        row = spec.shape[1]
        r0, r1 = (0, ny) if rows is None else rows
        if r1 > r0:
            _pocketfft.r2c(buffer.reshape(ny, mx)[r0:r1], (1,), True, 0, spec[r0:r1],
                           workers)
        for lo, hi in ((0, r0), (max(r1, r0), ny)):
            if hi > lo:
                in_chunks(lambda a, b: _zero(spec[lo + a:lo + b]), hi - lo, workers, row)
        if twiddles is None:
            in_chunks(lambda lo, hi: _zero(spec[ny + lo:ny + hi]), my - ny, workers, row)
            columns, axis = spec, 0
        else:  # two halves of M rows (class docstring)
            half = my // 2
            even, odd = spec[:half], spec[half:]
            shift, back = twiddles

            def shifted(lo, hi):
                np.multiply(even[lo:hi], shift[lo:hi], out=odd[lo:hi])

            in_chunks(shifted, ny, workers, row)
            _zero(even[ny:])
            _zero(odd[ny:])
            columns, axis = spec.reshape(2, half, row), 1
        _pocketfft.c2c(columns, (axis,), True, 0, columns, workers)
        if factor.shape == spec.shape:  # the real spectrum itself
            product = spec
        else:  # its (re, im) pairs
            product = spec.view(out.dtype).reshape(factor.shape)
        in_chunks(lambda lo, hi: np.multiply(product[lo:hi], factor[lo:hi],
                                             out=product[lo:hi]), my, workers, row)
        _pocketfft.c2c(columns, (axis,), False, 2, columns, workers)
        if twiddles is not None:

            def combined(lo, hi):
                part = odd[lo:hi]
                np.multiply(part, back[lo:hi], out=part)
                even[lo:hi] += part

            in_chunks(combined, ny, workers, row)
        _pocketfft.c2r(spec[:ny], (1,), mx, False, 2, out, workers)
        flat = out.reshape(-1)
        index = self.padded_index if index is None else index
        result = np.empty(index.shape[0])

        def gather(lo, hi):  # take, then widen (exact) into the float64 result
            result[lo:hi] = flat.take(index[lo:hi])

        in_chunks(gather, index.shape[0], workers)
        return result if watch is None else (result, flat.take(watch))


class CompliancePlan:
    """Apply the compliance operator to smeared pressures on the candidate cells.

    Parameters
    ----------
    shape : (int, int)
        Bounding grid (ny, nx).
    flat_index : ndarray of int
        Row-major grid index of each candidate cell.
    cell_size : float
        Cell side L (m).
    compliance : float
        gamma_l + gamma_s (1/Pa).
    pillar : ndarray of int, optional
        Owning pillar of each cell (for the Hooke term).
    spring_compliance : float
        c_s = 4 h / (pi d^2 E_p) (m/N); 0 for rigid pillars or a flat scene.
    workers : int, optional
        Threads for scipy.fft (default backend only; default
        :func:`pillar_xval.threads.thread_count`).
    correction : sparse matrix, optional
        Near-field correction (m/Pa) from :func:`near_field_correction`, on the same device.
    backend : optional
        Device backend (:mod:`bem_solver._xp`); default numpy and scipy.fft on the CPU.
        Vectors given to and returned by the plan live on its device.
    precision : {"mixed", "double"}
        "mixed" (default): the plan offers :meth:`approximate`, its convolution in float32,
        for the constrained CG's steps, and the preconditioner runs in float32; "double":
        float64 throughout (``approximate`` is None).
    workspace : TransformWorkspace, optional
        The transforms' work arrays (numpy), shared with the preconditioner; give one plan's
        to the next plan that runs after it (the warm start's levels), largest first.
    n_unique : int, optional
        Leading unknowns at distinct grid positions; the others share a position with one of
        them (the floor parts of rim cells, :class:`bem_solver._fft_grid.CellGrid`).
    floor_pillar : int, optional
        The ``pillar`` index of the floor's cells: no Hooke term, no pillar mode.
    """

    def __init__(self, shape, flat_index, cell_size, compliance, pillar=None,
                 spring_compliance=0.0, workers=None, correction=None, backend=None,
                 pillar_term=None, precision="mixed", workspace=None, n_unique=None,
                 floor_pillar=None):
        if precision not in PRECISIONS:
            raise ValueError(f"precision = {precision!r}: choose one of {', '.join(PRECISIONS)}")
        self.precision = precision
        be = NumpyDevice(workers) if backend is None else backend
        xp = be.xp
        self.backend = be
        ny, nx = shape
        self.shape = (ny, nx)
        self.cell_size = float(cell_size)
        self.compliance = float(compliance)
        self.workers = getattr(be, "workers", workers)
        # Linear convolution of n-point sequences with an even kernel: >= 2n - 2 points.
        self.fft_shape = (padded_rows(ny, be), padded_length(nx, be.next_fast_len))
        my, mx = self.fft_shape
        block = kernel_block(shape, cell_size, compliance, xp)
        padded = xp.zeros(self.fft_shape, dtype=xp.float64)
        padded[:ny, :nx] = block
        padded[my - ny + 1:, :nx] = xp.flip(block[1:, :], axis=0)       # negative y offsets
        padded[:, mx - nx + 1:] = xp.flip(padded[:, 1:nx], axis=1)      # negative x offsets
        # Even kernel -> real spectrum (imaginary part is round-off); a compact copy.
        self.kernel_spectrum = xp.asarray(xp.real(be.rfft2(padded)), copy=True)
        del padded
        self.self_coefficient = float(block[0, 0])
        self._block = block  # the kernel table, for apply_few
        self._few_grid = None
        self.direct_updates = 0
        self.single_applications = 0
        # Bound, relative to the result's largest value, on the error of an application in
        # single precision: the CG's schedule of exact refreshes (never its convergence).
        self.approximate_error = SINGLE_PRECISION_ERROR if precision == "mixed" else 0.0
        log_points = math.log2(my * mx)
        self.few_max = max(1, int(FEW_COST_RATIO * log_points * my * mx / (ny * nx)))
        self.few_max_single = max(1, int(SINGLE_COST_SHARE * self.few_max))
        flat = be.asarray(np.asarray(flat_index), dtype=xp.int64)
        self.workspace = workspace if workspace is not None else TransformWorkspace()
        self._convolution = PrunedConvolution(
            self.shape, self.fft_shape, flat, self.kernel_spectrum, be,
            ("double", "single") if precision == "mixed" else ("double",), self.workspace,
            n_unique)
        self.n_unique = n_unique
        self._convolution_index = flat
        self.spring = float(spring_compliance) * self.cell_size**2  # m/Pa per unit q
        self.pillar = None if pillar is None else be.asarray(np.asarray(pillar), dtype=xp.int64)
        self.n_pillars = 0 if pillar is None or len(pillar) == 0 else int(np.max(pillar)) + 1
        self._pillar_sums = None if self.pillar is None else \
            be.segments(self.pillar, self.n_pillars)
        self._pillar_spread = None if self.pillar is None else be.spreader(self.pillar)
        # Per pillar index, 1 on a pillar and 0 on the floor (None without floor): the floor
        # takes no spring and has no uniform mode.
        self.pillar_weight = None
        if floor_pillar is not None and self.pillar is not None \
                and floor_pillar < self.n_pillars:
            weight = np.ones(self.n_pillars)
            weight[floor_pillar] = 0.0
            self.pillar_weight = be.asarray(weight, dtype=xp.float64)
        # The Hooke term per unit q summed over a pillar (m/Pa), per pillar index.
        self.pillar_spring = self.spring if self.pillar_weight is None else \
            self.spring * self.pillar_weight
        self.applications = 0
        self.correction = correction
        self._correction_rows = None  # numpy: _add_correction's rows with entries, kept
        diagonal = xp.full(flat.shape[0], self.self_coefficient, dtype=xp.float64)
        if correction is not None:
            diagonal = diagonal + be.asarray(correction.diagonal())
        # Elastic pillars (bem_solver._elastic_pillar.FFTPillarTerm): a per-pillar excess
        # compliance; on a pillar top the kernel's high-frequency compliance becomes
        # gamma_l + gamma_p instead of gamma_l + gamma_s.
        self.pillar_term = pillar_term
        self.high_frequency_compliance = self.compliance
        if pillar_term is not None:
            diagonal = diagonal + be.asarray(pillar_term.diagonal)
            self.high_frequency_compliance = max(
                self.compliance + pillar_term.local_compliance, 1e-3 * self.compliance)
        self.diagonal = diagonal

    @property
    def has_spring(self) -> bool:
        return self.spring > 0.0 and self.pillar is not None

    @property
    def has_pillar_terms(self) -> bool:
        """A per-pillar term (Hooke spring or elastic pillar) in the operator."""
        return self.has_spring or (self.pillar_term is not None and self.pillar is not None)

    def pillar_sums(self, q):
        """Sum of q over the cells of each pillar (Pa); multiply by L^2 for forces."""
        return self._pillar_sums(q)

    def per_cell(self, values, lo=0, hi=None):
        """A value per pillar out to each of its cells (``values[pillar]``), or to the cells
        ``lo`` to ``hi`` (a chunk's)."""
        return self._pillar_spread(values, lo, hi)

    def half_space(self, q, single: bool = False):
        """K q on the candidate cells (m); ``single``: the transforms in float32."""
        self._count(single)
        return self._convolution(q, single=single)

    def watch_at(self, flat_index) -> None:
        """From now on, every float64 application also keeps K q at the cells
        ``flat_index`` of the plan's (ny, nx) box, candidates or not, with a copy of its q:
        :meth:`half_space_at` then takes it instead of a convolution of its own."""
        self._convolution.watch_at(flat_index)

    def half_space_at(self, q, flat_index):
        """K q (m, float64) at the cells ``flat_index`` of the plan's (ny, nx) box, candidates
        or not: the half-space part alone (no near-field correction, no pillar term); the
        watched values (:meth:`watch_at`, the same cells) where the last float64
        application was of this ``q``."""
        xp = self.backend.xp
        watched = self._convolution.watched
        if watched is not None and watched[0].shape == q.shape \
                and bool(xp.all(watched[0] == q)):
            return watched[1]
        self._count(False)
        return self._convolution(q, at=flat_index)

    def _count(self, single: bool) -> None:
        """One more convolution of the operator (``single``: in float32)."""
        self.applications += 1
        self.single_applications += bool(single)

    def pillar_mode_compliance(self, counts):
        """1^T A_p 1 of the per-pillar terms of the operator (m/Pa): the displacement summed
        over ``counts`` cells of a pillar under a unit q on each of them (the Hooke term:
        spring counts^2).  The preconditioner's coarse space uses it; a further per-pillar
        term of the operator adds its own share here."""
        share = self.pillar_spring * counts * counts if self.has_spring else 0.0 * counts
        if self.pillar_term is not None:
            share = share + self.pillar_term.mode_compliance(counts)
        return share

    def __call__(self, q, single: bool = False):
        """Full compliance: half-space convolution plus per-pillar Hooke shortening (m).
        ``single``: the convolution's transforms in float32 (relative error within
        ``approximate_error`` of the result's largest value; the rest in float64)."""
        u = self.half_space(q, single)
        if self.correction is not None:
            self._add_correction(u, q)
        if self.has_spring:
            self._add_per_cell(u, self.pillar_spring * self.pillar_sums(q))
        if self.pillar_term is not None:
            u += self.pillar_term(q)
        return u

    def _add_correction(self, u, q) -> None:
        """u += C q for the near-field correction C.  On numpy, only C's rows that hold
        entries (the cells within its reach of a partly covered one: 9 % of the candidates
        with the floor reached, R = 1 mm, Phi = 0.03, N = 36), in the backend's chunks
        (scipy's CSR product releases the GIL): each row summed from zero in its stored
        order, then added to its cell, as the whole product does, so the bits are the
        whole product's in any split; elsewhere the whole product."""
        c = self.correction
        if _csr_matvec is None or not isinstance(self.backend, NumpyDevice):
            u += c @ q
            return
        if self._correction_rows is None:
            rows = np.flatnonzero(np.diff(c.indptr))
            # Row rows[i] ends where the next row with entries starts (empty rows between).
            bounds = c.indptr[np.append(rows, c.shape[0])]
            self._correction_rows = (rows, bounds, np.empty(rows.shape[0]))
        rows, bounds, scratch = self._correction_rows
        x = np.ascontiguousarray(q, dtype=np.float64)

        def part(lo, hi):
            t = scratch[lo:hi]
            t.fill(0.0)
            _csr_matvec(hi - lo, c.shape[1], bounds[lo:hi + 1], c.indices, c.data, x, t)
            u[rows[lo:hi]] += t

        self.backend.chunks(part, int(rows.shape[0]), max(c.nnz // max(rows.shape[0], 1), 1))

    def _add_per_cell(self, u, values) -> None:
        """u += ``values[pillar]`` in place, in the backend's chunks (the FFT threads on
        numpy), each chunk spreading the values to its own cells."""
        def part(lo, hi):
            w = u[lo:hi]
            w += self.per_cell(values, lo, hi)

        getattr(self.backend, "chunks", one_piece)(part, int(u.shape[0]))

    @property
    def approximate(self):
        """The constrained CG's cheap step between its exact gap refreshes: q -> A q with the
        half-space convolution in float32 (see :meth:`__call__`); None in double precision.
        (A property, not a bound method kept on the plan: that cycle would hold the plan's
        arrays until the garbage collector ran, ~60 MB of coarse levels at 1e6 cells.)"""
        return self._approximate if self.precision == "mixed" else None

    def _approximate(self, q):
        return self(q, single=True)

    def apply_few(self, index, values, single: bool = False):
        """A d for d = ``values`` on the cells ``index`` and zero elsewhere: the constrained
        CG's gap update after a step that clips pressures, exact (``single``: its convolution
        in float32, as :meth:`approximate`).  The half-space part from the kernel table
        directly (one scaled copy of the table per cell, in four quadrant slices) for at most
        ``few_max`` cells (``few_max_single``), else by one convolution of d; the near-field
        correction and the pillar springs from the given cells only (not the whole
        application's sparse product and segment sums: 10-15 ms of an application's ~70 at
        N = 58); an elastic pillar term on those cells' pillars only where it can, else whole."""
        m = int(index.shape[0])
        be = self.backend
        xp = be.xp
        on_numpy = isinstance(be, NumpyDevice)
        n = self._convolution_index.shape[0]
        spread = None  # d on every cell, built once if a part needs it

        def whole():
            nonlocal spread
            if spread is None:
                spread = be.put(xp.zeros(n, dtype=xp.float64), index, values)
            return spread

        if m > (self.few_max_single if single else self.few_max):
            self._count(single)
            # numpy: only the clipped cells scattered; elsewhere the whole field, which the
            # parts below reuse (not built twice)
            u = self._convolution.few(index, values, single=single) if on_numpy else \
                self._convolution(whole(), single=single)
        else:
            u = self._table_sum(index, values)
            self.direct_updates += 1
        if self.correction is not None:
            if on_numpy and m <= n // SPARSE_ROWS_FRACTION:  # symmetric: columns are rows
                u += self.correction[index].T @ values
            else:
                self._add_correction(u, whole())
        if self.has_spring:
            forces = be.segment_sum(xp.take(self.pillar, index), values, self.n_pillars)
            self._add_per_cell(u, self.pillar_spring * forces)
        if self.pillar_term is not None:
            pillar_part = self.pillar_term.apply_few(index, values)
            u += self.pillar_term(whole()) if pillar_part is None else pillar_part
        return u

    def _table_sum(self, index, values):
        """K d on the candidate cells for d = ``values`` on the cells ``index``, from the
        kernel table (one scaled copy per cell)."""
        be = self.backend
        xp = be.xp
        on_numpy = isinstance(be, NumpyDevice)
        ny, nx = self.shape
        if self._few_grid is None:  # an accumulator (and on numpy a scratch grid), kept
            self._few_grid = (xp.zeros((ny, nx), dtype=xp.float64),
                              np.empty((ny, nx)) if on_numpy else None)
        acc, scratch = self._few_grid
        block = self._block
        cells = be.to_numpy(xp.take(self._convolution_index, index)).tolist()
        if on_numpy:  # rows in chunks on the FFT threads, each with its rows of the scratch
            return self._table_sum_numpy(cells, values.tolist(), acc, scratch)
        for cell, d in zip(cells, be.to_numpy(values).tolist()):
            jy, jx = divmod(cell, nx)
            # Cells below/right of cell j read the table forwards from offset 0, cells
            # above/left of it backwards from offset 1.
            for rows, table_rows in ((slice(jy, ny), slice(0, ny - jy)),
                                     (slice(0, jy), slice(jy, 0, -1))):
                for cols, table_cols in ((slice(jx, nx), slice(0, nx - jx)),
                                         (slice(0, jx), slice(jx, 0, -1))):
                    acc[rows, cols] += block[table_rows, table_cols] * d
        u = xp.take(xp.reshape(acc, (-1,)), self._convolution_index)
        acc[...] = 0.0
        return u

    def _table_sum_numpy(self, cells, values, acc, scratch):
        """:meth:`_table_sum` on numpy: rows of the accumulator in chunks on the FFT threads
        (:func:`in_chunks`; every element sums the same products in the same order), the
        products written into the chunk's rows of ``scratch`` (no fresh temporaries: page
        faults on large grids)."""
        ny, nx = self.shape
        block = self._block
        index = self._convolution_index
        workers = self.backend.workers

        def rows(r0, r1):
            for cell, d in zip(cells, values):
                jy, jx = divmod(cell, nx)
                # Rows at or below cell j read the table forwards from offset 0, rows above
                # it backwards from offset 1; the same for columns.
                lo, hi = max(r0, jy), min(r1, jy)
                for out_rows, table_rows in ((slice(lo, r1), slice(lo - jy, r1 - jy)),
                                             (slice(r0, hi), slice(jy - r0, jy - hi, -1))):
                    if out_rows.start >= out_rows.stop:
                        continue
                    for cols, table_cols in ((slice(jx, nx), slice(0, nx - jx)),
                                             (slice(0, jx), slice(jx, 0, -1))):
                        part = block[table_rows, table_cols]
                        work = scratch[out_rows.start:out_rows.start + part.shape[0],
                                       :part.shape[1]]
                        acc[out_rows, cols] += np.multiply(part, d, out=work)

        in_chunks(rows, ny, workers, nx)
        flat = acc.reshape(-1)
        u = np.empty(index.shape[0])

        def gather(lo, hi):
            u[lo:hi] = flat.take(index[lo:hi])

        in_chunks(gather, index.shape[0], workers)
        in_chunks(lambda lo, hi: _zero(acc[lo:hi]), ny, workers, nx)
        return u

    def dense_matrix(self, x, y) -> np.ndarray:
        """The same operator as a dense numpy matrix (m/Pa), for tests on small grids."""
        # Offsets are exact multiples of L: evaluate the kernel block on integer offsets.
        i = np.rint(np.abs(y[:, None] - y[None, :]) / self.cell_size).astype(int)
        j = np.rint(np.abs(x[:, None] - x[None, :]) / self.cell_size).astype(int)
        mat = kernel_block(self.shape, self.cell_size, self.compliance)[i, j]
        if self.correction is not None:
            mat = mat + self.backend.to_numpy(self.correction.toarray())
        if self.has_spring:
            pillar = self.backend.to_numpy(self.pillar)
            spring = self.spring if self.pillar_weight is None else \
                self.backend.to_numpy(self.pillar_spring)[pillar][:, None]
            mat = mat + spring * (pillar[:, None] == pillar[None, :])
        if self.pillar_term is not None:
            mat = mat + self.pillar_term.dense_matrix()
        return mat


class CirculantPreconditioner:
    """Preconditioner of the constrained CG on the free set F: an approximate inverse of the
    compliance operator A = K + C + (per-pillar terms), SPD on F and zero outside it,

        M^-1 = Q S H S Q + Z E^-1 Z^T,

    - H: the inverse of the half-space kernel as a circulant on the periodic (py, px) box
      that holds the grid (Strang's preconditioner: the kernel table K(i L, j L) wrapped onto
      the torus, its real spectrum inverted; no zero padding, so one pruned FFT pair on a
      quarter of the operator's padded grid).  K is a pseudo-differential operator of order
      -1 (spectrum ~ 2 gamma / |k|): H, of order +1, makes the preconditioned spectrum
      bounded up to the restriction to F (the Jacobi preconditioner leaves a condition
      number growing like the cells across the contact, and the CG iterations like its root).
    - S = diag(sqrt(K_00 / A_ii)): partly covered cells, whose equivalent square makes
      their self-compliance up to ~1 / sqrt(phi) times a full cell's, are scaled as the
      Jacobi preconditioner scales them (S = I without edge correction).
    - Z: the free cells of each pillar (incidence, n_pillars columns); Q = I - Z (Z^T Z)^-1
      Z^T subtracts the mean over each pillar's free cells; E = diag(1^T A 1 over each
      pillar's free cells), estimated as the per-pillar terms' own share
      (:meth:`CompliancePlan.pillar_mode_compliance`, the Hooke term: c n_k^2) plus the
      half-space's for a disk of the same area (n_k * 16 gamma a_k / (3 pi), the mean
      displacement under a uniform unit pressure, a_k = L sqrt(n_k / pi)).  The coarse part
      carries the uniform mode of each pillar, up to 1e4 times more compliant than the
      half-space modes on soft pillars: Q keeps H off that mode, so the CG sees neither
      the stiffness contrast nor the spring's scale.  Used only where the operator has
      per-pillar terms (``plan.has_spring``).

    Both parts are symmetric positive semi-definite on F and their sum is definite there, so
    M^-1 is a valid CG preconditioner for any free set.  Cost per application: one pruned
    FFT pair on the (py, px) box (~1/4 of the operator's; in float32 where the plan's
    precision is mixed, symmetric then to float32's rounding), plus three segment sums when
    the pillars have a spring.
    """

    def __init__(self, plan: "CompliancePlan"):
        be = plan.backend
        xp = be.xp
        self.backend = be
        self.plan = plan
        ny, nx = plan.shape
        py, px = smooth_length(ny), smooth_length(nx)
        self.box_shape = (py, px)
        block = kernel_block((py // 2 + 1, px // 2 + 1), plan.cell_size,
                             plan.high_frequency_compliance, xp)
        iy = xp.arange(py, dtype=xp.int64)
        ix = xp.arange(px, dtype=xp.int64)
        wrapped = xp.take(xp.take(block, xp.minimum(iy, py - iy), axis=0),
                          xp.minimum(ix, px - ix), axis=1)
        spectrum = xp.real(be.rfft2(wrapped))
        # Positive for this kernel (checked: ratio of extremes ~ 1e3 on 555^2); the floor
        # only guards definiteness against round-off.
        spectrum = xp.maximum(spectrum, xp.max(spectrum) * 1e-12)
        # An approximate inverse: float32 transforms suffice where the plan's steps use them.
        self.single = plan.precision == "mixed"
        self._inverse = PrunedConvolution(plan.shape, self.box_shape,
                                          plan._convolution_index, 1.0 / spectrum, be,
                                          ("single",) if self.single else ("double",),
                                          plan.workspace, plan.n_unique)
        full = plan.diagonal <= plan.self_coefficient * (1.0 + 1e-12)
        self.scale = None if bool(xp.all(full)) else xp.sqrt(plan.self_coefficient
                                                              / plan.diagonal)
        self._self_reference = plan.self_coefficient  # K_00 of S's scale
        if plan.pillar_term is not None:  # every cell: the kernel here is the pillar top's
            self_hf = plan.self_coefficient * plan.high_frequency_compliance / plan.compliance
            self.scale = xp.sqrt(self_hf / xp.maximum(plan.diagonal, 1e-3 * self_hf))
            self._self_reference = self_hf
        self.pillars = plan.has_pillar_terms
        # A rim cell with a floor holds two unknowns at one grid position, which H sees only
        # as their sum: the difference of the two is outside its range (measured: 2965 CG
        # iterations instead of 35 at h = 0.002 um).  Where both parts are free, both take a
        # Jacobi term as well, S (I / K_00) S = 1 / A_ii between the two S (so M^-1 stays
        # symmetric, and definite on F).  Where only one part is free, H sees it alone and
        # the term would only overweight it: on the tops of a mixed contact, whose rims' floor
        # parts are mostly out of contact, the term everywhere took 21 instead of 14 PCG
        # iterations on the final contact set (rigid pillars, R = 1 mm, Phi = 0.03, N = 36).
        self.pairs = None
        n = int(plan._convolution_index.shape[0])
        nu = n if plan.n_unique is None else int(plan.n_unique)
        if nu < n:
            flat = be.to_numpy(plan._convolution_index)
            lookup = np.full(ny * nx, -1, dtype=np.int64)
            lookup[flat[:nu]] = np.arange(nu)
            # (top part, floor part) of each rim cell
            self.pairs = (be.asarray(lookup[flat[nu:]], dtype=xp.int64),
                          be.asarray(np.arange(nu, n), dtype=xp.int64))
        gamma, L = plan.compliance, plan.cell_size
        self._disk = 16.0 * gamma * L / (3.0 * math.pi * math.sqrt(math.pi))

    def __call__(self, r, free):
        be = self.backend
        xp = be.xp
        chunks = getattr(be, "chunks", one_piece)
        n = int(r.shape[0])
        # Restrictions to F as products with its indicator (a third of where(free, x, 0)'s
        # time on numpy; the vectors are finite), S folded into it, in place where the
        # vector is this call's own (products by 0 or 1 are exact: the same values).  The
        # elementwise passes run in the backend's chunks (the FFT threads on numpy: the same
        # bits in any split), into arrays kept between calls; the pillar sums run whole.
        mask, rf, scaled = self._kept(r)
        scale = self.scale

        def restriction(lo, hi):  # the indicator times S, made once a call
            return mask[lo:hi] if scale is None else scaled[lo:hi]

        def restrict_input(lo, hi):
            m, v = mask[lo:hi], rf[lo:hi]
            m[...] = xp.astype(free[lo:hi], xp.float64)
            v[...] = r[lo:hi]
            v *= m
            if scale is not None:
                w = scaled[lo:hi]
                w[...] = m * scale[lo:hi]
                if not self.pillars:
                    v *= w

        chunks(restrict_input, n)
        weight = self.plan.pillar_weight
        if self.pillars:
            count = self.plan.pillar_sums(mask)
            if weight is not None:  # the floor: no uniform mode
                count = count * weight
            per_cell = 1.0 / xp.maximum(count, 1.0)
            sums = self.plan.pillar_sums(rf)
            if weight is not None:
                sums = sums * weight
            means = sums * per_cell  # per pillar; each chunk spreads its cells' own

            def remove_means(lo, hi):
                v = rf[lo:hi]
                v -= self.plan.per_cell(means, lo, hi)
                v *= restriction(lo, hi)

            chunks(remove_means, n)
        z = self._inverse(rf, single=self.single)
        if self.pairs is not None:
            top, floor = self.pairs
            both = xp.astype(xp.take(free, top) & xp.take(free, floor), xp.float64) \
                / self._self_reference
            for part in self.pairs:
                z = be.put(z, part, xp.take(z, part) + xp.take(rf, part) * both)

        def restrict_output(lo, hi):
            v = z[lo:hi]
            v *= restriction(lo, hi)

        chunks(restrict_output, n)
        if not self.pillars:
            return z
        z_sums = self.plan.pillar_sums(z)
        if weight is not None:
            z_sums = z_sums * weight
        mode = self.plan.pillar_mode_compliance(count) + self._disk * count * xp.sqrt(count)
        coarse = sums / xp.where(count > 0.0, mode, 1.0)
        modes = coarse - z_sums * per_cell

        def add_modes(lo, hi):
            v = z[lo:hi]
            v += self.plan.per_cell(modes, lo, hi)
            v *= mask[lo:hi]

        chunks(add_modes, n)
        return z

    def _kept(self, r):
        """The indicator of F, the restricted residual and the indicator times S (None
        without S): arrays of ``r``'s shape kept between calls (only this call reads them;
        z, returned, is the convolution's own)."""
        kept = getattr(self, "_arrays", None)
        if kept is None or kept[0].shape != r.shape:
            xp = self.backend.xp
            kept = self._arrays = (xp.empty_like(r), xp.empty_like(r),
                                   None if self.scale is None else xp.empty_like(r))
        return kept
