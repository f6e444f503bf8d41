"""Finite-element references for the lens-on-pillars contact (scikit-fem).

Units: SI in and out (m, Pa, N).  Internally a solve works in units of a length (the pillar
radius or the Hertz radius) and a modulus (the first elastic body's E).

``axisym.solve(scene, mesh_size=1.0, *, vtu_path=None, block_factor=1e5)`` (fem-axisym) solves a
flat (Hertz) scene or a single-pillar scene with the pillar as an elastic body bonded to the
substrate, Taylor-Hood P2/P1 in (r, z), and exact frictionless contact.

``solid3d.solve(scene, mesh_size=1.0, *, vtu_path=None, progress=None, ...)`` (fem-3d) solves any
pillar scene (zeta < h) or flat scene in 3D on the pi/6 wedge of the lattice: every pillar
the lens can reach, elastic and bonded to the substrate, Taylor-Hood P2/P1 tetrahedra,
mortar contact solved by constrained conjugate gradients through one PARDISO factorisation.
"""

from . import axisym, solid3d
from ._reduced import SolveError

__all__ = ["SolveError", "axisym", "solid3d"]
