"""gmsh meshes of the lens-on-pillar contact.

Units: metres for every length.  The axisymmetric builder meshes the (r, z) half-plane:
a lens block above the contact plane z = 0 (flat bottom; the lens curvature is the gap
function R - sqrt(R^2 - r^2) of the contact model), and below it a pillar bonded to a
substrate block, or a flat substrate.  Groups are named (``lens``, ``pillar``,
``substrate``, ``contact_lens``, ``contact_pillar``, ``contact_substrate``, ``pillar_base``,
``axis``, ``far_lens``, ``far_substrate``, ...) and code uses the names, never numeric tags.
"""

from ._geometry import (BODIES, AxisymmetricGeometry, GeometryError, MeshError, flat_geometry,
                        pillar_geometry)
from ._gmsh import build_axisymmetric_mesh
from ._mesh import MIN_QUALITY, AxisymmetricMesh

__all__ = [
    "BODIES",
    "MIN_QUALITY",
    "AxisymmetricGeometry",
    "AxisymmetricMesh",
    "GeometryError",
    "MeshError",
    "build_axisymmetric_mesh",
    "flat_geometry",
    "pillar_geometry",
]
