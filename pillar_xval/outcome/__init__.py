"""The outcome of a solve, the same for every model: the result schema (:class:`ContactResult`,
:class:`PillarForce`, :mod:`._schema`) with the package version stamped in it, atomic files
that write it and every report (:func:`write_atomic`, :mod:`._files`; with the locks and
non-blocking reads of verified caches), and the memory a solve
may take before it must refuse the scene (:mod:`.memory`).  It imports nothing of the toolkit:
every other package stands on it.
"""

from ._files import (CacheWarning, FileLock, UnusableFile, atomic_path, read_regular,
                     write_atomic)
from ._schema import SCHEMA_VERSION, ContactResult, PillarForce, package_version

__all__ = ["SCHEMA_VERSION", "CacheWarning", "ContactResult", "FileLock", "PillarForce",
           "UnusableFile", "atomic_path", "package_version", "read_regular", "write_atomic"]
