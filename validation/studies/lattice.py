"""The multi-pillar cross-validation: the paper's Hooke BEM and the elastic-pillar BEM against
the 3D FEM.

Over surface fractions Phi and stiffness ratios E_p/E_l at zeta = 0.3 um (Table 1 otherwise),
two boundary-element models are compared with fem-3d (every pillar a fully elastic body bonded
to the substrate): the Hooke-spring BEM (``bem-fft``, every pillar a uniformly shortening
spring on a half-space, the paper's model) and the elastic-pillar BEM (``bem-fft`` with
``pillars = "elastic"``: each pillar's top compliance from an axisymmetric FEM, PHYSICS.md "The
elastic-pillar BEM").  Each model climbs its own refinement ladder (both BEMs the same
cells-per-diameter ladder); each quantity gets its Richardson estimate and GCI band
(validation.analysis.verification), and every BEM-FEM difference is set beside both models'
numerical uncertainty: a difference larger than the two bands together is a modelling error
of that BEM's pillar, not noise.

Substrate conventions.  The grid (Phi x E_p/E_l, :data:`PHIS` x :data:`RATIOS`) keeps the
substrate the lens material (E_s = E_l): it asks what the spring model costs when only the
pillars change, so the half-space compliance gamma_l + gamma_s is the same in every scene and
the comparison isolates the pillar.  :data:`PAPER_SCENES` adds scenes at the paper's
convention E_s = E_p (Table 1), where a soft or stiff pillar sits on a substrate of its own
material; every row, label, title and legend names its convention.

Targets of the elastic BEM (:data:`TARGETS`), each against fem-3d's Richardson estimate and
met when |(BEM - FEM) / FEM| is within the target or within both GCI bands where the bands
are wider (:func:`judge`): F_T within 1 %, sigma0 within 3 %, every ring's force within 2 %
(the ring forces are extrapolated like the other quantities) and the centre pillar's top
pressure along theta = 0 within 5 % at r = x d/2, x in :data:`PROFILE_POINTS` (r < 0.9 d/2:
the edge of a stiff pillar is singular).  Each row carries ``targets`` and the report
``targets_met`` (n of m scenes meet every target).

Per-pillar forces are also compared at the finest level of each model, grouped by lattice ring
(ring 0 is the centre pillar): the FEM/BEM ratio of every pillar both models load, its mean
and range per ring, and its change from the next-coarser pair of levels (a measure of how
settled the ratio is).

A row of ``lattice.json``: ``label``, ``title``, ``surface_fraction``, ``ratio`` (E_p/E_l),
``substrate`` (the convention) and ``substrate_E_Pa``; ``quantities`` (the Hooke BEM against
the FEM, per quantity ``fem``, ``fem_band``, ``bem``, ``bem_band``, ``difference`` = (FEM - BEM)
/ BEM, ``band`` = both bands over BEM, ``significant``) and ``elastic_quantities`` (the same
for the elastic BEM); ``rings`` and ``elastic_rings`` (finest-level force ratios by ring);
``ring_forces`` and ``profile`` (the Richardson estimates the ring and profile targets judge);
``targets``; each model's ``*_levels`` (the elastic bem-fft's single rungs in
``elastic_fft_rungs``); ``status``.

All cases run on the engine, so the study resumes after an interruption.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pillar_xval.scenes import InputError, Scene, lattice, load_scene

from ..engine import Case, Engine
from ..registry import QUANTITIES, quantity_values
from ..analysis.verification import study
from .compare import profile_key, profile_studies
from .targets import TARGET_RULE, TARGETS, judge

PHIS = (0.03, 0.1, 0.2, 0.4)
RATIOS = (0.1, 1.0, 10.0, 1e6)
ZETA_UM = 0.3
E_LENS = 1.6e6
FEM_MODEL, BEM_MODEL = "fem-3d", "bem-fft"
# The two BEMs: the paper's Hooke pillar (the model's default, so its cases keep their keys)
# and the elastic pillar.
HOOKE, ELASTIC = "hooke", "elastic"
BEM_OPTIONS = {HOOKE: {}, ELASTIC: {"pillars": "elastic"}}
BEM_NAMES = {HOOKE: "Hooke BEM", ELASTIC: "elastic BEM"}
# fem-3d: sqrt(2) per level (x 2.8 unknowns); 1.41 is 2-4 minutes on the Phi = 0.4 scene.
FEM_LEVELS = (2.83, 2.0, 1.41)
# bem-fft: cells per diameter, ratio 2; the FFT model converges at order ~1 (smooth edge
# cells) where the dense model's edge-cut pattern makes its order wobble.  Both BEMs climb it.
BEM_LEVELS = (16, 32, 64)
QUICK_FEM_LEVELS, QUICK_BEM_LEVELS = (4.0, 2.83), (8, 16)
# The dense elastic-pillar BEM at the planner's rungs (its candidates "bem P=11 elastic",
# "bem P=15 elastic" and "bem P=21 elastic", same options): single levels, not a ladder; each
# is set against fem-3d's estimate, so the planner reads its error in a lattice directly
# (calibrate).  P = 15 and the elastic bem-fft's single levels FFT_RUNGS, between its ladder's
# levels, put the elastic rungs as close in time as the Hooke BEMs' (1.8-2.6x a step, against
# 3.6x from P = 11 to 21 and 4x from N = 16 to 32): a plan one rung finer than needed then
# stays near 2x of the cheapest.
DENSE_MODEL = "bem"
DENSE_LEVELS = (11, 15, 21)
QUICK_DENSE_LEVELS = (11,)
DENSE_OPTIONS = {"cells": "covered", "pillars": ELASTIC}
FFT_RUNGS = (24, 48)
QUICK_FFT_RUNGS = ()

# Substrate conventions: the lens material (the grid) or the pillars' (the paper's Table 1).
LENS, PILLAR = "E_s = E_l", "E_s = E_p"
CONVENTIONS = (LENS, PILLAR)
# The paper's convention on four scenes (Phi, E_p/E_l).  E_p/E_l = 1 would repeat an E_s = E_l
# scene and 1e6 makes the substrate rigid too (both BEMs then agree by construction: no pillar
# compliance is left), so the soft (0.1) and stiff (10) pillars; Phi = 0.2 and 0.4 load the most
# pillars (19-37 at zeta = 0.3 um), where the one approximation left in the elastic BEM (the
# pillars couple through a half-space at the plane of their tops, not through a substrate at
# depth h) matters most, and at E_s = E_p the substrate is as soft or stiff as the pillars, so
# the substrate's share of the compliance differs from the grid's by the same factor.
PAPER_SCENES = ((0.2, 0.1), (0.2, 10.0), (0.4, 0.1), (0.4, 10.0))

# The centre pillar's top profile along theta = 0 at r = x d/2 (r < 0.9 d/2).
PROFILE_POINTS = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85)


@dataclass(frozen=True)
class LatticePoint:
    surface_fraction: float
    ratio: float  # E_p / E_l
    substrate: str = LENS  # the convention: E_s = E_l or E_s = E_p
    zeta_um: float = ZETA_UM  # the indentation, micrometres

    def __post_init__(self):
        if self.substrate not in CONVENTIONS:
            raise InputError(f"substrate convention {self.substrate!r}: one of "
                             + ", ".join(CONVENTIONS))

    @property
    def label(self) -> str:
        """Short, for progress lines and messages: ``Phi=0.2 Ep/El=10 Es=Ep``."""
        return (f"Phi={self.surface_fraction:g} Ep/El={self.ratio:g} "
                + self.substrate.replace(" ", "").replace("_", "")
                + ("" if self.zeta_um == ZETA_UM else f" zeta={self.zeta_um:g}um"))

    @property
    def title(self) -> str:
        """For tables and figures: ``Phi = 0.2, E_p/E_l = 10, E_s = E_p``."""
        return (f"Phi = {self.surface_fraction:g}, E_p/E_l = {self.ratio:g}, {self.substrate}"
                + ("" if self.zeta_um == ZETA_UM else f", zeta = {self.zeta_um:g} um"))

    @property
    def substrate_E_Pa(self) -> float:
        return E_LENS if self.substrate == LENS else E_LENS * self.ratio

    def scene(self) -> Scene:
        """Table 1 (paper-fig3-sparse) with this Phi, E_p, substrate and zeta."""
        return load_scene("paper-fig3-sparse", [
            f"pillars.surface_fraction={self.surface_fraction!r}",
            f"pillars.E_Pa={E_LENS * self.ratio!r}", f"substrate.E_Pa={self.substrate_E_Pa!r}",
            "substrate.nu=0.5", f"load.indentation_um={self.zeta_um!r}"])


def grid(phis=PHIS, ratios=RATIOS, substrate: str = LENS,
         zeta_um: float = ZETA_UM) -> list[LatticePoint]:
    return [LatticePoint(p, r, substrate, zeta_um) for p in phis for r in ratios]


def paper_points(pairs=None, phis=PHIS, ratios=RATIOS,
                 zeta_um: float = ZETA_UM) -> list[LatticePoint]:
    """The E_s = E_p scenes: ``pairs`` of (Phi, E_p/E_l), by default those of
    :data:`PAPER_SCENES` whose Phi and ratio are in ``phis`` and ``ratios``."""
    if pairs is None:
        pairs = [(p, r) for p, r in PAPER_SCENES if p in phis and r in ratios]
    return [LatticePoint(p, r, PILLAR, zeta_um) for p, r in pairs]


def default_points(phis=PHIS, ratios=RATIOS, pairs=None,
                   zeta_um: float = ZETA_UM) -> list[LatticePoint]:
    """The study's scenes: the E_s = E_l grid, then the E_s = E_p scenes."""
    return grid(phis, ratios, LENS, zeta_um) + paper_points(pairs, phis, ratios, zeta_um)


