"""The approach at which a solver under a given indentation carries a given force.

A model that solves only under a given indentation zeta still answers a force-controlled
problem: its force F(zeta) is continuous and never falls as zeta grows (a deeper approach
only adds interpenetration to resolve), so F(zeta) = F_given has a root that a bracket
finds.  :func:`approach_for_force` steps from a guess by Hertz's power law until the root
is bracketed and closes the bracket by Illinois' regula falsi (superlinear on a smooth F; a
bracket on any other).  Each step is a whole
solve, so the models solve force control natively where they can (the solvers of this
package take ``force=``); this serves the rest: a displacement-controlled search that the
force cannot enter (the paper's radius search), the exact active set after a cycle, a model
registered without force control.

References
----------
.. [1] M. Dowell, P. Jarratt, "A modified regula falsi method for computing the root of an
   equation", BIT 11 (1971) 168-174 (the Illinois method).
"""

from __future__ import annotations

__all__ = ["approach_for_force", "solve_at_force"]


def approach_for_force(force_at, force: float, *, guess: float, floor: float = 0.0,
                       rtol: float = 1e-8, max_solves: int = 60):
    """The approach zeta > ``floor`` at which ``force_at(zeta)`` carries ``force``.

    Until the root is bracketed from both sides by solves, each step follows the power law
    F ~ (zeta - floor)^(3/2) (Hertz's, the steepest of the models' laws) through the last
    solve; then Illinois' regula falsi closes the bracket.

    Parameters
    ----------
    force_at : callable
        zeta -> (force, answer): the force carried at approach zeta and what the solve
        returned (kept for the zeta returned).
    force : float
        The given force (> 0).
    guess : float
        A first approach to try (> ``floor``).
    floor : float
        An approach at which no force is carried (first contact); not evaluated.
    rtol : float
        Stop when |F(zeta) - force| <= rtol force.
    max_solves : int
        Give up after this many calls of ``force_at``.

    Returns
    -------
    tuple
        (zeta, answer at zeta, met): ``met`` says whether the force was met within ``rtol``.
    """
    lo, f_lo, hi, f_hi = floor, None, None, None  # f_lo None: the floor, never solved
    zeta, side = guess, 0
    for _ in range(max_solves):
        carried, answer = force_at(zeta)
        f = carried - force
        if abs(f) <= rtol * force:
            return zeta, answer, True
        if f < 0.0:
            lo, f_lo = zeta, f
            side, f_hi = -1, (0.5 * f_hi if side == -1 and f_hi is not None else f_hi)
        else:
            hi, f_hi = zeta, f
            side, f_lo = 1, (0.5 * f_lo if side == 1 and f_lo is not None else f_lo)
        if f_lo is None or f_hi is None:  # one side only: the power law through this solve
            ratio = (force / carried) ** (2.0 / 3.0) if carried > 0.0 else 4.0
            zeta = floor + (zeta - floor) * min(ratio, 4.0)
        else:  # Illinois (the stale end's value halved above)
            zeta = hi - f_hi * (hi - lo) / (f_hi - f_lo)
        if hi is not None and not lo < zeta < hi:  # round-off at a closed bracket: bisect
            zeta = 0.5 * (lo + hi)
    return zeta, answer, False


def solve_at_force(solve, scene, *, guess: float, how: str, rtol: float = 1e-8,
                   max_solves: int = 60):
    """A model's answer to the force-controlled ``scene`` by whole solves under indentations
    (:func:`approach_for_force`): ``solve(scene at an indentation)`` -> its result.

    ``guess`` (m) is the first indentation tried, ``how`` names the solve in a refusal (the
    indentation found beyond the scene's scope: ``scene.implied``).  The result is that of
    the last solve, at the indentation found, as the answer to ``scene``; it says when the
    force was not met within ``rtol`` (``converged`` False, the reason in its message).
    """
    def force_at(zeta):
        result = solve(scene.designed(zeta))
        return result.total_force_N, result

    zeta, result, met = approach_for_force(force_at, scene.force_N, guess=guess, rtol=rtol,
                                           max_solves=max_solves)
    scene.implied(zeta, how)
    if not met:
        result.converged = False
        result.diagnostics["message"] = (
            f"{how} carried {result.total_force_N:.6g} N at its last indentation, not the "
            f"given {scene.force_N:.6g} N within {rtol:g} (after {max_solves} solves)")
    return result.for_force(scene.to_dict(), zeta, force_control="secant over solves")
