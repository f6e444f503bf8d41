"""The Gecit-like study of the Hooke-spring pillar.

Over stiffness ratios E_p/E_l and aspect ratios h/d on the single-pillar scene, with the
substrate as stiff as the pillars (E_s = E_p, the paper's convention), the Hooke-spring BEM
is compared with the elastic-pillar FEM in F_T and sigma_0, and the shape of the FEM pressure
across the pillar top is measured (:mod:`validation.analysis.profiles`): the centre plateau
sigma(d/4)/sigma_0, the exponent lambda of the edge singularity
sigma ~ (d/2 - r)^(-lambda) (a rigid pillar gives the flat punch's 1/2, a soft one none), and
the share of the pillar force carried by the outer 10 % of the radius.  Every case runs on
the engine: a rerun resumes.

References
----------
.. [G] M. R. Gecit, "Axisymmetric contact problem for a semi-infinite cylinder and a half
   space", Int. J. Engng Sci. 24(8) (1986) 1245-1256 (cited by the seed paper: the passage
   from a rigid punch on an elastic half-space to an elastic cylinder on a rigid flat).
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from pathlib import Path

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import InputError, load_scene
from pillar_xval.scenes.floor import floor_onset_bound, floor_reachable

from ..engine import Case, Engine
from ..registry import check_option, get_model, ladder_for, reference_model
from ..analysis.profiles import (EDGE_SKIP, EDGE_WINDOW, edge_exponent, outer_load_fraction,
                                 plateau_ratio)
from ._ladder import check_ladder, study_levels
from ..output.formatting import number, percent

# The paper's convention (Table 1: E_p = E_s): every scene of the study has it.
CONVENTION = "E_s = E_p (substrate as stiff as the pillars, the paper's convention)"
OUTPUTS = ("gecit.csv", "gecit.png", "gecit_profiles.png", "gecit.json")
RATIOS = (1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3, 1e6)
ASPECTS = (0.25, 0.5, 1.0)
FEM, BEM = reference_model("single-pillar"), "bem"


def study_scenes(scene: str, overrides=(), ratios=RATIOS, aspects=ASPECTS) -> list[dict]:
    """The validated scenes of the study, one per (h/d, E_p/E_l): refuses bad ratios before
    any solve.  The substrate takes the pillars' modulus, E_s = E_p (the paper's convention,
    :data:`CONVENTION`), whatever the base scene's substrate."""
    base = load_scene(scene, overrides)
    if base.pillars is None:
        raise InputError(f"--scene {scene}: the Gecit-like study needs a scene with pillars")
    for flag_, values in (("--ratios", ratios), ("--aspect", aspects)):
        bad = [x for x in values if not 0 < x < math.inf]
        if bad or not values:
            raise InputError(f"{flag_} {' '.join(map(repr, bad))}: allowed range is (0, inf)")
    if base.lens.material.rigid:
        raise InputError("--scene: the stiffness ratio E_p/E_l needs an elastic lens")
    e_l, d_um = base.lens.material.E_Pa, base.pillars.diameter_m * 1e6
    cases = []
    for aspect in aspects:
        for ratio in ratios:
            e_p = ratio * e_l
            sets = [*overrides, f"pillars.E_Pa={e_p!r}", f"substrate.E_Pa={e_p!r}",
                    f"pillars.height_um={aspect * d_um!r}"]
            case = load_scene(scene, sets)
            if floor_reachable(case):
                raise InputError(
                    f"--aspect {aspect:g}: the lens reaches the floor between the pillars "
                    f"(its indentation passes h + g(d/2) = {floor_onset_bound(case) * 1e6:.4g} "
                    f"um), which {BEM} and {FEM} do not include; choose a taller pillar")
            cases.append({"ratio": ratio, "aspect": aspect, "scene": case})
    return cases