def cases(point: LatticePoint, fem_levels=FEM_LEVELS, bem_levels=BEM_LEVELS,
          dense_levels=DENSE_LEVELS, fft_rungs=FFT_RUNGS) -> list[Case]:
    """fem-3d's levels, the Hooke BEM's, the elastic BEM's (same cells per diameter), the
    dense elastic BEM's, then the elastic bem-fft's single rungs."""
    scene = point.scene()
    out = [Case(FEM_MODEL, scene, {"mesh_size": float(s)}, tag=f"{point.label} fem")
           for s in fem_levels]
    for kind in (HOOKE, ELASTIC):
        out += [Case(BEM_MODEL, scene, {"cells_per_diameter": int(n), **BEM_OPTIONS[kind]},
                     tag=f"{point.label} {kind}") for n in bem_levels]
    out += [Case(DENSE_MODEL, scene, {"elements_per_diameter": int(n), **DENSE_OPTIONS},
                 tag=f"{point.label} dense {ELASTIC}") for n in dense_levels]
    out += [Case(BEM_MODEL, scene, {"cells_per_diameter": int(n), **BEM_OPTIONS[ELASTIC]},
                 tag=f"{point.label} {ELASTIC} rung") for n in fft_rungs]
    return out


def _single_levels(outcomes, option: str) -> list[dict]:
    """An elastic BEM's single levels (its ``option`` names each): each one's quantities, or
    the error that stopped it (a failed level is reported, not judged)."""
    out = []
    for o in outcomes:
        level = {option: o.case.options[option]}
        if o.ok:
            level.update(converged=bool(o.result.converged),
                         wall_time_s=o.result.wall_time_s, **quantity_values(o.result))
        else:
            level.update(converged=False, error=str(o.error))
        out.append(level)
    return out


def _ladder(outcomes, option, h_power) -> dict:
    """Levels of one model (coarse to fine) and the study of each quantity."""
    done = [o for o in outcomes if o.ok]
    if len(done) < 2:
        errors = [o.error for o in outcomes if not o.ok]
        return {"levels": [], "studies": {}, "results": [],
                "error": "; ".join(str(e) for e in errors) or "no level",
                # exit status of the failure: 2 if the model refused the scene, else 3
                "exit": 2 if errors and all(isinstance(e, InputError) for e in errors) else 3}
    values = [o.case.options[option] for o in done]
    h = [float(v) ** h_power for v in values]
    rows = [{option: v, "h": hh, "converged": bool(o.result.converged),
             "wall_time_s": o.result.wall_time_s, **quantity_values(o.result)}
            for v, hh, o in zip(values, h, done)]
    studies = {q.key: study(h, [r[q.key] for r in rows]) for q in QUANTITIES}
    return {"levels": rows, "studies": studies, "results": [o.result for o in done],
            "error": None}


