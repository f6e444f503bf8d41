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

``modal_compliance(PillarKind(h/d, E_p/E_s, nu_p, nu_s), modes, mesh_size)`` gives one
pillar's top compliance by Fourier modes in theta (cached on disk), which the elastic-pillar
BEM maps onto its cells.
"""

from ._axisym import BLOCK_FACTOR, MODEL, estimate_memory, solve_axisymmetric
from ._pillar_compliance import (DEFAULT_MODES, ModalCompliance, PillarKind,
                                 compute_modal_compliance, modal_compliance)
from ._solid3d import BLOCK_FACTOR_3D, estimate_memory_3d, solve_fem3d
from ._system import SolveError

__all__ = ["BLOCK_FACTOR", "BLOCK_FACTOR_3D", "DEFAULT_MODES", "MODEL", "ModalCompliance",
           "PillarKind", "SolveError", "compute_modal_compliance", "estimate_memory",
           "estimate_memory_3d", "modal_compliance",
           "solve_axisymmetric", "solve_fem3d"]