def check_fit_options(edge_window, edge_nodes, edge_skip, bem_levels,
                      mesh_size: float = 0.5, elements_per_diameter: int | None = None) -> None:
    """Refuse, before any solve, options the study would refuse later (one line each)."""
    lo, hi = edge_window
    if not 0 < lo < hi < 1:
        raise InputError(f"--edge-window {lo:g} {hi:g}: need 0 < LO < HI < 1")
    if not isinstance(bem_levels, int) or not 1 <= bem_levels <= 5:
        raise InputError(f"--levels {bem_levels!r}: allowed range is [1, 5]")
    if edge_nodes is not None and edge_nodes < 3:
        raise InputError(f"--edge-nodes {edge_nodes}: allowed range is >= 3")
    if edge_skip < 0:
        raise InputError(f"--edge-skip {edge_skip}: allowed range is >= 0")
    check_option("mesh_size", mesh_size, spec=get_model(FEM).options["mesh_size"])
    check_ladder(BEM, bem_levels, elements_per_diameter, lo=1)


def gecit_study(scenes: list[dict], cache_dir: Path, *, engine: Engine | None = None,
                mesh_size: float = 0.5, elements_per_diameter: int | None = None,
                bem_levels: int = 3, edge_window=EDGE_WINDOW, edge_nodes: int | None = None,
                edge_skip: int = EDGE_SKIP) -> dict:
    """Run (or resume) every FEM and BEM case of ``scenes`` (from :func:`study_scenes`) in
    one batch and analyse each scene; returns ``{"rows", "profiles", "meta"}``.  A scene whose
    case failed is a row with ``status = "failed: ..."``."""
    check_fit_options(edge_window, edge_nodes, edge_skip, bem_levels, mesh_size,
                      elements_per_diameter)
    t0 = time.perf_counter()
    fem_opts = ladder_for(FEM).options_at(mesh_size)
    bem_ladder = ladder_for(BEM)
    bem_opts = [bem_ladder.options(k, elements_per_diameter) for k in range(bem_levels)]
    batch = []
    for i, c in enumerate(scenes, 1):
        tag = f"{i}/{len(scenes)} E_p/E_l={c['ratio']:g} h/d={c['aspect']:g}" + (
            f" zeta={c['zeta_um']:g} um" if c.get("zeta_um") is not None else "")
        batch.append(Case(FEM, c["scene"], fem_opts, tag=tag))
        batch += [Case(BEM, c["scene"], o, tag=tag) for o in bem_opts]
    own = engine is None
    engine = engine or Engine("serial")
    try:
        outcomes = engine.run(batch, cache_dir, label="gecit")
    finally:
        if own:
            engine.close()
    per_scene = 1 + bem_levels
    rows, profiles, cached = [], [], 0
    for i, c in enumerate(scenes):
        fem_o, *bem_o = outcomes[i * per_scene:(i + 1) * per_scene]
        row = {"ratio": c["ratio"], "aspect": c["aspect"]}
        failed = next((o for o in (fem_o, *bem_o) if not o.ok), None)
        if failed is not None:
            row["status"] = f"failed: {failed.error}"
            row["refused"] = isinstance(failed.error, InputError)  # a model's scope, not a tool
            rows.append(row)
            continue
        cached += all(o.cached for o in (fem_o, *bem_o))
        if bem_levels >= 2:
            data = study_levels(BEM, c["scene"], bem_o)
            bem, studies = data["results"][-1], data["studies"]
        else:
            bem, studies = bem_o[0].result, None
        fem = fem_o.result
        row.update(analyse_case(c["scene"], fem, bem, edge_window, edge_nodes, studies,
                                edge_skip))
        rows.append(row)
        profiles.append({"ratio": c["ratio"], "aspect": c["aspect"],
                         "radius_m": c["scene"].pillars.diameter_m / 2.0,
                         "sigma0_Pa": fem.centre_pressure_Pa, **fem.pillar_top_profile})
    meta = {"convention": CONVENTION, "fem_options": fem_opts, "bem_options": bem_opts, "edge_window": list(edge_window),
            "edge_nodes": edge_nodes, "edge_skip": edge_skip, "executor": engine.describe(),
            "cached_cases": cached, "wall_time_s": time.perf_counter() - t0}
    return {"rows": rows, "profiles": profiles, "meta": meta}


