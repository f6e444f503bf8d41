"""fem-3d: the lattice's pi/6 wedge in 3D, every pillar the lens can reach elastic.

:mod:`.driver` (set-up, phases, verdict, result: :func:`solve`, :func:`estimate_memory`),
:mod:`.system` (assembly, mirror planes, PARDISO), :mod:`.contact` (mortar faces),
:mod:`.half_space` (the contact faces' half-space model: the contact CG's preconditioner and
starting point), :mod:`.fields` (stresses and VTU).  Weak forms:
:mod:`fem_reference.forms.solid3d`, their element matrices in closed form:
:mod:`fem_reference.forms.tet_p2`.
"""

from .driver import BLOCK_FACTOR, MODEL, estimate_memory, solve

__all__ = ["BLOCK_FACTOR", "MODEL", "estimate_memory", "solve"]
