"""Closed forms as models: ``solve_hertz`` and ``solve_spring`` return a
:class:`~pillar_xval.outcome.ContactResult` like every numerical model, so the study engine,
``compare`` and the planner treat them alike.

- ``hertz``: the lens on a continuum ([J] sec. 4.2; [P] eq. S0Hertz) with
  gamma = gamma_l + gamma_s.  On a flat substrate it is the Hertz problem itself (exact up to
  the sphere-versus-paraboloid difference, relative O(zeta / R)).  On pillars it is the
  paper's Hertz-like limit for dense lattices (Phi above Phi_H): sigma_0 = sigma_0H,
  F = (2 pi / 3) R zeta sigma_0H, a = sqrt(R zeta) and A = Phi pi a^2 ([P] Fig. 4b); the
  pillars' Hooke compliance is ignored.  Refused when only one pillar touches (Phi < Phi_S).
- ``spring``: the paper's soft-flat-punch model ([P] eq. S0SFP): one Hooke pillar between
  two half-spaces, sigma_0S = 2 zeta / (pi d gamma*), F = d zeta / gamma*, the flat-punch
  profile over the whole pillar top.  Refused when a second pillar touches (Phi >= Phi_S,
  eq. rSzeta at the next ring's rim: ``pillar_xval.scenes.analytic.single_pillar_threshold_rim``) or when the lens curvature across the pillar top, d^2 / (8 R), reaches zeta
  (then the contact covers only part of the top, which the flat punch cannot represent).

Under a given force both invert exactly: Hertz's F = (4/3) sqrt(R) zeta^(3/2) / gamma gives
zeta = (3 F gamma / (4 sqrt R))^(2/3), so a = (3 F R gamma / 4)^(1/3) and sigma_0 =
3 F / (2 pi a^2); the spring model is linear, zeta = F gamma* / d and sigma_0S = 2 F / (pi d^2).
The model is then the same closed form at that indentation, whose scope checks apply there.

How far either is from the truth is not decided here: the planner's error models measure it
(``pillar-xval calibrate``).

References
----------
.. [J] K. L. Johnson, *Contact Mechanics*, Cambridge University Press, 1985.
.. [P] R. Ledesma-Alonso et al., "Stress concentration in periodically rough hertzian
   contact: Hertz to soft-flat-punch transition" (the seed paper).
"""

from __future__ import annotations

import math
import time

import numpy as np

from pillar_xval.outcome import ContactResult, PillarForce
from pillar_xval.scenes import Scene, ScopeError, analytic
from pillar_xval.scenes.lattice import pillars_within

__all__ = ["HERTZ_MODEL", "SPRING_MODEL", "solve_hertz", "solve_spring"]

HERTZ_MODEL = "hertz"
SPRING_MODEL = "spring"
# Profile samples across the pillar top (or the Hertz contact), r / r_ref; the flat-punch
# edge r = d/2 is singular, so the last sample stays short of it.
PROFILE_SAMPLES = np.linspace(0.0, 0.99, 34)
# Pillars listed one by one up to this count; beyond it only their number is given (a lens
# of 1 m on a dense lattice touches millions).
MAX_LISTED_PILLARS = 20_000


def _result(model, scene, started, force, sigma0, radius, area, pillars, forces, r, p,
            note) -> ContactResult:
    return ContactResult(
        model=model, scene=scene.to_dict(), discretisation={"closed_form": note},
        total_force_N=float(force), centre_pressure_Pa=float(sigma0),
        contact_radius_m=float(radius), real_contact_area_m2=float(area),
        pillars_in_contact=int(pillars), pillar_forces=forces, converged=True, iterations=0,
        wall_time_s=time.perf_counter() - started,
        pillar_top_profile={"r_m": [float(v) for v in r], "pressure_Pa": [float(v) for v in p]},
        diagnostics={"message": "closed form", "force_balance_N": 0.0,
                     **({} if scene.is_flat else
                        {"pillars": "hooke" if model == SPRING_MODEL else "none"})})


def _under_force(model: str, scene: Scene, zeta: float, solve) -> ContactResult:
    """``solve`` (the closed form under a given indentation) at ``zeta`` (m), the indentation
    its exact inversion gives for the force of ``scene``."""
    started = time.perf_counter()
    solved = scene.implied(zeta, f"{model}, inverted exactly")
    try:
        result = solve(solved)
    except ScopeError as exc:
        raise ScopeError(f"load.force_uN = {scene.force_N * 1e6:.6g}: implies an indentation "
                         f"of {zeta * 1e6:.4g} um ({model}, inverted exactly): {exc}") from None
    result.wall_time_s = time.perf_counter() - started
    return result.for_force(scene.to_dict(), zeta, force_control="inverted exactly")


