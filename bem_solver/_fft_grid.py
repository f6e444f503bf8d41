"""Regular cell grid of the matrix-free BEM: candidate cells, covered fractions, gap.

The grid is made of square cells of side ``L``, axis-aligned, with the origin (centre of the
centre pillar, or of the Hertz contact) at the centre of a cell, so the centre pressure is a
cell value at every resolution.  Only *candidate* cells are unknowns: cells that overlap a
pillar top and whose centre lies where the undeformed gap ``g(r) = R - sqrt(R^2 - r^2)`` does
not exceed the indentation zeta.  Outside that disk no contact is possible: the half-space
kernel and the Hooke term are positive, so u >= 0 and gap = g + u - zeta > 0.

A pillar-top cell carries its covered fraction phi (exact area of the square-disk
intersection over L^2): the cell's force is q L^2 where q = phi p is the pressure smeared over
the whole cell, so the discrete pillar tops have exactly the area pi d^2 / 4 and a grid
convergence study is not spoiled by the staircase area error of whole cells.  Partly covered
cells are collocated at the centroid of their covered part (closed-form first moments).

The floor between the pillars, h below the tops, is a candidate too where its undeformed gap
g(r) + h - zeta can be <= 0, within the floor's reach (:func:`pillar_xval.scenes.floor.
floor_reach`).  A floor cell carries the part of its square that no top covers, 1 - phi,
collocated at the centroid of that part (the cell's moment less the tops' closed-form
moments), so a cell that a pillar's rim crosses holds two unknowns at one grid position: its
top part and its floor part.  The unknowns are ordered tops first, then the floor cells
alone at their position, then the floor parts of rim cells (``n_unique`` counts the first
two groups: the grid positions of the last group repeat positions of the first).  A floor
cell's ``pillar`` is the extra index ``len(pillar_nm)`` (the floor), which no Hooke term
touches.  Without floor cells (zeta below the floor's reach) the grid is exactly the
suspended one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pillar_xval.scenes import Scene, SceneError
from pillar_xval.scenes.analytic import lens_gap
from pillar_xval.scenes.floor import floor_reach
from pillar_xval.scenes.lattice import pillars_within

from ._disk import disk_rectangle_area, disk_rectangle_centroid

# Cells covered by less than this fraction of their area are dropped and their area is given
# to the other edge cells of the pillar.  Such slivers, with an equivalent-square
# self-compliance ~ 1/sqrt(phi) up to 3e4 times a full cell's, made the constrained CG creep
# (441 instead of 174 iterations at N = 58 on paper-fig3-dense, rigid pillars) while moving
# F_T by 1.5e-7 relative.
MIN_COVERED_FRACTION = 1e-3
# Flat (Hertz) scenes: candidate disk radius in units of the Hertz radius sqrt(R zeta) (plus
# two cells).  The contact radius of the discrete problem is a + O(L); the solver checks that
# no contact reaches this artificial edge.
FLAT_CANDIDATE_RATIO = 1.25
# Largest padded FFT grid (points) accepted on the CPU: 2 * 4096^2 doubles is ~1 GB of work
# arrays.  A GPU backend (bem_solver._xp) passes its own limit, from its free memory.
MAX_FFT_POINTS = 4096 * 4096


@dataclass
class CellGrid:
    """Candidate cells of one scene on a regular grid.

    Attributes
    ----------
    cell_size : float
        Side L of a cell (m).
    shape : tuple of int
        (ny, nx) of the bounding grid; both odd, the origin at the centre of cell
        (ny // 2, nx // 2).
    flat_index : ndarray of int
        Row-major index in the (ny, nx) grid of each candidate cell.
    x, y : ndarray
        Cell centres (m).
    covered : ndarray
        Covered fraction phi of each cell, in (0, 1].
    gap0 : ndarray
        Undeformed gap g(r) minus zeta at the collocation point (m); negative where the lens
        would interpenetrate a rigid top.
    colloc_x, colloc_y : ndarray
        Collocation points (m): the cell centre, or for a partly covered cell the centroid of
        its covered part, where its force also acts (as an equivalent square of area
        phi L^2; see :func:`bem_solver._fft_operator.near_field_correction`).
    pillar : ndarray of int
        Index (into ``pillar_nm``) of the pillar each cell belongs to; 0 for flat scenes;
        ``len(pillar_nm)`` for a floor cell.
    pillar_nm, pillar_xy : ndarray
        Lattice indices (n, m) and centres (m) of the candidate pillars (flat: one row (0, 0)).
    centre_cell : int
        Index of the candidate cell that holds the origin.
    floor : ndarray of bool
        Whether each unknown is on the floor (after every top unknown).
    n_unique : int
        Leading unknowns whose grid positions are all different; the others are the floor
        parts of rim cells, each at the position of a top unknown before them.
    floor_radius : float
        The floor's reach (m): floor cells have their centres within it; 0 without floor.
    reach : ndarray, optional
        Outer radius of each cell (m; collocation radius plus half the side of its
        equivalent square), a top's capped at its pillar's rim: what a contact radius is the
        largest of.  Built with the grid where a device builds it (one pass there, where the
        host took a second of a 2e7-cell result); None otherwise (the result computes it
        for the cells in contact only).
    """

    cell_size: float
    shape: tuple
    flat_index: np.ndarray
    x: np.ndarray
    y: np.ndarray
    covered: np.ndarray
    gap0: np.ndarray
    pillar: np.ndarray
    pillar_nm: np.ndarray
    pillar_xy: np.ndarray
    centre_cell: int
    candidate_radius: float
    flat: bool
    colloc_x: np.ndarray = None
    colloc_y: np.ndarray = None
    floor: np.ndarray = None
    n_unique: int = None
    floor_radius: float = 0.0
    reach: np.ndarray = None

    def __post_init__(self):
        if self.colloc_x is None:
            self.colloc_x, self.colloc_y = self.x, self.y
        if self.floor is None:
            self.floor = np.zeros(self.flat_index.size, dtype=bool)
        if self.n_unique is None:
            self.n_unique = int(self.flat_index.size)

    @property
    def has_floor(self) -> bool:
        """Whether any floor cell is a candidate."""
        return bool(self.floor.any())

    @property
    def n_top(self) -> int:
        """Unknowns on the pillar tops (the first ones)."""
        return int(self.flat_index.size - np.count_nonzero(self.floor))

    @property
    def n_cells(self) -> int:
        return int(self.flat_index.size)


def cell_size(scene: Scene, cells_per_diameter: int) -> float:
    """L = d / N for pillars; L = 2 sqrt(R zeta) / N (Hertz contact diameter) for a flat
    scene (m)."""
    if int(cells_per_diameter) != cells_per_diameter or cells_per_diameter < 2:
        raise ValueError(f"cells_per_diameter = {cells_per_diameter!r}: must be an integer >= 2")
    if scene.pillars is None:
        return 2.0 * math.sqrt(scene.lens.radius_m * scene.indentation_m) / cells_per_diameter
    return scene.pillars.diameter_m / cells_per_diameter


# Host memory of a solve per point of the candidate square (n_side^2, the padded FFT being
# about 4 n_side^2 points), measured with tracemalloc on paper-fig3-dense: the grid's build
# 97-99 B, a whole CPU solve 182-253 B per padded point (N = 32 and 24); rounded up.
GRID_BYTES_PER_POINT = 100.0
CPU_SOLVE_BYTES_PER_POINT = 4 * 200.0


def _candidate(scene: Scene, cells_per_diameter: int) -> tuple[float, float, int]:
    """(cell size L, candidate radius, half side in cells) of the grid."""
    R, zeta = scene.lens.radius_m, scene.indentation_m
    L = cell_size(scene, cells_per_diameter)
    # Radius where the undeformed gap equals zeta: r^2 = 2 R zeta - zeta^2.
    r_geo = math.sqrt(2.0 * R * zeta - zeta * zeta)
    # Flat scenes: a margin of two cells beyond 1.25 a keeps coarse grids clear of the edge.
    r_cand = min(r_geo, FLAT_CANDIDATE_RATIO * math.sqrt(R * zeta) + 2.0 * L) \
        if scene.pillars is None else r_geo
    return L, r_cand, int(math.ceil(r_cand / L)) + 1


def candidate_side(scene: Scene, cells_per_diameter: int) -> int:
    """Cells along a side of the square around the candidate disk (before cropping)."""
    return 2 * _candidate(scene, cells_per_diameter)[2] + 1


def estimate_host_memory(scene: Scene, cells_per_diameter: int, on_cpu: bool = True) -> float:
    """Peak host bytes of a solve (the grid's build; on the CPU the whole solve)."""
    n = float(candidate_side(scene, cells_per_diameter)) ** 2
    return n * (CPU_SOLVE_BYTES_PER_POINT if on_cpu else GRID_BYTES_PER_POINT)


def check_grid_side(n_side: int, cells_per_diameter: int, max_fft_points: int) -> None:
    """Refuse (SceneError) a candidate square of ``n_side`` cells a side whose padded FFT
    would exceed ``max_fft_points`` points."""
    if n_side**2 > 4 * max_fft_points:
        raise SceneError(
            f"cells_per_diameter = {cells_per_diameter}: the candidate disk would span "
            f"{n_side} x {n_side} cells; choose fewer cells per diameter")


def build_grid(scene: Scene, cells_per_diameter: int,
               max_fft_points: int = MAX_FFT_POINTS, xp=np, dense=None) -> CellGrid:
    """Candidate cells of ``scene`` with ``cells_per_diameter`` cells across a pillar (or
    across the Hertz contact diameter for a flat scene); a grid whose padded FFT would exceed
    ``max_fft_points`` points is refused (SceneError).  ``xp``: the array library that builds
    it (numpy, or cupy on a GPU: the same steps, and the grid comes back to the host).
    ``dense``: the tops' fractions by whole-array passes (default on a device; see
    :func:`_pillar_cells`)."""
    R, zeta = scene.lens.radius_m, scene.indentation_m
    flat = scene.pillars is None
    L, r_cand, half = _candidate(scene, cells_per_diameter)
    n_side = 2 * half + 1
    check_grid_side(n_side, cells_per_diameter, max_fft_points)
    # Cell (row iy, column ix) of the candidate square, flat index iy n_side + ix, has its
    # centre at (ax[ix], ax[iy]): the square's coordinates are never stored whole.
    ax = (xp.arange(n_side) - half) * L
    if flat:
        keep = xp.flatnonzero(xp.hypot(ax[None, :], ax[:, None]) <= r_cand)
        covered = xp.ones(keep.size)
        pillar = xp.zeros(keep.size, dtype=xp.int64)
        pillar_nm = np.zeros((1, 2), dtype=int)
        pillar_xy = np.zeros((1, 2))
    r_floor = 0.0 if flat else floor_reach(scene)
    if not flat:
        keep, covered, pillar, pillar_nm, pillar_xy, tops = _pillar_cells(
            scene, ax, L, r_cand, floor=r_floor > 0.0, xp=xp, dense=dense)
    row, col = xp.divmod(keep, n_side)
    colloc_x, colloc_y = ax[col], ax[row]
    if not flat:
        colloc_x, colloc_y = _centroids(colloc_x, colloc_y, covered, pillar,
                                        xp.asarray(pillar_xy), L,
                                        0.5 * scene.pillars.diameter_m)
    n_unique, floor = int(keep.size), None
    if r_floor > 0.0:
        fk, fcov, fx, fy, n_alone = _floor_cells(ax, L, r_floor, keep, tops, xp)
        n_unique = int(keep.size) + n_alone
        floor = xp.concatenate([xp.zeros(keep.size, dtype=bool), xp.ones(fk.size, dtype=bool)])
        keep = xp.concatenate([keep, fk])
        row, col = xp.divmod(keep, n_side)
        covered = xp.concatenate([covered, fcov])
        pillar = xp.concatenate([pillar, xp.full(fk.size, len(pillar_nm), dtype=pillar.dtype)])
        colloc_x, colloc_y = xp.concatenate([colloc_x, fx]), xp.concatenate([colloc_y, fy])
    keep, shape = _crop(row, col)
    if (2 * shape[0]) * (2 * shape[1]) > max_fft_points:
        raise SceneError(
            f"cells_per_diameter = {cells_per_diameter}: the grid would need {shape[0]} x "
            f"{shape[1]} cells (padded FFT {4 * shape[0] * shape[1]} points > "
            f"{max_fft_points}); choose fewer cells per diameter")
    x, y = ax[col], ax[row]
    gap0 = lens_gap(R, xp.hypot(colloc_x, colloc_y)) - zeta
    if floor is not None:
        gap0[floor] += scene.pillars.height_m
    centre = xp.nonzero((xp.abs(x) < 0.5 * L) & (xp.abs(y) < 0.5 * L))[0]
    if floor is not None:
        centre = centre[~floor[centre]]
    if centre.size != 1:
        raise RuntimeError("grid construction lost the centre cell")  # a bug, not user input
    reach = None
    if xp is not np and not flat:
        reach = outer_radii(colloc_x, colloc_y, covered, L, pillar,
                            xp.asarray(rim_radii(pillar_xy, scene.pillars.diameter_m)), xp)
    host = getattr(xp, "asnumpy", np.asarray)  # cupy's arrays come back once
    return CellGrid(L, shape, host(keep), host(x), host(y), host(covered), host(gap0),
                    host(pillar), pillar_nm, pillar_xy, int(centre[0]), r_cand, flat,
                    host(colloc_x), host(colloc_y), None if floor is None else host(floor),
                    n_unique, r_floor, None if reach is None else host(reach))


def rim_radii(pillar_xy, diameter: float):
    """Distance (m) of each pillar's rim's farthest point from the origin."""
    return np.hypot(pillar_xy[:, 0], pillar_xy[:, 1]) + 0.5 * diameter


def outer_radii(x, y, covered, L: float, pillar=None, rims=None, xp=np):
    """Outer radius (m) of cells collocated at (``x``, ``y``) with covered fractions
    ``covered``: the collocation radius plus half the side of the equivalent square, as in
    the dense model; with ``rims`` (:func:`rim_radii`) a top cell's capped at its pillar's
    rim (``pillar`` indices beyond ``rims``, the floor's, uncapped)."""
    r = xp.hypot(x, y) + 0.5 * xp.sqrt(covered) * L
    if rims is not None:
        top = pillar < rims.shape[0]
        r[top] = xp.minimum(r[top], rims[pillar[top]])
    return r


def _floor_cells(ax, L, r_floor, keep, tops, xp=np):
    """Floor cells within ``r_floor`` of the origin (centres ``ax`` x ``ax``): indices into
    the square, floor fractions 1 - phi, collocation points, and how many of them stand
    alone at their position (they come first; the rest share a position with a kept top
    cell).  ``tops`` = (top fraction, x moment, y moment) over the square, the moments of
    the covered parts about the origin (m^3) on rim cells."""
    total, mx, my = tops
    side = ax.size
    reach = _disk_cells(ax, r_floor, xp)
    frac = 1.0 - xp.minimum(total[reach], 1.0)
    # A floor sliver is dropped like a top sliver (MIN_COVERED_FRACTION); its area, below
    # 1e-3 L^2, is lost from the floor.
    cand = reach[frac > MIN_COVERED_FRACTION]
    frac = 1.0 - xp.minimum(total[cand], 1.0)
    shared = xp.zeros(side * side, dtype=bool)
    shared[keep] = True
    alone = ~shared[cand]
    order = xp.concatenate([xp.flatnonzero(alone), xp.flatnonzero(~alone)])
    cand, frac = cand[order], frac[order]
    iy, ix = xp.divmod(cand, side)
    cx, cy = ax[ix], ax[iy]
    part = frac < 1.0 - 1e-12
    area = frac * L * L
    # Centroid of the floor part: the square's moment less the tops' (where a rim crosses).
    cx, cy = cx.copy(), cy.copy()
    cx[part] = (cx[part] * L * L - mx[cand[part]]) / area[part]
    cy[part] = (cy[part] * L * L - my[cand[part]]) / area[part]
    return cand, frac, cx, cy, int(xp.count_nonzero(alone))


def _centroids(x, y, covered, pillar, pillar_xy, L, rad):
    """Collocation points: centroids of the covered parts of partly covered cells (m)."""
    x, y = x.copy(), y.copy()
    part = (covered < 1.0 - 1e-12).nonzero()[0]
    px, py = pillar_xy[pillar[part], 0], pillar_xy[pillar[part], 1]
    cx, cy = x[part] - px, y[part] - py
    mx, my = disk_rectangle_centroid(cx - 0.5 * L, cx + 0.5 * L, cy - 0.5 * L, cy + 0.5 * L,
                                     rad)
    x[part], y[part] = mx + px, my + py
    return x, y


def _crop(iy, ix):
    """Re-index the kept cells (rows ``iy``, columns ``ix`` of the candidate square) into
    their bounding box: the flat index in the box and the box shape (ny, nx)."""
    y0, x0 = int(iy.min()), int(ix.min())
    shape = (int(iy.max()) - y0 + 1, int(ix.max()) - x0 + 1)
    return (iy - y0) * shape[1] + (ix - x0), shape


def _pillar_cells(scene, ax, L, r_cand, floor=False, xp=np, dense=None):
    """Cells on pillar tops within the candidate disk: indices into the (n, n) square of
    centres ``ax`` x ``ax``, covered fractions, owning pillar, the pillar table, and with
    ``floor`` the tops' covered fraction of every cell of the square and the moments of the
    covered parts about the origin (m^3; else None).  ``dense``: the fractions from every
    cell's nearest lattice sites at once (:func:`_fractions_dense`, a device's way: a fixed
    number of whole-array passes) rather than pillar by pillar (:func:`_fractions_windows`,
    the host's: only the cells near each pillar); default: dense on a device, where it
    applies.  Both evaluate the same expressions per (cell, pillar) pair."""
    p = scene.pillars
    rad = 0.5 * p.diameter_m
    table = pillars_within(r_cand + rad, p.pitch_m)
    side = ax.size
    half = side // 2
    if dense is None:
        dense = xp is not np
    fractions = _fractions_dense if dense else _fractions_windows
    total_frac, owner, moment_x, moment_y = fractions(table, ax, L, rad, p.pitch_m, floor, xp)
    total_frac, owner = total_frac.ravel(), owner.ravel()
    tops = (total_frac.copy(), moment_x.ravel(), moment_y.ravel()) if floor else None
    # The tops outside the candidate disk are not candidates: cleared by each row's column
    # bound, so that the kept cells come from one scan of the square (no distance per cell).
    beyond = xp.abs(xp.arange(side)[None, :] - half) > _row_reach(ax, r_cand, xp)[:, None]
    total_frac[beyond.ravel()] = 0.0
    # Near close packing a cell may overlap two tops: it goes to the larger share and carries
    # the sum of both (the Hooke term then acts on one pillar only, an O(L^2) effect).
    keep = xp.flatnonzero(total_frac > MIN_COVERED_FRACTION)
    covered = total_frac[keep]
    xp.minimum(covered, 1.0, out=covered)
    owners = owner[keep]
    # The dropped slivers' area goes to the other partly covered cells of the same pillar, so
    # every top keeps its exact area.  (Whole cells carry a fraction 0 or >= 1: the cells in
    # (0, MIN_COVERED_FRACTION] are rim cells.)
    sliver = xp.flatnonzero((total_frac > 0.0) & (total_frac <= MIN_COVERED_FRACTION))
    n_table = len(table)
    lost = xp.bincount(owner[sliver], weights=xp.minimum(total_frac[sliver], 1.0),
                       minlength=n_table)
    partial = xp.flatnonzero(covered < 1.0)
    share = xp.bincount(owners[partial], weights=covered[partial], minlength=n_table)
    scale = 1.0 + lost / xp.where(share > 0, share, 1.0) * (share > 0)
    covered[partial] = xp.minimum(covered[partial] * scale[owners[partial]], 1.0)
    # The pillars that own a kept cell, in table order, and each cell's rank among them
    # (np.unique's result, by counting instead of sorting 1e7 labels).
    present = xp.bincount(owners, minlength=n_table) > 0
    pillar = (xp.cumsum(present) - 1)[owners]
    used = np.flatnonzero(getattr(xp, "asnumpy", np.asarray)(present))
    nm = table[used, :2].astype(int)
    xy = table[used, 2:4].astype(float)
    return keep, covered, pillar, nm, xy, tops


def _cover(cx, cy, L, rad, xp):
    """Covered fraction of the cells at offsets ``cx`` x ``cy`` (broadcast) from a top's
    centre: 1 where the farthest corner is inside the top, 0 where the nearest point is
    outside it, and the closed-form area only on the cells the rim crosses; with the rim
    cells' (row, column) indices into the broadcast shape."""
    far2 = (xp.abs(cx) + 0.5 * L) ** 2 + (xp.abs(cy) + 0.5 * L) ** 2
    near2 = xp.maximum(xp.abs(cx) - 0.5 * L, 0.0) ** 2 + xp.maximum(xp.abs(cy) - 0.5 * L,
                                                                     0.0) ** 2
    frac = (far2 <= rad * rad).astype(float)
    rim = xp.nonzero((near2 < rad * rad) & (far2 > rad * rad))
    return frac, rim


def _rim_parts(rx, ry, L, rad, floor):
    """Closed-form covered area over L^2 of the rim cells at offsets (rx, ry) from a top's
    centre, and with ``floor`` the centroids of the covered parts (else None)."""
    box = (rx - 0.5 * L, rx + 0.5 * L, ry - 0.5 * L, ry + 0.5 * L, rad)
    area = disk_rectangle_area(*box) / (L * L)
    return area, (disk_rectangle_centroid(*box) if floor else None)


def _square_arrays(side: int, floor: bool, xp):
    """Zeroed accumulators over the square: summed fraction, largest share, owner (-1), and
    with ``floor`` the two moments (else None)."""
    moments = (xp.zeros((side, side)), xp.zeros((side, side))) if floor else (None, None)
    return (xp.zeros((side, side)), xp.zeros((side, side)),
            xp.full((side, side), -1, dtype=xp.int64), *moments)


def _fractions_windows(table, ax, L, rad, pitch, floor, xp):
    """Tops' covered fraction summed over the pillars of ``table`` on the square ``ax`` x
    ``ax``, the owner of each cell (the pillar of the larger share, the first in table order
    on a tie; -1 for none) and with ``floor`` the covered parts' moments about the origin,
    pillar by pillar in the small window around each (views of the square, no gathers)."""
    side = ax.size
    half = side // 2
    total_frac, best_frac, owner, moment_x, moment_y = _square_arrays(side, floor, xp)
    m = int(math.ceil(rad / L)) + 1
    windows = []
    for _, _, px, py in table:
        ix0 = int(round(px / L)) + half
        iy0 = int(round(py / L)) + half
        cols = slice(max(ix0 - m, 0), min(ix0 + m + 1, side))
        rows = slice(max(iy0 - m, 0), min(iy0 + m + 1, side))
        cx, cy = ax[cols] - px, ax[rows] - py
        windows.append((rows, cols, cx, cy, *_cover(cx[None, :], cy[:, None], L, rad, xp)))
    # The rim cells' closed forms for all pillars at once (a few hundred cells each: per
    # pillar, the calls' overhead was most of their time).
    rims = [(cx[ci], cy[ri]) for _, _, cx, cy, _, (ri, ci) in windows]
    rim_area, centroid = _rim_parts(xp.concatenate([rx for rx, _ in rims]),
                                    xp.concatenate([ry for _, ry in rims]), L, rad, floor)
    ends = np.cumsum([0] + [rx.size for rx, _ in rims])
    for k, (rows, cols, cx, cy, frac, (ri, ci)) in enumerate(windows):
        px, py = table[k][2], table[k][3]
        lo, hi = int(ends[k]), int(ends[k + 1])
        frac[ri, ci] = rim_area[lo:hi]
        total_frac[rows, cols] += frac
        if floor:  # the covered parts' moments, full cells' at their centres
            area = frac * (L * L)
            mx_, my_ = xp.broadcast_to(cx[None, :], area.shape).copy(), \
                xp.broadcast_to(cy[:, None], area.shape).copy()
            if ri.size:
                mx_[ri, ci], my_[ri, ci] = centroid[0][lo:hi], centroid[1][lo:hi]
            moment_x[rows, cols] += area * (mx_ + px)
            moment_y[rows, cols] += area * (my_ + py)
        # Views of the square, updated in place: the pillar of the larger share owns a cell.
        best = best_frac[rows, cols]
        xp.copyto(owner[rows, cols], k, where=frac > best)
        xp.maximum(best, frac, out=best)
    return total_frac, owner, moment_x, moment_y


def _fractions_dense(table, ax, L, rad, pitch, floor, xp):
    """What :func:`_fractions_windows` gives, from every cell at once: each cell's four
    nearest lattice sites (the corners of the lattice parallelogram that holds its centre)
    are the only tops it can overlap, so the square takes four passes of whole-array work
    whatever the number of pillars, instead of a few launches per pillar.

    Why four suffice: a cell overlaps a top whose centre lies within rad + L / sqrt(2) of its
    centre; every other site is at least sqrt(3) / 2 pitch (a height of the parallelogram's
    two equilateral triangles) from any point of it; and rad <= pitch / 2 (tops do not
    overlap), L <= d / 2 (at least two cells across), so rad + L / sqrt(2) <= (1 + 1 /
    sqrt(2)) pitch / 2 = 0.854 pitch < 0.866 pitch."""
    side = ax.size
    # Table index of each lattice site (n, m) in the table's range, -1 for none.
    n_lo, m_lo = int(table[:, 0].min()), int(table[:, 1].min())
    n_hi, m_hi = int(table[:, 0].max()), int(table[:, 1].max())
    index = np.full((n_hi - n_lo + 2, m_hi - m_lo + 2), -1, dtype=np.int64)
    index[table[:, 0].astype(int) - n_lo, table[:, 1].astype(int) - m_lo] = \
        np.arange(len(table))
    index = xp.asarray(index)
    sites = xp.asarray(table[:, 2:4].astype(float))
    x, y = ax[None, :], ax[:, None]
    # Lattice coordinates: pillar (n, m) at ((2n - m) pitch / 2, sqrt(3) m pitch / 2).
    mf = xp.floor(2.0 * y / (math.sqrt(3.0) * pitch))
    nf = xp.floor((2.0 * x / pitch + 2.0 * y / (math.sqrt(3.0) * pitch)) / 2.0)
    total_frac, best, owner, moment_x, moment_y = _square_arrays(side, floor, xp)
    for dn, dm in ((0, 0), (1, 0), (0, 1), (1, 1)):
        n_ = (nf + dn).astype(xp.int64) - n_lo
        m_ = (mf + dm).astype(xp.int64) - m_lo
        inside = (n_ >= 0) & (n_ < index.shape[0]) & (m_ >= 0) & (m_ < index.shape[1])
        k = xp.where(inside, index[xp.clip(n_, 0, index.shape[0] - 1),
                                   xp.clip(m_, 0, index.shape[1] - 1)], -1)
        px = xp.where(k >= 0, sites[xp.maximum(k, 0), 0], 0.0)
        py = xp.where(k >= 0, sites[xp.maximum(k, 0), 1], 0.0)
        cx, cy = x - px, y - py
        frac, rim = _cover(cx, cy, L, rad, xp)
        frac[k < 0] = 0.0
        ri, ci = rim
        keep = k[ri, ci] >= 0
        ri, ci = ri[keep], ci[keep]
        rx, ry = cx[ri, ci], cy[ri, ci]
        frac[ri, ci], centroid = _rim_parts(rx, ry, L, rad, floor)
        total_frac += frac
        if floor:
            area = frac * (L * L)
            mx_, my_ = cx.copy(), cy.copy()
            if ri.size:
                mx_[ri, ci], my_[ri, ci] = centroid
            moment_x += area * (mx_ + px)
            moment_y += area * (my_ + py)
        # The larger share owns a cell, the first pillar in table order on a tie.
        take = (frac > best) | ((frac == best) & (frac > 0.0) & (k < owner))
        owner = xp.where(take, k, owner)
        best = xp.maximum(best, frac)
    return total_frac, owner, moment_x, moment_y


def _disk_cells(ax, radius: float, xp=np):
    """Flat indices, increasing, of the cells of the square ``ax`` x ``ax`` whose centres lie
    within ``radius`` of the origin (``hypot(x, y) <= radius``); on numpy row by row from
    :func:`_row_reach` (no distance per cell: 19 ms of a 1e6-cell floor's grid)."""
    side = ax.size
    if xp is not np:  # a device's library: one whole-array test (cupy repeats by a list)
        return xp.flatnonzero(xp.hypot(ax[None, :], ax[:, None]).ravel() <= radius)
    reach = _row_reach(ax, radius, xp)
    counts = xp.where(reach >= 0, 2 * reach + 1, 0)
    starts = xp.arange(side, dtype=xp.int64) * side + side // 2 - reach
    ends = xp.cumsum(counts)
    total = int(ends[-1]) if side else 0
    within = xp.arange(total, dtype=xp.int64) - xp.repeat(ends - counts, counts)
    return xp.repeat(starts, counts) + within


def _row_reach(ax, radius: float, xp=np):
    """For each row of the square of centres ``ax`` x ``ax``: the largest j (-1 for none)
    with the cell (row, centre + j) within ``radius`` of the origin, by the same
    ``hypot(x, y) <= radius`` test as a cell-by-cell check (the square root's estimate
    corrected by one cell either way)."""
    half = ax.size // 2
    y = ax
    L = float(ax[half + 1] - ax[half]) if ax.size > 1 else 1.0
    j = xp.floor(xp.sqrt(xp.maximum(radius * radius - y * y, 0.0)) / L).astype(xp.int64)
    j = xp.minimum(j, half)
    for _ in range(2):
        up = xp.minimum(j + 1, half)
        j = xp.where((up > j) & (xp.hypot(ax[half + up], y) <= radius), up, j)
        down = xp.hypot(ax[half + xp.maximum(j, 0)], y) > radius
        j = xp.where(down & (j >= 0), j - 1, j)
    return xp.where(xp.abs(y) <= radius, j, -1)
