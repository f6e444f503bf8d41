"""The elastic-pillar BEM's pillar-to-pillar coupling correction: the second moments of the
load each pillar passes to its substrate (PHYSICS.md, "The elastic-pillar BEM").

Checked against closed forms (the rigid punch's load distribution, its moments and the
quadrature of the Boussinesq field between two punches, with the multipole order fitted over
four distances), and each implementation (dense reduced, FFT) against the formula evaluated
independently here.
"""

import math

import numpy as np
import pytest

from bem_solver import expansion, full_operator
from bem_solver._discretise import discretise
from bem_solver._elastic_pillar import (FFTPillarTerm, coupling_block, coupling_kernel,
                                        coupling_moments)
from bem_solver._fft_grid import build_grid
from bem_solver._fft_operator import near_field_correction
from bem_solver._operator import reduced_operator
from fem_reference import PillarKind, modal_compliance
from pillar_xval.scenes import load_scene

COARSE = {"mesh_size": 4.0}


pytestmark = pytest.mark.usefixtures("compliance_cache")


class _Punch:
    """A stand-in compliance whose pillars pass their load on as a rigid punch: R_0 = 2/3,
    R_2 = 0 (closed form), on a P2 trace of 21 points."""

    def __init__(self):
        self.r_top = np.linspace(0.0, 1.0, 21)
        self.base_moments = np.array([np.full(21, 2.0 / 3.0), np.zeros(21)])

    def trace_basis(self, r):
        from fem_reference._pillar_compliance import ModalCompliance
        return ModalCompliance.trace_basis(self, r)


def _scene(phi=0.2, zeta_um=0.1, E_p=1.6e7):
    return load_scene("paper-fig3-sparse", [f"pillars.surface_fraction={phi}",
                                            f"load.indentation_um={zeta_um}",
                                            f"pillars.E_Pa={E_p}"])


def test_a_rigid_pillar_passes_its_load_on_as_a_rigid_punch(aspect=0.5):
    """A rigid pillar bonded to a half-space is a rigid flat punch whatever its height: the
    base pressure F / (2 pi a sqrt(a^2 - rho^2)) (1 + 3 x.y / a^2) for a load F at x, whose
    second moments are R_0 = 2/3 and R_2 = 0 (units of a^2) for every x.  The P2 nodal
    forces meet the edge's inverse square root, so R_0 converges with the mesh: measured
    1.0 % off at mesh_size 4 and 0.08 % at 2; asserted within 1.5 % at 4 and at least 4x
    closer at 2 (an order above 2 in the element size)."""
    errors = []
    for mesh_size in (4.0, 2.0):
        m = modal_compliance(PillarKind(aspect, math.inf, 0.5, 0.5), 2, mesh_size=mesh_size)
        R0, R2 = m.base_moments
        assert np.ptp(R0) < 1e-6 * R0.max()      # the same for every top point
        # A rigid pillar is modelled as E_p = 1e6 E_s (RIGID_CONTRAST): R_2 ~ 1e-6 r^2.
        np.testing.assert_allclose(R2, 0.0, atol=1e-5)
        errors.append(abs(R0.mean() / (2.0 / 3.0) - 1.0))
    assert errors[0] < 1.5e-2
    assert errors[1] < errors[0] / 4.0


def test_a_long_pillar_forgets_the_angular_shape_of_its_load():
    """Saint-Venant: the mode-2 part of the load dies out along a pillar (h/d = 4: e^-8 or
    less), so R_2 vanishes; the mode-0 moment lies between a uniform base pressure (1/2) and
    the rigid punch's (2/3), the same at every top point.  A short pillar (h/d = 0.25) of the
    substrate's material passes on a good share of the shape (R_2 > 0.2 r^2 at the rim)."""
    m = modal_compliance(PillarKind(4.0, 1.0, 0.5, 0.5), 2, **COARSE)
    R0, R2 = m.base_moments
    assert np.abs(R2).max() < 1e-3
    assert 0.5 < R0.min() and R0.max() < 2.0 / 3.0
    assert np.ptp(R0) < 1e-3
    short = modal_compliance(PillarKind(0.25, 1.0, 0.5, 0.5), 2, **COARSE)
    assert short.base_moments[1][-1] > 0.2 * short.r_top[-1] ** 2


