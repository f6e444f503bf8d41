"""The FFT model's candidate cells against a cell-by-cell construction: every cell of the
candidate square tested against every pillar top by the closed-form area, and the disk by
its distance (a slow, independent count of what bem_solver._fft_grid builds pillar window
by pillar window and row by row)."""

import math
import types

import numpy as np
import pytest

from bem_solver._disk import disk_rectangle_area
from bem_solver._fft_grid import MIN_COVERED_FRACTION, _row_reach, build_grid
from pillar_xval.scenes import load_scene
from pillar_xval.scenes.lattice import pillars_within


def _brute(scene, grid):
    """Per cell of the candidate square: the tops' summed fraction and the largest one's
    pillar (x, y), the cells within the candidate radius only."""
    L, rad = grid.cell_size, 0.5 * scene.pillars.diameter_m
    half = int(math.ceil(grid.candidate_radius / L)) + 1
    ax = (np.arange(2 * half + 1) - half) * L
    x, y = np.meshgrid(ax, ax)
    x, y = x.ravel(), y.ravel()
    inside = np.hypot(x, y) <= grid.candidate_radius
    x, y = x[inside], y[inside]
    table = pillars_within(grid.candidate_radius + rad, scene.pillars.pitch_m)
    fracs = np.stack([disk_rectangle_area(x - px - L / 2, x - px + L / 2, y - py - L / 2,
                                          y - py + L / 2, rad) / (L * L)
                      for _, _, px, py in table])
    total = fracs.sum(axis=0)
    owner = table[np.argmax(fracs, axis=0), 2:4]
    return x, y, total, owner


@pytest.mark.parametrize(("name", "overrides", "n"), [
    ("paper-fig3-sparse", [], 9),
    ("paper-fig3-dense", [], 8),
    # close packing: rim cells shared by two tops
    ("paper-fig3-dense", ["pillars.surface_fraction=0.9"], 7),
])
@pytest.mark.parametrize("dense", [False, True])
def test_the_cells_are_those_a_cell_by_cell_count_finds(name, overrides, n, dense):
    """The kept cells are exactly those within the disk whose tops' fraction exceeds the
    sliver limit; each is owned by the pillar of its largest share; the covered fractions
    are the summed shares (clipped at 1) where no sliver was dropped, and every pillar keeps
    the area its cells hold, slivers included (1e-12: the closed form's rounding)."""
    scene = load_scene(name, overrides)
    grid = build_grid(scene, n, dense=dense)
    x, y, total, owner = _brute(scene, grid)
    kept = total > MIN_COVERED_FRACTION
    L = grid.cell_size
    ours = {(round(a / L), round(b / L)): i for i, (a, b) in enumerate(zip(grid.x, grid.y))}
    theirs = {(round(a / L), round(b / L)): i for i, (a, b) in
              enumerate(zip(x[kept], y[kept]))}
    assert ours.keys() == theirs.keys()
    order = np.array([theirs[k] for k in ours])
    np.testing.assert_allclose(grid.pillar_xy[grid.pillar], owner[kept][order], rtol=0,
                               atol=1e-9 * L)
    # the area of each pillar: what its cells hold in the cell-by-cell count
    held = {}
    for (px, py), t in zip(map(tuple, owner[total > 0]), np.minimum(total[total > 0], 1.0)):
        held[(round(px / L, 6), round(py / L, 6))] = held.get((round(px / L, 6),
                                                               round(py / L, 6)), 0.0) + t
    ours_area = np.bincount(grid.pillar, weights=grid.covered)
    for k, (px, py) in enumerate(grid.pillar_xy):
        assert ours_area[k] == pytest.approx(held[(round(px / L, 6), round(py / L, 6))],
                                             rel=1e-12)
    whole = np.isclose(np.minimum(total[kept], 1.0)[order], grid.covered, rtol=1e-12)
    assert whole.mean() > 0.9  # most cells: no sliver dropped on their pillar


FLOOR = ["lens.radius_mm=0.25", "pillars.height_um=1.0", "substrate.E_Pa=1600000.0",
         "substrate.nu=0.5"]


