"""The 3D meshes of a lattice sector (the pi/6 wedge): :mod:`.geometry` (the pillars in the
sector, sizes, grading), :mod:`.gmsh` (the builder), :mod:`.mesh` (the mesh, its named groups
and checks)."""
