"""BEM (Hooke pillar) against FEM (elastic pillar) on one scene, with
the FEM's numerical uncertainty beside every difference.

Both models run on the same number of refinements (``levels``, 3 by default): the FEM from
mesh_size 2 (``FEM_COARSEST``; 2, 1, 0.5), the BEM from 11 elements per diameter (11, 23,
47).  Each model's uncertainty on each quantity is its GCI band U = GCI_fine |f1| (Roache,
Fs = 1.25), or, for a sequence without an observed order, the spread of the levels (marked);
the two bands add in quadrature.  A difference between the finest BEM and FEM values larger
than the combined band is marked: it is a model difference, not noise of the
discretisations.

Outputs (:data:`OUTPUTS`): summary.md, profiles.png and profiles.csv, the finest FEM VTU and a
pyvista render of its stress field revolved about the axis, and report.json, written last.

Three-way (``pillars="both"`` or ``("hooke", "elastic")``): the FEM runs once and both BEMs
(Hooke and elastic pillars) climb their ladders in the same batch; every row holds the FEM
and, under ``bems``, each BEM's value, band and difference against the FEM
(:func:`three_way_rows`); the table, the summary, profiles.csv (a ``pillars`` column) and
profiles.png (both BEMs and the FEM, with the FEM's GCI band at the sampled radii) show the
three.
"""

from __future__ import annotations

import json
import math
import shutil
import time
from functools import partial
from pathlib import Path

import numpy as np

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import Scene, analytic

from ..engine import Engine
from ..registry import QUANTITIES, ladder_for, quantity_values, reference_model
from ..registry.options import pillar_models
from ..analysis.profiles import profile_at
from ..output.report import scene_label
from ._ladder import check_ladder, level_cases, profile_key, profile_studies, study_levels
from .targets import TARGETS, judge

FEM, FEM_3D, BEM = reference_model("single-pillar"), reference_model("lattice"), "bem"
FEM_MODELS = (FEM, FEM_3D)
# Display units: (scale factor from SI, unit label).
DISPLAY = {"F_T": (1e6, "uN"), "sigma0": (1e-3, "kPa"), "a": (1e6, "um"), "A": (1e12, "um^2"),
           "profile": (1e-3, "kPa")}
# Profile sample points r / r_ref; the edge (r_ref) is singular for a stiff pillar, so the
# comparison stops short of it (PHYSICS.md, "The elastic pillar").
PROFILE_POINTS = (0.25, 0.5, 0.75, 0.9)
# FEM levels 2, 1, 0.5 by default: measured on single-pillar (hertz), mesh_size 2 / 1 / 0.5 /
# 0.25 took 0.5 / 1.1 / 8-20 / 290 s (0.6 / 6 / 122 s for 0.5 / 0.25), while F_T moved by
# 1e-4 relative from 1 to 0.5: the 0.25 level would cost minutes for a band already < 0.1 %.
# fem-3d: 2.83, 2, 1.41 (its ladder's sqrt(2) steps): about a minute on a 7-pillar scene and
# 4-5 minutes on the paper's densest one (validation/bench/fem3d.py).
FEM_COARSEST = {FEM: 2.0, FEM_3D: 2.0 * 2.0**0.5}
# The report folder's files, report.json last: its presence means a whole report.
OUTPUTS = ("summary.md", "profiles.png", "profiles.csv", "fem_finest.vtu", "fem_finest.json",
           "fem_stress_3d.png", "report.json")


def pillar_label(pillars: str) -> str:
    """The pillar model as titles and legends write it."""
    return "Hooke" if pillars == "hooke" else pillars


def fem_model_for(scene: Scene) -> str:
    """The cheapest FEM that represents ``scene``: the axisymmetric model on a flat scene or
    one pillar alone (Phi below the spring-model threshold Phi_S), fem-3d otherwise."""
    if scene.is_flat or \
            scene.pillars.surface_fraction < analytic.single_pillar_threshold_rim(scene):
        return FEM
    return FEM_3D


def reference_radius(scene: Scene) -> tuple[float, str]:
    """Radius (m) the profile is normalised by: d/2 on a pillar, the Hertz a on a flat."""
    if scene.is_flat:
        return analytic.hertz(scene).contact_radius, "a_Hertz"
    return scene.pillars.diameter_m / 2.0, "d/2"


