"""``pillar-xval gecit``: the Gecit-like study of the Hooke-spring pillar.

Over stiffness ratios E_p/E_l and aspect ratios h/d on the single-pillar scene, the
Hooke-spring BEM is compared with the elastic-pillar FEM in F_T and sigma_0, and the shape of
the FEM pressure across the pillar top is measured: the centre plateau sigma(d/4)/sigma_0, the
exponent lambda of the edge singularity sigma ~ (d/2 - r)^(-lambda) (a rigid pillar gives the
flat punch's 1/2, a soft one none), and the share of the pillar force carried by the outer
10 % of the radius.  Each case is cached like ``converge``: a rerun resumes.

References
----------
.. [G] M. R. Gecit, "Axisymmetric contact problem for a semi-infinite cylinder and a half
   space", Int. J. Engng Sci. 24(8) (1986) 1245-1256 (cited by the seed paper: the passage
   from a rigid punch on an elastic half-space to an elastic cylinder on a rigid flat).
.. [J] K. L. Johnson, *Contact Mechanics*, 1985, eq. 3.35 (rigid punch: lambda = 1/2, outer
   10 % of the radius carries sqrt(1 - 0.9^2) = 43.6 % of the force).
"""

from __future__ import annotations

import csv
import io
import json
import os
import time
from pathlib import Path

import numpy as np

from scenes import load_scene, write_atomic

from .cmd_converge import (
    CASE_ERRORS, converge_study, ladder_for, progress, run_cached, run_many)

RATIOS = (1e-3, 1e-2, 0.1, 1.0, 10.0, 100.0, 1e3, 1e6)
ASPECTS = (0.25, 0.5, 1.0)
# Edge-exponent fit range, rho = d/2 - r relative to d/2, and the profile nodes next to the
# edge left out (four P2 elements); edge_exponent gives the measurements behind them.
EDGE_WINDOW = (0.004, 0.03)
EDGE_SKIP = 8
FEM, BEM = "fem-axisym", "bem"


# --- shape of a pressure profile (pure functions, SI) ------------------------------------
def _sorted_profile(profile: dict) -> tuple[np.ndarray, np.ndarray]:
    r = np.asarray(profile.get("r_m", []), dtype=float)
    p = np.asarray(profile.get("pressure_Pa", []), dtype=float)
    order = np.argsort(r)
    return r[order], p[order]


def plateau_ratio(profile: dict, radius_m: float, sigma0_Pa: float) -> float | None:
    """sigma(r = radius/2) / sigma_0 (for a pillar of radius d/2: the pressure at r = d/4)."""
    r, p = _sorted_profile(profile)
    x = 0.5 * radius_m
    if r.size < 2 or not r[0] <= x <= r[-1] or sigma0_Pa == 0:
        return None
    return float(np.interp(x, r, p)) / sigma0_Pa


def _load_inside(r: np.ndarray, p: np.ndarray, rho: float) -> float:
    """int_0^rho sigma 2 pi r dr by the trapezoid rule on the profile nodes (N)."""
    rr = np.concatenate([r[r < rho], [rho]])
    pp = np.concatenate([p[r < rho], [np.interp(rho, r, p)]])
    if rr[0] > 0:
        rr, pp = np.concatenate([[0.0], rr]), np.concatenate([[pp[0]], pp])
    return float(np.trapezoid(2.0 * np.pi * rr * pp, rr))


def outer_load_fraction(profile: dict, radius_m: float, force_N: float,
                        outer: float = 0.1) -> dict:
    """Share of ``force_N`` carried by radius_m (1 - outer) < r < radius_m.

    The inner part is integrated from the profile, where it is smooth; the remainder of the
    model's own force is the outer share (the nodal profile cannot integrate an edge
    singularity).  ``profile_integral_ratio`` = (trapezoid integral of the whole profile) / F
    tells how far the profile alone is from the force.
    """
    r, p = _sorted_profile(profile)
    if r.size < 2 or force_N <= 0 or r[-1] < (1.0 - outer) * radius_m:
        return {"outer_load_fraction": None, "profile_integral_ratio": None}
    inner = _load_inside(r, p, (1.0 - outer) * radius_m)
    whole = _load_inside(r, p, min(radius_m, r[-1]))
    return {"outer_load_fraction": 1.0 - inner / force_N,
            "profile_integral_ratio": whole / force_N}


