"""Finite-element references for the lens-on-pillars contact (scikit-fem).

Units: SI in and out (m, Pa, N).  Internally a solve works in units of a length (the pillar
radius or the Hertz radius) and a modulus (the first elastic body's E).

``solve_axisymmetric(scene, mesh_size=1.0, *, vtu_path=None, block_factor=1e5)`` solves a
flat (Hertz) scene or a single-pillar scene with the pillar as an elastic body bonded to the
substrate, Taylor-Hood P2/P1 in (r, z), and exact frictionless contact.

``solve_fem3d(scene, mesh_size=1.0, *, vtu_path=None, progress=None, ...)`` solves any
pillar scene (zeta < h) or flat scene in 3D on the pi/6 wedge of the lattice: every pillar
the lens can reach, elastic and bonded to the substrate, Taylor-Hood P2/P1 tetrahedra,
mortar contact solved by constrained conjugate gradients through one PARDISO factorisation.
"""

from ._axisym import BLOCK_FACTOR, MODEL, estimate_memory, solve_axisymmetric
from ._solid3d import BLOCK_FACTOR_3D, estimate_memory_3d, solve_fem3d
from ._system import SolveError

__all__ = ["BLOCK_FACTOR", "BLOCK_FACTOR_3D", "MODEL", "SolveError", "estimate_memory",
           "estimate_memory_3d",
           "solve_axisymmetric", "solve_fem3d"]
