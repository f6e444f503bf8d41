"""The mesh a builder returns: arrays, named groups, checks and conversions.

Code speaks in names: ``mesh.subdomains["pillar"]`` are triangle indices,
``mesh.boundaries["contact_lens"]`` are line-element indices, and the scikit-fem mesh carries
the same names (``to_skfem().boundaries["axis"]`` are facet indices).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import AxisymmetricGeometry
from .._common import MeshError

# Shape-quality floor q = 4 sqrt(3) A / sum(l^2) (1 for an equilateral triangle); gmsh's
# Frontal-Delaunay gives q > 0.5 on these graded meshes, 0.1 means a near-degenerate element.
MIN_QUALITY = 0.1
# Two contact lines match when their nodes agree to this fraction of the focus radius.
MATCH_RTOL = 1e-9


@dataclass
class AxisymmetricMesh:
    """Linear triangle mesh of the (r, z) half-plane with named groups.

    Attributes
    ----------
    points : ndarray, shape (2, N)
        Node coordinates (r, z) in m.
    triangles : ndarray, shape (3, M)
        Node indices, counter-clockwise.
    lines : ndarray, shape (2, K)
        Boundary and interface line elements.
    subdomains : dict of str to ndarray
        Triangle indices of each meshed body.
    boundaries : dict of str to ndarray
        Line-element indices of each named curve group.
    geometry : AxisymmetricGeometry
        What was meshed.
    """

    points: np.ndarray
    triangles: np.ndarray
    lines: np.ndarray
    subdomains: dict
    boundaries: dict
    geometry: AxisymmetricGeometry
    _skfem: object = field(default=None, repr=False)

    def __post_init__(self):
        # Orient every triangle counter-clockwise (positive area in the (r, z) plane).
        neg = self.signed_areas() < 0
        if neg.any():
            t = self.triangles.copy()
            t[1, neg], t[2, neg] = self.triangles[2, neg], self.triangles[1, neg]
            self.triangles = t

    # --- measures --------------------------------------------------------------------
    @property
    def nelements(self) -> int:
        return self.triangles.shape[1]

    def signed_areas(self) -> np.ndarray:
        p = self.points[:, self.triangles]  # (2, 3, M)
        e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
        return 0.5 * (e1[0] * e2[1] - e1[1] * e2[0])

    def quality(self) -> np.ndarray:
        """Shape quality q = 4 sqrt(3) A / (l1^2 + l2^2 + l3^2) per triangle, in (0, 1]."""
        p = self.points[:, self.triangles]
        l2 = sum(np.sum((p[:, i] - p[:, (i + 1) % 3]) ** 2, axis=0) for i in range(3))
        return 4.0 * np.sqrt(3.0) * np.abs(self.signed_areas()) / l2

    def min_angle_deg(self) -> float:
        p = self.points[:, self.triangles]
        angles = []
        for i in range(3):
            a, b = p[:, (i + 1) % 3] - p[:, i], p[:, (i + 2) % 3] - p[:, i]
            cos = np.sum(a * b, axis=0) / np.linalg.norm(a, axis=0) / np.linalg.norm(b, axis=0)
            angles.append(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
        return float(np.min(angles))

    def contact_nodes(self, name: str) -> np.ndarray:
        """Vertex indices of boundary group ``name`` sorted by r (a straight line z = const)."""
        if name not in self.boundaries:
            raise MeshError(f"no boundary group named {name!r}; have {sorted(self.boundaries)}")
        nodes = np.unique(self.lines[:, self.boundaries[name]])
        return nodes[np.argsort(self.points[0, nodes])]

    def contact_pair(self) -> tuple[str | None, str | None]:
        """Names of the lens and lower-body contact lines (None for a rigid, unmeshed body)."""
        lower = next((n for n in ("contact_pillar", "contact_substrate") if n in self.boundaries),
                     None)
        return ("contact_lens" if "contact_lens" in self.boundaries else None), lower

    # --- checks ----------------------------------------------------------------------
    def check(self) -> None:
        """Raise MeshError unless every body has elements, every triangle has quality above
        MIN_QUALITY and the two contact lines (when both are meshed) match node for node."""
        for body in self.geometry.bodies:
            if len(self.subdomains.get(body, ())) == 0:
                raise MeshError(f"body {body!r} has no elements")
        q = self.quality()
        if not np.all(np.isfinite(q)) or q.min() < MIN_QUALITY:
            k = int(np.nanargmin(q))
            raise MeshError(
                f"mesh quality check failed: triangle {k} has q = {q[k]:.3g} < {MIN_QUALITY} "
                f"(near r = {self.points[0, self.triangles[0, k]]:.3g} m, "
                f"z = {self.points[1, self.triangles[0, k]]:.3g} m)")
        pairs = [self.contact_pair(), ("contact_lens_floor", "contact_floor")]
        for lens, lower in pairs:
            if lens not in self.boundaries or lower not in self.boundaries:
                continue
            a, b = self.contact_nodes(lens), self.contact_nodes(lower)
            tol = MATCH_RTOL * self.geometry.focus_radius_m
            if len(a) != len(b) or np.max(np.abs(self.points[0, a] - self.points[0, b])) > tol:
                raise MeshError(f"contact lines {lens!r} ({len(a)} nodes) and {lower!r} "
                                f"({len(b)} nodes) do not match node for node")

    def summary(self) -> dict:
        q = self.quality()
        return {"nodes": int(self.points.shape[1]), "elements": self.nelements,
                "min_quality": float(q.min()), "min_angle_deg": self.min_angle_deg(),
                "bodies": {k: int(len(v)) for k, v in self.subdomains.items()}}

    # --- conversions -----------------------------------------------------------------
    def to_skfem(self):
        """scikit-fem ``MeshTri`` with the same named subdomains and boundaries (cached)."""
        if self._skfem is None:
            from skfem import MeshTri

            m = MeshTri(np.ascontiguousarray(self.points, dtype=float),
                        np.ascontiguousarray(self.triangles, dtype=np.int64))
            n = m.p.shape[1]
            facet_keys = m.facets.min(axis=0) * n + m.facets.max(axis=0)
            order = np.argsort(facet_keys)
            line_keys = self.lines.min(axis=0) * n + self.lines.max(axis=0)
            pos = np.searchsorted(facet_keys, line_keys, sorter=order)
            facet_of_line = order[np.clip(pos, 0, len(order) - 1)]
            if not np.array_equal(facet_keys[facet_of_line], line_keys):
                raise MeshError("a named line element is not an edge of any triangle")
            m = m.with_subdomains(dict(self.subdomains))
            m = m.with_boundaries({k: facet_of_line[v] for k, v in self.boundaries.items()})
            self._skfem = m
        return self._skfem

    def to_meshio(self):
        """meshio ``Mesh`` with gmsh physical tags and names (3D points, z = 0)."""
        import meshio

        tri_tag = np.zeros(self.nelements, dtype=int)
        line_tag = np.zeros(self.lines.shape[1], dtype=int)
        field_data = {}
        for k, (name, idx) in enumerate(sorted(self.subdomains.items()), start=1):
            tri_tag[idx] = k
            field_data[name] = np.array([k, 2])
        for k, (name, idx) in enumerate(sorted(self.boundaries.items()), start=101):
            line_tag[idx] = k
            field_data[name] = np.array([k, 1])
        pts = np.vstack([self.points, np.zeros(self.points.shape[1])]).T
        return meshio.Mesh(
            pts, [("triangle", self.triangles.T), ("line", self.lines.T)],
            cell_data={"gmsh:physical": [tri_tag, line_tag],
                       "gmsh:geometrical": [tri_tag, line_tag]},
            field_data=field_data)

    def write(self, path) -> None:
        """Write the mesh with meshio (format from the suffix: .msh, .vtu, .xdmf, ...)."""
        from pathlib import Path

        from pillar_xval.outcome import atomic_path

        path = Path(path)
        mesh = self.to_meshio()
        with atomic_path(path, path.suffix) as tmp:
            if path.suffix == ".msh":
                mesh.write(tmp, file_format="gmsh22", binary=False)
            else:
                mesh.write(tmp)