def closed_form(scene: Scene) -> tuple[str, dict]:
    """Hertz values on a flat scene; the spring model (one Hooke pillar) for one pillar alone;
    none on a lattice scene with several pillars in contact."""
    r_ref, _ = reference_radius(scene)
    if fem_model_for(scene) == FEM_3D:
        return "none", {}
    r = np.array(PROFILE_POINTS) * r_ref
    if scene.is_flat:
        h = analytic.hertz(scene)
        name, out = "Hertz", {"F_T": h.force, "sigma0": h.centre_pressure,
                              "a": h.contact_radius, "A": h.contact_area}
        profile = h.pressure(r)
    else:
        s = analytic.spring_model(scene)
        d = scene.pillars.diameter_m
        name, out = "spring model", {"F_T": s.force, "sigma0": s.centre_pressure, "a": d / 2.0,
                                     "A": math.pi * d * d / 4.0}
        profile = s.pressure(r)
    out.update({profile_key(x): float(v) for x, v in zip(PROFILE_POINTS, profile)})
    return name, out


def _band(st: dict | None) -> tuple[float | None, bool]:
    """(uncertainty in SI, whether it is a true GCI) from a verification study dict."""
    if st is None:
        return None, False
    g = st["gci"]
    if g["status"] == "ok":
        return g["uncertainty"], True
    return g["fallback_uncertainty"], False


def target_of(key: str) -> float | None:
    """The tolerance a BEM-FEM difference of quantity ``key`` is judged against
    (:data:`.targets.TARGETS`: F_T 1 %, sigma0 3 %, the top pressure 5 % for r < 0.9 d/2);
    None where none is stated (a, A, the edge's last tenth)."""
    if key.startswith("sigma(r="):
        return TARGETS["profile"] if float(key[8:-1]) < 0.9 else None
    return TARGETS.get(key)


def expected_model_errors(scene: Scene, pillars: str | None) -> dict:
    """The model error the planner expects of a BEM with ``pillars`` against the FEM's elastic
    pillars on ``scene``, per quantity (fractions, as the planner counts them: |error| plus
    its margin): the Hooke pillar's (its top profile: sigma0's); {} for the elastic pillar
    and on a flat scene, where the two models solve the same problem."""
    from ..planner.plan import hooke_error

    if scene.is_flat or pillars != "hooke":
        return {}
    out = {q.key: hooke_error(scene, q.key) for q in QUANTITIES}
    out.update({profile_key(x): out.get("sigma0") for x in PROFILE_POINTS})
    return {k: float(v) for k, v in out.items() if v is not None}


def compare_rows(bem: dict, fem: dict, bem_studies: dict | None, fem_studies: dict,
                 reference: dict, expected: dict | None = None) -> list[dict]:
    """One row per quantity: values, difference, uncertainty bands, whether the difference
    exceeds them (``exceeds``: a model difference) and the verdict: ``passed`` against the
    tolerance ``target`` (:func:`target_of`, widened to both bands: ``allowed``), with the
    model error the planner expects of this BEM (``expected``, per quantity) and whether a
    failing difference lies within it (``model_error``: the expected one)."""
    rows = []
    for key in [q.key for q in QUANTITIES] + [profile_key(x) for x in PROFILE_POINTS]:
        fb, ff = bem.get(key), fem.get(key)
        st_f = fem_studies.get(key)
        u_f, gci_f = _band(st_f)
        st_b = bem_studies.get(key) if bem_studies else None
        u_b, gci_b = _band(st_b)
        row = {"quantity": key, "bem": fb, "fem": ff, "closed_form": reference.get(key),
               "fem_richardson": None if st_f is None else st_f["gci"]["f_exact"],
               "fem_order": None if st_f is None else st_f["gci"]["order"],
               "fem_status": None if st_f is None else st_f["gci"]["status"],
               "bem_richardson": None if st_b is None else st_b["gci"]["f_exact"],
               "bem_status": None if st_b is None else st_b["gci"]["status"],
               "u_fem": u_f, "u_fem_is_gci": gci_f, "u_bem": u_b, "u_bem_is_gci": gci_b,
               "difference": None, "relative_difference": None, "uncertainty": None,
               "exceeds": None}
        if fb is not None and ff is not None:
            diff = fb - ff
            u = math.hypot(u_f or 0.0, u_b or 0.0) if u_f is not None else None
            row.update(difference=diff, uncertainty=u,
                       relative_difference=diff / ff if ff else None,
                       exceeds=None if u is None else bool(abs(diff) > u))
        target = target_of(key)
        verdict = judge(fb, u_b, ff, u_f, target) if target is not None else {}
        model = (expected or {}).get(key)
        row.update(target=target, allowed=verdict.get("allowed"), passed=verdict.get("met"),
                   expected_model_error=model,
                   model_error=bool(verdict.get("met") is False and model is not None
                                    and abs(verdict["error"]) <= model))
        rows.append(row)
    return rows


