"""Closed-form limits of the lens-on-pillars contact (SI units throughout).

Every formula cites its source; PHYSICS.md ("Closed-form limits") lists the paper's slips
that these formulas correct.
``gamma`` always means a compliance (1 - nu^2) / E in 1/Pa.

References
----------
.. [J] K. L. Johnson, *Contact Mechanics*, Cambridge University Press, 1985.
.. [P] R. Ledesma-Alonso et al., "Stress concentration in periodically rough hertzian
   contact: Hertz to soft-flat-punch transition" (the seed paper).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._checks import rigid_flat_indentation
from ._scene import PHI_CLOSE_PACKING, Scene, SceneError


# --- geometry --------------------------------------------------------------------------
def float_array(a):
    """``a`` as a float array of its own library (numpy for scalars and lists): the geometry
    here also runs on a GPU's arrays (cupy), whose ufuncs numpy's calls dispatch to."""
    return a.astype(float, copy=False) if hasattr(a, "astype") else np.asarray(a, float)


def lens_gap(radius: float, r):
    """Gap before loading between a sphere of ``radius`` touching at r = 0 and the plane,
    R - sqrt(R^2 - r^2) (m), written r^2 / (R + sqrt(R^2 - r^2)) to avoid cancellation
    for r << R; arrays (numpy's or a GPU's) allowed."""
    r2 = float_array(r) ** 2
    return r2 / (radius + np.sqrt(radius * radius - r2))


# --- Hertz ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Hertz:
    """Sphere of radius R on a half-space, indentation zeta ([J] sec. 4.2; [P] eq. S0Hertz).

    Attributes: ``contact_radius`` a = sqrt(R zeta) (m), ``centre_pressure``
    sigma_0H = 2 sqrt(zeta / R) / (pi gamma) (Pa), ``force`` F = (2 pi / 3) R zeta sigma_0H (N).
    """

    radius: float
    indentation: float
    compliance: float

    @property
    def contact_radius(self) -> float:
        return math.sqrt(self.radius * self.indentation)

    @property
    def centre_pressure(self) -> float:
        return 2.0 * math.sqrt(self.indentation / self.radius) / (math.pi * self.compliance)

    @property
    def force(self) -> float:
        return 2.0 * math.pi / 3.0 * self.radius * self.indentation * self.centre_pressure

    @property
    def contact_area(self) -> float:
        return math.pi * self.radius * self.indentation

    def pressure(self, r):
        """sigma(r) = sigma_0H sqrt(1 - r^2 / a^2), zero outside (Pa)."""
        s = 1.0 - (np.asarray(r, dtype=float) / self.contact_radius) ** 2
        return self.centre_pressure * np.sqrt(np.clip(s, 0.0, None))

    @staticmethod
    def indentation_for_force(force: float, radius: float, compliance: float) -> float:
        """Inverse of ``force``: zeta = (3 F gamma / (4 sqrt R))^(2/3)."""
        return (3.0 * force * compliance / (4.0 * math.sqrt(radius))) ** (2.0 / 3.0)


def hertz(scene: Scene) -> Hertz:
    """Hertz on the scene's load: its indentation, or the one that carries its force."""
    R, gamma = scene.lens.radius_m, scene.half_space_compliance
    zeta = scene.indentation_m
    if scene.force_N is not None:
        zeta = Hertz.indentation_for_force(scene.force_N, R, gamma)
    return Hertz(R, zeta, gamma)


# --- flat punches ----------------------------------------------------------------------
@dataclass(frozen=True)
class FlatPunch:
    """Flat punch of diameter d pressed by ``indentation`` into half-spaces of total compliance
    ``compliance`` ([J] eq. 3.35-3.36; [P] eqs. SFSFP, S0SFPInf, S0SFP).

    With ``compliance`` = gamma_l (+ gamma_s) this is the rigid punch; with the effective
    gamma* of :func:`spring_model` it is the paper's soft-flat-punch model.
    """

    diameter: float
    indentation: float
    compliance: float

    @property
    def centre_pressure(self) -> float:
        """sigma_0S = 2 zeta / (pi d gamma) (Pa)."""
        return 2.0 * self.indentation / (math.pi * self.diameter * self.compliance)

    @property
    def force(self) -> float:
        """F = pi d^2 sigma_0S / 2 = d zeta / gamma (N)."""
        return math.pi * self.diameter**2 * self.centre_pressure / 2.0

    def pressure(self, r):
        """sigma(r) = sigma_0S [1 - (2r/d)^2]^(-1/2) for r < d/2, zero outside (Pa)."""
        r = np.asarray(r, dtype=float)
        s = 1.0 - (2.0 * r / self.diameter) ** 2
        out = np.zeros_like(s)
        inside = s > 0
        out[inside] = self.centre_pressure / np.sqrt(s[inside])
        return out