@pytest.mark.parametrize(("name", "overrides", "n"), [
    ("paper-fig3-dense", [], 16),
    ("paper-fig3-sparse", [], 12),
    ("paper-fig3-dense", ["pillars.surface_fraction=0.9"], 9),  # two tops share rim cells
    # the coarsest grid at close packing: a cell reaches farthest from its four sites
    ("paper-fig3-dense", ["pillars.surface_fraction=0.9"], 2),
    ("paper-fig3-sparse", FLOOR + ["pillars.surface_fraction=0.2",
                                   "load.indentation_um=3.5"], 8),  # floor cells
    ("paper-fig3-sparse", FLOOR + ["pillars.surface_fraction=0.4",
                                   "load.indentation_um=7"], 6),
])
def test_the_dense_construction_builds_the_windows_grid_bit_for_bit(name, overrides, n):
    """All tops at once (each cell's four nearest lattice sites, the device's way) against
    pillar window by pillar window (the host's): the same expressions per (cell, pillar)
    pair, so every field of the grid is equal, not close.  The one exception: a cell on
    three tops (two cells across a top at close packing) sums its shares in another order,
    so its covered fraction may differ in the last bits (2 ulp: two additions)."""
    scene = load_scene(name, overrides)
    windows, dense = build_grid(scene, n, dense=False), build_grid(scene, n, dense=True)
    assert dense.has_floor == windows.has_floor == ("load.indentation_um=3.5" in overrides
                                                   or "load.indentation_um=7" in overrides)
    for field in vars(windows):
        a, b = getattr(windows, field), getattr(dense, field)
        if field == "covered" and n == 2:
            np.testing.assert_allclose(a, b, rtol=2 * np.finfo(float).eps, atol=0)
        elif isinstance(a, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=field)
        else:
            assert a == b, field


@pytest.mark.parametrize("radius_cells", [0.0, 0.5, 3.0, 7.49, 7.5, 12.0, 40.0])
def test_row_reach_is_the_distance_test(radius_cells):
    """The last column within the radius on each row, against hypot on every cell."""
    L = 1.7e-7
    ax = (np.arange(2 * 20 + 1) - 20) * L
    r = radius_cells * L
    reach = _row_reach(ax, r)
    inside = np.hypot(ax[None, :], ax[:, None]) <= r
    for row in range(ax.size):
        cols = np.flatnonzero(inside[row]) - 20
        assert reach[row] == (cols.max() if cols.size else -1)
        if cols.size:
            assert cols.min() == -cols.max()


class _Device(types.ModuleType):
    """numpy under another name: build_grid takes the path it takes on a GPU's library."""

    asnumpy = staticmethod(np.asarray)

    def __getattr__(self, name):
        return getattr(np, name)


@pytest.mark.parametrize(("name", "overrides", "n"), [
    ("paper-fig3-dense", ["pillars.surface_fraction=0.9"], 9),
    ("paper-fig3-sparse", ["load.indentation_um=6"], 8),  # the floor between pillars
    ("hertz", [], 12),
])
def test_the_device_path_builds_the_same_grid(name, overrides, n):
    """The steps a GPU's array library takes (the disk cleared by one mask, the slivers'
    shares without numpy's ``where=``, the grid brought back to the host) give the host's
    grid exactly."""
    scene = load_scene(name, overrides)
    host = build_grid(scene, n)
    device = build_grid(scene, n, xp=_Device("device"))
    for field in ("flat_index", "x", "y", "covered", "gap0", "pillar", "colloc_x", "colloc_y",
                  "floor", "pillar_nm", "pillar_xy"):
        a, b = getattr(host, field), getattr(device, field)
        assert isinstance(b, np.ndarray) and b.dtype == a.dtype, field
        np.testing.assert_array_equal(b, a, err_msg=field)
    assert (device.shape, device.centre_cell, device.n_unique) == \
        (host.shape, host.centre_cell, host.n_unique)


class _OtherLibrary:
    """numpy under another name: what build_grid sees when a device library builds it."""

    def __getattr__(self, name):
        return getattr(np, name)


@pytest.mark.parametrize(("name", "overrides", "n"), [
    ("paper-fig3-dense", [], 12),
    ("paper-fig3-sparse", FLOOR + ["pillars.surface_fraction=0.2", "pillars.E_Pa=160000",
                                   "load.indentation_um=3.5"], 8),
])
def test_a_device_built_grid_carries_the_contact_radii_the_result_computes(name, overrides, n):
    """The outer radii a device builds with the grid (one pass over all cells) give the
    result's contact radius and floor contact radius exactly as the host's computation over
    the cells in contact (the same expressions, here in the same library)."""
    from bem_solver._fft import solve_fft

    scene = load_scene(name, overrides)
    on_device = build_grid(scene, n, xp=_OtherLibrary())
    assert on_device.reach is not None and build_grid(scene, n).reach is None
    res = solve_fft(scene, n)
    contact = res.fields["pressure_Pa"] > 0.0
    top = ~on_device.floor
    assert res.contact_radius_m == np.max(on_device.reach, where=contact, initial=0.0)
    assert res.floor_contact_radius_m == np.max(on_device.reach, where=contact & ~top,
                                                initial=0.0)
    if on_device.has_floor:
        assert res.floor_contact_radius_m > 0.0