def _estimate(st: dict) -> tuple[float, float, str]:
    """(value, band, how): the Richardson estimate and its GCI band when the finest levels
    are asymptotic; otherwise the finest value with the fallback band (3 x the spread)."""
    g = st["gci"]
    if g["status"] == "ok" and g["f_exact"] is not None:
        return g["f_exact"], g["uncertainty"], "richardson"
    return g["f"][0], g["fallback_uncertainty"], g["status"]


def ring_ratios(fem_result, bem_result) -> list[dict]:
    """FEM/BEM force ratio of every pillar both load, by ring: mean, min, max, count, and the
    pillars only one model loads."""
    fem = {(p.n, p.m): p.force_N for p in fem_result.pillar_forces}
    bem = {(p.n, p.m): p.force_N for p in bem_result.pillar_forces}
    rings: dict[int, dict] = {}
    for nm in set(fem) | set(bem):
        k = lattice.ring(*nm)
        r = rings.setdefault(k, {"ring": k, "ratios": [], "fem_only": 0, "bem_only": 0,
                                 "fem_force_N": 0.0, "bem_force_N": 0.0})
        r["fem_force_N"] += fem.get(nm, 0.0)
        r["bem_force_N"] += bem.get(nm, 0.0)
        if nm in fem and nm in bem and bem[nm] > 0:
            r["ratios"].append(fem[nm] / bem[nm])
        elif nm in fem:
            r["fem_only"] += 1
        else:
            r["bem_only"] += 1
    out = []
    for k in sorted(rings):
        r = rings[k]
        ratios = np.asarray(r.pop("ratios"))
        r.update({"pillars": int(ratios.size),
                  "ratio_mean": float(ratios.mean()) if ratios.size else None,
                  "ratio_min": float(ratios.min()) if ratios.size else None,
                  "ratio_max": float(ratios.max()) if ratios.size else None,
                  "ring_force_ratio": r["fem_force_N"] / r["bem_force_N"]
                  if r["bem_force_N"] > 0 else None})
        out.append(r)
    return out


def _rings(fem: dict, bem: dict) -> list[dict]:
    """:func:`ring_ratios` of the finest levels, with each ring's change from the next-coarser
    pair of levels."""
    rings = ring_ratios(fem["results"][-1], bem["results"][-1])
    if len(fem["results"]) >= 2 and len(bem["results"]) >= 2:
        coarser = {r["ring"]: r for r in ring_ratios(fem["results"][-2], bem["results"][-2])}
        for r in rings:
            c = coarser.get(r["ring"], {}).get("ring_force_ratio")
            r["ring_force_ratio_change"] = (None if c is None or r["ring_force_ratio"] is None
                                            else r["ring_force_ratio"] - c)
    return rings


def ring_forces(result) -> dict[int, float]:
    """The force (N) on each lattice ring: the sum over its pillars."""
    out: dict[int, float] = {}
    for p in result.pillar_forces:
        k = lattice.ring(p.n, p.m)
        out[k] = out.get(k, 0.0) + p.force_N
    return out


def ring_studies(ladder: dict) -> dict[int, dict]:
    """The convergence study of each ring's force over a ladder's levels (a ring a level does
    not load carries 0 N there)."""
    per_level = [ring_forces(r) for r in ladder["results"]]
    h = [lv["h"] for lv in ladder["levels"]]
    rings = sorted(set().union(*per_level)) if per_level else []
    return {k: study(h, [f.get(k, 0.0) for f in per_level]) for k in rings}


def _differences(fem: dict, bem: dict) -> dict:
    """Per quantity: both models' estimates and bands, (FEM - BEM) / BEM, both bands over
    |BEM|, and whether the difference is beyond them."""
    out = {}
    for q in QUANTITIES:
        fv, fb, fhow = _estimate(fem["studies"][q.key])
        bv, bb, bhow = _estimate(bem["studies"][q.key])
        diff = (fv - bv) / bv if bv else None
        band = (fb + bb) / abs(bv) if bv else None
        out[q.key] = {
            "fem": fv, "fem_band": fb, "fem_how": fhow, "bem": bv, "bem_band": bb,
            "bem_how": bhow, "difference": diff, "band": band,
            "significant": bool(diff is not None and band is not None and abs(diff) > band)}
    return out


def _estimates(studies: dict, key, prefix: str, unit: str) -> dict:
    """``{prefix_unit, prefix_band_unit, prefix_how}`` of one study (None when absent)."""
    if key not in studies:
        return {f"{prefix}_{unit}": None, f"{prefix}_band_{unit}": None, f"{prefix}_how": None}
    v, b, how = _estimate(studies[key])
    return {f"{prefix}_{unit}": v, f"{prefix}_band_{unit}": b, f"{prefix}_how": how}


def _ring_estimates(fem: dict, ladders: dict) -> list[dict]:
    """Each ring's force as the Richardson estimate of fem-3d and of each BEM ladder given."""
    studies = {"fem": ring_studies(fem)} | {k: ring_studies(v) for k, v in ladders.items()}
    rings = sorted(set().union(*(set(s) for s in studies.values())))
    return [{"ring": k, **{n: v for name, s in studies.items()
                           for n, v in _estimates(s, k, name, "N").items()}} for k in rings]


def _profile_estimates(fem: dict, ladders: dict, radius_m: float) -> list[dict]:
    """The centre pillar's top pressure at r = x radius, x in :data:`PROFILE_POINTS`, as each
    model's Richardson estimate (compare's profile sampling); points every model's levels
    cover."""
    studies = {"fem": profile_studies(fem, radius_m, PROFILE_POINTS)} | {
        k: profile_studies(v, radius_m, PROFILE_POINTS) for k, v in ladders.items()}
    out = []
    for x in PROFILE_POINTS:
        key = profile_key(x)
        if key not in studies["fem"]:
            continue
        out.append({"r_over_radius": x, "r_m": x * radius_m,
                    **{n: v for name, s in studies.items()
                       for n, v in _estimates(s, key, name, "Pa").items()}})
    return out


