"""Thresholds of the contact regimes: the paper's closed forms and the exact solver's.

Single-pillar threshold Phi_S (the largest Phi at which one pillar alone touches the lens):

- [P] eqs. rSzeta and PhiSrS: r_S is the radius at which the lens, pushed by the centre
  pillar's flat-punch field, just touches the plane of the pillar tops; [P] then sets the
  pitch e_S = r_S.  But the second ring of pillars first touches at its inner rim, a distance
  e - d/2 from the centre: the pitch at the threshold is e_S = r_S + d/2
  (:func:`single_pillar_threshold_rim`), which lowers Phi_S by a factor
  (r_S / (r_S + d/2))^2 (0.89 at zeta = 0.3 um).
- :func:`bisect_single_pillar`: the largest Phi with one pillar in contact, bisected in
  log Phi on the exact contact solver (dense BEM, complementarity on every element), every
  (zeta, E_p/E_l) in lockstep so each round is one batch on the engine.  The first contact of
  the ring is resolved to the collocation point of its innermost element, within half an
  element of the rim, so the bisected Phi_S sits at most (d/P) / e_S above the continuum one
  (relative, 1.2 % at zeta = 0.05 um and P = 21).

References
----------
.. [P] R. Ledesma-Alonso et al. (the seed paper), Discussion, eqs. rSzeta, PhiSrS.
.. [J] K. L. Johnson, Contact Mechanics, 1985, eq. 3.37 (surface outside a flat punch).
"""

from __future__ import annotations

import functools
import math

from pillar_xval.scenes import PHI_CLOSE_PACKING, analytic
from pillar_xval.scenes.analytic import rim_contact_radius, single_pillar_threshold_rim

from ...engine import Case, Engine
from .scenes import table1_scene

__all__ = ["analytic_thresholds", "bisect_single_pillar", "rim_contact_radius",
           "single_pillar_threshold_rim"]

# A bracket [guess / BRACKET, guess * BRACKET] around the closed-form estimate; widened by
# this factor again while it does not hold the threshold.
BRACKET = 1.15


@functools.lru_cache(maxsize=1024)
def analytic_thresholds(zeta_um: float, ratio: float) -> dict:
    """The closed forms at one (zeta, E_p/E_l): [P]'s Phi_S (eqs. rSzeta, PhiSrS), its
    large-zeta limit, the rim-corrected Phi_S, zeta_T / h and the limiting centre pressures
    sigma_0H (eq. S0Hertz) and sigma_0S (eq. S0SFP), in Pa."""
    scene = table1_scene(0.01, zeta_um, ratio)  # Phi does not enter these formulas
    h = scene.pillars.height_m
    return {"zeta_um": zeta_um, "ratio": ratio,
            "phi_s_paper": analytic.single_pillar_threshold(scene),
            "phi_s_large_zeta": analytic.single_pillar_threshold_large_indentation(scene),
            "phi_s_rim": single_pillar_threshold_rim(scene),
            "zeta_t_over_h": analytic.threshold_indentation(scene) / h,
            "sigma0_hertz_Pa": analytic.hertz(scene).centre_pressure,
            "sigma0_single_Pa": analytic.spring_model(scene).centre_pressure}


def _one_pillar(outcome) -> bool:
    result = outcome.unwrap()
    if not result.converged:
        raise RuntimeError(f"threshold bisection: a solve did not converge "
                           f"({result.diagnostics.get('message', '')})")
    return result.pillars_in_contact <= 1


def bisect_single_pillar(points: list[tuple[float, float]], engine: Engine, folder,
                         elements_per_diameter: int, steps: int,
                         options: dict | None = None) -> list[dict]:
    """Largest Phi with one pillar in contact at each (zeta_um, ratio) of ``points``.

    Each bracket [lo, hi] (one pillar at lo, more at hi) starts around the rim-corrected
    closed form and is halved ``steps`` times in log Phi; the answer is its geometric middle,
    uncertain by the returned ``rel_halfwidth``.  ``options``: the dense BEM's other options
    (``{"pillars": "elastic"}`` bisects with elastic pillars).  Returns one dict per point:
    ``phi_s``, ``lo``, ``hi``, ``rel_halfwidth``, ``solves``.
    """
    close = PHI_CLOSE_PACKING
    state = []
    for zeta_um, ratio in points:
        guess = single_pillar_threshold_rim(table1_scene(0.01, zeta_um, ratio))
        state.append({"zeta_um": zeta_um, "ratio": ratio, "lo": guess / BRACKET,
                      "hi": min(guess * BRACKET, close), "lo_ok": False, "hi_ok": False,
                      "solves": 0})
    opts = {**(options or {}), "elements_per_diameter": int(elements_per_diameter)}
    pillars = opts.get("pillars", "hooke")

    def run(which: list[tuple[dict, float]]) -> list[bool]:
        cases = [Case("bem", table1_scene(phi, s["zeta_um"], s["ratio"]), opts,
                      tag=f"Phi_S bisection zeta={s['zeta_um']:g} ratio={s['ratio']:g} "
                          f"Phi={phi:.5g}" + ("" if pillars == "hooke" else f" {pillars} pillars"))
                 for s, phi in which]
        for s, _ in which:
            s["solves"] += 1
        return [_one_pillar(o) for o in engine.run(cases, folder, label="threshold")]

    # Make every bracket hold the threshold: one pillar at lo, more at hi.
    for _ in range(12):
        todo = [(s, s["lo"]) for s in state if not s["lo_ok"]] + \
               [(s, s["hi"]) for s in state if not s["hi_ok"]]
        if not todo:
            break
        for (s, phi), single in zip(todo, run(todo)):
            if phi == s["lo"] and not s["lo_ok"]:
                if single:
                    s["lo_ok"] = True
                else:
                    s["hi"], s["hi_ok"], s["lo"] = s["lo"], True, s["lo"] / BRACKET
            elif phi == s["hi"]:
                if not single:
                    s["hi_ok"] = True
                elif s["hi"] >= close:
                    s["hi_ok"] = s["never"] = True  # one pillar up to close packing
                else:
                    s["lo"], s["lo_ok"], s["hi"] = s["hi"], True, min(s["hi"] * BRACKET, close)
    for _ in range(int(steps)):
        todo = [(s, math.sqrt(s["lo"] * s["hi"])) for s in state if not s.get("never")]
        if not todo:
            break
        for (s, mid), single in zip(todo, run(todo)):
            if single:
                s["lo"] = mid
            else:
                s["hi"] = mid
    return [{"zeta_um": s["zeta_um"], "ratio": s["ratio"],
             "phi_s": close if s.get("never") else math.sqrt(s["lo"] * s["hi"]),
             "lo": s["lo"], "hi": s["hi"],
             "rel_halfwidth": math.sqrt(s["hi"] / s["lo"]) - 1.0, "solves": s["solves"]}
            for s in state]
