"""The FFT model's working set: floor cells the coarse level finds clear of the lens are left
out of the fine solve, checked after it, and the whole grid solved when the check fails."""

from __future__ import annotations

import numpy as np
import pytest

from pillar_xval.scenes import load_scene

import bem_solver._fft as fft_model
import bem_solver._fft_working_set as working_set
from bem_solver._fft import _Options, _prepare, solve_fft
from bem_solver._fft_grid import _disk_cells
from bem_solver._fft_operator import kernel_block
from bem_solver._xp import NumpyDevice

# Rigid pillars (Phi = 0.03, h = 1 um) on a 0.3 mm lens at zeta = 3 h: the floor carries
# load, and at N = 16 (62,071 cells) the coarse level clears 24,404 floor cells.
MIXED = ["pillars.rigid=true", "substrate.E_Pa=1.6e6", "substrate.nu=0.5",
         "lens.radius_mm=0.3", "pillars.surface_fraction=0.03", "pillars.height_um=1",
         "load.indentation_um=3"]
N = 16
TOL = 1e-8
# Both solves stop at a min-map residual of TOL zeta from the same start; the answers then
# differ by the iterates' round-off (measured below 1e-12 in F_T and the floor's force on
# the benchmark's 1e6 cells, 3e-14 to 2e-13 here): bound at ten times the tolerance.
RTOL_SAME = 10 * TOL
# Round-off of one float64 convolution against a direct sum of its ~1e3 terms (measured
# 6.7e-16): bound at 1e-12, as the operator's other round-off tests.
RTOL_ROUNDOFF = 1e-12


@pytest.fixture(autouse=True)
def _small_grids(monkeypatch):
    # The working set pays from 1e5 cells; these grids are smaller, to keep the tests fast.
    monkeypatch.setattr(working_set, "MIN_GRID_CELLS", 0)


def test_small_grids_solve_whole(monkeypatch):
    monkeypatch.setattr(working_set, "MIN_GRID_CELLS", 10**9)
    result = solve_fft(load_scene("paper-fig3-sparse", MIXED), N, tol=TOL)
    assert result.converged and result.regime == "mixed"
    assert "left_out_floor_cells" not in result.diagnostics


def _solve_both(monkeypatch, **kw):
    scene = load_scene("paper-fig3-sparse", MIXED)
    left = solve_fft(scene, N, tol=TOL, **kw)
    with monkeypatch.context() as m:
        m.setattr(fft_model, "left_out_floor", lambda *a: None)
        whole = solve_fft(scene, N, tol=TOL, **kw)
    return scene, left, whole


def _same_answer(left, whole):
    assert left.converged and whole.converged
    for name in ("total_force_N", "floor_force_N", "floor_contact_area_m2",
                 "contact_radius_m", "floor_contact_radius_m", "centre_pressure_Pa"):
        assert getattr(left, name) == pytest.approx(getattr(whole, name), rel=RTOL_SAME), name
    a, b = left.fields, whole.fields
    assert a["pressure_Pa"].shape == b["pressure_Pa"].shape
    scale = float(np.max(b["pressure_Pa"]))
    assert np.max(np.abs(a["pressure_Pa"] - b["pressure_Pa"])) <= RTOL_SAME * scale
    assert np.array_equal(a["floor"], b["floor"]) and np.array_equal(a["x_m"], b["x_m"])


def test_left_out_floor_cells_change_the_work_not_the_answer(monkeypatch):
    scene, left, whole = _solve_both(monkeypatch)
    d = left.diagnostics
    assert d["left_out_accepted"] and "left_out_floor_cells" not in whole.diagnostics
    n = left.discretisation["cells"]
    assert 0.25 * n <= d["left_out_floor_cells"] < n
    _same_answer(left, whole)
    # The left-out cells' gaps are the exact ones: the whole solve's to round-off, all open.
    gap_a, gap_b = left.fields["gap_m"], whole.fields["gap_m"]
    assert np.max(np.abs(gap_a - gap_b)) <= RTOL_SAME * scene.indentation_m
    assert d["left_out_worst_interpenetration"] == 0.0