# --- targets of the elastic BEM -------------------------------------------------------------
def _group(checks: list[dict], target: float) -> dict:
    """Several checks of one target: met when every one is (None when one is not judged or
    there are none); ``worst`` the check with the largest |error| / allowed."""
    judged = [c for c in checks if c["error"] is not None]
    worst = max(judged, key=lambda c: abs(c["error"]) / c["allowed"], default=None)
    met = (None if not checks or any(c["met"] is None for c in checks)
           else all(c["met"] for c in checks))
    return {"target": target, "met": met, "checks": checks,
            "worst_error": None if worst is None else worst["error"],
            "worst_allowed": None if worst is None else worst["allowed"]}


def evaluate_targets(row: dict) -> dict:
    """The elastic BEM's targets on one row (its ``elastic_quantities``, ``ring_forces`` and
    ``profile``): F_T, sigma0, rings and profile, each with ``met``, and ``every`` (True only
    when each of the four is met)."""
    q = row.get("elastic_quantities") or {}
    out = {}
    for key in ("F_T", "sigma0"):
        d = q.get(key) or {}
        out[key] = judge(d.get("bem"), d.get("bem_band"), d.get("fem"), d.get("fem_band"),
                         TARGETS[key])
    out["rings"] = _group([{"ring": r["ring"], **judge(
        r.get("elastic_N"), r.get("elastic_band_N"), r.get("fem_N"), r.get("fem_band_N"),
        TARGETS["rings"])} for r in row.get("ring_forces") or []], TARGETS["rings"])
    out["profile"] = _group([{"r_over_radius": p["r_over_radius"], **judge(
        p.get("elastic_Pa"), p.get("elastic_band_Pa"), p.get("fem_Pa"), p.get("fem_band_Pa"),
        TARGETS["profile"])} for p in row.get("profile") or []], TARGETS["profile"])
    out["every"] = all(out[k]["met"] is True for k in TARGETS)
    return out


def targets_met(rows: list[dict]) -> dict:
    """How many scenes meet every target: ``{"scenes", "of", "text"}``."""
    n = sum(1 for r in rows if (r.get("targets") or {}).get("every"))
    return {"scenes": n, "of": len(rows),
            "text": f"{n} of {len(rows)} scenes meet every target of the elastic BEM"}


def compare_point(point: LatticePoint, fem_outcomes, bem_outcomes, elastic_outcomes=(),
                  dense_outcomes=(), rung_outcomes=()) -> dict:
    """One scene of the study: the three ladders, each BEM's differences beside the bands, the
    rings, the profile and the elastic BEM's targets."""
    fem = _ladder(fem_outcomes, "mesh_size", 1.0)
    bems = {HOOKE: _ladder(bem_outcomes, "cells_per_diameter", -1.0),
            ELASTIC: _ladder(elastic_outcomes, "cells_per_diameter", -1.0)}
    row = {"label": point.label, "title": point.title,
           "surface_fraction": point.surface_fraction, "ratio": point.ratio,
           "substrate": point.substrate, "substrate_E_Pa": point.substrate_E_Pa,
           "zeta_um": point.zeta_um, "fem_error": fem["error"],
           "bem_error": bems[HOOKE]["error"],
           "elastic_error": bems[ELASTIC]["error"], "quantities": {},
           "elastic_quantities": {}}
    failed = {name: ladder for name, ladder in
              (("fem-3d", fem), (BEM_NAMES[HOOKE], bems[HOOKE]),
               (BEM_NAMES[ELASTIC], bems[ELASTIC])) if ladder["error"]}
    good = {k: v for k, v in bems.items() if not v["error"]} if not fem["error"] else {}
    if good:
        row["converged"] = all(r["converged"] for ladder in [fem, *good.values()]
                               for r in ladder["levels"])
        row["pillars_in_contact"] = {"fem": fem["results"][-1].pillars_in_contact} | {
            ("bem" if k == HOOKE else k): v["results"][-1].pillars_in_contact
            for k, v in good.items()}
        row["fem_levels"] = fem["levels"]
    if HOOKE in good:
        row["quantities"] = _differences(fem, good[HOOKE])
        row["rings"] = _rings(fem, good[HOOKE])
        row["bem_levels"] = good[HOOKE]["levels"]
    if ELASTIC in good:
        row["elastic_quantities"] = _differences(fem, good[ELASTIC])
        row["elastic_rings"] = _rings(fem, good[ELASTIC])
        row["elastic_levels"] = good[ELASTIC]["levels"]
    if dense_outcomes:
        row["elastic_dense_levels"] = _single_levels(dense_outcomes, "elements_per_diameter")
    if rung_outcomes:
        row["elastic_fft_rungs"] = _single_levels(rung_outcomes, "cells_per_diameter")
    if good:
        radius = point.scene().pillars.diameter_m / 2.0
        row["ring_forces"] = _ring_estimates(fem, good)
        row["profile"] = _profile_estimates(fem, good, radius)
    row["targets"] = evaluate_targets(row)
    if failed:
        row["status"] = "failed: " + "; ".join(f"{name}: {ladder['error']}"
                                               for name, ladder in failed.items())
        row["exit"] = max(ladder["exit"] for ladder in failed.values())
    else:
        row["status"] = "ok" if row["converged"] else "not converged"
    return row