def _punch_pair(D, x, xp, n_u=28, n_phi=56):
    """The exact coupling of two rigid punches of radius 1 at distance D (centres (0, 0) and
    (D, 0)) loaded by unit forces at x and x' (relative to their centres): the mean of
    1/|y - z| over both base pressures, by Gauss quadrature in rho = sin u (which removes the
    edge's inverse square root) and the trapezoid rule in the angle."""
    u, wu = np.polynomial.legendre.leggauss(n_u)
    u = 0.25 * math.pi * (u + 1.0)
    wu = 0.25 * math.pi * wu
    ph = np.linspace(0.0, 2.0 * math.pi, n_phi, endpoint=False)
    rho = np.sin(u)[:, None] * np.ones(n_phi)
    px, py = (rho * np.cos(ph)).ravel(), (rho * np.sin(ph)).ravel()
    # p dA = sin u du dphi / (2 pi) (1 + 3 x.y): unit force, moment x.
    base = (np.sin(u) * wu)[:, None] * np.full(n_phi, 1.0 / n_phi)
    w1 = base.ravel() * (1.0 + 3.0 * (x[0] * px + x[1] * py))
    w2 = base.ravel() * (1.0 + 3.0 * (xp[0] * px + xp[1] * py))
    dist = np.hypot(px[:, None] - (D + px[None, :]), py[:, None] - py[None, :])
    return float(w1 @ (1.0 / dist) @ w2)


def test_the_correction_is_the_next_multipole_of_two_punches():
    """Two rigid punches: the column model's coupling 1/|D + x - x'| misses the exact one by
    O(D^-3); with the correction the miss falls to O(D^-5) for centred loads (their third
    moments vanish) and to O(D^-4) for off-centre ones.  Orders fitted over D = 4, 6, 8, 12,
    16 radii (the off-centre miss has a strong D^-4 part: its fitted order is 3.2-3.5).  At
    D = 4 radii (a close neighbour at Phi = 0.2) the correction removes 92 % of the centred
    miss and 66 % of the off-centre one (asserted: 80 % and 50 %)."""
    scene = _scene()
    a = 0.5 * scene.pillars.diameter_m
    punch = _Punch()
    scale = scene.substrate.compliance / math.pi
    Ds = np.array([4.0, 6.0, 8.0, 12.0, 16.0])
    for x, xp, corrected_order, removed in (((0.0, 0.0), (0.0, 0.0), 5.0, 0.8),
                                            ((0.5, 0.3), (-0.2, 0.6), 4.0, 0.5)):
        miss, fixed = [], []
        for D in Ds:
            exact = _punch_pair(D, x, xp)
            column = 1.0 / math.hypot(D + xp[0] - x[0], xp[1] - x[1])
            m = coupling_moments(scene, punch, a * np.array([x[0], xp[0]]),
                                 a * np.array([x[1], xp[1]]))
            h = coupling_kernel(scene, a * np.array([[0.0, 0.0], [D, 0.0]]))
            dK = (m[0] + m[1]) @ h[:, 0, 1] / scale * a   # in units of 1/a
            miss.append(abs(exact - column))
            fixed.append(abs(exact - column - dK))
        order_miss = -np.polyfit(np.log(Ds), np.log(miss), 1)[0]
        order_fixed = -np.polyfit(np.log(Ds), np.log(fixed), 1)[0]
        assert 2.8 < order_miss < 3.6
        assert order_fixed > corrected_order - 0.3
        assert fixed[0] < (1.0 - removed) * miss[0]


def _formula(scene, m, gx, gy, pillar, centres):
    """ΔK between every two points (global positions relative to their pillar's centre gx, gy;
    pillar indices; centres), written out with 2 x 2 tensors (independent of the code's
    three-component form)."""
    a = 0.5 * scene.pillars.diameter_m
    r, th = np.hypot(gx, gy) / a, np.arctan2(gy, gx)
    phi = m.trace_basis(r)
    R0, R2 = phi @ m.base_moments[0], phi @ m.base_moments[1]
    c, s = np.cos(2 * th), np.sin(2 * th)
    reflect = np.stack([np.stack([c, s], -1), np.stack([s, -c], -1)], -2)   # (n, 2, 2)
    x = np.stack([gx, gy], -1)
    M = 0.5 * a * a * (R0[:, None, None] * np.eye(2) + R2[:, None, None] * reflect) \
        - x[:, :, None] * x[:, None, :]
    Dv = centres[pillar][:, None, :] - centres[pillar][None, :, :]          # (n, n, 2)
    D = np.linalg.norm(Dv, axis=-1)
    same = pillar[:, None] == pillar[None, :]
    D = np.where(same, 1.0, D)
    e = Dv / D[..., None]
    H = (3.0 * e[..., :, None] * e[..., None, :] - np.eye(2)) / D[..., None, None] ** 3
    K = np.einsum("iab,ijab->ij", M, H) + np.einsum("jab,ijab->ij", M, H)
    return np.where(same, 0.0, scene.substrate.compliance / (2 * math.pi) * K)


