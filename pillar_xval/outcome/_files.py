"""Files that can be trusted: atomic writes (a reader never sees half a file, an interrupted
run leaves the old file or the new one: results, reports, caches, VTU fields), locks across
processes, and reads that never block on what is not a regular file."""

from __future__ import annotations

import errno
import fcntl
import os
import secrets
import stat
from contextlib import contextmanager
from pathlib import Path

__all__ = ["CACHE_ENV", "CacheWarning", "FileLock", "UnusableFile", "atomic_path",
           "cache_root", "read_regular",
           "write_atomic"]


# The folder of the toolkit's caches (compliance operators, the machine calibration).
CACHE_ENV = "PILLAR_XVAL_CACHE"


def cache_root(name: str) -> Path:
    """The cache folder ``name`` under ``$PILLAR_XVAL_CACHE`` (default
    ``~/.cache/pillar-xval``); not created here."""
    root = os.environ.get(CACHE_ENV)
    return (Path(root) if root else Path.home() / ".cache" / "pillar-xval") / name


class CacheWarning(UserWarning):
    """A cache file was damaged or foreign (and is rebuilt), or the cache cannot be used
    (the result is computed and returned all the same)."""


class UnusableFile(ValueError):
    """A file that exists but cannot be read as data: not a regular file, or too large."""


@contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = ".tmp"):
    """Yield a fresh temporary path beside ``path`` (ending in ``suffix``, for writers that
    pick the format from it); when the block succeeds it is renamed to ``path``, so a reader
    never sees half a file and an interrupted run leaves the old file or the new one.  When
    the block fails (a full disk, a signal) the temporary file is removed.

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
        if os.path.lexists(tmp):
            os.unlink(tmp)


def write_atomic(path: str | os.PathLike, text: str | bytes) -> Path:
    """Write ``text`` (str or bytes) to ``path`` atomically (see :func:`atomic_path`)."""
    with atomic_path(path) as tmp:
        if isinstance(text, bytes):
            tmp.write_bytes(text)
        else:
            tmp.write_text(text)
    return Path(path)


def read_regular(path: str | os.PathLike, limit: int) -> bytes:
    """The content of ``path`` (a symbolic link is followed) when it is a regular file of at
    most ``limit`` bytes.

    Never blocks: the file is opened non-blocking and checked before anything is read, so a
    FIFO, a device, a socket or a folder at ``path`` raises :class:`UnusableFile` naming what
    it is instead of waiting for a writer or reading forever.  FileNotFoundError when there
    is nothing at ``path`` (or a link that leads nowhere); other OSErrors as ``open`` raises
    them."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        if exc.errno == errno.ENXIO:  # a socket, or a FIFO's other end
            raise UnusableFile("not a regular file (a socket)") from None
        raise
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise UnusableFile(f"not a regular file ({_file_kind(info.st_mode)})")
        if info.st_size > limit:
            raise UnusableFile(f"{info.st_size} bytes, more than the {limit} such a file "
                               "can hold")
        chunks, left = [], limit + 1
        while left > 0:
            block = os.read(fd, min(left, 1 << 20))
            if not block:
                break
            chunks.append(block)
            left -= len(block)
        data = b"".join(chunks)
        if len(data) > limit:  # grew while it was read
            raise UnusableFile(f"more than the {limit} bytes such a file can hold")
        return data
    finally:
        os.close(fd)


def _file_kind(mode: int) -> str:
    for test, name in ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISDIR, "a folder"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a file"


class FileLock:
    """An exclusive advisory lock (``fcntl.flock``) on a lock file, held until
    :meth:`release` or the end of a ``with`` block.  The kernel frees it when its holder
    dies, even by ``kill -9``: no stale lock survives a crash.  A blocking wait is
    interrupted by a signal (Ctrl-C, SIGTERM) like any other system call."""

    def __init__(self, fd: int):
        self._fd: int | None = fd

    @classmethod
    def acquire(cls, path: str | os.PathLike, wait: bool = True) -> "FileLock | None":
        """The lock on ``path`` (the file and its folder created when missing); None when
        ``wait`` is False and another process holds it.  OSError when the lock file cannot
        be created or opened (a read-only folder, a file where the folder should be)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NONBLOCK, 0o644)
        except PermissionError:  # a lock file someone else made, in a folder we only read
            fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC | os.O_NONBLOCK)
        try:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise UnusableFile(f"lock {path}: not a regular file")
            fcntl.flock(fd, fcntl.LOCK_EX | (0 if wait else fcntl.LOCK_NB))
        except BlockingIOError:
            os.close(fd)
            return None
        except BaseException:
            os.close(fd)
            raise
        return cls(fd)

    def release(self) -> None:
        if self._fd is not None:
            try:
                fcntl.flock(self._fd, fcntl.LOCK_UN)
            finally:
                os.close(self._fd)
                self._fd = None

    def __enter__(self) -> "FileLock":
        return self

    def __exit__(self, *exc) -> None:
        self.release()
