"""Tests of the axisymmetric gmsh builder: names, matching contact lines, grading, quality,
export, and clear refusals."""

from __future__ import annotations

import numpy as np
import pytest

from meshes import (AxisymmetricGeometry, MeshError, build_axisymmetric_mesh,
                    flat_geometry)
from meshes import pillar_geometry as make_pillar_geometry

D2 = 2e-6  # pillar radius d/2 (m), the paper's d = 4 um
H = 2e-6   # pillar height (m)

PILLAR_GROUPS = {"contact_lens", "contact_pillar", "pillar_base", "axis", "far_lens",
                 "far_substrate", "side_lens", "side_substrate", "free_lens", "free_pillar",
                 "free_substrate"}
FLAT_GROUPS = {"contact_lens", "contact_substrate", "axis", "far_lens", "far_substrate",
               "side_lens", "side_substrate", "free_lens", "free_substrate"}


def pillar_geometry(**kw):
    return make_pillar_geometry(2 * D2, H, 1e4 * D2, **kw)


@pytest.fixture(scope="module")
def pillar_mesh():
    return build_axisymmetric_mesh(pillar_geometry())


@pytest.fixture(scope="module")
def flat_mesh():
    a = 2.45e-5
    return build_axisymmetric_mesh(flat_geometry(a, 1e4 * a))


def test_pillar_mesh_has_named_groups(pillar_mesh):
    assert set(pillar_mesh.subdomains) == {"lens", "pillar", "substrate"}
    assert set(pillar_mesh.boundaries) == PILLAR_GROUPS
    sk = pillar_mesh.to_skfem()
    assert set(sk.subdomains) == {"lens", "pillar", "substrate"}
    assert set(sk.boundaries) == PILLAR_GROUPS
    # The names point at the right places: the pillar lies in 0 <= r <= d/2, -h <= z <= 0.
    mid = sk.p[:, sk.t[:, sk.subdomains["pillar"]]].mean(axis=1)
    assert np.all((mid[0] < D2) & (mid[1] < 0) & (mid[1] > -H))
    axis = sk.p[:, sk.facets[:, sk.boundaries["axis"]]]
    assert np.all(axis[0] == 0.0)


def test_flat_mesh_has_named_groups(flat_mesh):
    assert set(flat_mesh.subdomains) == {"lens", "substrate"}
    assert set(flat_mesh.boundaries) == FLAT_GROUPS


def test_rigid_bodies_are_not_meshed():
    mesh = build_axisymmetric_mesh(pillar_geometry(bodies=("lens", "substrate"),
                                                   mesh_size=2.0))
    assert set(mesh.subdomains) == {"lens", "substrate"}
    assert "contact_pillar" not in mesh.boundaries
    assert "pillar_base" in mesh.boundaries  # where the rigid pillar is bonded


@pytest.mark.parametrize("name", ["pillar_mesh", "flat_mesh"])
def test_contact_lines_match_node_for_node(name, request):
    mesh = request.getfixturevalue(name)
    lens, lower = mesh.contact_pair()
    a, b = mesh.contact_nodes(lens), mesh.contact_nodes(lower)
    assert len(a) == len(b) and not set(a) & set(b)  # distinct nodes: bodies disconnected
    np.testing.assert_array_equal(mesh.points[:, a], mesh.points[:, b])


def test_pillar_and_substrate_are_bonded(pillar_mesh):
    """The pillar base is shared by both bodies (a conforming, bonded interface)."""
    base = np.unique(pillar_mesh.lines[:, pillar_mesh.boundaries["pillar_base"]])
    tri = pillar_mesh.triangles
    in_pillar = np.isin(base, tri[:, pillar_mesh.subdomains["pillar"]])
    in_substrate = np.isin(base, tri[:, pillar_mesh.subdomains["substrate"]])
    assert in_pillar.all() and in_substrate.all()