def edge_exponent(profile: dict, radius_m: float, window: tuple[float, float] | None = EDGE_WINDOW,
                  points: int = 6, skip: int = EDGE_SKIP) -> dict:
    """Fit log sigma = c - lambda log(radius - r) near the edge of the pillar top.

    The ``skip`` profile nodes nearest the edge (and the edge node itself) are never used;
    of the others, those whose distance to the edge rho = radius - r lies in ``window``
    (relative to the radius) are fitted, or, with ``window=None``, the ``points`` nearest.

    Returns ``lambda`` (0.5 for a rigid punch), the fit range ``rho_min_m``..``rho_max_m`` (also
    relative to the radius), the node count ``n``, ``r_squared`` and ``drift``: lambda fitted on
    the half of the nodes nearest the edge minus lambda on the other half (0 for a pure power
    law).  ``status`` says why a field is None (too few nodes: the mesh is too coarse for the
    window).

    Why these defaults (FEM P2 profiles, two nodes per element, single-pillar scene,
    E_p/E_l = 1e6): over the last four elements the nodal pressures alternate between vertex
    and mid-side nodes (local slopes 0.25..0.65 at every mesh_size), so ``skip`` = 8 nodes.
    Outside that zone the vertex-to-vertex slope rises towards 1/2 as rho falls (mesh_size
    0.5: 0.485 at rho/radius = 0.05, 0.494..0.497 over 0.01..0.02); beyond rho/radius ~ 0.03
    the far field bends it (0.44 at 0.2).  Hence the window [0.004, 0.03]: at mesh_size 0.5
    it keeps 6 nodes (0.0085..0.027) and gives lambda = 0.49-0.50; at mesh_size 1 no node is
    left and the fit is refused instead of returning the biased 0.46 that a fit reaching
    into the alternating zone gave.
    """
    r, p = _sorted_profile(profile)
    rho = radius_m - r
    interior = rho > 1e-9 * radius_m
    rho, p = rho[interior], p[interior]
    order = np.argsort(rho)[skip:]
    rho, p = rho[order], p[order]
    keep = p > 0
    if window is not None:
        keep &= (rho >= window[0] * radius_m) & (rho <= window[1] * radius_m)
    rho, p = rho[keep], p[keep]
    order = np.arange(rho.size) if window is not None else np.arange(min(points, rho.size))
    out = {"lambda": None, "r_squared": None, "drift": None, "n": int(order.size),
           "rho_min_m": None, "rho_max_m": None, "rho_min_rel": None, "rho_max_rel": None,
           "window": None if window is None else list(window), "status": "ok"}
    if order.size < 3:
        out["status"] = (f"too few nodes with positive pressure in the fit range "
                         f"({order.size} < 3): refine the mesh or widen --edge-window")
        return out
    x, y = np.log(rho[order]), np.log(p[order])
    slope, c = np.polyfit(x, y, 1)
    ss = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 - float(np.sum((y - slope * x - c) ** 2)) / ss if ss > 0 else 1.0
    half = max(2, order.size // 2)
    inner = np.polyfit(x[:half], y[:half], 1)[0]
    outer_ = np.polyfit(x[-half:], y[-half:], 1)[0]
    out.update({"lambda": float(-slope), "r_squared": float(r2),
                "drift": float(-(inner - outer_)),
                "rho_min_m": float(rho[order].min()), "rho_max_m": float(rho[order].max())})
    out["rho_min_rel"] = out["rho_min_m"] / radius_m
    out["rho_max_rel"] = out["rho_max_m"] / radius_m
    return out


# --- the study ---------------------------------------------------------------------------
def add_parser(sub) -> None:
    """Register ``gecit`` on the CLI's subparsers."""
    p = sub.add_parser("gecit", help="Hooke-spring BEM against the elastic-pillar FEM over "
                                     "stiffness and aspect ratios (Gecit-like study)")
    p.add_argument("--scene", default="single-pillar",
                   help="base scene, preset or TOML file (default single-pillar)")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="TABLE.KEY=VALUE", help="override a base-scene value (repeatable)")
    p.add_argument("--out", type=Path, default=Path("out") / "gecit", help="report folder")
    p.add_argument("--ratios", type=float, nargs="+", default=list(RATIOS), metavar="E_p/E_l",
                   help="pillar-to-lens stiffness ratios (default: 1e-3 ... 1e6)")
    p.add_argument("--aspect", type=float, nargs="+", default=list(ASPECTS), metavar="h/d",
                   help="pillar height over diameter (default 0.25 0.5 1)")
    p.add_argument("--mesh-size", type=float, default=0.5, help="FEM mesh_size (default 0.5)")
    p.add_argument("--elements-per-diameter", type=int, default=None, metavar="P",
                   help="BEM elements per pillar diameter on the coarsest level (default 11)")
    p.add_argument("--bem-levels", type=int, default=3, metavar="N",
                   help="BEM refinements (default 3: 11, 23, 47 elements; errors use the "
                        "BEM's Richardson estimate; 1: the single level as it is)")
    p.add_argument("--edge-window", type=float, nargs=2, default=list(EDGE_WINDOW),
                   metavar=("LO", "HI"),
                   help="edge-exponent fit over LO < (d/2 - r)/(d/2) < HI (default "
                        f"{EDGE_WINDOW[0]:g} {EDGE_WINDOW[1]:g})")
    p.add_argument("--edge-skip", type=int, default=EDGE_SKIP, metavar="SKIP",
                   help=f"profile nodes next to the edge never fitted (default {EDGE_SKIP}: "
                        "four P2 elements, where nodal pressures alternate)")
    p.add_argument("--edge-nodes", type=int, default=None, metavar="N",
                   help="fit instead over the N nodes nearest the edge after the skipped ones")
    p.add_argument("--jobs", type=int, default=min(2, os.cpu_count() or 1), metavar="N",
                   help="FEM cases solved in parallel processes (default: up to 2)")
    p.add_argument("--fresh", action="store_true", help="recompute cached cases")
    p.set_defaults(func=run)


