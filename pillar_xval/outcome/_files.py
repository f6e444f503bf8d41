"""Atomic files: a reader never sees half a file, an interrupted run leaves the old file or
the new one (results, reports, caches, VTU fields)."""

from __future__ import annotations

import os
import secrets
from contextlib import contextmanager
from pathlib import Path

__all__ = ["atomic_path", "write_atomic"]


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = ".tmp"):
    """Yield a fresh temporary path beside ``path`` (ending in ``suffix``, for writers that
    pick the format from it); when the block succeeds it is renamed to ``path``, so a reader
    never sees half a file and an interrupted run leaves the old file or the new one.

    The temporary file is created with mode 0666 filtered by the process umask, as ``open``
    would create ``path`` itself (``tempfile.mkstemp`` would make every file 0600)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    while True:
        tmp = path.parent / f".{path.name}.{secrets.token_hex(6)}{suffix}"
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
            break
        except FileExistsError:
            continue
    try:
        yield tmp
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_atomic(path: str | os.PathLike, text: str | bytes) -> Path:
    """Write ``text`` (str or bytes) to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        if isinstance(text, bytes):
            tmp.write_bytes(text)
        else:
            tmp.write_text(text)
    return Path(path)
