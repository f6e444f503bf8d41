"""The lattice study's tables: terminal text and CSV files."""

from __future__ import annotations

from ...registry import QUANTITIES
from .analysis import evaluate_targets, targets_met
from .points import ELASTIC, HOOKE, LENS
from ...output.formatting import percent


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
    return percent(v, "+.2f", "")


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
