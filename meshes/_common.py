"""What the axisymmetric and the 3D sector meshes share: the body names, and the two errors a
mesh builder raises (bad geometry input, exit 2; a failure of gmsh or a mesh check, exit 3)."""

from __future__ import annotations

from pillar_xval.scenes import InputError, ToolError

BODIES = ("lens", "pillar", "substrate")


class MeshError(ToolError):
    """gmsh failed, or a mesh fails its checks: a failure of the tool underneath (exit 3);
    the message says which check."""


class GeometryError(MeshError, InputError):
    """A geometry parameter outside its allowed range: bad input (exit 2), found before gmsh
    runs; the message names the parameter."""
