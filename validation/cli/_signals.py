"""Ctrl-C and SIGTERM end a command at once, whatever runs: 130 or 143 and one line.

Python runs a signal handler in the main thread between two bytecodes, so a handler that
raises (:class:`Terminated`, ``KeyboardInterrupt``) unwinds a command from Python code at
once: the engine kills its workers, finished cases stay on disk, and :func:`validation.cli.main`
prints the line.  Inside a long call into a library that holds no Python frame (a PARDISO
factorisation, gmsh's optimiser, a BLAS call of minutes) the handler would wait for the call
to return.  So :class:`Watchdog` also hears every signal at the C level, through the
interpreter's wakeup file descriptor, in a thread of its own; when the main thread has not
taken the signal within :data:`GRACE_S`, it prints the same line and ends the process with
the same status.  Nothing is lost by that: case records and caches are written atomically
(a reader sees the old file or the new one), locks are ``flock`` locks that the kernel frees,
and pool workers die with their parent (``PR_SET_PDEATHSIG``).

A handler that runs where Python cannot raise (a ``__del__``, a ctypes callback outside a
gmsh session, which keeps its own: :mod:`meshes._session`) has its exception reported to
``sys.unraisablehook`` and dropped; the watchdog holds that hook and counts such a signal as
not taken, so it ends the process itself instead of the signal being lost.
"""

from __future__ import annotations

import os
import signal
import sys
import threading

from ._exit import EXIT_INTERRUPTED, EXIT_TERMINATED

__all__ = ["GRACE_S", "Terminated", "Watchdog", "final_line"]

# How long the main thread may take to run a signal's handler before the watchdog ends the
# process itself: Python code takes microseconds to reach its next bytecode; a library call
# that has not returned by then may run for minutes.
GRACE_S = 1.0
_STOP = b"\0"


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread: it unwinds like Ctrl-C (the engine kills its
    workers, finished cases stay on disk) and exits 143."""


def final_line(prog: str, signum: int) -> tuple[int, str]:
    """(exit status, the line) of a command that a signal ends."""
    if signum == signal.SIGTERM:
        return EXIT_TERMINATED, f"{prog}: terminated (SIGTERM); finished cases are kept"
    return EXIT_INTERRUPTED, f"{prog}: interrupted"


class Watchdog:
    """Installs the handlers of SIGINT and SIGTERM for one command and ends the process
    when the main thread cannot take a signal (module docstring).  ``prog`` names the
    command in the final line; :meth:`stop` puts the previous handlers back."""

    def __init__(self, prog: str = "pillar-xval"):
        self.prog = prog
        self._taken = threading.Semaphore(0)
        self._previous = {}
        self._wakeup = None
        self._thread = None
        self._hook = sys.unraisablehook
        sys.unraisablehook = self._unraisable
        for signum, handler in ((signal.SIGTERM, self._on_term), (signal.SIGINT, self._on_int)):
            try:
                self._previous[signum] = signal.signal(signum, handler)
            except (ValueError, TypeError):  # not the main thread: Python's own handling
                pass
        if len(self._previous) < 2:
            return
        self._read, self._write = os.pipe()
        os.set_blocking(self._write, False)
        try:
            self._wakeup = signal.set_wakeup_fd(self._write, warn_on_full_buffer=False)
        except ValueError:
            os.close(self._read)
            os.close(self._write)
            return
        self._thread = threading.Thread(target=self._watch, name="signal-watchdog",
                                        daemon=True)
        self._thread.start()

    def _on_term(self, signum, frame):
        self._taken.release()
        raise Terminated()

    def _on_int(self, signum, frame):
        self._taken.release()
        raise KeyboardInterrupt()

    def _unraisable(self, info) -> None:
        if isinstance(info.exc_value, KeyboardInterrupt) and self._thread is not None:
            # A handler's exception, dropped: not taken after all.  Take back what the
            # handler gave the watchdog, or, when it has counted it already, tell it again.
            if not self._taken.acquire(blocking=False):
                signum = signal.SIGTERM if isinstance(info.exc_value, Terminated) \
                    else signal.SIGINT
                os.write(self._write, bytes([signum]))
            return
        self._hook(info)

    def _watch(self) -> None:
        while True:
            try:
                data = os.read(self._read, 64)
            except OSError:
                return
            for signum in data:
                if signum == _STOP[0]:
                    return
                if signum in (signal.SIGINT, signal.SIGTERM) and \
                        not self._taken.acquire(timeout=GRACE_S):
                    status, line = final_line(self.prog, signum)
                    try:
                        os.write(2, f"{line}\n".encode(errors="backslashreplace"))
                    finally:
                        os._exit(status)

    def stop(self) -> None:
        """Put back the previous handlers, hook and wakeup descriptor; end the thread."""
        if sys.unraisablehook == self._unraisable:
            sys.unraisablehook = self._hook
        if self._thread is not None:
            try:
                signal.set_wakeup_fd(self._wakeup)
            except ValueError:
                pass
            os.write(self._write, _STOP)
            self._thread.join(5.0)
            os.close(self._read)
            os.close(self._write)
            self._thread = None
        for signum, handler in self._previous.items():
            if handler is not None:
                signal.signal(signum, handler)
        self._previous = {}
