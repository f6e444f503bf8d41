"""The disk cache of pillar compliance operators (:mod:`._pillar_compliance`): a trusted store.

One file per operator, ``<cache_dir>/<key>.npz``, ``key`` = :func:`cache_key` of the pillar
kind, the modes, the mesh size and the code that computes it.  Beside the arrays (``r_top``,
``pillar``, ``halfspace``, ``base_moments``) and the build's ``diagnostics``, the file holds
its identity, ``meta``: the format, the key, the kind, the modes, the mesh size, the arrays'
shapes and the SHA-256 of the whole content (:func:`content_hash`).  A file is used only when

- it is a regular file (a FIFO, a device or a folder at the path is never opened for
  reading: nothing blocks) of a plausible size;
- it is a zip of exactly those members, and its identity hashes to its own file name (another
  kind's file copied or linked there does not);
- its arrays have the shapes of the identity, float64 and finite, the top's points rise from
  0 to 1 and every mode matrix is symmetric;
- its content hash matches (a scaled array, a doubled ``r_top``, a zeroed ``halfspace``).

Anything else is rebuilt, with one :class:`~pillar_xval.outcome.CacheWarning` naming the file
and what is wrong with it.  Builds of one key hold an exclusive lock,
``<cache_dir>/.locks/<key>.lock``, across processes (two commands, or two pool workers of one
sweep, build a kind once between them; the second reads the first's file).  Files are written
atomically (a temporary file renamed; on failure it is removed).  A cache folder that cannot
be created, locked or written costs the cache, not the result: the operator is computed and
returned, with a warning.

An operator carries its record in ``diagnostics["operator"]`` (the store, the key, the
content hash), which a result copies into its ``diagnostics["operators"]``, and a
study's cached case is reused only while the cache still holds that operator
(:func:`stored_digest`, read by the engine's case store): after a bad operator is replaced,
the cases computed with it are recomputed.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import math
import os
import re
import warnings
import zipfile
from dataclasses import asdict
from pathlib import Path

import numpy as np

from pillar_xval.outcome import (CacheWarning, FileLock, UnusableFile, cache_root,
                                 read_regular, write_atomic)
from pillar_xval.scenes import InputError

from . import _pillar_compliance as _build
from ._pillar_compliance import (COMPLIANCE_VERSION, DEFAULT_MODES, ModalCompliance, PillarKind,
                                 _source_hash)

__all__ = ["STORE", "cache_dir", "cache_key", "content_hash", "modal_compliance", "stored",
           "stored_digest"]

STORE = "pillar-compliance"   # the store's name in a result's diagnostics["operators"]
STORE_FORMAT = "pillar-xval pillar compliance 1"
ARRAYS = ("r_top", "pillar", "halfspace", "base_moments")
MEMBERS = {f"{name}.npy" for name in (*ARRAYS, "diagnostics", "meta")}
KEY_PATTERN = re.compile(r"[0-9a-f]{20}")
# Points on the pillar's top: 47 at mesh_size 1 (6 modes), about inversely proportional to the
# mesh size (its elements are); a file is refused unread beyond four times that count.
TOP_POINTS_AT_UNIT_MESH = 200


def cache_dir() -> Path:
    """Where compliance operators are cached: $PILLAR_XVAL_CACHE, else
    ~/.cache/pillar-xval/pillar-compliance."""
    return cache_root("pillar-compliance")


def _identity(kind: PillarKind, modes: int, mesh_size: float) -> dict:
    return {"kind": {k: repr(float(v)) for k, v in asdict(kind).items()},
            "modes": int(modes), "mesh_size": repr(float(mesh_size))}


def cache_key(kind: PillarKind, modes: int, mesh_size: float) -> str:
    """20 hex digits of SHA-256 over the kind, the modes, the mesh size, the operator's
    version and its sources' hash: the file name of the operator."""
    payload = json.dumps({**_identity(kind, modes, mesh_size), "version": COMPLIANCE_VERSION,
                          "source": _source_hash()}, sort_keys=True)
    return hashlib.sha256(payload.encode()).hexdigest()[:20]


def content_hash(op: ModalCompliance, diagnostics: str) -> str:
    """SHA-256 of an operator's identity, arrays (dtype, shape and bytes) and diagnostics."""
    h = hashlib.sha256(json.dumps(_identity(op.kind, op.modes, op.mesh_size),
                                  sort_keys=True).encode())
    for name in ARRAYS:
        a = np.ascontiguousarray(getattr(op, name), dtype="<f8")
        h.update(f"\0{name}{a.shape}\0".encode())
        h.update(a.tobytes())
    h.update(diagnostics.encode())
    return h.hexdigest()


def _size_limit(modes: int, mesh_size: float) -> int:
    """The most bytes an operator file of ``modes`` and ``mesh_size`` can take."""
    n = TOP_POINTS_AT_UNIT_MESH / mesh_size
    return int(8 * (2 * (modes + 1) * n * n + 3 * n)) + (1 << 20)


