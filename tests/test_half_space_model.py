"""The half-space model of fem-3d's contact faces (fem_reference.solid3d.half_space), the
contact CG's preconditioner, against Boussinesq's closed form."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
from scipy.spatial import Delaunay

from fem_reference.solid3d.half_space import (ROWS, HalfSpaceModel, half_space_compliance,
                                              mirror_group)

ALPHA = math.pi / 6
# A uniform unit pressure on the disk r <= 1 (gamma = 1): its sector's share of the work,
# 1/12 of gamma/pi x the integral of 1/|x - y| over the disk twice, 16 pi / 3 (Johnson 1985,
# sec. 3.2: the mean deflection is 16 gamma p a / (3 pi)).
UNIFORM_DISK = 16.0 / 36.0
# Measured on the sector meshed with 12 rings: -1.3 % with the near pieces, -4.5 % lumped
# (-0.6 % and -2.3 % with 24 rings; the polygon misses 0.1 % of the disk's area).
RTOL_NEAR = 0.02


def _sector_disk(rings: int):
    """Vertices (2, n), weights (the hats' integrals) and triangles (3, m) of the sector
    0 <= theta <= pi/6 of the unit disk."""
    pts = [(0.0, 0.0)]
    for k in range(1, rings + 1):
        r = k / rings
        m = max(1, math.ceil(r * ALPHA * rings))
        pts += [(r * math.cos(ALPHA * j / m), r * math.sin(ALPHA * j / m)) for j in range(m + 1)]
    pts = np.array(pts)
    tri = Delaunay(pts).simplices.T
    P = pts[tri]
    area = 0.5 * np.abs((P[1, :, 0] - P[0, :, 0]) * (P[2, :, 1] - P[0, :, 1])
                        - (P[2, :, 0] - P[0, :, 0]) * (P[1, :, 1] - P[0, :, 1]))
    w = np.bincount(tri.ravel(), weights=np.tile(area / 3.0, 3), minlength=len(pts))
    return pts.T, w, tri


def test_uniform_pressure_on_a_disk_matches_boussinesq():
    xy, w, tri = _sector_disk(12)
    H = half_space_compliance(xy, w, tri, 1.0, ALPHA)
    lumped = half_space_compliance(xy, w, np.zeros((3, 0), dtype=int), 1.0, ALPHA)
    near_error = H.sum() / UNIFORM_DISK - 1.0
    assert abs(near_error) < RTOL_NEAR
    assert abs(near_error) < 0.5 * abs(lumped.sum() / UNIFORM_DISK - 1.0)


def test_model_is_symmetric_positive_definite_and_scales_with_the_compliance():
    xy, w, tri = _sector_disk(8)
    H = half_space_compliance(xy, w, tri, 1.0, ALPHA)
    assert np.array_equal(H, H.T)
    assert np.linalg.eigvalsh(H)[0] > 0.0
    assert np.allclose(half_space_compliance(xy, w, tri, 2.5, ALPHA), 2.5 * H, rtol=1e-14)


def test_mirror_groups_are_the_sectors_dihedral_groups():
    for alpha, order in ((math.pi / 6, 12), (math.pi / 3, 6), (math.pi / 2, 4)):
        group = mirror_group(alpha)
        assert len(group) == order
        for g in group:
            assert np.allclose(g @ g.T, np.eye(2))
        # closed under composition: every product is in the group
        for g in group:
            for h in group:
                assert any(np.allclose(g @ h, k) for k in group)


def _lumped_directly(xy, w, gamma, alpha, tol=1e-9):
    """The lumped model by its definition, every pair and image summed at once (a vertex's
    coinciding images, its own and any other vertex's, join its hat as a uniform disk)."""
    x = xy.T
    S, merged = np.zeros((len(w), len(w))), np.zeros(len(w))
    for g in mirror_group(alpha):
        d = np.linalg.norm(x[:, None, :] - (x @ g.T)[None, :, :], axis=2)
        same = d <= tol
        merged += same.sum(axis=1)
        S += np.where(same, 0.0, 1.0 / np.where(same, 1.0, d))
    S *= np.outer(w, w)
    S[np.diag_indices(len(w))] += 16.0 / (3.0 * math.pi) * w * np.sqrt(merged * w / math.pi)
    return S * gamma / math.pi


def test_lumped_model_matches_its_definition_across_row_blocks():
    # more vertices than one block of rows (ROWS), and a vertex repeated far from its twin
    # (a pillar top's rim above the floor's): its images counted from both sides
    xy, w, _ = _sector_disk(48)
    assert xy.shape[1] > ROWS
    xy = np.hstack([xy, xy[:, 3:4]])
    w = np.append(w, 0.5 * w[3])
    H = half_space_compliance(xy, w, np.zeros((3, 0), dtype=int), 1.7, ALPHA)
    direct = _lumped_directly(xy, w, 1.7, ALPHA)
    assert np.max(np.abs(H - direct)) <= 1e-13 * np.max(np.abs(direct))


def _model(gamma):
    xy, w, tri = _sector_disk(8)
    faces = SimpleNamespace(vertex_points=xy, weights=w, triangles=tri,
                            pillar_of_vertex=np.full(len(w), -1))
    return HalfSpaceModel(faces, None, gamma, ALPHA)


def test_preconditioner_solves_the_free_set_block():
    model = _model(1.0)
    free = np.arange(len(model.H)) % 3 != 0
    r = np.random.default_rng(2).standard_normal(len(model.H))
    z = model.precondition(r, free)
    exact = np.linalg.solve(model.H[np.ix_(free, free)], r[free])
    assert model.name == "half-space"
    assert np.all(z[~free] == 0.0)
    # the float32 factor: its solves agree to a few float32 epsilons of the model's condition
    assert np.max(np.abs(z[free] - exact)) <= 1e-4 * np.max(np.abs(exact))


def test_a_model_not_positive_definite_turns_to_the_diagonal_without_a_start():
    model = _model(-1.0)  # a negative compliance: H negative definite
    free = np.ones(len(model.H), dtype=bool)
    r = np.ones(len(model.H))
    assert np.array_equal(model.precondition(r, free), r * model.inverse_diagonal)
    assert model.name.startswith("diagonal")
    assert not np.any(model.warm_start(-np.ones(len(r)), 1.0))