def test_dense_reduced_coupling_equals_the_formula_over_every_image():
    """The reduced coupling block (coupling_block, through reduced_operator) equals E^T K E of
    the formula over every image element, on a lattice with centre, mirror-line and general
    pillar orbits (FEM moments of a stiff pillar, E_p = 10 E_s)."""
    scene = _scene(E_p=1.6e7)
    m = modal_compliance(PillarKind.of_scene(scene), 2, **COARSE)
    d = scene.pillars.diameter_m
    disc = discretise(scene, 5, "covered", 5.9 * d)
    assert {1, 6, 12} <= set(disc.orbit_size.tolist())
    M = reduced_operator(scene, disc, coupling_block(scene, disc, m))
    centre = disc.pillar_xy[disc.img_pillar]
    gx, gy = disc.img_x - centre[:, 0], disc.img_y - centre[:, 1]
    K = full_operator(scene, disc, pillar_full=_formula(scene, m, gx, gy, disc.img_pillar,
                                                         disc.pillar_xy))
    E = expansion(disc)
    np.testing.assert_allclose(M, E.T @ K @ E, rtol=0, atol=1e-9 * np.abs(M).max())


def test_fft_coupling_equals_the_formula_on_its_cells():
    """The FFT model's coupling (the pillar term with and without it, applied to random
    pressures) equals the formula on its cells' collocation points times L^2."""
    scene = _scene(zeta_um=0.05, E_p=1.6e9)
    m = modal_compliance(PillarKind.of_scene(scene), 2, **COARSE)
    grid = build_grid(scene, 6)
    term = FFTPillarTerm(scene, grid, m, lambda g, where: near_field_correction(grid, g, backend=where))
    assert term.coupling is not None and len(grid.pillar_xy) >= 7
    centre = grid.pillar_xy[grid.pillar]
    K = _formula(scene, m, grid.colloc_x - centre[:, 0], grid.colloc_y - centre[:, 1],
                 grid.pillar, grid.pillar_xy)
    rng = np.random.default_rng(3)
    q = rng.random((grid.n_cells, 2))
    for k in range(2):
        with_c = term(q[:, k])
        saved, term.coupling = term.coupling, None
        without = term(q[:, k])
        term.coupling = saved
        expect = K @ q[:, k] * grid.cell_size**2
        np.testing.assert_allclose(with_c - without, expect, rtol=0,
                                   atol=1e-10 * np.abs(expect).max())
    # apply_few (a few clipped cells) carries the coupling to every pillar as well.  It runs
    # only without a local Love part, i.e. with E_p = E_s (same nu): on that scene's term.
    same = _scene(zeta_um=0.05, E_p=1.6e6)
    grid = build_grid(same, 6)
    term = FFTPillarTerm(same, grid, modal_compliance(PillarKind.of_scene(same), 2, **COARSE),
                         lambda g, where: near_field_correction(grid, g, backend=where))
    assert term.local is None and term.coupling is not None
    idx = np.array([0, grid.n_cells // 2])
    few = term.apply_few(idx, np.array([1.0, -2.0]))
    e = np.zeros(grid.n_cells)
    e[idx] = [1.0, -2.0]
    whole = term(e)
    others = ~np.isin(grid.pillar, grid.pillar[idx])
    assert others.any() and np.abs(whole[others]).max() > 0.0  # the coupling reaches them
    np.testing.assert_allclose(few, whole, rtol=0, atol=1e-12 * np.abs(whole).max())


def test_no_correction_on_a_rigid_substrate():
    """A rigid substrate carries no coupling through it: the correction is off (and so is it
    for a compliance without base moments)."""
    from bem_solver._elastic_pillar import uses_coupling

    rigid = load_scene("paper-fig3-sparse", ["pillars.surface_fraction=0.2",
                                             "pillars.E_Pa=1.6e7", "substrate.rigid=true"])
    assert not uses_coupling(rigid, _Punch())
    assert uses_coupling(_scene(), _Punch())
    bare = _Punch()
    bare.base_moments = None
    assert not uses_coupling(_scene(), bare)