def _single_pillar(scene: Scene):
    if scene.pillars is None:
        raise SceneError("this limit needs a scene with pillars (the scene is flat)")
    return scene.pillars


def rigid_punch(scene: Scene) -> FlatPunch:
    """Rigid pillar on a rigid substrate pressed into the lens (compliance gamma_l)."""
    p = _single_pillar(scene)
    gamma = scene.lens.material.compliance
    if gamma == 0.0:
        raise SceneError("rigid punch limit needs an elastic lens (lens.rigid is true)")
    return FlatPunch(p.diameter_m, _punch_indentation(scene, gamma), gamma)


def effective_compliance(scene: Scene) -> float:
    """gamma* = gamma_l + gamma_s + 4 h / (pi d E_p) (1/Pa): half-spaces and the Hooke pillar
    in series ([P] eq. for gamma*, with nu_f read as nu_l)."""
    p = _single_pillar(scene)
    spring = 0.0 if p.material.rigid else 4.0 * p.height_m / (math.pi * p.diameter_m * p.material.E_Pa)
    return scene.half_space_compliance + spring


def spring_model(scene: Scene) -> FlatPunch:
    """The paper's soft-flat-punch model: one Hooke pillar between two half-spaces."""
    p = _single_pillar(scene)
    gamma = effective_compliance(scene)
    return FlatPunch(p.diameter_m, _punch_indentation(scene, gamma), gamma)


def _punch_indentation(scene: Scene, compliance: float) -> float:
    """A punch's indentation on the scene's load: given, or the one that carries its force
    (F = d zeta / gamma, inverted)."""
    if scene.force_N is None:
        return scene.indentation_m
    return scene.force_N * compliance / scene.pillars.diameter_m


def _indentation(scene: Scene) -> float:
    """The indentation a threshold is read at: the scene's, or under a force the guess
    (:func:`indentation_estimate`)."""
    return scene.indentation_m if scene.force_N is None else indentation_estimate(scene)


def least_indentation(scene: Scene) -> float:
    """A lower bound (m) of the indentation at which any model carries a force-controlled
    scene's force: where the lens pressed on a rigid flat carries it (any substrate, pillar
    or partial contact deflects more); 0 for a rigid lens."""
    return rigid_flat_indentation(scene.force_N, scene.lens.radius_m,
                                  scene.lens.material.compliance)


def indentation_estimate(scene: Scene) -> float:
    """A first guess (m) of the indentation at which a force-controlled scene carries its
    force F, for the models to build a first discretisation on (they correct it by their own
    answer).

    - Flat: Hertz's, zeta_H = (3 F gamma / (4 sqrt R))^(2/3), gamma = gamma_l + gamma_s.
    - One pillar (Phi below Phi_S at the guess): the spring model's, F gamma* / d, plus half
      the lens sag d^2 / (8 R) over the top (the curved lens meets the punch's edge later).
    - Several pillars: zeta_H is a lower bound (the pillars add compliance and leave gaps);
      zeta_H + f_0 c adds each pillar's local compliance c at the centre pillar's force f_0
      (Hertz's apparent centre pressure on its lattice cell): the Hooke spring and the
      half-space under its top beyond the smeared load's (a punch, f gamma / d, against a
      uniform load on a disk of the cell's area, mean 16 f gamma / (3 pi^2 R_c)), an upper
      estimate.  The guess is their geometric mean.  Against the dense BEM at P = 7 on 45
      scenes (Phi 0.03-0.82, zeta 0.05-1.5 um, E_p / E_l 0.1-10): 0.96 to 1.29 of the
      solved indentation, 1.0 to 1.1 where E_p >= E_l and Phi >= 0.1.
    """
    force, R = scene.force_N, scene.lens.radius_m
    gamma = scene.half_space_compliance
    hertz_zeta = Hertz.indentation_for_force(force, R, gamma)
    p = scene.pillars
    if p is None:
        return hertz_zeta
    d = p.diameter_m
    spring = scene.pillar_spring_compliance
    single = force * (gamma / d + spring) + 0.5 * float(lens_gap(R, d / 2.0))
    if p.surface_fraction < single_pillar_threshold_rim(scene.designed(single)):
        return single
    cell = math.sqrt(3.0) / 2.0 * p.pitch_m**2
    local = max(0.0, gamma * (1.0 / d - 16.0 / (3.0 * math.pi**2 * math.sqrt(cell / math.pi))))
    centre_force = 3.0 * force / (2.0 * math.pi * R * hertz_zeta) * cell
    return math.sqrt(hertz_zeta * (hertz_zeta + centre_force * (local + spring)))


