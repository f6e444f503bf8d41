"""What the planner knows about a scene before solving it: its regime and the dimensionless
features its error and cost models are tabulated against.

Regime (thresholds of [P], computed by :mod:`pillar_xval.scenes.analytic`):

- ``flat``: no pillars, the Hertz problem;
- ``single``: Phi < Phi_S, one pillar touches.  Phi_S is where the lens, the undeformed
  sphere plus the centre punch's lift ([P] eq. rSzeta, outer root), reaches the inner rim of
  the next ring (:func:`pillar_xval.scenes.analytic.single_pillar_threshold_rim`; [P]'s eq. PhiSrS puts
  that ring's centre there and so counts one pillar where its rim already touches);
- ``multi``: a second pillar touches.  Within it, ``hertz-like`` above Phi_H and
  ``transition`` below.  Phi_H is [P]'s fitted value, 0.306 for hard to 0.38 for soft pillars
  (Fig. 4a, zeta = 0.3 um), taken linearly in log10(E_p/E_l) between 1e6 and 1e-3 and
  clamped; [P] finds it falls as zeta/h grows (Fig. 7b), so it labels the regime only: the
  planner's choice rests on measured errors, never on Phi_H.

Features (every one dimensionless, so tables measured on the paper's scenes apply to any
scene with the same values):

============== ==========================================================================
``w``          share of the half-spaces in the compliance of one pillar in contact,
               (gamma_l + gamma_s) / gamma*; 1 for rigid pillars (and flat scenes)
``log_phi_s``  log10(Phi / Phi_S): how deep in the multi-pillar regime (< 0: one pillar)
``phi``        Phi itself
``log_sag``    log10(d^2 / (8 R zeta)): lens curvature across a pillar top over zeta
``log_ep``     log10(E_p / E_l), rigid pillars 12
``log_es``     log10(E_s / E_l), rigid substrate 12
``c_p``        E_l / (E_l + E_p): the pillar's share of the two moduli's compliance, 0 for
               rigid pillars, 1/2 at E_p = E_l, 1 for pillars infinitely softer than the
               lens
``c_s``        E_l / (E_l + E_s), the same for the substrate
``es_share``   log10(E_s / E_l) / log10(E_p / E_l): where the substrate sits between the
               lattice study's two conventions, 0 at E_s = E_l and 1 at the paper's
               E_s = E_p (0 where E_p = E_l, when the two coincide)
``aspect``     h / d
``log_zeta_r`` log10(zeta / R)
============== ==========================================================================

The stiffness axes of the tables that vary E_p and E_s (the Hooke pillar's error, the
lattice studies' tables) are ``c_p`` and ``c_s``, not the log ratios.  A model error that
comes from the pillar's (or substrate's) compliance is regular in that compliance at both
ends: it tends to its rigid value as c_p -> 0 (for E_p >> E_l, as E_l / E_p) and to its
soft value as c_p -> 1.  Linear interpolation in c_p follows that law between stiffness
decades, where linear interpolation in log10(E_p / E_l) does not: the lattice study's Hooke
error of sigma0 falls from -10.6 % at E_p = 10 E_l to -1.2 % at 100 E_l and 0.09 % at 1e6 E_l
(Phi = 0.1, zeta = 0.05 um, E_s = E_p), and a straight line in the log ratio from 10 to 1e6
misses the node at 100 by 7.2 points, one in c_p by 0.17.  The tables' leave-one-out margins
(the planner's safety term, :mod:`.tables`) shrink with it: the lattice Hooke table's median
margin of sigma0 from 1.4 % to 0.5 %.

References
----------
.. [P] R. Ledesma-Alonso et al., "Stress concentration in periodically rough hertzian
   contact: Hertz to soft-flat-punch transition" (the seed paper).
"""

from __future__ import annotations

import math

from pillar_xval.scenes import Scene, analytic
from pillar_xval.scenes.floor import floor_onset_bound, floor_reachable

__all__ = ["FEATURES", "PHI_H_HARD", "PHI_H_SOFT", "REGIMES", "features", "phi_h", "regime",
           "scope_refusal"]

# [P] Fig. 4a: Phi_H from 0.306 (hard, E_p/E_l = 1e6) to 0.38 (soft, 1e-3) at zeta = 0.3 um.
PHI_H_HARD, PHI_H_SOFT = 0.306, 0.38
LOG_RATIO_RIGID = 12.0  # log10 of a modulus ratio standing for a rigid body


def _compliance_share(E: float, E_lens: float) -> float:
    """E_lens / (E_lens + E), with a rigid body (inf) as 0 and a rigid lens as 1."""
    if math.isinf(E):
        return 0.0
    if math.isinf(E_lens):
        return 1.0
    return E_lens / (E_lens + E)


def _log_ratio(E: float, E_lens: float) -> float:
    if math.isinf(E):
        return LOG_RATIO_RIGID
    if math.isinf(E_lens):
        return -LOG_RATIO_RIGID
    return max(-LOG_RATIO_RIGID, min(LOG_RATIO_RIGID, math.log10(E / E_lens)))