def lattice_study(folder, *, engine: Engine | None = None, points=None, fem_levels=FEM_LEVELS,
                  bem_levels=BEM_LEVELS, dense_levels=DENSE_LEVELS,
                  fft_rungs=FFT_RUNGS) -> dict:
    """Run (or resume) the study into ``folder``/cases; returns the JSON-ready report.
    ``points`` default to :func:`default_points` (the E_s = E_l grid and the E_s = E_p
    scenes); they share one indentation."""
    from pathlib import Path

    points = list(points or default_points())
    zetas = {p.zeta_um for p in points}
    if len(zetas) != 1:
        raise InputError(f"lattice study: the scenes have indentations {sorted(zetas)} um; "
                         "one study runs at one zeta")
    engine = engine or Engine("serial")
    all_cases = [c for p in points
                 for c in cases(p, fem_levels, bem_levels, dense_levels, fft_rungs)]
    # Cheap cases first: the Hooke BEM, then the elastic BEMs (2-3x the Hooke time, and one
    # pillar compliance per kind, cached), then the FEM from coarse to fine: a long run
    # shows its BEM columns early and an interruption loses at most one FEM solve.
    order = sorted(range(len(all_cases)),
                   key=lambda i: (all_cases[i].model == FEM_MODEL,
                                  all_cases[i].options.get("pillars") == "elastic",
                                  -all_cases[i].options.get("mesh_size", 0.0), i))
    outcomes = [None] * len(all_cases)
    ran = engine.run([all_cases[i] for i in order], Path(folder) / "cases", "lattice")
    for i, o in zip(order, ran):
        outcomes[i] = o
    rows, k = [], 0
    sizes = (len(fem_levels), len(bem_levels), len(bem_levels), len(dense_levels),
             len(fft_rungs))
    for p in points:
        parts = []
        for n in sizes:
            parts.append(outcomes[k:k + n])
            k += n
        rows.append(compare_point(p, *parts))
    conventions = [c for c in CONVENTIONS if any(p.substrate == c for p in points)]
    return {"zeta_um": zetas.pop(), "E_lens_Pa": E_LENS,
            "substrate": conventions[0] if len(conventions) == 1
            else "per scene: " + ", ".join(conventions),
            "substrates": conventions,
            "fem": {"model": FEM_MODEL, "mesh_size": list(fem_levels)},
            "bem": {"model": BEM_MODEL, "pillars": HOOKE,
                    "cells_per_diameter": list(bem_levels)},
            "elastic": {"model": BEM_MODEL, "pillars": ELASTIC,
                        "cells_per_diameter": list(bem_levels)},
            "dense_elastic": {"model": DENSE_MODEL, **DENSE_OPTIONS,
                              "elements_per_diameter": list(dense_levels)},
            "targets": {**TARGETS, "rule": TARGET_RULE,
                        "profile_points_over_radius": list(PROFILE_POINTS)},
            "targets_met": targets_met(rows),
            "rows": rows}


# --- tables ---------------------------------------------------------------------------------
def _convention(row: dict) -> str:
    """``Es=El`` or ``Es=Ep`` (a row of an older report has no ``substrate``: E_s = E_l)."""
    return row.get("substrate", LENS).replace(" ", "").replace("_", "")


def _difference_table(report: dict, key: str) -> str:
    """Plain-text table of one BEM (``quantities``: Hooke; ``elastic_quantities``): per scene
    and quantity, the FEM/BEM difference and the band."""
    rings = "rings" if key == "quantities" else "elastic_rings"
    pillars = "bem" if key == "quantities" else ELASTIC
    head = (f"{'Phi':>6} {'Ep/El':>7} {'Es':>5} "
            + " ".join(f"{q.key + ' diff':>12} {'band':>7}" for q in QUANTITIES[:3])
            + f" {'pillars F/B':>12} {'ring0 F/B':>9}")
    lines = [head]
    for r in report["rows"]:
        start = f"{r['surface_fraction']:>6g} {r['ratio']:>7g} {_convention(r):>5}"
        if not r.get(key):
            lines.append(f"{start}  {r['status']}")
            continue
        cells = []
        for q in QUANTITIES[:3]:
            d = r[key][q.key]
            if d["difference"] is None:
                cells.append(f"{'-':>12} {'-':>7}")
                continue
            mark = "*" if d["significant"] else " "
            cells.append(f"{100 * d['difference']:>+11.2f}%{mark}{100 * d['band']:>6.2f}%")
        ring0 = next((x["ring_force_ratio"] for x in r.get(rings, []) if x["ring"] == 0), None)
        pic = r["pillars_in_contact"]
        lines.append(f"{start} " + " ".join(cells)
                     + f" {pic['fem']:>5d}/{pic[pillars]:<6d} "
                     + ("-" if ring0 is None else f"{ring0:>9.4f}")
                     + ("" if r["status"] == "ok" else
                        "  NOT CONVERGED" if r["status"] == "not converged" else
                        f"  {r['status']}"))
    return "\n".join(lines)


def _pct(v) -> str:
    return "-" if v is None else f"{100 * v:+.2f}%"


def _verdict(d: dict, error: str = "error") -> str:
    mark = {True: "ok", False: "MISS", None: "n/a"}[d["met"]]
    allowed = d.get("allowed", d.get("worst_allowed"))
    err = d.get(error)
    return f"{_pct(err):>8} /{'-' if allowed is None else f'{100 * allowed:.2g}%':>5} {mark:<4}"


def targets_table(report: dict) -> str:
    """Per scene: each target's error (the worst ring and profile point), what it may be, and
    whether it is met."""
    head = (f"{'Phi':>6} {'Ep/El':>7} {'Es':>5}  {'F_T':^19} {'sigma0':^19} "
            f"{'rings (worst)':^19} {'profile (worst)':^19} all")
    lines = [head]
    for r in report["rows"]:
        t = r.get("targets") or evaluate_targets(r)
        lines.append(f"{r['surface_fraction']:>6g} {r['ratio']:>7g} {_convention(r):>5}  "
                     f"{_verdict(t['F_T'])} {_verdict(t['sigma0'])} "
                     f"{_verdict(t['rings'], 'worst_error')} "
                     f"{_verdict(t['profile'], 'worst_error')} "
                     + ("yes" if t["every"] else "no"))
    met = report.get("targets_met") or targets_met(report["rows"])
    lines.append(f"error = (elastic BEM - FEM) / FEM / allowed: the target or both bands where "
                 f"wider; {met['text']}")
    return "\n".join(lines)


def table_text(report: dict) -> str:
    """Plain-text tables: each BEM's FEM/BEM differences beside the bands, and the elastic
    BEM's targets."""
    note = ("diff = (FEM - BEM) / BEM of the Richardson estimates; band = both GCI bands "
            "over BEM; * = beyond the band (a modelling difference, not noise); Es: the "
            "substrate convention (Es=El: E_s = E_l, Es=Ep: E_s = E_p)")
    return "\n".join([f"Hooke BEM ({report['bem']['model']}) against {report['fem']['model']}",
                      _difference_table(report, "quantities"), "",
                      f"elastic-pillar BEM ({report['elastic']['model']}, pillars = elastic) "
                      f"against {report['fem']['model']}",
                      _difference_table(report, "elastic_quantities"), note, "",
                      "targets of the elastic BEM against fem-3d",
                      targets_table(report)])