# The keys of a compare row that describe the BEM and its difference to the FEM; the others
# (quantity, FEM, closed form) are common to every BEM of a three-way row.
_BEM_KEYS = {"bem": "value", "u_bem": "u", "u_bem_is_gci": "u_is_gci",
             "bem_richardson": "richardson", "bem_status": "status",
             "difference": "difference", "relative_difference": "relative_difference",
             "uncertainty": "uncertainty", "exceeds": "exceeds", "allowed": "allowed",
             "passed": "passed", "expected_model_error": "expected_model_error",
             "model_error": "model_error"}


def three_way_rows(rows_by: dict[str, list[dict]]) -> list[dict]:
    """One row per quantity from each BEM's :func:`compare_rows` (``{pillars: rows}``, one
    FEM): the FEM's and the closed form's keys once, and under ``bems``, per pillar model,
    ``value``, ``u``, ``u_is_gci``, ``richardson``, ``status``, ``difference``,
    ``relative_difference``, ``uncertainty`` and ``exceeds`` (against the FEM)."""
    kinds = list(rows_by)
    out = []
    for k, first in enumerate(rows_by[kinds[0]]):
        row = {key: v for key, v in first.items() if key not in _BEM_KEYS}
        row["bems"] = {}
        for p in kinds:
            own = rows_by[p][k]
            assert own["quantity"] == row["quantity"]
            row["bems"][p] = {new: own[old] for old, new in _BEM_KEYS.items()}
        out.append(row)
    return out


def _values(result, r_ref: float) -> dict:
    vals = quantity_values(result)
    for x, v in zip(PROFILE_POINTS, profile_at(result.pillar_top_profile, r_ref, PROFILE_POINTS)):
        vals[profile_key(x)] = v
    return vals


def _quantity_name(key: str, r_label: str) -> str:
    _, unit = DISPLAY.get(key, DISPLAY["profile"])
    if key.startswith("sigma(r="):
        return f"p({key[8:-1]} {'a_H' if r_label != 'd/2' else 'd/2'}) [{unit}]"
    return f"{key} [{unit}]"


def _band_note(levels: int | None) -> str:
    """What the +-U columns are, for a ladder of ``levels`` levels."""
    if levels == 2:
        return ("U: two levels give no observed order: band = 3 |f_fine - f_coarse| (Fs = 3), "
                "marked *.")
    finest = "" if levels in (None, 3) else f"three finest of {levels} "
    return (f"U: GCI band GCI_fine |f| from each model's {finest}levels (Fs = 1.25); * = no "
            "observed order (oscillating or round-off), band = spread of the levels (x3 when "
            "oscillating).")


def _verdict(b: dict) -> str:
    """pass, FAIL, FAIL* (the model error the planner expects of this BEM) or - (no
    tolerance stated, or not judged)."""
    if b.get("passed") is None:
        return "-"
    return "pass" if b["passed"] else "FAIL*" if b.get("model_error") else "FAIL"


def _tolerance(r: dict) -> str:
    return "-" if r.get("target") is None else f"{100 * r['target']:g}%"


def verdict_notes(rows: list[dict], kinds) -> list[str]:
    """The lines under a table that say what its verdicts judge: the tolerance and its
    source, the expected model error of each BEM that has one, and '>U'."""
    lines = [f"verdict: pass when |BEM - FEM| / |FEM| is within tol (the elastic-pillar "
             f"BEM's targets: F_T {100 * TARGETS['F_T']:g} %, sigma0 "
             f"{100 * TARGETS['sigma0']:g} %, the top "
             f"pressure {100 * TARGETS['profile']:g} % for r < 0.9 d/2), or within both U "
             "bands where they are wider; '-': no tolerance stated."]
    for p in kinds:
        expected = {r["quantity"]: (r["bems"][p] if "bems" in r else r).get(
            "expected_model_error") for r in rows if r["quantity"] in ("F_T", "sigma0")}
        if any(v is not None for v in expected.values()):
            said = ", ".join(f"{q} up to {100 * v:.2g} %" for q, v in expected.items()
                             if v is not None)
            lines.append(f"FAIL*: within the {pillar_label(p)} pillar's expected model error "
                         f"(the planner's, on this scene: {said}): the difference the "
                         "paper's spring makes, not a fault; --pillars elastic removes it.")
    lines.append("'>U': |BEM - FEM| > sqrt(U_BEM^2 + U_FEM^2), a difference beyond the "
                 "numerical uncertainty.")
    return lines


