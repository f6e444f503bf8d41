"""The toolkit's failure policy: three kinds of failure, each with its own exception, and a
fourth outcome that is not an exception at all (the CLI's exit status of each:
:mod:`validation.cli._exit`).

=========================  =====================================
what happened              how it is reported
=========================  =====================================
solver missed tolerance    ``ContactResult.converged = False``
                           and ``diagnostics["message"]``
bad input                  :class:`InputError` (incl.
                           :class:`SceneError`)
scene outside a model      :class:`ScopeError` (an InputError:
                           the model refuses it, with the reason)
a tool underneath failed   :class:`ToolError` (gmsh, a linear
                           solver, the file system, memory)
=========================  =====================================

Messages are one line: bad input names the parameter as the user wrote it, its value and the
allowed range; a tool failure names the tool and what it said.
"""

from __future__ import annotations

import math

class InputError(ValueError):
    """Bad input: the message names the parameter, its value and the allowed range."""


class SceneError(InputError):
    """Bad scene input (a scene file, a preset or an override)."""


class ScopeError(InputError):
    """A valid scene that a model cannot represent; the message says which model and why."""


class ToolError(RuntimeError):
    """A tool underneath failed (mesher, linear solver, file system, memory); the message says
    which tool and what it reported."""


def show(value) -> str:
    """A value as an error message prints it: exactly (``repr`` of a float, so 0.5000001 never
    reads as 0.5), as TOML writes booleans, one line, and at most about 60 characters (a
    400-digit integer is shown by its ends and its length)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        try:
            text = str(value)
        except ValueError:  # beyond Python's int-to-str digit limit
            return f"an integer of about {int(value.bit_length() * math.log10(2))} digits"
        if len(text) > 24:
            return f"{text[:8]}...{text[-4:]} (a {len(text.lstrip('-'))}-digit integer)"
        return text
    text = repr(value)
    return text if len(text) <= 60 else f"{text[:40]}... ({type(value).__name__})"


def show_amount(x: float) -> str:
    """A bound or a derived amount in a message: 12 significant digits, with an exponent from
    1e5 up (``1e+09``, not ``1000000000``)."""
    text = f"{x:.12g}"
    if "e" in text or not 1e5 <= abs(x) < math.inf:
        return text
    mantissa, exponent = f"{x:.11e}".split("e")
    return f"{mantissa.rstrip('0').rstrip('.')}e{exponent}"