# --- thresholds ------------------------------------------------------------------------
def stiffness_number(scene: Scene) -> float:
    """Pi = pi + 4 h / (d (gamma_l + gamma_s) E_p) = pi gamma* / (gamma_l + gamma_s)."""
    return math.pi * effective_compliance(scene) / scene.half_space_compliance


def second_pillar_radius(scene: Scene) -> float:
    """r_S, the outer root of eq. rSzeta of [P]:
    R - sqrt(R^2 - r^2) + [(2 / Pi) arcsin(d / (2 r)) - 1] zeta = 0  (m).

    The centre punch lifts the half-space surfaces by (2/pi) w_0 arcsin(d / 2r) outside it
    ([J] eq. 3.37).  For Pi close to pi a spurious root sits just above d/2; the physical
    threshold is the outer root, found by scanning inwards from where the gap is positive.
    A pitch is never below d, so the scan stops at r = d; when the gap stays open down to d
    no lattice brings a second pillar into contact and r_S = d (Phi_S = close packing).
    """
    gap, hi = _punch_gap(scene)
    lo = _single_pillar(scene).diameter_m  # a lattice pitch is never below the diameter
    if gap(hi) <= 0:
        raise SceneError("second_pillar_radius: no root below 0.999 R (indentation too large)")
    radii = np.geomspace(lo, hi, 4000)[::-1]
    neg = np.nonzero(gap(radii) <= 0)[0]
    if len(neg) == 0:
        return lo  # the gap stays open down to r = d: no pitch brings a second pillar in
    k = neg[0]
    from scipy.optimize import brentq  # here, not at import: scipy.optimize costs 0.5 s

    return brentq(lambda r: float(gap(r)), radii[k], radii[k - 1],
                  xtol=1e-15 * scene.lens.radius_m, rtol=1e-14)


def _punch_gap(scene: Scene):
    """(gap, hi): the gap of [P] eq. rSzeta at radius r (m; vectorised), the undeformed lens
    less the indentation plus the centre punch's lift (2/Pi) zeta arcsin(d / 2r) ([J] eq.
    3.37), and the radius from which the threshold scans inwards (where it is open)."""
    R, d, zeta = scene.lens.radius_m, _single_pillar(scene).diameter_m, _indentation(scene)
    big_pi = stiffness_number(scene)

    def gap(r):
        r = np.asarray(r, float)
        return lens_gap(R, r) + (2.0 / big_pi * np.arcsin(
            np.minimum(d / (2.0 * r), 1.0)) - 1.0) * zeta

    return gap, min(0.999 * R, max(2.0 * math.sqrt(2.0 * R * zeta), 2.0 * d))


def phi_from_pitch(diameter: float, pitch: float) -> float:
    """Phi = pi / (2 sqrt 3) (d / e)^2 ([P] eq. Frac)."""
    return PHI_CLOSE_PACKING * (diameter / pitch) ** 2


def single_pillar_threshold(scene: Scene) -> float:
    """Phi_S = pi / (2 sqrt 3) (d / r_S)^2 ([P] eq. PhiSrS): below it one pillar touches."""
    return phi_from_pitch(_single_pillar(scene).diameter_m, second_pillar_radius(scene))


