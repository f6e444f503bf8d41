"""The shared contact solvers: one convention (gap = A p + b), one residual, exact answers.

Both solvers are checked against brute-force enumeration of every active set of small SPD
problems: an SPD linear complementarity problem has exactly one solution, so agreement to
round-off (dense, exact) or to the stopping tolerance (constrained CG) proves them right.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from pillar_xval.contact import (constrained_cg, diagonal_preconditioner, evaluate, min_map_residual,
                     solve_active_set)

RTOL_ROUNDOFF = 1e-10  # exact active-set solutions: round-off only


def _enumerate(A, b):
    """The unique solution of the SPD LCP by trying all 2^n active sets."""
    n = len(b)
    found = []
    for active in itertools.product([False, True], repeat=n):
        act = np.array(active)
        p = np.zeros(n)
        if act.any():
            p[act] = np.linalg.solve(A[np.ix_(act, act)], -b[act])
        gap = A @ p + b
        if np.all(p >= -1e-12) and np.all(gap[~act] >= -1e-12):
            found.append(p)
    assert len(found) >= 1
    return found[0]


def _problems(count, n=6, seed=20261123):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        G = rng.standard_normal((n, n))
        yield G @ G.T + 0.1 * np.eye(n), rng.standard_normal(n)


def test_dense_solver_matches_enumeration():
    for A, b in _problems(20):
        sol = solve_active_set(A, b, scale=1.0)
        assert sol.converged, sol.message
        np.testing.assert_allclose(sol.pressure, _enumerate(A, b), atol=RTOL_ROUNDOFF)
        assert sol.residual < RTOL_ROUNDOFF
        assert sol.pressure.min() >= 0.0


def test_constrained_cg_matches_enumeration():
    for A, b in _problems(20):
        # tol 1e-10: round-off of the recursively updated gap of these O(1), cond ~ 1e3
        # matrices stalls near 5e-12.
        sol = constrained_cg(lambda p, A=A: A @ p, b, np.zeros(len(b)), scale=1.0, tol=1e-10,
                             max_iterations=500,
                             precondition=diagonal_preconditioner(np.diag(A)),
                             inverse_diagonal=1.0 / np.diag(A))
        assert sol.converged, sol.message
        np.testing.assert_allclose(sol.pressure, _enumerate(A, b), atol=1e-7)
        assert sol.history[-1] == sol.residual <= 1e-10


def test_directions_cut_at_the_bound_reach_the_same_solution():
    """``cut_outward``: directions with their components zeroed where a zero pressure would be
    taken below zero.  The answers are still the enumeration's to the tolerance, from a zero
    and from a wrong warm start, with the Jacobi preconditioner and with A's own inverse on
    the free set (coupled, as the FFT model's circulant one: there the cut changes the path
    on a third of the runs); the cut itself on a small example."""
    from pillar_xval.contact._cg import _cut_outward

    def inverse_on_free(A):
        def apply(r, free):
            z = np.zeros_like(r)
            if free.any():
                z[free] = np.linalg.solve(A[np.ix_(free, free)], r[free])
            return z
        return apply

    rng = np.random.default_rng(1)
    changed = 0
    for A, b in _problems(20, n=8):
        warm = rng.uniform(0.0, 1.0, len(b)) * (rng.random(len(b)) < 0.5)
        for q0 in (np.zeros(len(b)), warm):
            for precondition in (diagonal_preconditioner(np.diag(A)), inverse_on_free(A)):
                runs = [constrained_cg(lambda p, A=A: A @ p, b, q0, scale=1.0, tol=1e-10,
                                       max_iterations=500, precondition=precondition,
                                       cut_outward=cut) for cut in (False, True)]
                for sol in runs:
                    assert sol.converged, sol.message
                    np.testing.assert_allclose(sol.pressure, _enumerate(A, b), atol=1e-7)
                changed += runs[0].history != runs[1].history
    assert changed >= 20  # of 80 runs

    def dot(a, c):
        return float(a @ c)

    q, gap = np.array([0.0, 1.0, 0.0]), np.array([-1.0, 2.0, -1.0])
    t = np.array([2.0, 1.0, -1.0])  # its first component would take q[0] below zero
    cut, slope = _cut_outward(np, dot, t, dot(gap, t), q, gap)
    np.testing.assert_array_equal(cut, [0.0, 1.0, -1.0])
    assert slope == dot(gap, cut) == 3.0 > dot(gap, t)  # the cut raised the slope
    t = np.array([-2.0, 1.0, -1.0])  # nothing to cut: the same direction
    kept, slope = _cut_outward(np, dot, t, 5.0, q, gap)
    assert kept is t and slope == 5.0


class _Perturbed:
    """A @ p exactly, and an ``approximate`` application off by a relative ``error`` of its
    largest value (a fixed random pattern, as rounding leaves), that counts its calls."""

    def __init__(self, A, error, seed=3):
        self.A, self.approximate_error = A, error
        self.noise = np.random.default_rng(seed).uniform(-1.0, 1.0, len(A))
        self.exact = self.approx = 0

    def __call__(self, p):
        self.exact += 1
        return self.A @ p

    def approximate(self, p):
        self.approx += 1
        u = self.A @ p
        return u + self.approximate_error * np.max(np.abs(u)) * self.noise


@pytest.mark.parametrize("error", [1e-7, 1e-4, 1e-2])
def test_mixed_precision_steps_still_meet_the_tolerance_in_the_exact_gap(error):
    """With steps from an approximate operator the CG recomputes the gap exactly when the
    carried error could matter and before accepting: the returned gap is A p + b and its
    residual is within tol, the answer the enumeration's to the tolerance, for step errors
    from float32's scale up to 1e-2 (which needs more exact refreshes, never a wrong
    answer)."""
    for A, b in _problems(10, n=8, seed=11):
        op = _Perturbed(A, error)
        sol = constrained_cg(op, b, np.zeros(len(b)), scale=1.0, tol=1e-10, max_iterations=500,
                             inverse_diagonal=1.0 / np.diag(A))
        assert sol.converged, sol.message
        np.testing.assert_allclose(sol.gap, A @ sol.pressure + b, rtol=0, atol=1e-13)
        assert min_map_residual(sol.pressure, A @ sol.pressure + b) <= 1e-10
        np.testing.assert_allclose(sol.pressure, _enumerate(A, b), atol=1e-7)
        assert op.approx >= sol.iterations and op.exact >= 2  # the first gap and the check


def test_monotone_mode_lowers_the_energy_at_every_step(monkeypatch):
    """The constrained CG's monotone mode (contact._cg: once the residual stalls), forced on
    from the first iteration.  The iterate after k iterations (a run stopped at
    max_iterations = k, the path being deterministic) has an energy 1/2 p.A p + b.p that
    never rises with k beyond round-off; some truncated steps had to be shortened for that;
    the answer is still the enumeration's, also with approximate (1e-4) step applications."""
    import pillar_xval.contact._cg as cg

    monkeypatch.setattr(cg, "STALL_ITERATIONS", 0)
    halvings = 0
    for A, b in _problems(10, n=8, seed=5):
        def energy(p, A=A, b=b):
            return 0.5 * p @ (A @ p) + b @ p

        def solve(k, op=None, A=A, b=b):
            return constrained_cg(op or (lambda p: A @ p), b, np.zeros(len(b)), scale=1.0,
                                  tol=1e-10, max_iterations=k,
                                  inverse_diagonal=1.0 / np.diag(A))

        full = solve(500)
        assert full.converged, full.message
        np.testing.assert_allclose(full.pressure, _enumerate(A, b), atol=1e-7)
        path = [energy(solve(k).pressure) for k in range(1, full.iterations + 1)]
        assert np.all(np.diff(path) <= 1e-12 * np.abs(path[:-1]).max())
        halvings += full.halvings
        mixed = solve(500, _Perturbed(A, 1e-4))
        assert mixed.converged, mixed.message
        np.testing.assert_allclose(mixed.pressure, _enumerate(A, b), atol=1e-7)
    assert halvings > 0  # these problems have steps whose truncation would raise the energy


