"""The axisymmetric (r, z) meshes: :mod:`.geometry` (bodies, sizes, grading), :mod:`.gmsh`
(the builder), :mod:`.mesh` (the mesh, its named groups and checks)."""