def test_grading_towards_the_singular_points(pillar_mesh):
    """Elements at the pillar-top edge and the base corner are ~50x smaller than at the axis."""
    m = pillar_mesh
    nodes = m.contact_nodes("contact_pillar")
    h = np.diff(m.points[0, nodes])
    assert h[-1] < h[0] / 20
    assert h[-1] == pytest.approx(m.geometry.edge_ratio * D2 / 16, rel=0.5)
    base = m.contact_nodes("pillar_base")
    assert np.diff(m.points[0, base])[-1] < h[0] / 20


def test_mesh_size_halves_every_element():
    coarse = build_axisymmetric_mesh(pillar_geometry(mesh_size=1.0))
    fine = build_axisymmetric_mesh(pillar_geometry(mesh_size=0.5))
    # Element count ~ 1/mesh_size^2 (measured 3.8x; grading ratio also halves).
    assert 3.0 < fine.nelements / coarse.nelements < 5.0
    hc = np.diff(coarse.points[0, coarse.contact_nodes("contact_lens")])
    hf = np.diff(fine.points[0, fine.contact_nodes("contact_lens")])
    assert hf.min() == pytest.approx(0.5 * hc.min(), rel=0.2)
    assert hf.max() == pytest.approx(0.5 * hc.max(), rel=0.2)


def test_block_size_is_nearly_free():
    """Geometric grading: 10x the block costs a few rings of elements (< 15 % more)."""
    small = build_axisymmetric_mesh(pillar_geometry())
    big = build_axisymmetric_mesh(AxisymmetricGeometry(D2, 1e5 * D2, pillar_height_m=H))
    assert big.nelements < 1.15 * small.nelements
    assert big.points[1].max() == pytest.approx(1e5 * D2)


def test_quality(pillar_mesh):
    s = pillar_mesh.summary()
    assert s["min_quality"] > 0.5 and s["min_angle_deg"] > 25.0
    assert np.all(pillar_mesh.signed_areas() > 0)  # counter-clockwise


def test_quality_check_refuses_a_sliver():
    bad = build_axisymmetric_mesh(pillar_geometry(mesh_size=2.0))
    k = 0
    i, j, _ = bad.triangles[:, k]
    # Collapse one triangle onto its first edge: quality -> 0.
    bad.points[:, bad.triangles[2, k]] = 0.5 * (bad.points[:, i] + bad.points[:, j]) + 1e-15
    with pytest.raises(MeshError, match="quality"):
        bad.check()


def test_meshio_export_keeps_names(pillar_mesh, tmp_path):
    import meshio

    for suffix in (".msh", ".vtu"):
        pillar_mesh.write(tmp_path / f"mesh{suffix}")
    back = meshio.read(tmp_path / "mesh.msh")
    assert set(back.field_data) == PILLAR_GROUPS | {"lens", "pillar", "substrate"}
    assert len(back.cells_dict["triangle"]) == pillar_mesh.nelements
    assert (tmp_path / "mesh.vtu").stat().st_size > 0


@pytest.mark.parametrize("kwargs, match", [
    (dict(block_size_m=2 * D2), "block_size_m"),
    (dict(pillar_height_m=-1e-6), "pillar_height_m"),
    (dict(mesh_size=0.0), "mesh_size"),
    (dict(mesh_size=10.0), "mesh_size"),
    (dict(bodies=("lens", "shell")), "bodies"),
    (dict(pillar_height_m=None), "pillar"),
    (dict(contact_radius_m=3 * D2), "contact_radius_m"),
    (dict(block_size_m=float("nan")), "block_size_m"),
])
def test_bad_geometry_is_refused_clearly(kwargs, match):
    args = dict(focus_radius_m=D2, block_size_m=1e4 * D2, pillar_height_m=H)
    args.update(kwargs)
    with pytest.raises(MeshError, match=match):
        build_axisymmetric_mesh(AxisymmetricGeometry(**args))


def test_gmsh_failure_becomes_a_mesh_error(monkeypatch):
    import meshes.axisym.gmsh as builder

    def broken(gmsh, geo):
        raise Exception("simulated gmsh failure")

    monkeypatch.setattr(builder, "_mesh", broken)
    with pytest.raises(MeshError, match="gmsh could not mesh.*simulated"):
        build_axisymmetric_mesh(pillar_geometry())
    import gmsh

    assert not gmsh.isInitialized()  # finalized even on failure