def test_min_map_residual_definition():
    p = np.array([1.0, 0.0, 0.0, 2.0])
    gap = np.array([0.1, 0.5, -0.3, -0.05])
    # |gap| on the contact set (0.1, 0.05), interpenetration off it (0.3).
    assert min_map_residual(p, gap) == pytest.approx(0.3)
    # Weights turn weighted gaps into gaps: 0.3 / 3.
    assert min_map_residual(p, gap, weights=np.array([1.0, 1.0, 3.0, 1.0])) == pytest.approx(0.1)
    assert min_map_residual(np.zeros(0), np.zeros(0)) == 0.0


def test_residual_is_relative_to_the_scale():
    A, b = next(_problems(1))
    sol = solve_active_set(A, b, scale=1.0)
    wrong = sol.pressure * 1.01
    got = evaluate(A, b, wrong, scale=1e-3)
    assert got.residual == pytest.approx(min_map_residual(wrong, A @ wrong + b) / 1e-3)
    assert not got.converged and "tolerance" in got.message


def test_non_convergence_is_reported_not_raised():
    A, b = next(_problems(1, n=40, seed=7))
    sol = constrained_cg(lambda p: A @ p, b, np.zeros(len(b)), scale=1.0, tol=1e-14,
                         max_iterations=2)
    assert not sol.converged and "no convergence" in sol.message
    assert sol.iterations == 2 and len(sol.history) == 3


def _labels(kind, n, rng):
    """Labels below n: in runs of at least RUNS_PAY (a grid's pillar cells), scattered, or
    none."""
    from pillar_xval.contact._xp import RUNS_PAY

    if kind == "runs":
        return np.repeat(rng.integers(0, n, 300), rng.integers(RUNS_PAY, 30, 300))
    if kind == "scattered":
        return rng.integers(0, n, 5000)
    return np.zeros(0, dtype=np.int64)