def solve_hertz(scene: Scene) -> ContactResult:
    """Hertz contact of the lens on the substrate (flat), or the Hertz-like limit of a dense
    lattice (pillars); see the module docstring.

    Parameters
    ----------
    scene : Scene
        Flat, or with pillars in the multi-pillar regime (Phi >= Phi_S).

    Returns
    -------
    ContactResult
        ``model = "hertz"``; lengths in m, pressures in Pa, forces in N.

    Raises
    ------
    ScopeError
        On pillars where only one pillar touches (Phi < Phi_S), or with a rigid lens on a
        rigid substrate (no compliance).
    """
    started = time.perf_counter()
    if scene.half_space_compliance == 0.0:
        raise ScopeError("hertz: lens and substrate are both rigid; the Hertz contact needs "
                         "an elastic body")
    if scene.force_N is not None:
        zeta = analytic.Hertz.indentation_for_force(scene.force_N, scene.lens.radius_m,
                                                    scene.half_space_compliance)
        return _under_force(HERTZ_MODEL, scene, zeta, solve_hertz)
    h = analytic.hertz(scene)
    a = h.contact_radius
    r = PROFILE_SAMPLES * a
    if scene.is_flat:
        return _result(HERTZ_MODEL, scene, started, h.force, h.centre_pressure, a,
                       h.contact_area, 0, [], r, h.pressure(r), "Hertz ([J] sec. 4.2)")
    phi_s = analytic.single_pillar_threshold_rim(scene)
    phi = scene.pillars.surface_fraction
    if phi < phi_s:
        raise ScopeError(
            f"hertz: pillars.surface_fraction = {phi:.4g} < Phi_S = {phi_s:.4g}: one pillar "
            "touches, the lens does not meet a near-continuum (use the spring model or a BEM)")
    pitch = scene.pillars.pitch_m
    count = analytic.pillars_in_apparent_contact(a, pitch)
    forces = []
    if count <= MAX_LISTED_PILLARS:
        rows = pillars_within(a, pitch)
        # Apparent Hertz pressure at each pillar centre times the pillar's lattice cell,
        # scaled so that the pillar forces add up to F exactly.
        share = h.pressure(np.hypot(rows[:, 2], rows[:, 3]))
        if share.sum() > 0:
            share = share / share.sum() * h.force
            forces = [PillarForce(int(n), int(m), float(x), float(y), float(f))
                      for (n, m, x, y), f in zip(rows, share) if f > 0]
            count = len(forces)
    return _result(HERTZ_MODEL, scene, started, h.force, h.centre_pressure, a,
                   phi * h.contact_area, round(count), forces, r, h.pressure(r),
                   "Hertz-like limit of a dense lattice ([P] eq. S0Hertz, A = Phi pi a^2)")


def solve_spring(scene: Scene) -> ContactResult:
    """The paper's soft-flat-punch (spring) model of one pillar in contact.

    Parameters
    ----------
    scene : Scene
        With pillars, in the single-pillar regime (Phi < Phi_S).

    Returns
    -------
    ContactResult
        ``model = "spring"``: F = d zeta / gamma* (N), sigma_0S (Pa), a = d/2 and
        A = pi d^2 / 4 (the whole top), the flat-punch profile (Pa).

    Raises
    ------
    ScopeError
        On a flat scene, when a second pillar touches (Phi >= Phi_S), when the lens
        curvature across the top reaches zeta, or when every body is rigid.
    """
    started = time.perf_counter()
    if scene.is_flat:
        raise ScopeError("spring: the scene is flat (no pillars); use the hertz model")
    p = scene.pillars
    d = p.diameter_m
    if analytic.effective_compliance(scene) == 0.0:
        raise ScopeError("spring: lens, pillars and substrate are all rigid")
    if scene.force_N is not None:
        zeta = scene.force_N * analytic.effective_compliance(scene) / d  # F = d zeta / gamma*
        return _under_force(SPRING_MODEL, scene, zeta, solve_spring)
    phi_s = analytic.single_pillar_threshold_rim(scene)
    if p.surface_fraction >= phi_s:
        raise ScopeError(
            f"spring: pillars.surface_fraction = {p.surface_fraction:.4g} >= Phi_S = "
            f"{phi_s:.4g}: a second pillar touches (use a BEM)")
    sag = float(analytic.lens_gap(scene.lens.radius_m, d / 2.0))
    if sag >= scene.indentation_m:
        raise ScopeError(
            f"spring: load.indentation_m = {scene.indentation_m:.4g} does not exceed the lens "
            f"sag across the pillar top, {sag:.4g} m: the contact covers part of the top, "
            "which the flat-punch model cannot represent (use a BEM or fem-axisym)")
    s = analytic.spring_model(scene)
    r = PROFILE_SAMPLES * d / 2.0
    return _result(SPRING_MODEL, scene, started, s.force, s.centre_pressure, d / 2.0,
                   math.pi * d * d / 4.0, 1, [PillarForce(0, 0, 0.0, 0.0, float(s.force))],
                   r, s.pressure(r), "soft-flat-punch spring model ([P] eq. S0SFP)")