def study_cases(args) -> list[dict]:
    """The validated scenes of the study (refuses bad ratios before any solve)."""
    base = load_scene(args.scene, args.overrides)
    if base.pillars is None:
        raise ValueError(f"--scene {args.scene}: the Gecit-like study needs a scene with pillars")
    if any(not x > 0 for x in args.ratios) or any(not x > 0 for x in args.aspect):
        raise ValueError("--ratios and --aspect: values must be > 0")
    lo, hi = args.edge_window
    if not 0 < lo < hi < 1:
        raise ValueError(f"--edge-window {lo:g} {hi:g}: need 0 < LO < HI < 1")
    if args.jobs < 1:
        raise ValueError(f"--jobs {args.jobs}: must be >= 1")
    if not 1 <= args.bem_levels <= 5:
        raise ValueError(f"--bem-levels {args.bem_levels}: allowed range is 1..5")
    if (args.edge_nodes is not None and args.edge_nodes < 3) or args.edge_skip < 0:
        raise ValueError(f"--edge-nodes {args.edge_nodes}, --edge-skip {args.edge_skip}: need "
                         "N >= 3 and SKIP >= 0")
    if base.lens.material.rigid:
        raise ValueError("--scene: the stiffness ratio E_p/E_l needs an elastic lens")
    e_l, d_um = base.lens.material.E_Pa, base.pillars.diameter_m * 1e6
    cases = []
    for aspect in args.aspect:
        for ratio in args.ratios:
            sets = [*args.overrides, f"pillars.E_Pa={ratio * e_l!r}",
                    f"pillars.height_um={aspect * d_um!r}"]
            cases.append({"ratio": ratio, "aspect": aspect, "scene": load_scene(args.scene, sets)})
    return cases


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
    from scenes import analytic

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
        return "-" if v is None else f"{100 * v:+.2f}%"

    def band(v):
        return "-" if v is None else f"{100 * v:.2f}%"

    def num(v, f):
        return "-" if v is None else format(v, f)

    for r in rows:
        e = r.get("edge_fit") or {}
        rng = ("-" if e.get("rho_min_rel") is None
               else f"{e['rho_min_rel']:.1e}..{e['rho_max_rel']:.1e}")
        lines.append(
            f"{r['ratio']:>8.3g}{r['aspect']:>6.3g}{pct(r.get('err_F_T')):>9}"
            f"{band(r.get('U_BEM_F_T')):>7}{pct(r.get('err_sigma0')):>9}"
            f"{band(r.get('U_BEM_sigma0')):>7}{pct(r.get('err_F_spring')):>9}"
            f"{num(r.get('plateau'), '.3f'):>8}{num(r.get('edge_exponent'), '.3f'):>7}"
            f"{num(e.get('r_squared'), '.3f'):>6}{rng:>19}"
            f"{num(r.get('outer_load_fraction'), '.3f'):>9}"
            f"{num(r.get('fem_time_s'), '.1f'):>7}{num(r.get('bem_time_s'), '.1f'):>7}"
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


def run(args) -> int:
    """``pillar-xval gecit``: run or resume every case, write the table and figure; exit 1 if a
    case failed."""
    t0 = time.perf_counter()
    cases = study_cases(args)
    cache = args.out / "cases"
    fem_opts = {**ladder_for(FEM).fixed, ladder_for(FEM).option: args.mesh_size}
    bem_ladder = ladder_for(BEM)
    bem_opts = [bem_ladder.options(k, args.elements_per_diameter) for k in range(args.bem_levels)]
    tags = [f"gecit {i}/{len(cases)} E_p/E_l={c['ratio']:g} h/d={c['aspect']:g}"
            for i, c in enumerate(cases, 1)]
    fems = run_many(FEM, [(c["scene"], fem_opts, t) for c, t in zip(cases, tags)], cache,
                    workers=args.jobs, fresh=args.fresh)
    rows, cached, profiles = [], 0, []
    for case, tag, (fem, hit_f) in zip(cases, tags, fems):
        row = {"ratio": case["ratio"], "aspect": case["aspect"]}
        try:
            if isinstance(fem, Exception):
                raise fem
            if args.bem_levels >= 2:
                data = converge_study(BEM, case["scene"], args.bem_levels, cache, tag=tag,
                                      coarsest=args.elements_per_diameter, fresh=args.fresh)
                bem, studies = data["results"][-1], data["studies"]
                hit_b = all(lv["cached"] for lv in data["levels"])
            else:
                (bem, hit_b), studies = run_cached(BEM, case["scene"], bem_opts[0], cache,
                                                   fresh=args.fresh, tag=tag), None
            cached += hit_f and hit_b
            row.update(analyse_case(case["scene"], fem, bem, args.edge_window, args.edge_nodes,
                                    studies, args.edge_skip))
            profiles.append({"ratio": case["ratio"], "aspect": case["aspect"],
                             "radius_m": case["scene"].pillars.diameter_m / 2.0,
                             "sigma0_Pa": fem.centre_pressure_Pa, **fem.pillar_top_profile})
        except CASE_ERRORS as exc:  # one failed case is a row of the table
            progress(tag, f"FAILED: {exc}")
            row["status"] = f"failed: {exc}"
        rows.append(row)
    meta = {"base_scene": args.scene, "overrides": args.overrides, "fem_options": fem_opts,
            "bem_options": bem_opts, "edge_window": args.edge_window,
            "edge_nodes": args.edge_nodes, "edge_skip": args.edge_skip, "jobs": args.jobs,
            "wall_time_s": time.perf_counter() - t0}
    write_atomic(args.out / "gecit.json", json.dumps({**meta, "rows": rows}, indent=2,
                                                     allow_nan=False))
    write_atomic(args.out / "gecit.csv", rows_csv(rows))
    from .plots_xval import plot_gecit, plot_gecit_profiles

    plot_gecit([r for r in rows if r["status"] == "ok" or "err_F_T" in r], args.out / "gecit.png")
    plot_gecit_profiles(profiles, args.out / "gecit_profiles.png")
    print("Hooke-spring BEM vs elastic-pillar FEM: err = (BEM - FEM)/FEM with the BEM's "
          "Richardson estimate (+-U: its GCI band) when refined; 'spring F': closed-form spring "
          "model vs FEM")
    print(table_text(rows))
    print("lambda: sigma ~ (d/2 - r)^-lambda fitted in the window shown (R^2 means little when "
          "lambda ~ 0); plateau = sigma(d/4)/sigma0; outer10% = share of the pillar force on "
          "r > 0.45 d; t_FEM, t_BEM: solve times (s)")
    print(f"{len(rows)} cases ({cached} from the cache) in {meta['wall_time_s']:.1f} s; "
          f"report: {args.out}/ "
          "(gecit.json, gecit.csv, gecit.png, gecit_profiles.png)")
    return 0 if all(r["status"] == "ok" for r in rows) else 1
