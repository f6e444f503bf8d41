"""fem-axisym: the lens on one elastic pillar (or a flat substrate) in (r, z).

:mod:`.driver` (set-up, phases, verdict, result: :func:`solve`, :func:`estimate_memory`),
:mod:`.system` (assembly and factorisation), :mod:`.contact` (the mortar LCP),
:mod:`.fields` (stresses and VTU).  Weak forms: :mod:`fem_reference.forms.axisymmetric`.
"""

from .driver import BLOCK_FACTOR, MODEL, estimate_memory, solve

__all__ = ["BLOCK_FACTOR", "MODEL", "estimate_memory", "solve"]