def _cell(v, w: int = 10, f: str = ".5g", *, scale: float) -> str:
    """``v`` in display units (``v * scale``), right-aligned in ``w``; "-" where it is None."""
    return f"{'-':>{w}}" if v is None else f"{v * scale:>{w}{f}}"


def _band_cell(u, is_gci: bool, *, scale: float) -> str:
    """A band's cell: marked * when it is not a GCI."""
    mark = " " if is_gci else "*"
    return f"{'-':>9}" if u is None else f"{_cell(u, 8, '.2g', scale=scale)}{mark}"


def _three_way_text(rows: list[dict], ref_name: str, r_label: str,
                    levels: int | None = None) -> str:
    """The three-way table: each BEM and the FEM with their bands, and each BEM's relative
    difference against the FEM, marked where it exceeds the combined band, with its verdict
    against the tolerance."""
    has_ref = ref_name != "none"
    kinds = list(rows[0]["bems"])
    head = f"{'quantity':<18}"
    for p in kinds:
        head += f" {'BEM ' + pillar_label(p):>11} {'+-U':>9}"
    head += f" {'FEM':>10} {'+-U_FEM':>9} {'tol':>4}"
    for p in kinds:
        head += f" {pillar_label(p) + '-FEM':>11} {'>U':>3} {'verdict':>7}"
    head += f" {ref_name:>12}" if has_ref else ""
    lines = [head, "-" * len(head)]
    for r in rows:
        scale, _ = DISPLAY.get(r["quantity"], DISPLAY["profile"])

        fmt, band = partial(_cell, scale=scale), partial(_band_cell, scale=scale)
        line = f"{_quantity_name(r['quantity'], r_label):<18}"
        for p in kinds:
            b = r["bems"][p]
            line += f" {fmt(b['value'], 11)} {band(b['u'], b['u_is_gci'])}"
        line += f" {fmt(r['fem'])} {band(r['u_fem'], r['u_fem_is_gci'])} {_tolerance(r):>4}"
        for p in kinds:
            b = r["bems"][p]
            rel = "-" if b["relative_difference"] is None else \
                f"{100 * b['relative_difference']:+.2f}%"
            exceeds = "-" if b["exceeds"] is None else ("YES" if b["exceeds"] else "no")
            line += f" {rel:>11} {exceeds:>3} {_verdict(b):>7}"
        lines.append(line + (f" {fmt(r['closed_form'], 12)}" if has_ref else ""))
    lines.append(_band_note(levels) + " X-FEM: (BEM - FEM) / FEM.")
    return "\n".join(lines + verdict_notes(rows, kinds))


