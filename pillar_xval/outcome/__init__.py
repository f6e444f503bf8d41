"""The outcome of a solve, the same for every model: the result schema (:class:`ContactResult`,
:class:`PillarForce`, :mod:`._schema`) with the package version stamped in it, atomic files
that write it and every report (:func:`write_atomic`, :mod:`._files`; with the locks and
non-blocking reads of verified caches), and the memory a solve
may take before it must refuse the scene (:mod:`.memory`).  It imports nothing of the toolkit:
every other package stands on it.
"""

from ._files import (CACHE_ENV, CacheWarning, FileLock, UnusableFile, atomic_path, cache_root,
                     read_regular, write_atomic)
from ._schema import (PILLAR_LABELS, REGIMES, SCHEMA_VERSION, ContactResult, PillarForce,
                      model_label, package_version, regime_of)

__all__ = ["CACHE_ENV", "PILLAR_LABELS", "REGIMES", "SCHEMA_VERSION", "CacheWarning",
           "ContactResult", "FileLock", "PillarForce", "UnusableFile", "atomic_path",
           "cache_root", "model_label", "package_version", "read_regular", "regime_of",
           "write_atomic"]