def rim_contact_radius(scene: Scene) -> float | None:
    """The outer root r_S >= d/2 of [P] eq. rSzeta (m), None when the gap stays closed down
    to the centre pillar's rim (no pitch then leaves a pillar of the ring apart).

    Unlike :func:`second_pillar_radius`, which needs a pillar centre at r_S >= d, the ring's
    rim may touch anywhere beyond the centre pillar's rim, so the scan (inwards, vectorised;
    the first sign change is the outer root, never the spurious one just above d/2) runs
    down to d/2.
    """
    gap, hi = _punch_gap(scene)
    d = _single_pillar(scene).diameter_m
    radii = np.geomspace(d / 2.0, hi, 4000)[::-1]
    closed = np.nonzero(gap(radii) <= 0.0)[0]
    if closed.size == 0 or closed[0] == 0:
        return None
    k = int(closed[0])
    from scipy.optimize import brentq  # here, not at import: scipy.optimize costs 0.5 s

    return brentq(lambda r: float(gap(r)), radii[k], radii[k - 1],
                  xtol=1e-15 * scene.lens.radius_m, rtol=1e-14)


def single_pillar_threshold_rim(scene: Scene) -> float:
    """Phi_S where the second ring first touches: at its inner rim, a distance e - d/2 from
    the centre, so the pitch at the threshold is e_S = r_S + d/2 (:func:`rim_contact_radius`),
    not [P]'s e_S = r_S (:func:`single_pillar_threshold`, which lets the lens reach a
    neighbour's rim while it counts one pillar).  Close packing when no pitch keeps the ring
    apart.  The models that hold one pillar, and the planner's regimes, use this one."""
    d = _single_pillar(scene).diameter_m
    r_s = rim_contact_radius(scene)
    return PHI_CLOSE_PACKING if r_s is None else phi_from_pitch(d, max(r_s + d / 2.0, d))


def single_pillar_threshold_large_indentation(scene: Scene) -> float:
    """Large-zeta limit Phi_S ~ pi d^2 / (4 sqrt 3 R zeta), valid for
    zeta >> (d / Pi)^2 / (2 R) (the paper's stated criterion is dimensionally wrong)."""
    d = _single_pillar(scene).diameter_m
    return math.pi * d**2 / (4.0 * math.sqrt(3.0) * scene.lens.radius_m * _indentation(scene))


def threshold_indentation(scene: Scene) -> float:
    """zeta_T = [gamma* / (gamma_l + gamma_s)]^2 d^2 / R (m): where Hertz and single-pillar
    centre stresses match ([P], Discussion)."""
    d = _single_pillar(scene).diameter_m
    ratio = effective_compliance(scene) / scene.half_space_compliance
    return ratio**2 * d**2 / scene.lens.radius_m


def pillars_in_apparent_contact(contact_radius: float, pitch: float) -> float:
    """Q ~ (2 pi / sqrt 3) (a / e)^2 ([P] eq. Count)."""
    return 2.0 * math.pi / math.sqrt(3.0) * (contact_radius / pitch) ** 2


# --- master curves (empirical fits of [P]) -----------------------------------------------
def reduced_centre_pressure(reduced_fraction):
    """sigma_0* = (1 + Phi*)^-3 ([P] eq. MasterSig0Phi)."""
    return (1.0 + np.asarray(reduced_fraction, dtype=float)) ** -3


def reduced_area(surface_fraction):
    """A* = Phi^0.7 ([P] eq. MasterAPhi)."""
    return np.asarray(surface_fraction, dtype=float) ** 0.7


def master_centre_pressure(phi, phi_s, phi_h, sigma_0h, sigma_0s):
    """sigma_0(Phi) from the master curve with Phi* = (Phi - Phi_S) / Phi_H (Pa); Phi < Phi_S
    gives the single-pillar value."""
    star = np.maximum((np.asarray(phi, dtype=float) - phi_s) / phi_h, 0.0)
    return sigma_0h + (sigma_0s - sigma_0h) * reduced_centre_pressure(star)


def master_contact_area(phi, radius, indentation, diameter):
    """A(Phi) = A_S + (A_H - A_S) Phi^0.7 with A_H = pi R zeta, A_S = pi d^2 / 4 (m^2)."""
    a_h = math.pi * radius * indentation
    a_s = math.pi * diameter**2 / 4.0
    return a_s + (a_h - a_s) * reduced_area(phi)
