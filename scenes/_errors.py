"""The toolkit's failure policy: three kinds of failure, each with its own exception and exit
status, and a fourth outcome that is not an exception at all.

=========================  =====================================  ===========
what happened              how it is reported                     CLI exit
=========================  =====================================  ===========
solver missed tolerance    ``ContactResult.converged = False``    1
                           and ``diagnostics["message"]``
bad input                  :class:`InputError` (incl.             2
                           :class:`SceneError`)
scene outside a model      :class:`ScopeError` (an InputError:    2
                           the model refuses it, with the reason)
a tool underneath failed   :class:`ToolError` (gmsh, a linear     3
                           solver, the file system, memory)
=========================  =====================================  ===========

Messages are one line: bad input names the parameter as the user wrote it, its value and the
allowed range; a tool failure names the tool and what it said.
"""

from __future__ import annotations

EXIT_OK = 0
EXIT_NOT_CONVERGED = 1
EXIT_BAD_INPUT = 2
EXIT_TOOL_FAILURE = 3
EXIT_INTERRUPTED = 130


class InputError(ValueError):
    """Bad input: the message names the parameter, its value and the allowed range."""


class SceneError(InputError):
    """Bad scene input (a scene file, a preset or an override)."""


class ScopeError(InputError):
    """A valid scene that a model cannot represent; the message says which model and why."""


class ToolError(RuntimeError):
    """A tool underneath failed (mesher, linear solver, file system, memory); the message says
    which tool and what it reported."""