def best_estimate(result, studies: dict | None, key: str, attr: str) -> dict:
    """The BEM value to compare: its Richardson estimate when the refinement study has an
    observed order, else the finest value with the fallback band (SI, band absolute)."""
    finest = float(getattr(result, attr))
    if studies is None:
        return {"value": finest, "band": None, "how": "finest (one level)"}
    g = studies[key]["gci"]
    if g["status"] == "ok":
        return {"value": g["f_exact"], "band": g["uncertainty"], "how": "Richardson"}
    return {"value": finest, "band": g["fallback_uncertainty"], "how": f"finest ({g['status']})"}


def analyse_case(scene, fem, bem, edge_window=EDGE_WINDOW, edge_nodes=None,
                 bem_studies: dict | None = None, edge_skip: int = EDGE_SKIP) -> dict:
    """One row of the study from the FEM and the (finest) BEM result of one scene (SI).

    With ``bem_studies`` (the BEM's refinement study) the BEM's discretisation error is
    removed by Richardson extrapolation, so that ``err_F_T`` and ``err_sigma0`` measure the
    Hooke-spring model, not the BEM mesh; ``U_BEM_*`` is the BEM's GCI band, relative.
    """
    from pillar_xval.scenes import analytic

    radius = scene.pillars.diameter_m / 2.0
    f_fem = fem.pillar_forces[0].force_N if fem.pillar_forces else fem.total_force_N
    spring = analytic.spring_model(scene)
    if edge_nodes is None:
        edge = edge_exponent(fem.pillar_top_profile, radius, tuple(edge_window), skip=edge_skip)
    else:
        edge = edge_exponent(fem.pillar_top_profile, radius, None, edge_nodes, edge_skip)
    f_b = best_estimate(bem, bem_studies, "F_T", "total_force_N")
    s_b = best_estimate(bem, bem_studies, "sigma0", "centre_pressure_Pa")
    f_f, s_f = fem.total_force_N, fem.centre_pressure_Pa
    row = {"E_p_Pa": scene.pillars.material.E_Pa, "h_m": scene.pillars.height_m,
           "F_FEM_N": f_f, "F_BEM_N": bem.total_force_N, "F_BEM_best_N": f_b["value"],
           "sigma0_FEM_Pa": s_f, "sigma0_BEM_Pa": bem.centre_pressure_Pa,
           "sigma0_BEM_best_Pa": s_b["value"],
           "err_F_T": (f_b["value"] - f_f) / f_f, "err_sigma0": (s_b["value"] - s_f) / s_f,
           "U_BEM_F_T": None if f_b["band"] is None else f_b["band"] / f_f,
           "U_BEM_sigma0": None if s_b["band"] is None else s_b["band"] / s_f,
           "bem_estimate": f"F_T: {f_b['how']}; sigma0: {s_b['how']}",
           "err_F_T_finest": (bem.total_force_N - f_f) / f_f,
           "err_sigma0_finest": (bem.centre_pressure_Pa - s_f) / s_f,
           "err_F_spring": (spring.force - fem.total_force_N) / fem.total_force_N,
           "plateau": plateau_ratio(fem.pillar_top_profile, radius, fem.centre_pressure_Pa),
           "edge_exponent": edge["lambda"], "edge_fit": edge,
           **outer_load_fraction(fem.pillar_top_profile, radius, f_fem),
           "bem_pillars_in_contact": bem.pillars_in_contact,
           "fem_time_s": fem.wall_time_s, "bem_time_s": bem.wall_time_s,
           "converged": bool(fem.converged and bem.converged)}
    row["status"] = "ok" if row["converged"] else "not converged"
    if bem.pillars_in_contact != 1:
        row["status"] = f"BEM has {bem.pillars_in_contact} pillars in contact (FEM: one)"
    return row


