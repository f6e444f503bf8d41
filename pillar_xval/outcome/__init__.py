"""The outcome of a solve, the same for every model: the result schema (:class:`ContactResult`,
:class:`PillarForce`, :mod:`._schema`) with the package version stamped in it, atomic files
that write it and every report (:func:`write_atomic`, :mod:`._files`), and the memory a solve
may take before it must refuse the scene (:mod:`.memory`).  It imports nothing of the toolkit:
every other package stands on it.
"""

from ._files import atomic_path, write_atomic
from ._schema import (REGIMES, SCHEMA_VERSION, ContactResult, PillarForce, package_version,
                      regime_of)

__all__ = ["REGIMES", "SCHEMA_VERSION", "ContactResult", "PillarForce", "atomic_path",
           "package_version", "regime_of",
           "write_atomic"]
