"""The elastic-pillar BEM's accuracy targets against an FEM with elastic pillars, and the one
rule that judges a difference against them (:func:`judge`): the lattice study's verdicts and
``compare``'s pass or fail.

F_T within 1 %, sigma0 within 3 %, every lattice ring's force within 2 %, the pillar-top
pressure within 5 % for r < 0.9 d/2 (the last tenth of a stiff pillar's top carries its edge
singularity); or within both models' numerical bands (GCI) where those are wider.  The
lattice study measured the elastic BEM within them on its 20 scenes (PHYSICS.md).
"""

from __future__ import annotations

__all__ = ["TARGETS", "TARGET_RULE", "judge"]

TARGETS = {"F_T": 0.01, "sigma0": 0.03, "rings": 0.02, "profile": 0.05}
TARGET_RULE = ("|(elastic BEM - FEM) / FEM| within the target, or within both GCI bands "
               "(over |FEM|) where the bands are wider; FEM and BEM as Richardson estimates")


def judge(value, band, reference, reference_band, target: float) -> dict:
    """One target: ``error`` = (value - reference) / reference; ``allowed`` = the target, or
    both bands over |reference| where they are wider; ``met`` = |error| <= allowed.  A
    reference of 0 is met when |value| is within both bands; a missing value is not judged
    (``met`` None)."""
    out = {"target": target, "error": None, "allowed": None, "met": None}
    if any(v is None for v in (value, band, reference, reference_band)):
        return out
    if reference == 0:
        out["met"] = bool(abs(value) <= band + reference_band)
        return out
    error = (value - reference) / reference
    allowed = max(target, (band + reference_band) / abs(reference))
    out.update(error=error, allowed=allowed, met=bool(abs(error) <= allowed))
    return out