def _csv(cols: list[str], rows: list[dict]) -> str:
    import csv
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, cols, restval="", lineterminator="\r\n")
    w.writeheader()
    for row in rows:
        # repr of a float, never of numpy's scalar type (``np.float64(...)``, which the
        # studies' bands are): a value reads back with float() exactly.
        w.writerow({k: "" if v is None else repr(float(v)) if isinstance(v, float) else v
                    for k, v in row.items()})
    return buf.getvalue()


def _quantity_columns(q, kind: str) -> dict[str, str]:
    """The lattice.csv column of each field of one BEM's comparison on quantity ``q`` (the
    Hooke BEM's as they were before the elastic column: ``F_T_bem_N``, ``F_T_difference``)."""
    u = q.unit
    if kind == HOOKE:
        own = {"bem": f"{q.key}_bem_{u}", "bem_band": f"{q.key}_bem_band_{u}",
               "difference": f"{q.key}_difference", "band": f"{q.key}_band",
               "significant": f"{q.key}_significant"}
    else:
        own = {"bem": f"{q.key}_{kind}_{u}", "bem_band": f"{q.key}_{kind}_band_{u}",
               "difference": f"{q.key}_{kind}_difference",
               "band": f"{q.key}_{kind}_difference_band",
               "significant": f"{q.key}_{kind}_significant"}
    return {"fem": f"{q.key}_fem_{u}", "fem_band": f"{q.key}_fem_band_{u}", **own}


def rows_csv(report: dict) -> str:
    """lattice.csv, one line per scene: the Hooke columns first, then the
    substrate, the elastic BEM's columns and its targets."""
    cols = ["surface_fraction", "Ep_over_El", "status", "pillars_fem", "pillars_bem"]
    for q in QUANTITIES:
        cols += list(_quantity_columns(q, HOOKE).values())
    cols += ["substrate", "substrate_E_Pa", "pillars_elastic"]
    for q in QUANTITIES:
        cols += [c for f, c in _quantity_columns(q, ELASTIC).items() if not f.startswith("fem")]
    for t in ("F_T", "sigma0"):
        cols += [f"target_{t}_error", f"target_{t}_allowed", f"target_{t}_met"]
    for t in ("rings", "profile"):
        cols += [f"target_{t}_worst_error", f"target_{t}_worst_allowed", f"target_{t}_met"]
    cols += ["targets_met"]
    out = []
    for r in report["rows"]:
        pic = r.get("pillars_in_contact") or {}
        row = {"surface_fraction": r["surface_fraction"], "Ep_over_El": r["ratio"],
               "status": r["status"], "pillars_fem": pic.get("fem"),
               "pillars_bem": pic.get("bem"), "substrate": r.get("substrate", LENS),
               "substrate_E_Pa": r.get("substrate_E_Pa"), "pillars_elastic": pic.get(ELASTIC)}
        for q in QUANTITIES:
            for kind, key in ((HOOKE, "quantities"), (ELASTIC, "elastic_quantities")):
                d = (r.get(key) or {}).get(q.key)
                if d:
                    row.update({c: d[f] for f, c in _quantity_columns(q, kind).items()})
        t = r.get("targets") or evaluate_targets(r)
        for k in ("F_T", "sigma0"):
            row.update({f"target_{k}_error": t[k]["error"], f"target_{k}_allowed": t[k]["allowed"],
                        f"target_{k}_met": t[k]["met"]})
        for k in ("rings", "profile"):
            row.update({f"target_{k}_worst_error": t[k]["worst_error"],
                        f"target_{k}_worst_allowed": t[k]["worst_allowed"],
                        f"target_{k}_met": t[k]["met"]})
        row["targets_met"] = t["every"]
        out.append(row)
    return _csv(cols, out)


RING_COLUMNS = ["pillars", "ratio_mean", "ratio_min", "ratio_max", "ring_force_ratio",
                "ring_force_ratio_change", "fem_only", "bem_only"]


def rings_csv(report: dict) -> str:
    """rings.csv, one line per scene and ring: the Hooke BEM's finest-level ratios, then the
    elastic BEM's, each model's Richardson ring force and the ring target."""
    cols = ["surface_fraction", "Ep_over_El", "ring", *RING_COLUMNS, "fem_force_N",
            "bem_force_N", "substrate", *(f"elastic_{c}" for c in RING_COLUMNS),
            "elastic_force_N", "fem_estimate_N", "fem_band_N", "bem_estimate_N", "bem_band_N",
            "elastic_estimate_N", "elastic_band_N", "target_error", "target_allowed",
            "target_met"]
    out = []
    for r in report["rows"]:
        hooke = {x["ring"]: x for x in r.get("rings", [])}
        elastic = {x["ring"]: x for x in r.get("elastic_rings", [])}
        est = {x["ring"]: x for x in r.get("ring_forces", [])}
        checks = {c["ring"]: c for c in ((r.get("targets") or {}).get("rings") or {}).get(
            "checks", [])}
        for k in sorted(set(hooke) | set(elastic) | set(est)):
            h, e, s, c = hooke.get(k, {}), elastic.get(k, {}), est.get(k, {}), checks.get(k, {})
            row = {"surface_fraction": r["surface_fraction"], "Ep_over_El": r["ratio"],
                   "ring": k, "substrate": r.get("substrate", LENS),
                   "fem_force_N": h.get("fem_force_N", e.get("fem_force_N")),
                   "bem_force_N": h.get("bem_force_N"), "elastic_force_N": e.get("bem_force_N"),
                   **{c_: h.get(c_) for c_ in RING_COLUMNS},
                   **{f"elastic_{c_}": e.get(c_) for c_ in RING_COLUMNS},
                   "fem_estimate_N": s.get("fem_N"), "fem_band_N": s.get("fem_band_N"),
                   "bem_estimate_N": s.get("hooke_N"), "bem_band_N": s.get("hooke_band_N"),
                   "elastic_estimate_N": s.get("elastic_N"),
                   "elastic_band_N": s.get("elastic_band_N"),
                   "target_error": c.get("error"), "target_allowed": c.get("allowed"),
                   "target_met": c.get("met")}
            out.append(row)
    return _csv(cols, out)