# Diagnostics entries of the cache's own, not stored: whether this read came from the cache,
# and the operator's record (its store, key and content hash).
OWN_ENTRIES = ("cached", "operator")


def _stored_diagnostics(op: ModalCompliance) -> str:
    return json.dumps({k: v for k, v in op.diagnostics.items() if k not in OWN_ENTRIES},
                      sort_keys=True)


def _record(op: ModalCompliance, key: str, digest: str) -> ModalCompliance:
    op.diagnostics["operator"] = {"store": STORE, "key": key, "sha256": digest}
    return op


def _encode(op: ModalCompliance) -> bytes:
    record = op.diagnostics["operator"]
    meta = {"format": STORE_FORMAT, "key": record["key"],
            **_identity(op.kind, op.modes, op.mesh_size),
            "shapes": {name: list(np.shape(getattr(op, name))) for name in ARRAYS},
            "sha256": record["sha256"]}
    buf = io.BytesIO()
    # numpy's stub reads a ** mapping as its allow_pickle flag.
    np.savez(buf, **{name: np.asarray(getattr(op, name), dtype="<f8")  # type: ignore[arg-type]
                     for name in ARRAYS},
             diagnostics=_stored_diagnostics(op), meta=json.dumps(meta, sort_keys=True))
    return buf.getvalue()


class _Unusable(Exception):
    """Why a cache file cannot be used."""


def _decode(data: bytes, key: str, limit: int) -> ModalCompliance:
    """The verified operator of ``data`` (the bytes of file ``key``.npz); _Unusable saying
    what is wrong otherwise (module docstring)."""
    if not data:
        raise _Unusable("empty file")
    try:
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            infos = archive.infolist()
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise _Unusable(f"not a readable archive ({type(exc).__name__}: {exc})") from None
    names = {i.filename for i in infos}
    if names != MEMBERS:
        raise _Unusable(f"not an operator file of this format (members {sorted(names)})")
    if sum(i.file_size for i in infos) > limit:
        raise _Unusable("its members unpack to more than such an operator can hold")
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {name: z[name] for name in ARRAYS}
            meta = json.loads(str(z["meta"]))
            diag_text = str(z["diagnostics"])
            diagnostics = json.loads(diag_text)
    except MemoryError:
        raise
    except Exception as exc:  # any parser failure of a damaged member: the file is unusable
        raise _Unusable(f"unreadable ({type(exc).__name__}: {exc})") from None
    if not isinstance(meta, dict) or meta.get("format") != STORE_FORMAT:
        raise _Unusable("not an operator file of this format")
    try:
        kind = PillarKind(**{k: float(v) for k, v in meta["kind"].items()})
        modes, mesh_size = int(meta["modes"]), float(meta["mesh_size"])
        shapes = {name: tuple(meta["shapes"][name]) for name in ARRAYS}
        recorded = str(meta["sha256"])
    except (InputError, KeyError, TypeError, ValueError, AttributeError) as exc:
        raise _Unusable(f"its identity is damaged ({type(exc).__name__}: {exc})") from None
    if cache_key(kind, modes, mesh_size) != key or meta.get("key") != key:
        raise _Unusable(f"it holds another operator (h/d = {kind.height_over_diameter:g}, "
                        f"E_p/E_s = {kind.modulus_ratio:g}, nu_p = {kind.nu_pillar:g}, "
                        f"nu_s = {kind.nu_substrate:g}, {modes} modes, mesh_size "
                        f"{mesh_size:g}), not the one its name stands for")
    n = len(arrays["r_top"])
    want = {"r_top": (n,), "pillar": (modes + 1, n, n), "halfspace": (modes + 1, n, n),
            "base_moments": (2, n)}
    for name in ARRAYS:
        a = arrays[name]
        if a.dtype != np.float64 or a.shape != want[name] or a.shape != shapes[name]:
            raise _Unusable(f"array {name} is {a.dtype} {a.shape}, expected float64 "
                            f"{want[name]} (recorded {shapes[name]})")
        if not np.all(np.isfinite(a)):
            raise _Unusable(f"array {name} holds non-finite numbers")
    op = ModalCompliance(kind, modes, mesh_size, arrays["r_top"], arrays["pillar"],
                         arrays["halfspace"], diagnostics, arrays["base_moments"])
    if content_hash(op, diag_text) != recorded:
        raise _Unusable("its content does not match its hash (changed after it was written)")
    r = op.r_top
    if n < 3 or n % 2 == 0 or r[0] != 0.0 or abs(r[-1] - 1.0) > 1e-12 or np.any(np.diff(r) <= 0):
        raise _Unusable(f"its top points do not rise from 0 to 1 ({n} points)")
    for name in ("pillar", "halfspace"):
        a = arrays[name]
        if not np.array_equal(a, a.transpose(0, 2, 1)):
            raise _Unusable(f"array {name} is not symmetric")
    return _record(op, key, recorded)


