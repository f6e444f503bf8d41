"""One gmsh session per mesh: both builders (axisymmetric and sector) open it here."""

from __future__ import annotations

from contextlib import contextmanager

from pillar_xval.threads import thread_count

from ._common import MeshError

__all__ = ["gmsh_model"]


@contextmanager
def gmsh_model(name: str, what: str):
    """A fresh gmsh model named ``name`` (gmsh initialised here unless a caller already did,
    and finalised, or the model removed, on the way out), meshing on
    :func:`pillar_xval.threads.thread_count` threads; a gmsh failure becomes a MeshError
    naming ``what``."""
    import gmsh

    owner = not gmsh.isInitialized()
    if owner:
        # interruptible=False: gmsh must not install a SIGINT handler (threads, pytest).
        gmsh.initialize(interruptible=False)
        _restore_python_handlers()
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
    except MeshError:
        raise
    except Exception as exc:  # gmsh raises plain Exception with its own message
        raise MeshError(f"gmsh could not mesh {what}: {exc}") from exc
    finally:
        if owner:
            gmsh.finalize()
        else:
            gmsh.model.remove()


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
