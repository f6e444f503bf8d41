"""The skeleton both FEM drivers share (:mod:`.axisym.driver`, :mod:`.solid3d.driver`).

A driver's ``solve`` runs the same four steps, each a function of its own module:

1. set-up: units and bodies of the scene (:func:`flat_candidate`, :func:`refuse_rigid_pair`,
   :func:`scaled_materials`), then the mesh and the factorised system;
2. phases: each announced on ``progress`` and timed (:class:`PhaseClock`);
3. the verdict: finite values, then why the solution is not converged, if it is not
   (:func:`verdict`, :func:`solve_failures`); the contact radius along a line of pressures and
   gaps (:func:`contact_radius`);
4. the result: the one schema with the diagnostics both FEMs report (:func:`fem_result`).
"""

from __future__ import annotations

import math
import time

import numpy as np

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import ScopeError

from ._reduced import SolveError

# Candidate contact zone of a flat scene, in Hertz radii (the contact radius of a sphere on
# a half-space is sqrt(R zeta) whatever the materials; 1.5 leaves room for the gap law).
HERTZ_CANDIDATE = 1.5
# The contact solvers' complementarity tolerance (min-map residual over zeta) for
# ``converged`` (a miss is reported in the result, not raised).
RTOL_COMPLEMENTARITY = 1e-8


def flat_candidate(scene) -> tuple[float, float]:
    """(length unit, candidate contact radius) of a flat scene, in m: the Hertz radius
    sqrt(R zeta), and :data:`HERTZ_CANDIDATE` of them, inside the sphere (r < R) even at the
    deepest allowed zeta."""
    ell = math.sqrt(scene.lens.radius_m * scene.indentation_m)
    return ell, min(HERTZ_CANDIDATE * ell, 0.9 * scene.lens.radius_m)


def refuse_rigid_pair(lens, pillar, pillars: str) -> None:
    """ScopeError for a rigid lens on rigid pillars (``pillars``: "a rigid pillar", ...)."""
    if lens.rigid and pillar.rigid:
        raise ScopeError(f"lens.rigid and pillars.rigid are both true: a rigid lens on "
                         f"{pillars} has no contact pressure distribution to compute")


def scaled_materials(lens, pillar, substrate, bodies) -> tuple[float, dict]:
    """(E_ref, {body: (E / E_ref, nu)} of the meshed ``bodies``): the modulus unit is the first
    elastic body's E, so every number the solver factorises is O(1)."""
    elastic = [m for m in (lens, pillar, substrate) if m is not None and not m.rigid]
    E_ref = elastic[0].E_Pa
    return E_ref, {b: (m.E_Pa / E_ref, m.nu)
                   for b, m in (("lens", lens), ("pillar", pillar), ("substrate", substrate))
                   if b in bodies}


class PhaseClock:
    """Announces each phase on ``progress`` (``progress(text)``; None: silent) and times it:
    :meth:`done` marks the end of a phase, :meth:`durations` gives each phase's seconds."""

    def __init__(self, progress=None):
        self.say = progress or (lambda text: None)
        self._marks = [("start", time.perf_counter())]

    def done(self, phase: str) -> None:
        self._marks.append((phase, time.perf_counter()))

    def durations(self) -> dict:
        """Seconds by phase, summed over the rounds that repeat it."""
        out: dict = {}
        for (_, t0), (k, t) in zip(self._marks, self._marks[1:]):
            out[k] = out.get(k, 0.0) + t - t0
        return out

    def elapsed(self) -> float:
        return time.perf_counter() - self._marks[0][1]


def verdict(values, residual: float, contact, force: float, zeta: float, penetration: float,
            reaches_end: str = "") -> list:
    """Why a FEM solution is not converged (empty: it is): SolveError when a value is not
    finite, then :func:`solve_failures`, and ``reaches_end`` (the contact reached the end of
    the candidate zone: what to say) when given."""
    if not np.all(np.isfinite(values)):
        raise SolveError(f"the linear solver returned non-finite values (force {force}, "
                         f"residual {residual})")
    failures = solve_failures(residual, contact, force, zeta, penetration)
    if reaches_end:
        failures.append(reaches_end)
    return failures