def profile_csv(report: dict) -> str:
    """profile.csv, one line per scene and radius: the centre pillar's top pressure along
    theta = 0 as each model's Richardson estimate and band, and the profile target."""
    cols = ["surface_fraction", "Ep_over_El", "substrate", "r_over_half_d", "r_m", "fem_Pa",
            "fem_band_Pa", "bem_Pa", "bem_band_Pa", "elastic_Pa", "elastic_band_Pa",
            "target_error", "target_allowed", "target_met"]
    out = []
    for r in report["rows"]:
        checks = {c["r_over_radius"]: c for c in ((r.get("targets") or {}).get("profile")
                                                  or {}).get("checks", [])}
        for p in r.get("profile", []):
            c = checks.get(p["r_over_radius"], {})
            out.append({"surface_fraction": r["surface_fraction"], "Ep_over_El": r["ratio"],
                        "substrate": r.get("substrate", LENS),
                        "r_over_half_d": p["r_over_radius"], "r_m": p["r_m"],
                        "fem_Pa": p.get("fem_Pa"), "fem_band_Pa": p.get("fem_band_Pa"),
                        "bem_Pa": p.get("hooke_Pa"), "bem_band_Pa": p.get("hooke_band_Pa"),
                        "elastic_Pa": p.get("elastic_Pa"),
                        "elastic_band_Pa": p.get("elastic_band_Pa"),
                        "target_error": c.get("error"), "target_allowed": c.get("allowed"),
                        "target_met": c.get("met")})
    return _csv(cols, out)


# --- report folder -----------------------------------------------------------------------
OUTPUTS = ("lattice.csv", "rings.csv", "profile.csv", "lattice.png", "profiles.png",
           "summary.md", "lattice.json")
# Line style of each BEM, marker of each substrate convention.
STYLES = {HOOKE: "--", ELASTIC: "-"}
MARKERS = {LENS: "o", PILLAR: "s"}


def plot_lattice(report: dict, path) -> None:
    """Four panels: (FEM - BEM) / BEM of F_T, sigma0 and a against Phi for both BEMs (Hooke
    dashed, elastic solid), one colour per E_p/E_l and one marker per substrate convention,
    both models' bands as error bars, the elastic BEM's targets shaded; and the FEM/BEM force
    ratio by ring."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from ..output.report import save_figure, stamp_not_converged

    rows = [r for r in report["rows"] if r.get("quantities") or r.get("elastic_quantities")]
    ratios = sorted({r["ratio"] for r in rows})
    colours = dict(zip(ratios, plt.cm.viridis(np.linspace(0.0, 0.9, max(len(ratios), 1)))))
    fig, axes = plt.subplots(2, 2, figsize=(13, 8.5))
    names = {"F_T": "total force F_T", "sigma0": "centre pressure σ0", "a": "contact radius a"}
    keys = {HOOKE: ("quantities", "rings"), ELASTIC: ("elastic_quantities", "elastic_rings")}
    # Hooke and elastic points side by side at each Phi, so that their error bars do not hide
    # each other.
    shift = {HOOKE: 0.97, ELASTIC: 1.03}
    for ax, key in zip(axes.ravel()[:3], ("F_T", "sigma0", "a")):
        if key in TARGETS:
            ax.axhspan(-100 * TARGETS[key], 100 * TARGETS[key], color="tab:green", alpha=0.12,
                       lw=0)
        for kind, (qkey, _) in keys.items():
            for ratio in ratios:
                for conv in CONVENTIONS:
                    mine = sorted((r for r in rows if r["ratio"] == ratio
                                   and r.get("substrate", LENS) == conv
                                   and (r.get(qkey) or {}).get(key, {}).get("difference")
                                   is not None), key=lambda r: r["surface_fraction"])
                    if not mine:
                        continue
                    x = [shift[kind] * r["surface_fraction"] for r in mine]
                    y = [100 * r[qkey][key]["difference"] for r in mine]
                    err = [100 * r[qkey][key]["band"] for r in mine]
                    ax.errorbar(x, y, yerr=err, fmt=MARKERS[conv], ls=STYLES[kind], capsize=3,
                                color=colours[ratio],
                                mfc="none" if conv == PILLAR else colours[ratio])
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(xscale="log", xlabel="surface fraction Φ",
               ylabel="(FEM − BEM) / BEM (%)", title=names[key])
        ax.grid(True, which="both", alpha=0.3)
    ax = axes[1, 1]
    for r in rows:
        for kind, (_, rkey) in keys.items():
            rings = [x for x in r.get(rkey, []) if x["ring_force_ratio"] is not None]
            ax.plot([x["ring"] for x in rings], [x["ring_force_ratio"] for x in rings],
                    marker=MARKERS[r.get("substrate", LENS)], ls=STYLES[kind],
                    color=colours[r["ratio"]], lw=1,
                    mfc="none" if r.get("substrate", LENS) == PILLAR else colours[r["ratio"]])
    ax.axhline(1.0, color="k", lw=0.8)
    ax.axhspan(1 - TARGETS["rings"], 1 + TARGETS["rings"], color="tab:green", alpha=0.12, lw=0)
    ax.set(xlabel="lattice ring (0 = centre pillar)", ylabel="force FEM / BEM",
           title="per-ring force ratio (finest levels)")
    ax.grid(True, alpha=0.3)
    # One legend for the figure: colour = E_p/E_l, line = BEM, marker = substrate convention.
    handles = [Line2D([], [], color=colours[r], lw=2, label=f"E_p/E_l = {r:g}") for r in ratios]
    handles += [Line2D([], [], color="k", ls=STYLES[k], label=f"{BEM_NAMES[k]}")
                for k in (HOOKE, ELASTIC)]
    handles += [Line2D([], [], color="k", ls="", marker=MARKERS[c],
                       mfc="none" if c == PILLAR else "k", label=c)
                for c in CONVENTIONS if any(r.get("substrate", LENS) == c for r in rows)]
    handles.append(Line2D([], [], color="tab:green", alpha=0.3, lw=8,
                          label="elastic BEM's target"))
    axes[0, 1].legend(handles=handles, fontsize=8, loc="upper left",
                      bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    fig.suptitle(f"Hooke and elastic-pillar BEMs ({report['bem']['model']}) vs elastic-pillar "
                 f"FEM ({report['fem']['model']}), ζ = {report['zeta_um']:g} µm, "
                 f"{report['substrate']}; error bars: both GCI bands")
    bad = [r.get("label") or f"Phi={r['surface_fraction']:g} Ep/El={r['ratio']:g}"
           for r in report["rows"] if r["status"] != "ok"]
    if bad:
        stamp_not_converged(fig, bad)
    save_figure(fig, path)


def plot_profiles(report: dict, path) -> None:
    """The centre pillar's top pressure along theta = 0 on every scene: fem-3d's Richardson
    estimate with its band, the elastic BEM (solid) and the Hooke BEM (dashed), over r / (d/2);
    each panel's title says its scene, its convention and whether the profile target is met."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..output.report import save_figure, stamp_not_converged

    rows = [r for r in report["rows"] if r.get("profile")]
    n = max(len(rows), 1)
    ncol = min(4, n)
    nrow = -(-n // ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(max(3.4 * ncol, 8.0), 2.8 * nrow + 0.6),
                             squeeze=False)
    for ax in axes.ravel()[len(rows):]:
        ax.set_visible(False)
    for ax, r in zip(axes.ravel(), rows):
        prof = r["profile"]
        x = [p["r_over_radius"] for p in prof]

        def kpa(key):
            return [np.nan if p.get(key) is None else 1e-3 * p[key] for p in prof]

        fem, band = np.array(kpa("fem_Pa")), np.array(kpa("fem_band_Pa"))
        ax.fill_between(x, fem - band, fem + band, color="0.8", lw=0)
        ax.plot(x, fem, "k.-", lw=1, label="fem-3d")
        ax.plot(x, kpa("elastic_Pa"), "-", color="tab:red", label=BEM_NAMES[ELASTIC])
        ax.plot(x, kpa("hooke_Pa"), "--", color="tab:blue", label=BEM_NAMES[HOOKE])
        met = ((r.get("targets") or {}).get("profile") or {}).get("met")
        ax.set_title(f"Φ={r['surface_fraction']:g}, E_p/E_l={r['ratio']:g}, "
                     f"{r.get('substrate', LENS)}: {'met' if met else 'missed'}", fontsize=9)
        ax.set(xlabel="r / (d/2)", ylabel="p (kPa)")
        ax.grid(True, alpha=0.3)
    if rows:
        axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"centre pillar's top pressure along θ = 0, Richardson estimates (grey: "
                 f"fem-3d's band)\ntarget: elastic BEM within "
                 f"{100 * TARGETS['profile']:g} % for r < 0.9 d/2")
    bad = [r.get("label", "") for r in report["rows"] if r["status"] != "ok"]
    if bad:
        stamp_not_converged(fig, bad)
    save_figure(fig, path)