def _read(path: Path, key: str, limit: int) -> tuple[ModalCompliance | None, str]:
    """(operator, '') for a valid file; (None, '') when there is none; (None, why) when the
    file cannot be used."""
    try:
        data = read_regular(path, limit)
    except FileNotFoundError:
        return None, ""
    except UnusableFile as exc:   # a FIFO, a device, a folder, too large
        return None, str(exc)
    except OSError as exc:
        return None, f"cannot be read ({exc})"
    try:
        op = _decode(data, key, limit)
    except _Unusable as exc:
        return None, str(exc)
    op.diagnostics["cached"] = True
    return op, ""


def _check_options(modes, mesh_size) -> None:
    if isinstance(modes, bool) or not isinstance(modes, (int, np.integer)) \
            or not 0 <= modes <= 64:
        raise InputError(f"modes = {modes!r}: allowed range is integers in [0, 64]")
    if isinstance(mesh_size, bool) or not isinstance(mesh_size, (int, float)) \
            or not (math.isfinite(mesh_size) and 0.1 <= mesh_size <= 4.0):
        raise InputError(f"mesh_size = {mesh_size!r}: allowed range is [0.1, 4]")


def _warn(text: str) -> None:
    warnings.warn(f"pillar compliance cache: {text}", CacheWarning, stacklevel=3)


def stored(kind: PillarKind, modes: int = DEFAULT_MODES,
           mesh_size: float = 1.0) -> ModalCompliance | None:
    """The cached operator when the cache holds a valid one; None otherwise (nothing is
    built, nothing warned)."""
    _check_options(modes, mesh_size)
    key = cache_key(kind, modes, mesh_size)
    return _read(cache_dir() / f"{key}.npz", key, _size_limit(modes, mesh_size))[0]


def stored_digest(key: str) -> str | None:
    """The content hash of the valid operator the cache holds under ``key`` now; None when
    it holds none (or a damaged one).  Verified once per file version (path, inode, size,
    modification time) in a process."""
    if not isinstance(key, str) or not KEY_PATTERN.fullmatch(key):
        return None
    path = cache_dir() / f"{key}.npz"
    try:
        info = os.stat(path)
    except OSError:
        return None
    return _digest_of(str(path), key, info.st_ino, info.st_size, info.st_mtime_ns)


@functools.lru_cache(maxsize=256)
def _digest_of(path: str, key: str, inode: int, size: int, mtime_ns: int) -> str | None:
    op, _ = _read(Path(path), key, max(size, 1))
    return None if op is None else op.diagnostics["operator"]["sha256"]


def modal_compliance(kind: PillarKind, modes: int = DEFAULT_MODES, mesh_size: float = 1.0, *,
                     cache: bool = True, progress=None) -> ModalCompliance:
    """The mode matrices of ``kind``: from the disk cache when it holds a valid file (then
    ``diagnostics["cached"]`` is True), else computed and stored (module docstring).
    ``diagnostics["operator"]`` is its record: ``{"store", "key", "sha256"}``.

    Parameters
    ----------
    kind : PillarKind
    modes : int
        Highest Fourier mode n kept; [0, 64].
    mesh_size : float
        Refinement factor of the 2D mesh (0.5 halves every element); [0.1, 4].
    cache : bool
        Read and write the disk cache (False: compute, touch no file).
    progress : callable, optional
        ``progress(text)`` hears of the build's phases and of a wait for another process's.
    """
    _check_options(modes, mesh_size)
    key = cache_key(kind, modes, mesh_size)
    if not cache:
        return _built(kind, modes, mesh_size, progress, key)
    folder = cache_dir()
    path, limit = folder / f"{key}.npz", _size_limit(modes, mesh_size)
    found, why = _read(path, key, limit)
    if found is not None:
        return found
    lock_path = folder / ".locks" / f"{key}.lock"
    try:
        lock = FileLock.acquire(lock_path, wait=False)
        if lock is None:
            if progress:
                progress("another process is building this pillar kind; waiting for it")
            lock = FileLock.acquire(lock_path)
            assert lock is not None  # a waiting acquire returns its lock or raises
    except (OSError, ValueError) as exc:
        _warn(f"the operator is computed, not stored: {folder} cannot be used ({exc})")
        return _built(kind, modes, mesh_size, progress, key)
    try:
        found, why_now = _read(path, key, limit)   # another process may have built it
        if found is not None:
            return found
        why = why_now or why
        if why:
            _warn(f"rebuilding {path}: {why}")
        op = _built(kind, modes, mesh_size, progress, key)
        try:
            write_atomic(path, _encode(op))
        except OSError as exc:
            _warn(f"the operator is used, not stored: cannot store {path} ({exc})")
        return op
    finally:
        lock.release()


def _built(kind, modes, mesh_size, progress, key) -> ModalCompliance:
    op = _build.compute_modal_compliance(kind, modes, mesh_size, progress)
    op.diagnostics["cached"] = False
    return _record(op, key, content_hash(op, _stored_diagnostics(op)))