@pytest.mark.parametrize("kind", ["runs", "scattered", "empty"])
def test_spreader_is_the_gather(kind):
    """The backend's reusable spread of per-label values to their entries: exactly
    ``values[index]`` (a copy, so bit for bit) whether the labels come in runs (repeated per
    run) or scattered (gathered), and ``values[index[lo:hi]]`` for a range of entries."""
    from pillar_xval.contact._xp import NUMPY

    rng = np.random.default_rng(8)
    n = 40
    index = _labels(kind, n, rng)
    values = rng.standard_normal(n)
    spread = NUMPY.spreader(index)
    got = spread(values)
    assert got.shape == index.shape
    assert np.array_equal(got, values[index])
    # a chunk's entries: ranges that cut runs, hold one run's middle, or nothing
    bounds = [0, 1, 3, index.size // 3, index.size // 2, index.size - 1, index.size]
    for lo in bounds:
        for hi in bounds:
            part = spread(values, lo, hi)
            assert part.shape == index[lo:hi].shape
            assert np.array_equal(part, values[index[lo:hi]])


@pytest.mark.parametrize("kind", ["runs", "scattered", "empty"])
def test_segments_sum_like_bincount(kind):
    """The backend's reusable segment sums: the same sums as a bincount per label (to
    round-off: runs are summed first) whether the labels come in runs (a grid's pillar cells)
    or scattered, and zeros for no cells at all."""
    from pillar_xval.contact._xp import NUMPY

    rng = np.random.default_rng(7)
    n = 40
    index = _labels(kind, n, rng)
    weights = rng.standard_normal(index.size)
    expect = np.bincount(index, weights=weights, minlength=n)
    got = NUMPY.segments(index, n)(weights)
    assert got.shape == (n,)
    np.testing.assert_allclose(got, expect, rtol=1e-12, atol=1e-12 * np.abs(weights).sum())


@pytest.mark.parametrize("kind", ["runs", "scattered", "empty"])
def test_threaded_segments_give_the_one_piece_bits(kind, monkeypatch):
    """The FFT model's numpy backend sums the runs in chunks of runs on its threads: on 2,
    3 and 7 threads the same bits as the whole reduceat of :class:`NumpyArrays` (each run's
    sum over the same elements), and bincount's sums to round-off."""
    import bem_solver._xp as devices
    from pillar_xval.contact._xp import NUMPY

    monkeypatch.setattr(devices, "CHUNK_MIN", 1)  # chunks on these few labels too
    rng = np.random.default_rng(9)
    n = 40
    index = _labels(kind, n, rng)
    weights = rng.standard_normal(index.size)
    expect = NUMPY.segments(index, n)(weights)
    for workers in (2, 3, 7):
        assert np.array_equal(devices.NumpyDevice(workers).segments(index, n)(weights), expect)


def test_chunked_steps_are_the_plain_steps():
    """The CG's fused passes (in chunks, in kept arrays) against the plain expressions they
    replace, bit for bit, in one piece and in uneven pieces: the residual and the free set,
    the conjugate direction, the step and its minimum, the cells it drives negative, the
    clipping, the gap's update with its rounding scale, and the new contact set with its
    entries."""
    from pillar_xval.contact import _cg

    rng = np.random.default_rng(11)
    n = 1001
    gap, t, z, w, clip = (rng.standard_normal(n) for _ in range(5))
    q = np.maximum(rng.standard_normal(n), 0.0)
    active = q > 0.0
    weights = rng.random(n) + 0.5
    tau, beta = 0.37, 0.81

    def uneven(work, size):
        for lo, hi in ((0, 0), (0, 17), (17, 17), (17, 600), (600, size)):
            work(lo, hi)

    for chunks in (_cg.one_piece, uneven):
        for weight in (None, weights):
            free = np.zeros(n, dtype=bool)
            g = gap if weight is None else gap / weight
            plain = max(-float(g.min()), float((g * active).max()), 0.0)
            assert _cg._residual(np, gap, active, weight, n, chunks, free) == plain
            assert np.array_equal(free, active | (gap < 0.0))
        got = t.copy()
        chunks(_cg._conjugate(np, got, beta, z, free), n)
        assert np.array_equal(got, (t * beta + z) * free)
        step = np.empty(n)
        low = _cg._step(np, chunks, step, q, tau, t, n)
        assert np.array_equal(step, q - tau * t) and low == float((q - tau * t).min())
        negatives = _cg.ArrayPasses(np, chunks).negatives(step, n)
        assert negatives.size > 0 and np.array_equal(negatives, np.nonzero(step < 0.0)[0])
        clipped = step.copy()
        chunks(_cg._clip(np, clipped), n)
        assert np.array_equal(clipped, np.maximum(step, 0.0))
        for extra in (None, clip):
            g, ww = gap.copy(), w.copy()
            scale = _cg._update_gap(np, chunks, g, ww, tau, extra, n)
            expect = gap - w * tau + (0.0 if extra is None else extra)
            assert np.array_equal(g, expect) and np.array_equal(ww, w * tau)
            assert scale == _cg._max_abs(np, w * tau) + (
                0.0 if extra is None else _cg._max_abs(np, extra))
        new = np.zeros(n, dtype=bool)
        entered = _cg._new_set(np, chunks, new, clipped, active, n)
        assert np.array_equal(new, clipped > 0.0)
        assert entered == bool(np.any(new & ~active))
