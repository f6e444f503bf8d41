"""The FFT model's circulant preconditioner: the same answers as the Jacobi
preconditioner within the solver's tolerance, a valid (SPD) preconditioner on every free set,
iterations that grow slowly with the grid, and convergence over the stiffness contrasts."""

from __future__ import annotations

import numpy as np
import pytest

from pillar_xval.scenes import load_scene

from bem_solver._fft import solve_fft
from bem_solver._fft_grid import build_grid
from bem_solver._fft_operator import (CirculantPreconditioner, CompliancePlan,
                                      near_field_correction, smooth_length)

RIGID = ["pillars.rigid=true", "substrate.rigid=true", "substrate.nu=0.5"]
TOL = 1e-8
# Both runs stop at a max-norm gap residual of TOL * zeta.  F_T then carries errors of that
# order times the conditioning of the contact problem: the measured differences between the
# two preconditioners are 2e-11 to 5e-9 (F_T) and up to 8e-6 (sigma_0 on pillars 1000 times
# softer than the lens, where a cell's gap error of 1e-8 zeta is a large share of its
# pressure); tests/test_bem_fft.py bounds the same solver errors by RTOL_SOLVER.
RTOL_SOLVER = 1e-6
RTOL_CENTRE_SOFT = 1e-4


def _plan(scene, n, edge_correction=True, precision="mixed"):
    grid = build_grid(scene, n)
    correction = near_field_correction(grid, scene.half_space_compliance) \
        if edge_correction else None
    spring = 0.0 if grid.flat else scene.pillar_spring_compliance
    plan = CompliancePlan(grid.shape, grid.flat_index, grid.cell_size,
                          scene.half_space_compliance, pillar=grid.pillar,
                          spring_compliance=spring, correction=correction,
                          precision=precision)
    return grid, plan


def test_smooth_length_is_scipys_real_fast_length():
    import scipy.fft

    assert all(smooth_length(n) == scipy.fft.next_fast_len(n, real=True)
               for n in range(1, 3000))


@pytest.mark.parametrize("precision", ["double", "mixed"])
@pytest.mark.parametrize("overrides", [[], ["pillars.E_Pa=1.6e3"], RIGID])
def test_preconditioner_is_symmetric_positive_definite_on_the_free_set(overrides, precision):
    """M^-1 as a matrix (applied to unit vectors) on a random free set: symmetric, positive
    definite there, zero outside it; with and without the pillar springs' coarse space.  In
    float64 symmetric to round-off; with its transforms in float32 (mixed precision) to the
    float32 convolution's stated error (the CG's iterations are those of the float64
    preconditioner or within one: tests/test_bem_fft.py)."""
    scene = load_scene("paper-fig3-sparse", overrides)
    grid, plan = _plan(scene, 6, precision=precision)
    pre = CirculantPreconditioner(plan)
    symmetric = 1e-10 if precision == "double" else plan.approximate_error
    n = grid.n_cells
    free = np.random.default_rng(1).random(n) < 0.7
    columns = np.column_stack([pre(np.eye(n)[k], free) for k in range(n)])
    assert np.all(columns[~free, :] == 0.0) and np.all(columns[:, ~free] == 0.0)
    sub = columns[np.ix_(free, free)]
    np.testing.assert_allclose(sub, sub.T, rtol=0, atol=symmetric * np.abs(sub).max())
    assert np.linalg.eigvalsh(0.5 * (sub + sub.T)).min() > 0.0


@pytest.mark.parametrize("name, overrides, n, edge", [
    ("paper-fig3-dense", RIGID, 16, False),
    ("paper-fig3-dense", [], 16, True),
    ("paper-fig3-sparse", ["pillars.E_Pa=1.6e3"], 16, True),
    ("paper-fig3-sparse", ["pillars.E_Pa=1.6e12"], 16, True),
    ("hertz", [], 16, True),
])
def test_circulant_gives_the_jacobi_answer_within_the_tolerance(name, overrides, n, edge):
    scene = load_scene(name, overrides)
    old = solve_fft(scene, n, edge_correction=edge, preconditioner="jacobi", tol=TOL)
    new = solve_fft(scene, n, edge_correction=edge, tol=TOL)
    assert old.converged and new.converged
    assert new.diagnostics["contact_residual"] <= TOL
    assert new.total_force_N == pytest.approx(old.total_force_N, rel=RTOL_SOLVER)
    centre = RTOL_CENTRE_SOFT if "pillars.E_Pa=1.6e3" in overrides else RTOL_SOLVER
    assert new.centre_pressure_Pa == pytest.approx(old.centre_pressure_Pa, rel=centre)
    assert new.contact_radius_m == pytest.approx(old.contact_radius_m, rel=RTOL_SOLVER)
    # Fewer iterations, except on pillars 1000 times softer than the lens at this small
    # grid, where the spring's Sherman-Morrison term already did well (measured 22 vs 20).
    assert new.iterations <= 1.2 * old.iterations


def test_iterations_grow_slowly_with_the_grid():
    """Rigid pillars on the dense scene from a cold start over N = 8, 16, 24: the circulant
    preconditioner's iterations grow by at most 2x over the ladder (measured 18, 28, 28) and
    stay under 40 % of Jacobi's at the finest level (measured 104)."""
    scene = load_scene("paper-fig3-dense", RIGID)
    counts = [solve_fft(scene, n, warm_start=False, edge_correction=False).iterations
              for n in (8, 16, 24)]
    jacobi = solve_fft(scene, 24, warm_start=False, edge_correction=False,
                       preconditioner="jacobi").iterations
    assert counts[-1] <= 2 * counts[0]
    assert max(counts) <= 2 * min(counts)
    assert counts[-1] <= 0.4 * jacobi


def test_nested_warm_start_keeps_the_fine_iterations_flat():
    """With the nested warm start the finest level's iterations hardly move from N = 16 to 32
    (rigid pillars, the benchmark's problem; measured 21 and 26)."""
    scene = load_scene("paper-fig3-dense", RIGID)
    fine = [solve_fft(scene, n, edge_correction=False).iterations for n in (16, 32)]
    assert fine[1] <= 1.5 * fine[0] + 5


@pytest.mark.parametrize("ratio", [1e-3, 1e-1, 1.0, 1e2, 1e4, 1e6])
def test_converges_over_the_stiffness_contrasts(ratio):
    """E_p / E_l from 1e-3 to 1e6: converged to the tolerance in a number of iterations that
    does not grow with the contrast (the spring's uniform mode lives in the coarse space)."""
    scene = load_scene("paper-fig3-sparse", [f"pillars.E_Pa={1.6e6 * ratio:g}"])
    res = solve_fft(scene, 16, warm_start=False)
    assert res.converged and res.diagnostics["contact_residual"] <= TOL
    assert res.iterations <= 40
