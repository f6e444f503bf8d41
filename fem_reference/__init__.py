"""Finite-element references for the lens-on-pillars contact (scikit-fem).

Units: SI in and out (m, Pa, N).  Internally a solve works in units of a length (the pillar
radius or the Hertz radius) and a modulus (the first elastic body's E).

Two models, one subpackage each with the same modules (driver, system, contact, fields) and
the same names (``MODEL``, ``BLOCK_FACTOR``, ``estimate_memory``, ``solve``); both drivers run
the skeleton of :mod:`._driver` (set-up, phase clock, verdict, result):

- :mod:`.axisym` (fem-axisym): ``axisym.solve(scene, mesh_size=1.0, *, vtu_path=None,
  block_factor=1e5)`` solves a flat (Hertz) scene or a single-pillar scene with the pillar as
  an elastic body bonded to the substrate, Taylor-Hood P2/P1 in (r, z), and exact
  frictionless contact;
- :mod:`.solid3d` (fem-3d): ``solid3d.solve(scene, mesh_size=1.0, *, vtu_path=None,
  progress=None, ...)`` solves any pillar scene (zeta < h) or flat scene in 3D on the pi/6
  wedge of the lattice: every pillar the lens can reach, elastic and bonded to the
  substrate, Taylor-Hood P2/P1 tetrahedra, mortar contact solved by constrained conjugate
  gradients through one PARDISO factorisation.

``modal_compliance(PillarKind(h/d, E_p/E_s, nu_p, nu_s), modes, mesh_size)`` gives one
pillar's top compliance by Fourier modes in theta (cached on disk), which the elastic-pillar
BEM maps onto its cells (:mod:`._pillar_compliance`; its verified disk cache:
:mod:`._compliance_store`).

Weak forms: :mod:`.forms`; the reduced-unknown system both assemble: :mod:`._reduced`.
"""

from . import axisym, solid3d
from ._compliance_store import modal_compliance
from ._pillar_compliance import (DEFAULT_MODES, ModalCompliance, PillarKind,
                                 compute_modal_compliance)
from ._reduced import SolveError

__all__ = ["DEFAULT_MODES", "ModalCompliance", "PillarKind", "SolveError", "axisym",
           "compute_modal_compliance", "modal_compliance", "solid3d"]
