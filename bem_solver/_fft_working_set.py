"""The floor cells a fine FFT solve leaves out: those its coarse level finds clear of the lens.

With the floor reached, every floor cell where the undeformed gap is negative is a candidate
(within sqrt(2 R (zeta - h)) of the axis), but the pillars hold the lens up over most of
them: with rigid pillars, R = 1 mm, Phi = 0.03, h = 1 um, zeta = 3 um and N = 36, 784,268
of the 987,338 candidate floor cells end with a positive gap.  Each costs the constrained
CG's passes, its scalar products and the preconditioner's restrictions at every iteration.

The nested iteration's coarse solution says which they are.  A floor cell is left out of the
fine solve where

- the coarse level's floor gap exceeds ``FLOOR_CLEARANCE`` zeta at the coarse cell nearest
  its centre and at that cell's eight neighbours (a position beyond the coarse floor counts
  as touching),
- it is wholly floor (no rim crosses it), and
- no partly covered cell lies within the near-field correction's reach
  (``NEAR_FIELD_CELLS`` cells either way): no correction pair touches it.

The solve then runs on the other cells.  After it, the gap on the left-out cells is computed
exactly: the undeformed gap plus the half-space convolution of the solved pressures at those
cells (the floor meets the pillars through the half-space kernel alone, for Hooke and
elastic pillars, and no near-field pair reaches them).  The answer stands only if none of them
interpenetrates by more than the solve's tolerance; otherwise the whole grid is solved, from
that answer.  Either way the result holds every candidate cell.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ._fft_grid import CellGrid
from ._fft_operator import NEAR_FIELD_CELLS

# A floor cell is left out where the coarse level's gap there exceeds this fraction of the
# indentation.  From the coarse level to the fine one the floor's gap fell by at most 0.0061
# zeta (at a coarse gap of 0.0061 zeta) over seven mixed scenes (rigid and Hooke pillars,
# Phi = 0.03-0.2, h = 0.5-1 um, zeta = 2-6 um, R = 0.3-1 mm, N = 16-36): a third of this
# clearance.  Each cell kept costs every CG pass: at 0.02 instead of 0.05, 3.9e5 instead of
# 4.7e5 unknowns at N = 36 (R = 1 mm, Phi = 0.03, h = 1 um, zeta = 3 um).  The check after
# the solve makes any choice safe; this one keeps the fallback rare.
FLOOR_CLEARANCE = 0.02
# Leaving out fewer than this share of the cells does not pay for the selection.
MIN_LEFT_OUT_SHARE = 0.25
# Nor on fewer cells than this: on rigid pillars (Phi = 0.03, h = 1 um, zeta = 3 um) the
# solve took 1.08x as long on 6.2e4 cells (R = 0.3 mm, N = 16), 0.91x on 1.4e5 (N = 24) and
# 0.92x on 2.3e5 (R = 0.5 mm), medians of 7 alternate runs.
MIN_GRID_CELLS = 100_000


def left_out_floor(rough, grid: CellGrid, indentation: float):
    """Indices (increasing) of the floor cells of ``grid`` that the coarse solution
    ``rough`` finds clear of the lens (module docstring), or None when too few are."""
    f = rough.fields
    coarse_floor = f.get("floor")
    if grid.n_cells < MIN_GRID_CELLS or not grid.has_floor or coarse_floor is None \
            or not coarse_floor.any() or not rough.converged:
        return None
    # Wholly floor, standing alone at its position: the floor's unknowns up to n_unique.
    cells = np.arange(grid.n_top, grid.n_unique)
    cells = cells[grid.covered[cells] >= 1.0]
    # Marked: every cell within the correction's square around a partly covered one (an
    # offset past a row's end marks a cell of the next row too: kept needlessly, never
    # left out wrongly).
    ny, nx = grid.shape
    w = np.arange(-NEAR_FIELD_CELLS, NEAR_FIELD_CELLS + 1)
    marks = (grid.flat_index[grid.covered < 1.0][:, None]
             + (w[:, None] * nx + w[None, :]).ravel()[None, :]).ravel()
    near = np.zeros(ny * nx, dtype=bool)
    near[marks[(marks >= 0) & (marks < ny * nx)]] = True
    cells = cells[~near[grid.flat_index[cells]]]
    if cells.size < MIN_LEFT_OUT_SHARE * grid.n_cells:
        return None
    cells = cells[_clear_of_coarse(f, coarse_floor, grid.x[cells], grid.y[cells],
                                   FLOOR_CLEARANCE * indentation)]
    return cells if cells.size >= MIN_LEFT_OUT_SHARE * grid.n_cells else None


def _clear_of_coarse(f: dict, coarse_floor, x, y, clearance: float):
    """Whether the points (``x``, ``y``) lie where the coarse solution's floor gap exceeds
    ``clearance`` (m) at the nearest coarse cell and at its eight neighbours (so at every
    coarse cell a bilinear interpolation there would read); a coarse position that is not
    a floor candidate counts as touching."""
    from scipy.ndimage import minimum_filter

    from ._fft import coarse_layout

    Lc = f["cell_size_m"]
    at, shape, (y0, x0) = coarse_layout(f, coarse_floor)
    image = np.full(shape, -1.0)
    image[at] = f["gap_m"][coarse_floor]
    clear = minimum_filter(image, size=3, mode="constant", cval=-1.0) > clearance
    jx = np.rint(x / Lc).astype(np.int64) - x0
    jy = np.rint(y / Lc).astype(np.int64) - y0
    inside = (jx >= 0) & (jx < clear.shape[1]) & (jy >= 0) & (jy < clear.shape[0])
    out = np.zeros(x.shape, dtype=bool)
    out[inside] = clear[jy[inside], jx[inside]]
    return out


def working_grid(grid: CellGrid, left_out: np.ndarray):
    """``grid`` without the cells ``left_out``, and the kept cells' indices in ``grid``
    (the tops and the rims' floor parts are all kept, so the order of the unknowns holds:
    the tops first, then the floor's, the shared positions last)."""
    keep = np.ones(grid.n_cells, dtype=bool)
    keep[left_out] = False
    kept = np.flatnonzero(keep)

    def part(a):
        return None if a is None else a[kept]

    sub = replace(grid, flat_index=grid.flat_index[kept], x=grid.x[kept], y=grid.y[kept],
                  covered=grid.covered[kept], gap0=grid.gap0[kept],
                  pillar=grid.pillar[kept], colloc_x=grid.colloc_x[kept],
                  colloc_y=grid.colloc_y[kept], floor=grid.floor[kept],
                  n_unique=grid.n_unique - left_out.size, reach=part(grid.reach))
    return sub, kept


def gap_left_out(plan, grid: CellGrid, left_out: np.ndarray, pressure, be) -> np.ndarray:
    """The exact gap (m) on the left-out cells of ``grid`` under the kept cells' solved
    ``pressure`` (host arrays): their undeformed gap plus the half-space convolution there."""
    u = plan.half_space_at(be.asarray(pressure, dtype=be.xp.float64),
                           be.asarray(grid.flat_index[left_out]))
    return grid.gap0[left_out] + be.to_numpy(u)


def whole(grid: CellGrid, kept, left_out, values, outside) -> np.ndarray:
    """A vector on every cell of ``grid``: ``values`` on the kept cells, ``outside`` (an
    array or a number) on the left-out ones."""
    out = np.empty(grid.n_cells)
    out[kept] = values
    out[left_out] = outside
    return out
