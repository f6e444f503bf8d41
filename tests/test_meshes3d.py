"""Tests of the 3D sector mesh builder: named groups, pillar tops by lattice index, cut
pillars, bonded bases, matching contact faces, grading, quality and clear refusals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from meshes import (MIN_QUALITY_3D, MeshError, WedgeGeometry, build_wedge_mesh,
                    sector_pillars)

D, H = 4e-6, 2e-6
PITCH = 2.2 * D  # Phi = 0.187


@pytest.fixture(scope="module")
def lattice_mesh():
    pillars = sector_pillars(PITCH, D, 1.2 * PITCH)
    geo = WedgeGeometry(D / 2, 1e3 * D / 2, pillars=pillars, pillar_height_m=H, mesh_size=2.0)
    return build_wedge_mesh(geo)


def test_sector_pillars_and_shares():
    pillars = {p.name: p for p in sector_pillars(PITCH, D, 2.1 * PITCH)}
    # rings 0..2 of the wedge: (0,0) centre, (1,0), (2,0) on theta = 0, (2,1) on pi/6
    assert set(pillars) == {"0_0", "1_0", "2_0", "2_1"}
    assert pillars["0_0"].share == pytest.approx(1 / 12)
    assert pillars["1_0"].share == pillars["2_1"].share == 0.5
    quadrant = {p.name: p.share for p in sector_pillars(PITCH, D, 1.6 * PITCH, math.pi / 2)}
    # (1,0) on x, (1,1) at 60 deg and (2,1) at 30 deg inside, (1,2) on the y axis (x = 0)
    assert quadrant == {"0_0": 0.25, "1_0": 0.5, "1_1": 1.0, "2_1": 1.0, "1_2": 0.5}


def test_named_groups_and_pillars_by_index(lattice_mesh):
    m = lattice_mesh
    names = [p.name for p in m.geometry.pillars]
    assert names == ["0_0", "1_0"]
    for body in ("lens", "pillar", "substrate"):
        assert len(m.subdomains[body]) > 0
    for n in names:
        for group in ("contact_lens_", "contact_pillar_", "pillar_base_"):
            assert len(m.boundaries[group + n]) > 0
        assert len(m.subdomains["pillar_" + n]) > 0
    for group in ("mirror_0", "mirror_1", "mirror_0_lens", "mirror_1_substrate", "far_lens",
                  "far_substrate", "side_lens", "side_substrate", "free_lens",
                  "free_pillar", "free_substrate", "contact_lens", "contact_pillar",
                  "pillar_base"):
        assert len(m.boundaries[group]) > 0, group
    sk = m.to_skfem()
    assert set(sk.boundaries) == set(m.boundaries)


def test_groups_lie_where_their_names_say(lattice_mesh):
    m = lattice_mesh
    p = m.points
    alpha = m.geometry.sector_angle

    def nodes(name):
        return p[:, m.face_nodes(name)]

    assert np.allclose(nodes("mirror_0")[1], 0.0, atol=1e-12)
    n1 = np.array([-math.sin(alpha), math.cos(alpha), 0.0])
    assert np.allclose(n1 @ nodes("mirror_1"), 0.0, atol=1e-12)
    top = nodes("contact_pillar_1_0")
    assert np.allclose(top[2], 0.0) and np.all(top[1] >= -1e-15)
    assert np.all(np.hypot(top[0] - PITCH, top[1]) <= D / 2 * (1 + 1e-9))
    base = nodes("pillar_base_1_0")
    assert np.allclose(base[2], -H)
    # the half pillar on theta = 0 covers half a disk: its top area is pi d^2 / 8
    tri = m.triangles[:, m.boundaries["contact_pillar_1_0"]]
    e1, e2 = p[:, tri[1]] - p[:, tri[0]], p[:, tri[2]] - p[:, tri[0]]
    area = 0.5 * np.abs(np.cross(e1, e2, axis=0)[2]).sum()
    # polygonal circle: area deficit ~ (2 pi / N)^2 / 6 with N edges on the rim
    assert area == pytest.approx(math.pi * D**2 / 8, rel=0.02)


def test_contact_faces_match_and_bodies_stay_apart(lattice_mesh):
    m = lattice_mesh
    pairs = m.contact_pairs()
    assert ("contact_lens_1_0", "contact_pillar_1_0") in pairs and len(pairs) == 2
    for lens, lower in pairs:
        a, b = m.face_nodes(lens), m.face_nodes(lower)
        assert not set(a) & set(b)  # distinct nodes: the lens is not glued to the pillars
        assert len(a) == len(b)
        dist, _ = cKDTree(m.points[:, b].T).query(m.points[:, a].T)
        assert dist.max() < 1e-9 * m.geometry.focus_radius_m
    # pillar and substrate share their base nodes (bonded, conforming)
    base = m.face_nodes("pillar_base")
    in_pillar = np.isin(base, m.tets[:, m.subdomains["pillar"]])
    in_substrate = np.isin(base, m.tets[:, m.subdomains["substrate"]])
    assert in_pillar.all() and in_substrate.all()


def test_grading_and_quality(lattice_mesh):
    m = lattice_mesh
    assert m.quality().min() > MIN_QUALITY_3D
    assert np.all(m.signed_volumes() > 0)
    # edges on the top face: shortest near the rim, longest near the centre of the top
    tri = m.triangles[:, m.boundaries["contact_pillar_1_0"]]
    p = m.points
    mid = p[:, tri].mean(axis=1)
    h = np.sqrt(np.sum((p[:, tri[0]] - p[:, tri[1]]) ** 2, axis=0))
    rho = np.hypot(mid[0] - PITCH, mid[1]) / (D / 2)
    assert np.median(h[rho > 0.9]) < 0.6 * np.median(h[rho < 0.4])
    assert p[2].max() == pytest.approx(m.geometry.block_size_m)  # the big block is there


def test_centre_pillar_top_is_refined():
    """centre_ratio shrinks the elements on the centre pillar's top only (where sigma0 and the
    profile are read): the size rule there and on a neighbour's top, and the built mesh's edges."""
    pillars = sector_pillars(PITCH, D, 1.2 * PITCH)
    plain = WedgeGeometry(D / 2, 1e3 * D / 2, pillars=pillars, pillar_height_m=H,
                          mesh_size=2.0)
    fine = WedgeGeometry(D / 2, 1e3 * D / 2, pillars=pillars, pillar_height_m=H,
                         mesh_size=2.0, centre_ratio=0.25)
    h_c = 2.0 / plain.elements_across_contact
    assert plain.size_at(0.3, 0.05, 0.0) == pytest.approx(h_c)
    assert fine.size_at(0.3, 0.05, 0.0) == pytest.approx(0.25 * h_c)
    neighbour = (PITCH / (D / 2) + 0.3, 0.05, 0.0)
    assert fine.size_at(*neighbour) == pytest.approx(plain.size_at(*neighbour))
    refined, coarse = build_wedge_mesh(fine), build_wedge_mesh(plain)

    def median_edge(m, name):
        tri = m.triangles[:, m.boundaries[name]]
        p = m.points
        mid = p[:, tri].mean(axis=1)
        inner = np.hypot(*mid[:2]) < 0.6 * D / 2  # the centre top, away from its rim
        h = np.sqrt(np.sum((p[:, tri[0]] - p[:, tri[1]]) ** 2, axis=0))
        return np.median(h[inner])

    # measured 0.50x (2.2e-7 against 4.4e-7 m): the rim's grading already refines much of it
    assert median_edge(refined, "contact_pillar_0_0") < 0.6 * median_edge(coarse,
                                                                          "contact_pillar_0_0")


def test_size_rule_takes_the_nearest_meshed_pillar_everywhere():
    """Without a floor the rule equals the least of its one-pillar rules (each size grows with
    the distance from its pillar), near the pillars, beyond the meshed ones and far out along
    the block: its pillar is the nearest meshed one.  On a dense lattice (Phi = 0.82) a search
    of the rounded lattice point's 3 x 3 block took a farther pillar beyond the meshed ones
    (on 20 of these 1,000 points; one call of gmsh's 5.6e5 on the scene at mesh_size 2)."""
    pitch = 1.05 * D
    pillars = sector_pillars(pitch, D, 8.0 * pitch)
    kw = dict(focus_radius_m=D / 2, block_size_m=1e4 * D / 2, pillar_height_m=H,
              mesh_size=2.0, centre_ratio=0.25)
    geo = WedgeGeometry(pillars=pillars, **kw)
    alone = [WedgeGeometry(pillars=(p,), **kw) for p in pillars]
    rng = np.random.default_rng(3)
    near = rng.uniform([-0.5, -0.5, -6.0], [25.0, 15.0, 4.0], size=(800, 3))
    far = rng.uniform([0.0, 0.0, -2.0], [1.0, 0.6, 2.0], size=(200, 3)) * np.exp(
        rng.uniform(2.0, 9.0, size=(200, 1)))  # out to the block's edges (1e4 focus radii)
    points = np.vstack([near, far])
    assert len(pillars) >= 25
    for x, y, z in points:
        assert geo.size_at(x, y, z) == min(g.size_at(x, y, z) for g in alone), (x, y, z)


def test_skfem_form_numbers_facets_and_edges_as_skfem_does(lattice_mesh):
    """The keyed facets and edges (one int64 key per entity) are scikit-fem's own arrays, on
    the mesh and on the copies scaled() and with_boundaries() make."""
    from skfem import MeshTet

    sk = lattice_mesh.to_skfem()
    plain = MeshTet(sk.p, sk.t)
    for copy in (sk, sk.scaled([2.0] * 3), sk.with_boundaries({"x": np.arange(3)})):
        assert type(copy) is type(sk)
        for name in ("facets", "t2f", "edges", "t2e", "f2t"):
            a, b = getattr(copy, name), getattr(plain, name)
            assert a.dtype == b.dtype and np.array_equal(a, b), name


def test_flat_sector_and_rigid_bodies():
    a = 2.45e-5
    flat = build_wedge_mesh(WedgeGeometry(a, 1e3 * a, contact_radius_m=1.5 * a, mesh_size=2.0,
                                          bodies=("lens", "substrate")))
    assert flat.contact_pairs() == [("contact_lens", "contact_substrate")]
    pillars = sector_pillars(PITCH, D, 0.5 * PITCH)
    rigid = build_wedge_mesh(WedgeGeometry(D / 2, 1e3 * D / 2, pillars=pillars,
                                           pillar_height_m=H, mesh_size=2.0,
                                           bodies=("lens", "substrate")))
    assert "pillar" not in rigid.subdomains and "contact_pillar" not in rigid.boundaries
    assert len(rigid.boundaries["pillar_base_0_0"]) > 0  # where the rigid pillar is bonded
    assert len(rigid.boundaries["contact_lens_0_0"]) > 0


def test_quality_check_refuses_a_sliver(lattice_mesh):
    import copy

    bad = copy.deepcopy(lattice_mesh)
    i, j, k, l = bad.tets[:, 0]
    bad.points[:, l] = (bad.points[:, i] + bad.points[:, j] + bad.points[:, k]) / 3 + 1e-13
    with pytest.raises(MeshError, match="quality"):
        bad.check()


@pytest.mark.parametrize("kwargs, match", [
    (dict(sector_angle=0.3), "sector_angle"),
    (dict(block_size_m=1e-6), "block_size_m"),
    (dict(mesh_size=0.0), "mesh_size"),
    (dict(pillar_height_m=None), "pillar_height_m"),
    (dict(bodies=("lens", "shell")), "bodies"),
])
def test_bad_geometry_is_refused_clearly(kwargs, match):
    args = dict(focus_radius_m=D / 2, block_size_m=1e3 * D / 2,
                pillars=sector_pillars(PITCH, D, 0.0), pillar_height_m=H)
    args.update(kwargs)
    with pytest.raises(MeshError, match=match):
        WedgeGeometry(**args)