def fem_result(model: str, scene, clock: PhaseClock, failures: list, *, mesh, system,
               mesh_size: float, block_size_m: float, ell: float, E_ref: float,
               residual: float, contact_residual: float, penetration: float, force: float,
               centre_pressure: float, contact_radius_m: float, area: float, pillar_forces,
               iterations: int, profile: dict, fields: dict, discretisation: dict,
               diagnostics: dict, floor: dict | None = None) -> ContactResult:
    """The result of a FEM solve: the discretisation and diagnostics both FEMs report,
    updated with the driver's own (``discretisation``, ``diagnostics``); ``floor``: the
    result's floor fields (``floor_force_N``, ...; none: no floor contact), its regime
    from them and the pillars."""
    disc = {"mesh_size": float(mesh_size), "block_size_m": block_size_m,
            "elements": int(mesh.nelements), "dofs": int(system.n_reduced), **discretisation}
    zeta = scene.indentation_m
    common = {
        "message": "; ".join(failures) or "converged",
        "linear_residual": residual, "contact_residual": contact_residual,
        "block_size_m": block_size_m,
        "truncation_estimate": force * scene.half_space_compliance
        / (math.pi * block_size_m * zeta),
        "max_pointwise_penetration": penetration,
        "length_unit_m": ell, "modulus_unit_Pa": E_ref,
        "mesh_min_quality": float(mesh.quality().min()),
        "time_s": clock.durations(),
    }
    if scene.pillars is not None:
        common["pillars"] = "elastic"  # the FEMs mesh the pillar as a body
    return ContactResult(
        model=model, scene=scene.to_dict(), discretisation=disc, total_force_N=force,
        centre_pressure_Pa=centre_pressure, contact_radius_m=contact_radius_m,
        real_contact_area_m2=area, pillars_in_contact=len(pillar_forces),
        pillar_forces=pillar_forces, converged=not failures, iterations=int(iterations),
        wall_time_s=clock.elapsed(), pillar_top_profile=profile,
        diagnostics={**common, **diagnostics}, fields=fields, **(floor or {}))

# The linear solve's relative residual below which a solution is taken as exact.
RTOL_LINEAR = 1e-8
# The mortar contact holds the weighted gaps; the pointwise gap at the P2 points beside a
# contact edge dips below zero by a share of zeta: 1-3 % on smooth or well-resolved edges
# (fem-axisym: at most 1.5 % over 838 solves at mesh_size 0.5-4; fem-3d: 2.8 % over the
# lattice study), up to ~9 % beside a flat punch's singular edge at mesh_size 2 (F still
# within 1e-3 of the closed form), 29-53 % where a contact under 1 um spans one or two
# elements.  Beyond this share the mesh does not resolve the contact: not converged.
MAX_POINTWISE_PENETRATION = 0.2


def solve_failures(residual: float, contact, force: float, zeta: float,
                   penetration: float) -> list:
    """Why a FEM solution is not converged (empty: it is): the linear residual, the contact
    solver's own verdict (``contact.converged``, ``contact.message``), no contact force, and a
    pointwise ``penetration`` (over zeta) beyond :data:`MAX_POINTWISE_PENETRATION`."""
    failures = []
    if residual >= RTOL_LINEAR:
        failures.append(f"linear residual {residual:.2e} >= {RTOL_LINEAR:g}")
    if not contact.converged:
        failures.append(f"contact: {contact.message}")
    if force <= 0.0:
        failures.append(f"no contact force (F = {force:g} N): the mesh does not resolve "
                        f"zeta = {zeta:g} m")
    if penetration > MAX_POINTWISE_PENETRATION:
        failures.append(
            f"the contact is under-resolved: the gap at the P2 points dips {penetration:.1%} "
            f"of zeta below zero (at most {MAX_POINTWISE_PENETRATION:.0%} where the mesh "
            "resolves the contact); use a smaller mesh_size")
    return failures


def contact_radius(r: np.ndarray, lam: np.ndarray, w: np.ndarray,
                   band: float = 0.1) -> tuple[float, bool]:
    """Radius of the outermost point of contact, and whether it is the last point.

    The edge lies between the last vertex with positive pressure, r_k, and the next vertex.
    Outside a smooth contact edge the gap opens as (r - a)^(3/2) (Johnson 1985, sec. 4.2),
    so w^(2/3) is fitted by a straight line over the points in [r_k+1, (1 + band) r_k] and
    its root is a, kept in [r_k, r_k+1].  (The pointwise gaps of a mortar solution wobble
    by ~1e-5 zeta at the first points outside; a least-squares fit over ~10 % of the radius
    measured +-2e-4 a on Hertz, against +-3e-3 from the first two points alone.)

    Parameters
    ----------
    r : ndarray
        P2 points of the contact line (vertices at even indices).
    lam : ndarray
        Pressure at the vertices.
    w : ndarray
        Pointwise gaps at the P2 points.
    """
    active = np.nonzero(lam > 0)[0]
    if len(active) == 0:
        return 0.0, False
    k = 2 * active[-1]
    if k == len(r) - 1:
        return float(r[k]), True
    outside = np.nonzero((r >= r[k + 2]) & (w > 0))[0]
    sel = outside[r[outside] <= (1.0 + band) * r[k]]
    if len(sel) < 3:
        sel = outside[:3]
    if len(sel) < 2:
        return float(0.5 * (r[k] + r[k + 2])), False
    slope, intercept = np.polyfit(r[sel], w[sel] ** (2.0 / 3.0), 1)
    a = -intercept / slope if slope > 0 else 0.5 * (r[k] + r[k + 2])
    return float(np.clip(a, r[k], r[k + 2])), False
