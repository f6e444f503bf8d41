"""One gmsh session per mesh: every builder (axisymmetric, sector, the pillar compliance's)
opens it here and hands gmsh its size rule through :func:`set_size_callback`."""

from __future__ import annotations

import sys
from contextlib import contextmanager

from pillar_xval.threads import thread_count

from ._common import MeshError

__all__ = ["gmsh_model", "set_size_callback"]

# The sessions open now (innermost last): where a size callback leaves what it raised.
_SESSIONS: list = []


class _Session:
    """What the size callback raised (a signal's KeyboardInterrupt or SIGTERM, or a bug of a
    size rule): gmsh calls the rule through ctypes, which would print the exception as
    "ignored" and hand gmsh an arbitrary size, so it is kept here and raised when gmsh
    returns.

    Python may run a signal's handler as soon as a callback's first frame starts (gmsh's
    own wrapper of the rule), before any ``try`` of ours: ctypes then reports the exception
    to ``sys.unraisablehook``, which the session holds while it is open (:meth:`hook`)."""

    def __init__(self):
        self.raised: BaseException | None = None
        self._previous = None

    def reraise(self) -> None:
        if self.raised is not None:
            exc, self.raised = self.raised, None
            raise exc

    def hook(self) -> None:
        """Take ``sys.unraisablehook`` until :meth:`unhook`."""
        self._previous = sys.unraisablehook
        sys.unraisablehook = self._unraisable

    def unhook(self) -> None:
        if sys.unraisablehook == self._unraisable:
            sys.unraisablehook = self._previous

    def _unraisable(self, info) -> None:
        if "ctypes callback" in (info.err_msg or "") and info.exc_value is not None:
            if self.raised is None:
                self.raised = info.exc_value
            return
        self._previous(info)


@contextmanager
def gmsh_model(name: str, what: str):
    """A fresh gmsh model named ``name`` (gmsh initialised here unless a caller already did,
    and finalised, or the model removed, on the way out), meshing on
    :func:`pillar_xval.threads.thread_count` threads; a gmsh failure becomes a MeshError
    naming ``what``.  What a size callback raised (:func:`set_size_callback`) is raised
    instead, unchanged, and the half-made mesh is dropped with the model."""
    import gmsh

    owner = not gmsh.isInitialized()
    if owner:
        # interruptible=False: gmsh must not install a SIGINT handler (threads, pytest).
        gmsh.initialize(interruptible=False)
        _restore_python_handlers()
    session = _Session()
    _SESSIONS.append(session)
    session.hook()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        # gmsh's OpenMP threads: 3D meshing follows the count (0: General.NumThreads).  Curves
        # and surfaces stay on one thread: meshed in parallel, they come out in a different
        # order on every run (measured: three runs on 2 threads gave three different meshes
        # of the Phi = 0.2 wedge at mesh_size 4, sigma0 2e-3 apart); 3D on 2 threads gives
        # the 1-thread mesh, node for node (tests/test_threads.py).
        gmsh.option.setNumber("General.NumThreads", thread_count())
        gmsh.option.setNumber("Mesh.MaxNumThreads1D", 1)
        gmsh.option.setNumber("Mesh.MaxNumThreads2D", 1)
        gmsh.option.setNumber("Mesh.MaxNumThreads3D", 0)
        gmsh.model.add(name)
        yield gmsh
        session.reraise()
    except MeshError:
        session.reraise()
        raise
    except Exception as exc:  # gmsh raises plain Exception with its own message
        session.reraise()
        raise MeshError(f"gmsh could not mesh {what}: {exc}") from exc
    finally:
        session.unhook()
        _SESSIONS.remove(session)
        if owner:
            gmsh.finalize()
        else:
            gmsh.model.remove()


def set_size_callback(gmsh, size) -> None:
    """Give gmsh the size rule ``size(dim, tag, x, y, z, lc)`` of the open session.

    An exception inside the rule or on its way in (Ctrl-C or SIGTERM arrives while gmsh
    meshes, since Python runs its signal handlers in the callback) is kept by the session
    and the rule answers 0 from then on: gmsh stops meshing at its next size ("Wrong mesh
    element size lc = 0"), and :func:`gmsh_model` raises the kept exception in place of
    gmsh's error."""
    session = _SESSIONS[-1]

    def guarded(dim, tag, x, y, z, lc):
        if session.raised is not None:
            return 0.0
        try:
            return size(dim, tag, x, y, z, lc)
        except BaseException as exc:  # kept, and raised when gmsh returns
            session.raised = exc
            return 0.0

    gmsh.model.mesh.setSizeCallback(guarded)


def _restore_python_handlers() -> None:
    """gmsh's initialize installs its own C handler for SIGTERM (it then ends the process
    at once, so the CLI's one-line exit 143 and the engine's clean-up never ran): give the
    signals back to the handlers Python holds for them (main thread only)."""
    import signal

    for signum in (signal.SIGTERM, signal.SIGINT):
        handler = signal.getsignal(signum)
        if handler is None:
            continue
        try:
            signal.signal(signum, handler)
        except ValueError:  # not the main thread: Python cannot set handlers there
            pass
