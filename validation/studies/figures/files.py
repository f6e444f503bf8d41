"""The files of ``pillar-xval figures``: each figure's PNG (:mod:`.plots`) and the CSV
of its data (SI units, the unit in each column name; the first column, ``pillars``, names
the pillar model: ``hooke`` or ``elastic``)."""

from __future__ import annotations

import csv
import dataclasses
import io
from pathlib import Path

import numpy as np

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import Material, Scene, analytic

from . import plots
from .fits import master_curve
from .scenes import in_um as _um
from .scenes import pillar_height

__all__ = ["write_figures"]


def _csv(path: Path, header: list[str], rows) -> Path:
    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(header)
    for row in rows:
        w.writerow(["" if v is None else f"{v:.10g}" if isinstance(v, float) else v
                    for v in row])
    return write_atomic(path, buf.getvalue())


def write_figures(out: Path, docs: dict, pairs: dict) -> list[Path]:
    """Figs. 3-8 as PNG + CSV in ``out`` from the study's documents and (case, outcome) pairs,
    one of each per pillar model (``{"hooke": ..., "elastic": ...}``; Fig. 3 reads the
    pressure maps kept with its cases); several pillar models share each figure's axes and
    each CSV, whose first column ``pillars`` names the model.  Returns the paths."""
    from .maps import ElementMap, quadrant_extent

    paths = []
    variants = list(docs)
    first = docs[variants[0]]
    dpi = first["grid"]["dpi"]
    # Fig. 3
    panels, elements = [], []
    for v in variants:
        for c, o in pairs[v]["fig3"]:
            if not o.ok:
                continue
            res = o.result
            arrays = o.field_arrays()
            emap = ElementMap(res, arrays["pressure_Pa"])
            scene = c.scene
            panels.append({"result": res, "map": emap, "extent": quadrant_extent(res),
                           "hertz": analytic.hertz(scene), "punch": analytic.spring_model(scene),
                           "phi": scene.pillars.surface_fraction, "pillars": v})
            for x, y, w, p in zip(arrays["x_m"], arrays["y_m"], arrays["weight"],
                                  arrays["pressure_Pa"]):
                elements.append([v, scene.pillars.surface_fraction, float(x), float(y), int(w),
                                 float(p)])
    if panels:
        panels.sort(key=lambda p: (p["phi"], variants.index(p["pillars"])))
        paths.append(plots.plot_fig3(panels, out / "fig3.png", first["grid"]["map_pixels"],
                                     dpi, variants=variants))
        paths.append(_csv(out / "fig3.csv", ["pillars", "surface_fraction", "x_m", "y_m",
                                             "orbit_size", "pressure_Pa"], elements))
    # Fig. 4
    curves, area_rows, table = {}, {}, []
    for v in variants:
        doc = docs[v]
        curves[v] = {}
        for c in doc["fig4a_curves"]:
            s_h, s_s, ps, ph = (c["sigma0_hertz_Pa"], c["sigma0_single_Pa"], c["phi_s_fit"],
                                c["phi_h_fit"])
            curves[v][c["ratio"]] = {
                "phi": c["phi"], "sigma0_Pa": c["sigma0_Pa"],
                "master_Pa": (lambda x, s_h=s_h, s_s=s_s, ps=ps, ph=ph:
                              s_h + (s_s - s_h) * master_curve(x, ps, ph))}
        area_rows[v] = [r for r in doc["rows"]["fig4b"] if r.get("converged")]
        for r in doc["rows"]["fig4a"]:
            m = curves[v].get(r["ratio"])
            table.append([v, "a", r["ratio"], r["phi"], r["zeta_m"], r.get("sigma0_Pa"),
                          float(m["master_Pa"](r["phi"])) if m else None, r.get("a_m"), None,
                          r.get("A_m2"), r.get("F_N"), r.get("pillars")])
        for r in doc["rows"]["fig4b"]:
            table.append([v, "b", r["ratio"], r["phi"], r["zeta_m"], r.get("sigma0_Pa"), None,
                          r.get("a_m"),
                          np.pi * r["a_m"] ** 2 if r.get("a_m") is not None else None,
                          r.get("A_m2"), r.get("F_N"), r.get("pillars")])
    paths.append(plots.plot_fig4(curves, area_rows, out / "fig4.png", dpi))
    paths.append(_csv(out / "fig4.csv", ["pillars", "panel", "E_p_over_E_l", "surface_fraction",
                                         "indentation_m", "centre_pressure_Pa",
                                         "master_curve_Pa", "contact_radius_m",
                                         "apparent_area_m2", "real_contact_area_m2",
                                         "total_force_N", "pillars_in_contact"], table))
    # Fig. 5
    scene5 = pairs[variants[0]]["fig5"][0][0].scene
    lens_e = scene5.lens.material.E_Pa

    def closed(x):  # eq. S0BvsE at E_p = E_s = E_l / x
        return np.array([analytic.spring_model(_with_modulus(scene5, lens_e / v))
                         .centre_pressure for v in np.atleast_1d(x)])

    rigid = analytic.rigid_punch(scene5).centre_pressure
    fig5, table = {}, []
    for v in variants:
        fig5[v] = [{"El_over_Ep": lens_e / r["E_p_Pa"], "sigma0_Pa": r["sigma0_Pa"],
                    "E_p_Pa": r["E_p_Pa"]} for r in docs[v]["rows"]["fig5"]
                   if r.get("converged")]
        for r in fig5[v]:
            r["closed_form_Pa"] = float(closed(r["El_over_Ep"])[0])
            table.append([v, r["E_p_Pa"], r["El_over_Ep"], r["sigma0_Pa"], r["closed_form_Pa"],
                          rigid])
        docs[v]["fig5"] = fig5[v]
        docs[v]["fig5_rigid_Pa"] = rigid
    paths.append(plots.plot_fig5(fig5, closed, rigid, out / "fig5.png", dpi))
    paths.append(_csv(out / "fig5.csv", ["pillars", "E_p_Pa", "E_l_over_E_p",
                                         "centre_pressure_Pa", "closed_form_Pa",
                                         "rigid_punch_Pa"], table))
    # Fig. 6
    paths.append(plots.plot_fig6({v: docs[v]["master_points"] for v in variants},
                                 {v: docs[v]["thresholds"]["area_exponent"]["exponent"]
                                  for v in variants}, out / "fig6.png", dpi))
    table = []
    for v in variants:
        by_curve = {(c["ratio"], c["zeta_um"]): c for c in docs[v]["thresholds"]["curves"]}
        for p in docs[v]["master_points"]:
            c = by_curve[(p["ratio"], _um(p["zeta_m"]))]
            table.append([v, p["ratio"], p["zeta_m"], p["phi"], p["phi_star"], p["sigma_star"],
                          p["area_star"], c["phi_s_fit"], c["phi_h_fit"]])
    paths.append(_csv(out / "fig6.csv", ["pillars", "E_p_over_E_l", "indentation_m",
                                         "surface_fraction", "reduced_surface_fraction",
                                         "reduced_centre_pressure", "reduced_area", "phi_s_fit",
                                         "phi_h_fit"], table))
    # Figs. 7 and 8
    thresholds = {v: docs[v]["thresholds"] for v in variants}
    paths.append(plots.plot_fig7(thresholds, out / "fig7.png", dpi))
    paths.append(plots.plot_fig8(thresholds, out / "fig8.png", dpi))
    header = ["pillars", "E_p_over_E_l", "indentation_m", "zeta_over_h", "phi_s_fit",
              "phi_h_fit", "fit_rms", "phi_h_band", "phi_s_exact", "phi_s_exact_rel_halfwidth",
              "phi_s_paper_eqs", "phi_s_rim", "phi_s_large_zeta", "zeta_t_over_h"]
    table = []
    for v in variants:
        t = thresholds[v]
        by_curve = {(c["ratio"], c["zeta_um"]): c for c in t["curves"]}
        exact = {(e["ratio"], e["zeta_um"]): e for e in t["exact"]}
        for key in sorted(set(exact) | set(by_curve)):
            c, e = by_curve.get(key, {}), exact.get(key, {})
            table.append([v, key[0], key[1] * 1e-6, key[1] * 1e-6 / pillar_height(),
                          c.get("phi_s_fit"), c.get("phi_h_fit"), c.get("fit_rms"),
                          c.get("phi_h_band"), e.get("phi_s"), e.get("rel_halfwidth"),
                          e.get("phi_s_paper"), e.get("phi_s_rim"), e.get("phi_s_large_zeta"),
                          t["zeta_t_over_h"].get(str(key[0]))])
    paths.append(_csv(out / "fig7.csv", header, table))
    paths.append(_csv(out / "fig8.csv", header, table))
    return paths


def _with_modulus(scene: Scene, e_pa: float) -> Scene:
    """``scene`` with E_p = E_s = ``e_pa`` (Pa)."""
    pillars = dataclasses.replace(scene.pillars,
                                  material=Material(e_pa, scene.pillars.material.nu))
    return scene.replace(pillars=pillars, substrate=Material(e_pa, scene.substrate.nu))