def table_text(rows: list[dict], ref_name: str, r_label: str, levels: int | None = None,
               pillars: str | None = None) -> str:
    """Fixed-width table of the comparison (display units); bands marked * are not a GCI;
    each difference with its verdict against the tolerance.  Three-way rows
    (:func:`three_way_rows`) give one column per BEM.  ``levels``: each model's ladder
    (the band note says how the bands came); ``pillars``: the BEM's pillar model, named in
    its column and its expected model error's note."""
    if rows and "bems" in rows[0]:
        return _three_way_text(rows, ref_name, r_label, levels)
    # No closed form applies (several pillars share the load): no column for it, rather than
    # one headed "none".
    has_ref = ref_name != "none"
    bem = "BEM" if not pillars else f"BEM {pillar_label(pillars)}"
    head = (f"{'quantity':<18} {bem:>11} {'+-U_BEM':>9} {'FEM':>10} {'+-U_FEM':>9} "
            f"{'FEM Richardson':>14} {'BEM-FEM':>10} {'rel':>8} {'>U':>3} {'tol':>4} "
            f"{'verdict':>7}" + (f" {ref_name:>12}" if has_ref else ""))
    lines = [head, "-" * len(head)]
    for r in rows:
        key = r["quantity"]
        scale, _ = DISPLAY.get(key, DISPLAY["profile"])
        name = _quantity_name(key, r_label)

        fmt, band = partial(_cell, scale=scale), partial(_band_cell, scale=scale)
        diff = r["difference"]
        if diff is not None and abs(diff) <= 1e-12 * max(abs(r["bem"]), abs(r["fem"])):
            diff = 0.0  # round-off
        rel = "-" if r["relative_difference"] is None else f"{100 * r['relative_difference']:+.2f}%"
        exceeds = "-" if r["exceeds"] is None else ("YES" if r["exceeds"] else "no")
        lines.append(f"{name:<18} {fmt(r['bem'], 11)} {band(r['u_bem'], r['u_bem_is_gci'])} "
                     f"{fmt(r['fem'])} {band(r['u_fem'], r['u_fem_is_gci'])} "
                     f"{fmt(r['fem_richardson'], 14)} {fmt(diff)} {rel:>8} {exceeds:>3} "
                     f"{_tolerance(r):>4} {_verdict(r):>7}"
                     + (f" {fmt(r['closed_form'], 12)}" if has_ref else ""))
    lines.append(_band_note(levels) + " rel: (BEM - FEM) / FEM.")
    return "\n".join(lines + verdict_notes(rows, [pillars] if pillars else []))


def _closed_form_curves(scene: Scene, fem_model: str, r_ref: float) -> list[dict]:
    """The closed forms' profiles where one applies (none on a lattice: several pillars share
    the load)."""
    r = np.linspace(0.0, 0.999 * r_ref, 400)
    if fem_model == FEM_3D:
        return []
    if scene.is_flat:
        return [{"label": "Hertz", "style": "k--", "r_m": r,
                 "pressure_Pa": analytic.hertz(scene).pressure(r)}]
    return [{"label": "rigid punch", "style": "k--", "r_m": r,
             "pressure_Pa": analytic.rigid_punch(scene).pressure(r)},
            {"label": "spring model (Hooke)", "style": "k-.", "r_m": r,
             "pressure_Pa": analytic.spring_model(scene).pressure(r)}]


def _profile_curves(scene: Scene, bem_res, fem_data: dict, r_ref: float) -> list[dict]:
    option = ladder_for(BEM).option
    disc = f"{option}={bem_res.discretisation.get(option, '?')}"
    bem = bem_name(scene, bem_res.diagnostics.get("pillars", "hooke"))
    curves = [{"label": f"{bem}, {disc}", "style": "o-",
               **bem_res.pillar_top_profile}]
    for lv, res in zip(fem_data["levels"], fem_data["results"]):
        finest = lv is fem_data["levels"][-1]
        curves.append({"label": f"FEM mesh_size={lv['value']:g}" + (" (finest)" if finest else ""),
                       "style": "-" if finest else ":", **res.pillar_top_profile})
    return curves + _closed_form_curves(scene, fem_data["model"], r_ref)


# Markers of each BEM in the three-way profile plot.
_BEM_STYLES = {"hooke": "o-", "elastic": "s-"}


def _three_way_curves(scene: Scene, bem_res: dict, fem_data: dict, fem_studies: dict,
                      r_ref: float) -> list[dict]:
    """Both BEMs' finest profiles, the finest FEM's, and the FEM's band (GCI, or the spread of
    its levels where it has no observed order) at the sampled radii where it has one."""
    option = ladder_for(BEM).option
    curves = [{"label": f"BEM ({pillar_label(p)} pillars), "
                        f"{option}={res.discretisation.get(option, '?')}",
               "style": _BEM_STYLES.get(p, "^-"), "markersize": 3, **res.pillar_top_profile}
              for p, res in bem_res.items()]
    fem_res, finest = fem_data["results"][-1], fem_data["levels"][-1]
    curves.append({"label": f"FEM {fem_data['model']} (elastic pillars), "
                            f"mesh_size={finest['value']:g}",
                   "style": "k-", **fem_res.pillar_top_profile})
    centre = profile_at(fem_res.pillar_top_profile, r_ref, PROFILE_POINTS)
    band = [(x, v, *_band(fem_studies.get(profile_key(x))))
            for x, v in zip(PROFILE_POINTS, centre)]
    band = [b for b in band if b[1] is not None and b[2] is not None]
    if band:
        gci = all(b[3] for b in band)
        curves.append({"label": "FEM +-U (GCI band)" if gci else
                                "FEM +-U (GCI band; spread of the levels where no order)",
                       "style": "none", "color": "k",
                       "r_m": [x * r_ref for x, *_ in band],
                       "pressure_Pa": [v for _, v, *_ in band],
                       "yerr_Pa": [u for _, _, u, _ in band]})
    return curves + _closed_form_curves(scene, fem_data["model"], r_ref)


