"""Matrix-free compliance operator of the cell grid: half-space kernel by zero-padded FFT plus
the Hooke shortening of each pillar.

The displacement (m) of cell i under smeared cell pressures q (Pa) is

    u_i = sum_j K(x_i - x_j) q_j  +  c_s L^2 sum_{j in pillar(i)} q_j,

with K = (gamma / pi) D, D Love's integral of 1/|x - x'| over a square cell (see
:mod:`bem_solver._love`), gamma = gamma_l + gamma_s, and c_s = 4 h / (pi d^2 E_p) the spring
compliance of a pillar (m/N).  The convolution is linear (free surface, not periodic): the grid
is zero-padded to at least 2 n - 1 points per axis, so no image of the kernel wraps onto the
grid.  K is even in both axes, so its spectrum is real and is stored as one real array.

References
----------
.. [1] S. Liu, Q. Wang, G. Liu, "A versatile method of discrete convolution and FFT (DC-FFT)
   for contact analyses", Wear 243 (2000) 101-111.
.. [2] A. E. H. Love, Phil. Trans. R. Soc. A 228 (1929) 377-420.
"""

from __future__ import annotations

import math

import numpy as np
import scipy.fft as sfft
import scipy.sparse as sp

from ._love import love_square

FFT_WORKERS = 2  # this machine has two cores; scipy.fft threads the 2D transforms
# Half-width (in cells) of the stencil around a partly covered cell within which its grid
# coefficients are replaced by the equivalent-square ones.  Beyond it the two differ by a
# dipole of the O(L) centroid shift, ~ phi L^3 / r^2; tests/test_bem_fft.py shows the effect of
# the width on the answer.
NEAR_FIELD_CELLS = 3


def kernel_block(shape, cell_size: float, compliance: float) -> np.ndarray:
    """K(i L, j L) for 0 <= i < ny, 0 <= j < nx in m/Pa (rows = y offsets)."""
    ny, nx = shape
    oy = np.arange(ny) * cell_size
    ox = np.arange(nx) * cell_size
    return compliance / math.pi * love_square(ox[None, :], oy[:, None], cell_size)