def test_the_check_reads_the_last_exact_application_in_mixed_precision(monkeypatch):
    # Mixed precision: the CG's last exact application is of the answer, and the check
    # takes the left-out cells' values from it (no convolution more than the whole solve's
    # at the fine level); in double precision it convolves once more.
    _, left, whole = _solve_both(monkeypatch)
    extra = left.diagnostics["operator_applications"] - whole.diagnostics["operator_applications"]
    assert extra <= 0
    _, left64, whole64 = _solve_both(monkeypatch, precision="double")
    _same_answer(left64, whole64)


def test_a_wrong_working_set_is_caught_and_the_whole_grid_solved(monkeypatch):
    # A negative clearance leaves out floor cells in contact: the check must see them
    # interpenetrate, and the whole grid's answer must follow.
    monkeypatch.setattr(working_set, "FLOOR_CLEARANCE", -1.0)
    scene, left, whole = _solve_both(monkeypatch)
    d = left.diagnostics
    assert not d["left_out_accepted"] and d["left_out_worst_interpenetration"] > TOL
    assert d["working_set_iterations"] > 0
    _same_answer(left, whole)


def test_half_space_at_any_cells_is_the_direct_sum():
    scene = load_scene("paper-fig3-sparse", MIXED)
    be = NumpyDevice()
    opts = _Options(TOL, None, be.workers, True, True, None, "circulant", "hooke", None,
                    "mixed", False)
    setup = _prepare(scene, 6, opts, be, None, 0.0)
    grid, plan = setup.grid, setup.plan
    rng = np.random.default_rng(3)
    q = rng.random(grid.n_cells)
    ny, nx = grid.shape
    cells = rng.choice(ny * nx, 200, replace=False)  # candidates or not
    table = kernel_block(grid.shape, grid.cell_size, scene.half_space_compliance)
    iy, ix = np.divmod(cells, nx)
    jy, jx = np.divmod(grid.flat_index, nx)
    direct = (table[np.abs(iy[:, None] - jy[None, :]), np.abs(ix[:, None] - jx[None, :])]
              * q[None, :]).sum(axis=1)
    fresh = plan.half_space_at(q, cells)
    assert fresh == pytest.approx(direct, rel=RTOL_ROUNDOFF)
    # Watched: an exact application of q keeps the same values, which half_space_at takes
    # without a convolution of its own; a different q gets its own.
    plan.watch_at(cells)
    plan(q)
    count = plan.applications
    assert np.array_equal(plan.half_space_at(q, cells), fresh)
    assert plan.applications == count
    other = q * 2.0
    assert plan.half_space_at(other, cells) == pytest.approx(2.0 * direct,
                                                             rel=RTOL_ROUNDOFF)
    assert plan.applications == count + 1


@pytest.mark.parametrize("side, radius", [(1, 0.5), (7, 0.2), (11, 3.0), (101, 24.99),
                                          (101, 30.0), (101, 50.0 * 2 ** 0.5), (100, 17.3)])
def test_disk_cells_are_the_cells_within_the_radius(side, radius):
    ax = (np.arange(side) - side // 2) * 0.5
    by_distance = np.flatnonzero(np.hypot(ax[None, :], ax[:, None]).ravel() <= radius * 0.5)
    assert np.array_equal(_disk_cells(ax, radius * 0.5), by_distance)


def test_the_working_set_on_the_strict_namespace_gives_the_numpy_answer():
    # The array-API stand-in (a device's path: no kept work arrays, generic gathers) takes
    # the same working set and check, to round-off of the numpy path with whole transforms.
    from test_bem_fft_devices import RTOL_ROUNDOFF as DEVICE_ROUNDOFF
    from test_bem_fft_devices import UNSPLIT, StrictDevice, _agree

    scene = load_scene("paper-fig3-sparse", MIXED)
    ref = solve_fft(scene, N, tol=TOL, backend=UNSPLIT)
    strict = solve_fft(scene, N, tol=TOL, backend=StrictDevice(numpy_primitives=True))
    assert ref.diagnostics["left_out_accepted"] and strict.diagnostics["left_out_accepted"]
    assert strict.diagnostics["left_out_floor_cells"] == ref.diagnostics["left_out_floor_cells"]
    _agree(ref, strict, DEVICE_ROUNDOFF, scene.indentation_m)
