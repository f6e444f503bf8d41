"""fem-3d's reduced stiffness written from the node-pair blocks
(:mod:`fem_reference.solid3d.reduction`) against scipy's products T_u^T (A T_u).

The claim is bit for bit: the writer sums each entry in the products' order and lays out
each row as they do, so its arrays equal the products' (exact zeros dropped) with no
tolerance, and the solves that use them take the same steps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.sparse as sp
from skfem import Basis, ElementTetP2, MeshTet

from fem_reference.solid3d import reduction, system

ALPHA = math.pi / 6


def _mesh(boundaries: dict):
    """A distorted unit cube of two bodies (general tetrahedra), faces named as given."""
    mesh = MeshTet().refined(2)
    inner = (mesh.p > 0) & (mesh.p < 1)
    shift = 0.02 * np.random.default_rng(0).standard_normal(mesh.p.shape) * inner
    mesh = MeshTet(mesh.p + shift, mesh.t)
    low = mesh.p[2, mesh.t].mean(axis=0) < 0.5
    mesh = mesh.with_subdomains({"a": np.nonzero(~low)[0], "b": np.nonzero(low)[0]})
    return mesh.with_boundaries(boundaries)


def _nonzero(K):
    K = sp.csr_matrix(K)
    K.eliminate_zeros()
    return K


# The constraints' sets (the normals are the sector's whatever the face: the algebra is the
# same): none; the mirrors and far faces, whose corners and edges carry two or three
# normals (bases of 2, 1 and 0 columns, one skew); and a clamp besides.
CASES = {
    "free": ({"top": lambda x: np.isclose(x[2], 1.0)}, False),  # a face of no constraint
    "mirrors and far faces": ({"mirror_0": lambda x: np.isclose(x[1], 0.0),
                               "mirror_1": lambda x: np.isclose(x[0], 0.0),
                               "far_substrate": lambda x: np.isclose(x[2], 0.0),
                               "far_lens": lambda x: np.isclose(x[2], 1.0)}, False),
    "and a clamp": ({"mirror_1": lambda x: np.isclose(x[0], 0.0),
                     "far_lens": lambda x: np.isclose(x[2], 1.0),
                     "pillar_base": lambda x: np.isclose(x[1], 1.0)}, True),
}


@pytest.mark.parametrize("case", list(CASES))
@pytest.mark.parametrize("pairs", [None, 7])
def test_the_written_reduction_is_scipys_product(case, pairs, monkeypatch):
    """ReducedStiffness (in one pass, and in passes of 7 node pairs) gives the arrays of
    T_u^T (A T_u) bit for bit, their order too, on meshes with and without mirror planes, far
    faces and a clamp (the skew mirror's rows with entries the product meets late)."""
    if pairs is not None:
        monkeypatch.setattr(reduction, "PAIRS", pairs)
    boundaries, clamp = CASES[case]
    mesh = _mesh(boundaries)
    sb = Basis(mesh, ElementTetP2(), intorder=1)
    spaces = [system.PressureSpace3D(b, None, np.unique(mesh.t[:, mesh.subdomains[b]]), 1.0,
                                     mu, 0) for b, mu in (("a", 1.3), ("b", 0.7))]
    (row, col, blocks), _, _ = system.assemble_blocks(mesh, sb, spaces)
    T, _, bases = system._transform(mesh, sb, 3 * sb.N, ALPHA, clamp, [])
    assert bases.direct
    if case != "free":  # bases of 3 (the identity), 2, 1 and 0 columns, a skew one among them
        assert {2, 1, 0} <= set(bases.count.tolist())
        assert np.any(np.isclose(np.abs(bases.bases), math.sin(ALPHA)))
    ref = _nonzero(T.T.tocsr() @ (system._vector_csr(row, col, blocks, sb.N) @ T))
    written = reduction.ReducedStiffness(row, col, blocks.copy(), bases, T.shape[1])
    if "mirror_0" in boundaries:
        assert np.any(written.meets > 0)  # a late entry to place
    got = _nonzero(written.tocsr())
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(got, name), getattr(ref, name)), name


def test_the_sector_matrix_is_the_products_and_rigid_pillars_keep_them(monkeypatch):
    """assemble_sector's scaled matrix, the written reduction stacked with the pressures'
    blocks, equals the one from scipy's products (the path that rigid pillars take) bit for
    bit, its scale and nodes alike; with a rigid pillar the products are taken."""
    mesh = _mesh(CASES["mirrors and far faces"][0])
    materials = {"a": (1.0, 0.3), "b": (2.0, 0.45)}

    def sector(rigid=()):
        return system.assemble_sector(mesh, materials, sector_angle=ALPHA,
                                      clamp_pillar_base=False, rigid_pillars=list(rigid))

    written = sector()
    monkeypatch.setattr(reduction.NodeBases, "direct", property(lambda self: False))
    products = sector()
    assert np.array_equal(written.scale, products.scale)
    assert np.array_equal(written.nodes, products.nodes)
    a, b = written.K, products.K
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    monkeypatch.undo()
    mesh = mesh.with_boundaries({"pillar_base_0_0": lambda x: np.isclose(x[1], 1.0)})
    sb = Basis(mesh, ElementTetP2(), intorder=1)
    _, rigid, bases = system._transform(mesh, sb, 3 * sb.N, ALPHA, False,
                                        [("0_0", (0.5, 0.5))])
    assert not bases.direct and np.all(bases.count[bases.count < 0] == -1)