def summary_markdown(scene: Scene, rows: list[dict], ref_name: str, r_label: str,
                     meta: dict) -> str:
    """summary.md: what ran, the table, and which differences exceed the uncertainty."""
    kinds = meta["pillars"] if isinstance(meta["pillars"], (list, tuple)) else None
    finest = (", ".join(f"{k}={v}" for k, v in meta["bem_discretisation"].items())
              if kinds is None else
              "; ".join(f"{pillar_label(p)}: " + ", ".join(f"{k}={v}" for k, v in d.items())
                        for p, d in meta["bem_discretisation"].items()))
    bems = ("BEM" if kinds is None else
            "BEMs (" + ", ".join(f"{pillar_label(p)} pillars" for p in kinds) + ")")
    lines = [f"# {title(scene, meta['fem_model'], meta['pillars'])}", "",
             f"- FEM ({meta['fem_model']}): {meta['levels']} levels of mesh_size "
             f"{', '.join(f'{v:g}' for v in meta['fem_sizes'])}; finest VTU: "
             f"`{meta['vtu'] or 'not written'}`",
             f"- {bems}: {meta['levels']} levels of elements_per_diameter "
             f"{', '.join(str(v) for v in meta['bem_sizes'])}; finest: " + finest,
             (f"- closed form: {ref_name}" if ref_name != "none" else
              "- closed form: none applies (several pillars share the load)")
             + f"; profile radii are r / ({r_label})",
             f"- render: {meta['render']}", f"- wall time: {meta['wall_time_s']:.1f} s", "",
             "```", table_text(rows, ref_name, r_label, meta["levels"],
                               None if scene.is_flat or kinds else meta["pillars"]),
             "```", ""]
    odd = [r for r in rows if r["fem_status"] not in (None, "ok")]
    if odd:
        lines.append("FEM sequences without an observed order: "
                     + "; ".join(f"{r['quantity']}: {r['fem_status']}" for r in odd))
    lines.append("")
    for p in kinds or [None]:
        own = [r["bems"][p] if p is not None else r for r in rows]
        name = bem_name(scene, p if p is not None else meta["pillars"])
        real = [r["quantity"] for r, b in zip(rows, own) if b["exceeds"]]
        lines.append(f"- {name} - FEM differences larger than the numerical uncertainty "
                     "(model differences): " + (", ".join(real) if real else "none"))
        judged = [(r["quantity"], b) for r, b in zip(rows, own) if b.get("passed") is not None]
        failed = [q for q, b in judged if not b["passed"] and not b.get("model_error")]
        expected = [q for q, b in judged if not b["passed"] and b.get("model_error")]
        lines.append(f"- {name} against the tolerance: {len(judged) - len(failed) - len(expected)}"
                     f" of {len(judged)} pass; FAIL: {', '.join(failed) or 'none'}"
                     + (f"; FAIL within the expected model error: {', '.join(expected)}"
                        if expected else ""))
    if meta.get("not_converged"):
        lines += ["", "**NOT CONVERGED**: " + "; ".join(meta["not_converged"])]
    return "\n".join(lines) + "\n"


def profiles_csv(bem_res, fem_res) -> str:
    """The pillar-top profiles of the finest BEM and FEM runs: model, r_m, pressure_Pa.  With
    several BEMs (``{pillars: result}``): model, pillars, r_m, pressure_Pa, the FEM's pillars
    being elastic."""
    if isinstance(bem_res, dict):
        series = [(res, p) for p, res in bem_res.items()] + [(fem_res, "elastic")]
        lines = ["model,pillars,r_m,pressure_Pa"]
        for res, p in series:
            prof = res.pillar_top_profile
            lines += [f"{res.model},{p},{r!r},{v!r}"
                      for r, v in zip(prof["r_m"], prof["pressure_Pa"])]
        return "\n".join(lines) + "\n"
    lines = ["model,r_m,pressure_Pa"]
    for label, res in ((bem_res.model, bem_res), (fem_res.model, fem_res)):
        prof = res.pillar_top_profile
        lines += [f"{label},{r!r},{p!r}" for r, p in zip(prof["r_m"], prof["pressure_Pa"])]
    return "\n".join(lines) + "\n"