def table_text(rows: list[dict]) -> str:
    """Fixed-width table of the study (errors and bands in %)."""
    head = (f"{'E_p/E_l':>8}{'h/d':>6}{'err F_T':>9}{'+-U':>7}{'err sig0':>9}{'+-U':>7}"
            f"{'spring F':>9}"
            f"{'plateau':>8}{'lambda':>7}{'R^2':>6}{'fit (d/2-r)/(d/2)':>19}{'outer10%':>9}"
            f"{'t_FEM':>7}{'t_BEM':>7}  status")
    lines = [head, "-" * len(head)]

    def pct(v):
        return percent(v, "+.2f", "")

    def band(v):
        return percent(v, ".2f", "")

    for r in rows:
        e = r.get("edge_fit") or {}
        rng = ("-" if e.get("rho_min_rel") is None
               else f"{e['rho_min_rel']:.1e}..{e['rho_max_rel']:.1e}")
        lines.append(
            f"{r['ratio']:>8.3g}{r['aspect']:>6.3g}{pct(r.get('err_F_T')):>9}"
            f"{band(r.get('U_BEM_F_T')):>7}{pct(r.get('err_sigma0')):>9}"
            f"{band(r.get('U_BEM_sigma0')):>7}{pct(r.get('err_F_spring')):>9}"
            f"{number(r.get('plateau'), '.3f'):>8}{number(r.get('edge_exponent'), '.3f'):>7}"
            f"{number(e.get('r_squared'), '.3f'):>6}{rng:>19}"
            f"{number(r.get('outer_load_fraction'), '.3f'):>9}"
            f"{number(r.get('fem_time_s'), '.1f'):>7}{number(r.get('bem_time_s'), '.1f'):>7}"
            f"  {r['status']}")
    return "\n".join(lines)


CSV_COLUMNS = ("ratio", "aspect", "E_p_Pa", "h_m", "F_FEM_N", "F_BEM_N", "F_BEM_best_N",
               "err_F_T", "U_BEM_F_T", "err_F_T_finest", "sigma0_FEM_Pa", "sigma0_BEM_Pa",
               "sigma0_BEM_best_Pa", "err_sigma0", "U_BEM_sigma0", "err_sigma0_finest",
               "bem_estimate", "err_F_spring", "plateau",
               "edge_exponent", "edge_r_squared", "edge_drift", "edge_rho_min_m", "edge_rho_max_m",
               "edge_n", "outer_load_fraction", "profile_integral_ratio",
               "bem_pillars_in_contact", "fem_time_s", "bem_time_s", "status")


def rows_csv(rows: list[dict]) -> str:
    """CSV of the study, one row per (E_p/E_l, h/d), SI values, errors as fractions."""
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(CSV_COLUMNS)
    for r in rows:
        e = r.get("edge_fit") or {}
        flat = {**r, "edge_r_squared": e.get("r_squared"), "edge_drift": e.get("drift"),
                "edge_rho_min_m": e.get("rho_min_m"), "edge_rho_max_m": e.get("rho_max_m"),
                "edge_n": e.get("n")}
        w.writerow(["" if flat.get(c) is None else flat[c] for c in CSV_COLUMNS])
    return buf.getvalue()


def report_doc(doc: dict, extra_meta: dict | None = None) -> dict:
    """What gecit.json holds: the meta data and the rows."""
    return {**(extra_meta or {}), **doc["meta"], "rows": doc["rows"]}


def write_report(doc: dict, out: Path, extra_meta: dict | None = None) -> list[str]:
    """:data:`OUTPUTS` in ``out``, gecit.json last (its presence means a whole report)."""
    from ..output.plots import plot_gecit, plot_gecit_profiles

    rows = doc["rows"]
    write_atomic(out / "gecit.csv", rows_csv(rows))
    plot_gecit([r for r in rows if r["status"] == "ok" or "err_F_T" in r], out / "gecit.png",
               CONVENTION)
    plot_gecit_profiles(doc["profiles"], out / "gecit_profiles.png", CONVENTION)
    write_atomic(out / "gecit.json", json.dumps(report_doc(doc, extra_meta), indent=2,
                                                allow_nan=False))
    return list(OUTPUTS)