def summary_markdown(report: dict) -> str:
    t = report["targets"]
    met = report["targets_met"]
    lines = ["# Multi-pillar cross-validation: Hooke and elastic-pillar BEMs against the "
             "elastic-pillar 3D FEM", "",
             f"- zeta = {report['zeta_um']:g} um, Table 1 lens and pillars; substrate: "
             f"{report['substrate']} (column Es of each table)",
             f"- FEM: {report['fem']['model']}, mesh_size "
             f"{', '.join(f'{v:g}' for v in report['fem']['mesh_size'])}",
             f"- BEMs: {report['bem']['model']} with the paper's Hooke pillars and with elastic "
             f"pillars (pillars = elastic), cells per diameter "
             f"{', '.join(str(v) for v in report['bem']['cells_per_diameter'])}",
             "- each value is its model's Richardson estimate (or its finest level with the "
             "spread band when the levels have no observed order)",
             f"- targets of the elastic BEM: F_T {100 * t['F_T']:g} %, sigma0 "
             f"{100 * t['sigma0']:g} %, every ring's force {100 * t['rings']:g} %, the centre "
             f"pillar's top profile along theta = 0 {100 * t['profile']:g} % at r / (d/2) = "
             + ", ".join(f"{x:g}" for x in t["profile_points_over_radius"])
             + f"; {t['rule']}", "",
             f"**{met['text']}.**", "",
             "```", table_text(report), "```", ""]
    for key, name in (("quantities", "Hooke"), ("elastic_quantities", "elastic")):
        sig = [f"{r.get('title') or r['surface_fraction']}: "
               + ", ".join(k for k, d in r[key].items() if d["significant"])
               for r in report["rows"] if r.get(key)
               and any(d["significant"] for d in r[key].values())]
        lines.append(f"Differences beyond both bands (modelling error of the {name} pillar):")
        lines += [f"- {s}" for s in sig] or ["- none"]
        lines.append("")
    missed = []
    for r in report["rows"]:
        tg = r.get("targets") or {}
        bad = [k for k in TARGETS if (tg.get(k) or {}).get("met") is not True]
        if bad:
            missed.append(f"{r.get('title') or r['surface_fraction']}: " + ", ".join(
                f"{k} {'not judged' if tg[k]['met'] is None else 'missed'}" for k in bad))
    lines.append("Elastic-BEM targets not met:")
    lines += [f"- {s}" for s in missed] or ["- none"]
    failed = [r for r in report["rows"] if r["status"] != "ok"]
    if failed:
        lines += ["", "**Not converged or failed:** " + "; ".join(
            f"{r.get('title') or r['surface_fraction']}: {r['status']}" for r in failed)]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out) -> list[str]:
    """The report folder, lattice.json last (its presence means a whole report)."""
    import json
    from pathlib import Path

    from pillar_xval.outcome import write_atomic

    out = Path(out)
    write_atomic(out / "lattice.csv", rows_csv(report))
    write_atomic(out / "rings.csv", rings_csv(report))
    write_atomic(out / "profile.csv", profile_csv(report))
    plot_lattice(report, out / "lattice.png")
    plot_profiles(report, out / "profiles.png")
    write_atomic(out / "summary.md", summary_markdown(report))
    write_atomic(out / "lattice.json", json.dumps(report, indent=2, allow_nan=False))
    return list(OUTPUTS)