def check_options(levels: int = 3, mesh_size: float | None = None,
                  elements_per_diameter: int | None = None, fem_model: str = FEM) -> None:
    """Refuse, before any solve, ladders whose levels a model would refuse (one line)."""
    check_ladder(fem_model, levels, FEM_COARSEST[fem_model] if mesh_size is None else mesh_size)
    check_ladder(BEM, levels, elements_per_diameter)


def compare_study(scene: Scene, out: Path, *, engine: Engine | None = None, levels: int = 3,
                  mesh_size: float | None = None, elements_per_diameter: int | None = None,
                  render: bool = True, fem_model: str | None = None,
                  pillars="hooke") -> dict:
    """Run both models on ``levels`` refinements each (one batch on the engine, cached in
    ``out/cases``), write the report folder and return the report dict (``rows``,
    ``converged``, ``not_converged``, ``render``, ...).

    ``fem_model`` is fem-axisym or fem-3d (default :func:`fem_model_for`: the axisymmetric
    model where it applies); ``mesh_size`` is its coarsest level (default
    :data:`FEM_COARSEST`),
    ``elements_per_diameter`` the BEM's (default its ladder's), ``pillars`` its pillar model
    (the paper's Hooke spring, or the elastic pillar), or several (``"both"``,
    ``"hooke,elastic"`` or a sequence: :func:`pillar_models`): a three-way comparison, the
    FEM once and one BEM per pillar model (rows: :func:`three_way_rows`; ``bems`` and
    ``bems_finest`` in place of ``bem`` and ``bem_finest``).  The files of an earlier
    report in ``out`` are removed first and ``report.json`` is written last, so the folder
    never mixes two runs."""
    from ..output.report import clear_outputs

    t0 = time.perf_counter()
    kinds = pillar_models(pillars)
    several = len(kinds) > 1
    fem = fem_model or fem_model_for(scene)
    check_options(levels, mesh_size, elements_per_diameter, fem)
    fem_coarsest = FEM_COARSEST[fem] if mesh_size is None else mesh_size
    cache = out / "cases"
    r_ref, r_label = reference_radius(scene)
    fem_cases = level_cases(fem, scene, levels, coarsest=fem_coarsest, tag="fem",
                            vtu_finest=True)
    bem_cases = {p: level_cases(BEM, scene, levels, coarsest=elements_per_diameter,
                                tag=f"bem {p}" if several else "bem",
                                options=None if p == "hooke" else {"pillars": p})
                 for p in kinds}
    clear_outputs(out, OUTPUTS, "compare")
    own = engine is None
    engine = engine or Engine("serial")
    try:
        outcomes = engine.run(fem_cases + [c for p in kinds for c in bem_cases[p]], cache,
                              label="compare")
    finally:
        if own:
            engine.close()
    fem_data = study_levels(fem, scene, outcomes[:len(fem_cases)])
    fem_res = fem_data["results"][-1]
    fem_studies = dict(fem_data["studies"]) | profile_studies(fem_data, r_ref, PROFILE_POINTS)
    ref_name, reference = closed_form(scene)
    bem_data, bem_res, rows_by = {}, {}, {}
    start = len(fem_cases)
    for p in kinds:
        bem_data[p] = study_levels(BEM, scene, outcomes[start:start + len(bem_cases[p])])
        start += len(bem_cases[p])
        bem_res[p] = bem_data[p]["results"][-1]
        bem_studies = dict(bem_data[p]["studies"]) | profile_studies(bem_data[p], r_ref,
                                                                     PROFILE_POINTS)
        rows_by[p] = compare_rows(_values(bem_res[p], r_ref), _values(fem_res, r_ref),
                                  bem_studies, fem_studies, reference,
                                  expected_model_errors(scene, p))
    rows = three_way_rows(rows_by) if several else rows_by[kinds[0]]
    unconverged = [f"{data['model']}"
                   + (f" ({pillar_label(p)} pillars)" if several and p else "")
                   + f" level {lv['level'] + 1} "
                   f"({data['ladder']['option']}={lv['value']}): {lv['message']}"
                   for p, data in [(None, fem_data)] + list(bem_data.items())
                   for lv in data["levels"] if not lv["converged"]]

    vtu = fem_data["levels"][-1]["vtu"]
    if vtu:
        sidecar = Path(vtu).with_suffix(".json")  # the model's parameters for the VTU
        vtu = str(shutil.copyfile(vtu, out / "fem_finest.vtu"))
        if sidecar.exists():
            shutil.copyfile(sidecar, out / "fem_finest.json")
    if not render:
        render_msg = "skipped (--no-render)"
    elif not vtu:
        render_msg = "not possible: the FEM model wrote no VTU"
    elif fem == FEM_3D:
        from ..output.render3d import render_sector

        ok, msg = render_sector(Path(vtu), out / "fem_stress_3d.png",
                                stamp="" if fem_res.converged else "NOT CONVERGED")
        render_msg = msg if ok else f"not rendered on this machine: {msg}"
    else:
        from ..output.render import render_stress

        ok, msg = render_stress(Path(vtu), out / "fem_stress_3d.png", roi_m=2.5 * r_ref,
                                stamp="" if fem_res.converged else "NOT CONVERGED")
        render_msg = msg if ok else f"not rendered on this machine: {msg}"
    from ..output.plots import plot_profiles

    where = ("contact" if scene.is_flat else
             "centre pillar top (θ = 0)" if several else "pillar top")
    curves = (_three_way_curves(scene, bem_res, fem_data, fem_studies, r_ref) if several
              else _profile_curves(scene, bem_res[kinds[0]], fem_data, r_ref))
    plot_profiles(curves, r_ref, out / "profiles.png",
                  f"pressure across the {where}: {scene_label(scene)}", r_label,
                  not_converged=unconverged)
    first = bem_data[kinds[0]]
    meta = {"levels": levels, "fem_model": fem,
            "pillars": list(kinds) if several else kinds[0],
            "fem_sizes": [lv["value"] for lv in fem_data["levels"]],
            "bem_sizes": [lv["value"] for lv in first["levels"]],
            "bem_discretisation": ({p: bem_res[p].discretisation for p in kinds} if several
                                   else bem_res[kinds[0]].discretisation),
            "vtu": vtu, "render": render_msg,
            "executor": engine.describe(), "wall_time_s": time.perf_counter() - t0}
    if several:
        bem_part = {"bems": {p: {k: v for k, v in d.items() if k != "results"}
                             for p, d in bem_data.items()},
                    "bems_finest": {p: res.to_dict() for p, res in bem_res.items()}}
    else:
        bem_part = {"bem": {k: v for k, v in first.items() if k != "results"},
                    "bem_finest": bem_res[kinds[0]].to_dict()}
    report = {"scene": scene.to_dict(), "closed_form": {"name": ref_name, **reference},
              "profile_radius_m": r_ref, "profile_points": list(PROFILE_POINTS), "rows": rows,
              "fem": {k: v for k, v in fem_data.items() if k != "results"},
              "fem_profile_studies": {k: v for k, v in fem_studies.items()
                                      if k.startswith("sigma(")},
              **bem_part, "fem_finest": fem_res.to_dict(),
              "converged": not unconverged, "not_converged": unconverged, **meta}
    write_atomic(out / "summary.md", summary_markdown(scene, rows, ref_name, r_label,
                                                      {**meta, "not_converged": unconverged}))
    write_atomic(out / "profiles.csv",
                 profiles_csv(bem_res if several else bem_res[kinds[0]], fem_res))
    write_atomic(out / "report.json", json.dumps(report, indent=2, allow_nan=False, default=str))
    return report


def bem_name(scene, pillars="hooke") -> str:
    """The BEM as a title calls it: its pillar model (a flat scene has no pillar); several
    pillar models (a three-way compare): each BEM, joined by 'and'."""
    if not isinstance(pillars, str):
        return " and ".join(f"BEM ({pillar_label(p)} pillars)" for p in pillars)
    return "BEM" if scene.is_flat else f"BEM ({pillar_label(pillars)} pillars)"


def title(scene, fem_model: str | None = None, pillars="hooke") -> str:
    if scene.is_flat and isinstance(pillars, str):
        return f"BEM vs FEM on {scene_label(scene)} (flat substrate: both solve the Hertz problem)"
    fem = fem_model or fem_model_for(scene)
    return f"{bem_name(scene, pillars)} vs {fem} (elastic pillars) on {scene_label(scene)}"
