"""The tetrahedral mesh a 3D builder returns: arrays, named groups, checks, conversions.

Code speaks in names: ``mesh.subdomains["pillar"]`` are tetrahedron indices,
``mesh.boundaries["contact_lens_1_0"]`` triangle indices, and the scikit-fem mesh carries the
same names as facet indices.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np

from .._common import MeshError

# Mean-ratio floor, q = 12 (3 V)^(2/3) / sum(l^2) (1 for a regular tetrahedron).  gmsh's
# optimised Delaunay meshes of these graded sectors measured q_min 0.17-0.3; below 0.02 an
# element is a sliver whose P2 stiffness is badly conditioned.
MIN_QUALITY_3D = 0.02
# Two sides of a contact face match when their nodes agree to this fraction of the focus radius.
MATCH_RTOL = 1e-9


@dataclass
class WedgeMesh:
    """Linear tetrahedral mesh of a sector with named groups.

    Attributes
    ----------
    points : ndarray, shape (3, N)
        Node coordinates (x, y, z) in m.
    tets : ndarray, shape (4, M)
        Node indices, positively oriented.
    triangles : ndarray, shape (3, K)
        Boundary and interface triangles of the named face groups.
    subdomains, boundaries : dict of str to ndarray
        Tetrahedron / triangle indices of each named group.
    geometry : WedgeGeometry
        What was meshed.
    optimised : bool
        Whether gmsh's mesh needed Netgen's optimiser to pass the quality floor.
    """

    points: np.ndarray
    tets: np.ndarray
    triangles: np.ndarray
    subdomains: dict
    boundaries: dict
    geometry: object
    _skfem: object = field(default=None, repr=False)
    optimised: bool = False

    def __post_init__(self):
        neg = self.signed_volumes() < 0
        if neg.any():
            t = self.tets.copy()
            t[2, neg], t[3, neg] = self.tets[3, neg], self.tets[2, neg]
            self.tets = t

    @property
    def nelements(self) -> int:
        return self.tets.shape[1]

    def signed_volumes(self) -> np.ndarray:
        p = self.points[:, self.tets]
        a, b, c = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]
        return np.einsum("ij,ij->j", a, np.cross(b, c, axis=0)) / 6.0

    def quality(self) -> np.ndarray:
        """Mean ratio 12 (3 |V|)^(2/3) / sum of squared edge lengths, in (0, 1]."""
        p = self.points[:, self.tets]
        l2 = sum(np.sum((p[:, i] - p[:, j]) ** 2, axis=0)
                 for i in range(4) for j in range(i + 1, 4))
        return 12.0 * (3.0 * np.abs(self.signed_volumes())) ** (2.0 / 3.0) / l2

    def face_nodes(self, name: str) -> np.ndarray:
        if name not in self.boundaries:
            raise MeshError(f"no boundary group named {name!r}; have {sorted(self.boundaries)}")
        return np.unique(self.triangles[:, self.boundaries[name]])

    def contact_pairs(self) -> list:
        """(lens face group, lower face group) of every contact face whose two sides are both
        meshed: per pillar, or the flat candidate sector."""
        pairs = []
        for name in sorted(self.boundaries):
            m = re.fullmatch(r"contact_pillar_(-?\d+_-?\d+)", name)
            if m and f"contact_lens_{m.group(1)}" in self.boundaries:
                pairs.append((f"contact_lens_{m.group(1)}", name))
        if "contact_substrate" in self.boundaries and "contact_lens" in self.boundaries:
            pairs.append(("contact_lens", "contact_substrate"))
        if "contact_floor" in self.boundaries and "contact_lens_floor" in self.boundaries:
            pairs.append(("contact_lens_floor", "contact_floor"))  # h apart: in (x, y)
        return pairs

    def check(self) -> None:
        """Raise MeshError unless every body has elements, every tetrahedron has quality
        above MIN_QUALITY_3D and the two sides of every contact face match node for node."""
        for body in self.geometry.bodies:
            if len(self.subdomains.get(body, ())) == 0:
                raise MeshError(f"body {body!r} has no elements")
        q = self.quality()
        if not np.all(np.isfinite(q)) or q.min() < MIN_QUALITY_3D:
            k = int(np.nanargmin(q))
            x = self.points[:, self.tets[0, k]]
            raise MeshError(f"mesh quality check failed: tetrahedron {k} has q = {q[k]:.3g} < "
                            f"{MIN_QUALITY_3D} (near x = {x[0]:.3g}, y = {x[1]:.3g}, "
                            f"z = {x[2]:.3g} m)")
        tol = MATCH_RTOL * self.geometry.focus_radius_m
        for lens, lower in self.contact_pairs():
            a, b = self.face_nodes(lens), self.face_nodes(lower)
            if len(a) != len(b) or _unmatched(self.points[:2, a], self.points[:2, b]) > tol:
                raise MeshError(f"contact faces {lens!r} ({len(a)} nodes) and {lower!r} "
                                f"({len(b)} nodes) do not match node for node")

    def summary(self) -> dict:
        q = self.quality()
        return {"nodes": int(self.points.shape[1]), "elements": self.nelements,
                "min_quality": float(q.min()), "optimised": bool(self.optimised),
                "bodies": {k: int(len(v)) for k, v in self.subdomains.items()
                           if k in ("lens", "pillar", "substrate")}}

    def to_skfem(self):
        """scikit-fem ``MeshTet`` with the same named subdomains and boundaries (cached); its
        facets and edges numbered through integer keys (:class:`._skfem.KeyedMeshTet`)."""
        if self._skfem is None:
            from ._skfem import KeyedMeshTet

            m = KeyedMeshTet(np.ascontiguousarray(self.points, dtype=float),
                        np.ascontiguousarray(self.tets, dtype=np.int64))
            n = np.int64(m.p.shape[1])
            fk = _keys(m.facets, n)
            order = np.argsort(fk)
            tk = _keys(self.triangles, n)
            pos = np.clip(np.searchsorted(fk, tk, sorter=order), 0, len(order) - 1)
            facet_of = order[pos]
            if not np.array_equal(fk[facet_of], tk):
                raise MeshError("a named triangle is not a face of any tetrahedron")
            m = m.with_subdomains(dict(self.subdomains))
            m = m.with_boundaries({k: facet_of[v] for k, v in self.boundaries.items()})
            self._skfem = m
        return self._skfem

    def to_meshio(self):
        """meshio ``Mesh`` with gmsh physical tags of the bodies and names."""
        import meshio

        tag = np.zeros(self.nelements, dtype=int)
        field_data = {}
        for k, name in enumerate(("lens", "pillar", "substrate"), start=1):
            if name in self.subdomains:
                tag[self.subdomains[name]] = k
                field_data[name] = np.array([k, 3])
        return meshio.Mesh(self.points.T, [("tetra", self.tets.T)],
                           cell_data={"gmsh:physical": [tag], "gmsh:geometrical": [tag]},
                           field_data=field_data)


def _unmatched(pa: np.ndarray, pb: np.ndarray) -> float:
    """Largest distance from a point of either set to the nearest point of the other."""
    from scipy.spatial import cKDTree

    return max(float(cKDTree(pb.T).query(pa.T)[0].max()),
               float(cKDTree(pa.T).query(pb.T)[0].max()))


def _keys(tri: np.ndarray, n) -> np.ndarray:
    """One int64 key per triangle, independent of vertex order (n^3 < 2^63 for n < 2e6)."""
    s = np.sort(tri.astype(np.int64), axis=0)
    return (s[0] * n + s[1]) * n + s[2]
