"""Finite-element references for the lens-on-pillars contact (scikit-fem).

Units: SI in and out (m, Pa, N).  Internally a solve works in units of a length (the pillar
radius or the Hertz radius) and a modulus (the first elastic body's E).

``solve_axisymmetric(scene, mesh_size=1.0, *, vtu_path=None, block_factor=1e5)`` solves a
flat (Hertz) scene or a single-pillar scene with the pillar as an elastic body bonded to the
substrate, Taylor-Hood P2/P1 in (r, z), and exact frictionless contact.
"""

from ._axisym import BLOCK_FACTOR, MODEL, estimate_memory, solve_axisymmetric
from ._system import SolveError

__all__ = ["BLOCK_FACTOR", "MODEL", "SolveError", "estimate_memory", "solve_axisymmetric"]