def phi_h(scene: Scene) -> float:
    """[P]'s Hertz-like threshold for the scene's stiffness ratio (see the module docstring)."""
    x = _log_ratio(scene.pillars.material.E_Pa, scene.lens.material.E_Pa)
    t = min(1.0, max(0.0, (6.0 - x) / 9.0))  # 0 at E_p/E_l = 1e6, 1 at 1e-3
    return PHI_H_HARD + t * (PHI_H_SOFT - PHI_H_HARD)


# The regimes' names (:func:`regime`), which a model's declared scopes list.
REGIMES = ("flat", "single", "multi")


def regime(scene: Scene) -> dict:
    """The scene's regime: ``name`` (flat, single, multi, or mixed where the lens can reach
    the floor between the pillars), ``label`` (flat, single pillar, transition, hertz-like;
    mixed ...), the thresholds and one sentence saying why."""
    if scene.is_flat:
        return {"name": "flat", "label": "flat (Hertz problem)", "phi": None, "phi_s": None,
                "phi_h": None, "why": "no pillars: a sphere on a flat substrate"}
    phi = scene.pillars.surface_fraction
    phi_s = analytic.single_pillar_threshold_rim(scene)
    ph = phi_h(scene)
    if phi < phi_s:
        name, label = "single", "single pillar"
        why = (f"Phi = {phi:.4g} < Phi_S = {phi_s:.4g} (eq. rSzeta, at the next ring's rim): "
               "one pillar touches")
    elif phi >= ph:
        name, label = "multi", "hertz-like"
        why = (f"Phi = {phi:.4g} >= Phi_H = {ph:.3g} ([P] Fig. 4a fit): many pillars touch, "
               "the lens meets a near-continuum")
    else:
        name, label = "multi", "transition"
        why = f"Phi_S = {phi_s:.4g} <= Phi = {phi:.4g} < Phi_H = {ph:.3g}: several pillars touch"
    if floor_reachable(scene):
        name, label = "mixed", f"mixed ({label} and the floor)"
        why += (f"; zeta = {scene.indentation_m * 1e6:.4g} um > h + g(d/2) = "
                f"{floor_onset_bound(scene) * 1e6:.4g} um: the lens can reach the floor "
                "between the pillars")
    return {"name": name, "label": label, "phi": phi, "phi_s": phi_s, "phi_h": ph, "why": why}


def scope_refusal(model: str, scene: Scene) -> str | None:
    """Why ``model`` does not apply to ``scene`` by the regimes its declaration gives
    (``Model.scopes``: fem-axisym on flat scenes and one pillar, the spring model on one
    pillar, Hertz off the single-pillar regime), or None where it applies or declares none.
    The same regimes the planner chooses by, so a spec is refused before anything is solved
    where the model itself would refuse the scene."""
    from ..registry import MODELS

    declared = MODELS.get(model)
    if declared is None or not declared.scopes or set(declared.scopes) >= set(REGIMES):
        return None  # no regime to compute (a root solve for Phi_S: ~1 ms a scene)
    reg = regime(scene)
    if reg["name"] in declared.scopes:
        return None
    return (f"{model} applies to {', '.join(declared.scopes)} scenes; this one is "
            f"{reg['label']} ({reg['why']}); {model}: {declared.scope_note}")


def features(scene: Scene, reg: dict | None = None) -> dict:
    """The features of the module docstring (those that apply: a flat scene has no pillar
    features)."""
    reg = reg or regime(scene)
    E_l = scene.lens.material.E_Pa
    out = {"log_es": _log_ratio(scene.substrate.E_Pa, E_l),
           "c_s": _compliance_share(scene.substrate.E_Pa, E_l),
           "log_zeta_r": math.log10(scene.indentation_m / scene.lens.radius_m), "w": 1.0}
    if scene.is_flat:
        return out
    p = scene.pillars
    gamma_star = analytic.effective_compliance(scene)
    out.update({
        "w": scene.half_space_compliance / gamma_star if gamma_star > 0 else 1.0,
        "log_phi_s": math.log10(p.surface_fraction / reg["phi_s"]),
        "phi": p.surface_fraction,
        "log_sag": math.log10(p.diameter_m**2 / (8.0 * scene.lens.radius_m
                                                 * scene.indentation_m)),
        "log_ep": _log_ratio(p.material.E_Pa, E_l),
        "c_p": _compliance_share(p.material.E_Pa, E_l),
        "aspect": p.height_m / p.diameter_m,
    })
    out["es_share"] = out["log_es"] / out["log_ep"] if abs(out["log_ep"]) > 1e-9 else 0.0
    return out


FEATURES = ("w", "log_phi_s", "phi", "log_sag", "log_ep", "log_es", "c_p", "c_s", "es_share",
            "aspect", "log_zeta_r")