def near_field_correction(grid, compliance: float, width: int = NEAR_FIELD_CELLS):
    """Sparse symmetric correction C (m/Pa) that turns the grid operator into the
    equivalent-square operator near partly covered cells.

    The force q_j L^2 of a partly covered cell acts as a uniform pressure on a square of side
    sqrt(phi_j) L centred on the centroid c_j of its covered part, and the cell is collocated
    at c_j (as in the dense model's ``covered`` cells).  For every pair (i, j) within ``width``
    cells of each other with i or j partly covered,

        C_ij = 1/2 [A'_ij + A'_ji] - K(x_i - x_j),
        A'_ij = (gamma / pi) D(c_i - c_j; sqrt(phi_j) L) / phi_j,

    symmetrised so that the constrained CG keeps a symmetric operator.  Returns ``None``
    when every cell is fully covered.
    """
    L = grid.cell_size
    part = np.nonzero(grid.covered < 1.0 - 1e-12)[0]
    if part.size == 0:
        return None
    ny, nx = grid.shape
    lookup = np.full(ny * nx, -1, dtype=np.int64)
    lookup[grid.flat_index] = np.arange(grid.n_cells)
    iy, ix = np.divmod(grid.flat_index[part], nx)
    offs = np.arange(-width, width + 1)
    dy, dx = (a.ravel() for a in np.meshgrid(offs, offs, indexing="ij"))
    jy, jx = iy[:, None] + dy[None, :], ix[:, None] + dx[None, :]
    inside = (jy >= 0) & (jy < ny) & (jx >= 0) & (jx < nx)
    j = np.where(inside, lookup[np.clip(jy, 0, ny - 1) * nx + np.clip(jx, 0, nx - 1)], -1)
    i = np.broadcast_to(part[:, None], j.shape)
    ok = j >= 0
    i, j = i[ok], j[ok]
    # Each unordered pair once: (partial, full) pairs, and (partial, partial) with i <= j.
    full_j = grid.covered[j] >= 1.0 - 1e-12
    keep = full_j | (i <= j)
    i, j = i[keep], j[keep]
    cx, cy, phi = grid.colloc_x, grid.colloc_y, grid.covered
    side = np.sqrt(phi) * L
    k = compliance / math.pi
    a_ij = k * love_square(cx[i] - cx[j], cy[i] - cy[j], side[j]) / phi[j]
    a_ji = k * love_square(cx[j] - cx[i], cy[j] - cy[i], side[i]) / phi[i]
    # Grid coefficients of the pairs: a (width + 1)^2 table of integer offsets.
    table = kernel_block((width + 1, width + 1), L, compliance)
    iy_i, ix_i = np.divmod(grid.flat_index[i], nx)
    iy_j, ix_j = np.divmod(grid.flat_index[j], nx)
    grid_ij = table[np.abs(iy_i - iy_j), np.abs(ix_i - ix_j)]
    value = 0.5 * (a_ij + a_ji) - grid_ij
    diag = i == j
    rows = np.concatenate([i, j[~diag]])
    cols = np.concatenate([j, i[~diag]])
    vals = np.concatenate([value, value[~diag]])
    return sp.csr_matrix((vals, (rows, cols)), shape=(grid.n_cells, grid.n_cells))


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
    workers : int
        Threads for scipy.fft.
    correction : scipy.sparse matrix, optional
        Near-field correction (m/Pa) from :func:`near_field_correction`.
    """

    def __init__(self, shape, flat_index, cell_size, compliance, pillar=None,
                 spring_compliance=0.0, workers=FFT_WORKERS, correction=None):
        ny, nx = shape
        self.shape = (ny, nx)
        self.cell_size = float(cell_size)
        self.compliance = float(compliance)
        self.workers = workers
        # Linear convolution of n-point sequences needs >= 2n - 1 points.
        self.fft_shape = (sfft.next_fast_len(2 * ny - 1, real=True),
                          sfft.next_fast_len(2 * nx - 1, real=True))
        my, mx = self.fft_shape
        block = kernel_block(shape, cell_size, compliance)
        padded = np.zeros(self.fft_shape)
        padded[:ny, :nx] = block
        padded[my - ny + 1:, :nx] = block[1:][::-1]          # negative y offsets
        padded[:, mx - nx + 1:] = padded[:, 1:nx][:, ::-1]  # negative x offsets
        # Even kernel -> real spectrum (imaginary part is round-off).
        self.kernel_spectrum = np.ascontiguousarray(
            sfft.rfft2(padded, workers=workers).real)
        self.self_coefficient = float(block[0, 0])
        iy, ix = np.divmod(np.asarray(flat_index), nx)
        self.padded_index = iy * mx + ix
        # Only the first ny rows of the padded input are non-zero and only the first ny rows
        # of the output are needed: the row transforms run on ny rows, the column transforms
        # zero-pad to my (a pruned 2D FFT, ~40 % cheaper than rfft2 on the padded array).
        self._buffer = np.zeros((ny, mx))
        self.spring = float(spring_compliance) * self.cell_size**2  # m/Pa per unit q
        self.pillar = None if pillar is None else np.asarray(pillar)
        self.n_pillars = 0 if pillar is None or len(pillar) == 0 else int(pillar.max()) + 1
        self.applications = 0
        self.correction = correction
        diagonal = np.full(len(flat_index), self.self_coefficient)
        if correction is not None:
            diagonal += correction.diagonal()
        self.diagonal = diagonal

    @property
    def has_spring(self) -> bool:
        return self.spring > 0.0 and self.pillar is not None

    def pillar_sums(self, q: np.ndarray) -> np.ndarray:
        """Sum of q over the cells of each pillar (Pa); multiply by L^2 for forces."""
        return np.bincount(self.pillar, weights=q, minlength=self.n_pillars)

    def half_space(self, q: np.ndarray) -> np.ndarray:
        """K q on the candidate cells (m)."""
        buf = self._buffer
        buf.flat[self.padded_index] = q  # the rest of the buffer stays zero
        w = self.workers
        my, mx = self.fft_shape
        spec = sfft.fft(sfft.rfft(buf, axis=1, workers=w), n=my, axis=0, workers=w,
                        overwrite_x=True)
        spec *= self.kernel_spectrum
        rows = sfft.ifft(spec, axis=0, workers=w, overwrite_x=True)[:self.shape[0]]
        out = sfft.irfft(rows, n=mx, axis=1, workers=w)
        self.applications += 1
        return out.ravel()[self.padded_index]

    def __call__(self, q: np.ndarray) -> np.ndarray:
        """Full compliance: half-space convolution plus per-pillar Hooke shortening (m)."""
        u = self.half_space(q)
        if self.correction is not None:
            u += self.correction @ q
        if self.has_spring:
            u += self.spring * self.pillar_sums(q)[self.pillar]
        return u

    def dense_matrix(self, x, y) -> np.ndarray:
        """The same operator as a dense matrix (m/Pa), for tests on small grids."""
        # Offsets are exact multiples of L: evaluate the kernel block on integer offsets.
        i = np.rint(np.abs(y[:, None] - y[None, :]) / self.cell_size).astype(int)
        j = np.rint(np.abs(x[:, None] - x[None, :]) / self.cell_size).astype(int)
        mat = kernel_block(self.shape, self.cell_size, self.compliance)[i, j]
        if self.correction is not None:
            mat = mat + self.correction.toarray()
        if self.has_spring:
            mat = mat + self.spring * (self.pillar[:, None] == self.pillar[None, :])
        return mat
