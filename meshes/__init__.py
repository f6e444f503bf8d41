"""gmsh meshes of the lens-on-pillar contact.

Units: metres for every length.  The axisymmetric builder meshes the (r, z) half-plane:
a lens block above the contact plane z = 0 (flat bottom; the lens curvature is the gap
function R - sqrt(R^2 - r^2) of the contact model), and below it a pillar bonded to a
substrate block, or a flat substrate.  Groups are named (``lens``, ``pillar``,
``substrate``, ``contact_lens``, ``contact_pillar``, ``contact_substrate``, ``pillar_base``,
``axis``, ``far_lens``, ``far_substrate``, ...) and code uses the names, never numeric tags.
The 3D builder meshes a sector 0 <= theta <= alpha of the lattice centred on pillar (0, 0)
(alpha = pi/6, the D6 primitive wedge) with tetrahedra: lens block, the pillars the lens can
reach, substrate block, with per-pillar groups (``contact_pillar_{n}_{m}``, ...).
One subpackage per geometry with the same modules (geometry, gmsh, mesh): :mod:`.axisym`,
:mod:`.wedge`; the body names and errors both raise: :mod:`._common`.
"""

from ._common import BODIES, GeometryError, MeshError
from .axisym.geometry import MESH_SIZE_RANGE, AxisymmetricGeometry, flat_geometry, pillar_geometry
from .axisym.gmsh import build_axisymmetric_mesh
from .axisym.mesh import MIN_QUALITY, AxisymmetricMesh
from .wedge.geometry import (MESH_SIZE_RANGE_3D, SECTORS, SectorPillar, WedgeGeometry,
                             floor_clear_of_pillars, sector_pillars)
from .wedge.gmsh import build_wedge_mesh
from .wedge.mesh import MIN_QUALITY_3D, WedgeMesh

__all__ = [
    "BODIES",
    "MESH_SIZE_RANGE",
    "MESH_SIZE_RANGE_3D",
    "MIN_QUALITY",
    "MIN_QUALITY_3D",
    "SECTORS",
    "SectorPillar",
    "WedgeGeometry",
    "WedgeMesh",
    "AxisymmetricGeometry",
    "AxisymmetricMesh",
    "GeometryError",
    "MeshError",
    "build_axisymmetric_mesh",
    "build_wedge_mesh",
    "floor_clear_of_pillars",
    "flat_geometry",
    "pillar_geometry",
    "sector_pillars",
]
