"""The first multi-pillar cross-validation: the paper's Hooke BEM against the 3D FEM.

Over surface fractions Phi and stiffness ratios E_p/E_l at zeta = 0.3 um (Table 1 otherwise),
the Hooke-spring boundary-element model (every pillar a uniformly shortening spring on a
half-space) is compared with fem-3d (every pillar a fully elastic body bonded to the
substrate).  Each model climbs its own refinement ladder; each quantity gets its Richardson
estimate and GCI band (validation.analysis.verification), and every BEM-FEM difference is set beside
both models' numerical uncertainty: a difference larger than the two bands together is the
modelling error of the Hooke pillar, not noise.

The substrate is the lens material (E_s = E_l), not the paper's E_s = E_p: the study asks what
the spring model costs when only the pillars change, so the half-space compliance
gamma_l + gamma_s is the same in every scene and the comparison isolates the pillar.

Per-pillar forces are compared at the finest level of each model, grouped by lattice ring
(ring 0 is the centre pillar): the FEM/BEM ratio of every pillar both models load, its mean
and range per ring, and its change from the next-coarser pair of levels (a measure of how
settled the ratio is).

All cases run on the engine, so the study resumes after an interruption.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenes import InputError, Scene, lattice, load_scene

from ..engine import Case, Engine
from ..registry import QUANTITIES, quantity_values
from ..analysis.verification import study

PHIS = (0.03, 0.1, 0.2, 0.4)
RATIOS = (0.1, 1.0, 10.0, 1e6)
ZETA_UM = 0.3
E_LENS = 1.6e6
FEM_MODEL, BEM_MODEL = "fem-3d", "bem-fft"
# fem-3d: sqrt(2) per level (x 2.8 unknowns); 1.41 is 2-4 minutes on the Phi = 0.4 scene.
FEM_LEVELS = (2.83, 2.0, 1.41)
# bem-fft: cells per diameter, ratio 2; the FFT model converges at order ~1 (smooth edge
# cells) where the dense model's edge-cut pattern makes its order wobble.
BEM_LEVELS = (16, 32, 64)
QUICK_FEM_LEVELS, QUICK_BEM_LEVELS = (4.0, 2.83), (8, 16)


@dataclass(frozen=True)
class LatticePoint:
    surface_fraction: float
    ratio: float  # E_p / E_l

    @property
    def label(self) -> str:
        return f"Phi={self.surface_fraction:g} Ep/El={self.ratio:g}"

    def scene(self) -> Scene:
        """Table 1 (paper-fig3-sparse) with this Phi and E_p, E_s = E_l, zeta = 0.3 um."""
        return load_scene("paper-fig3-sparse", [
            f"pillars.surface_fraction={self.surface_fraction!r}",
            f"pillars.E_Pa={E_LENS * self.ratio!r}", f"substrate.E_Pa={E_LENS!r}",
            "substrate.nu=0.5", f"load.indentation_um={ZETA_UM!r}"])


def grid(phis=PHIS, ratios=RATIOS) -> list[LatticePoint]:
    return [LatticePoint(p, r) for p in phis for r in ratios]


def cases(point: LatticePoint, fem_levels=FEM_LEVELS, bem_levels=BEM_LEVELS) -> list[Case]:
    scene = point.scene()
    out = [Case(FEM_MODEL, scene, {"mesh_size": float(s)}, tag=f"{point.label} fem")
           for s in fem_levels]
    out += [Case(BEM_MODEL, scene, {"cells_per_diameter": int(n)}, tag=f"{point.label} bem")
            for n in bem_levels]
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


def compare_point(point: LatticePoint, fem_outcomes, bem_outcomes) -> dict:
    """One scene of the study: both ladders, the differences beside the bands, the rings."""
    fem = _ladder(fem_outcomes, "mesh_size", 1.0)
    bem = _ladder(bem_outcomes, "cells_per_diameter", -1.0)
    row = {"surface_fraction": point.surface_fraction, "ratio": point.ratio,
           "fem_error": fem["error"], "bem_error": bem["error"], "quantities": {}}
    if fem["error"] or bem["error"]:
        row["status"] = "failed: " + "; ".join(e for e in (fem["error"], bem["error"]) if e)
        row["exit"] = max(fem.get("exit", 0), bem.get("exit", 0))
        return row
    row["converged"] = all(r["converged"] for r in fem["levels"] + bem["levels"])
    for q in QUANTITIES:
        fv, fb, fhow = _estimate(fem["studies"][q.key])
        bv, bb, bhow = _estimate(bem["studies"][q.key])
        diff = (fv - bv) / bv if bv else None
        band = (fb + bb) / abs(bv) if bv else None
        row["quantities"][q.key] = {
            "fem": fv, "fem_band": fb, "fem_how": fhow, "bem": bv, "bem_band": bb,
            "bem_how": bhow, "difference": diff, "band": band,
            "significant": bool(diff is not None and band is not None and abs(diff) > band)}
    row["pillars_in_contact"] = {"fem": fem["results"][-1].pillars_in_contact,
                                 "bem": bem["results"][-1].pillars_in_contact}
    row["rings"] = ring_ratios(fem["results"][-1], bem["results"][-1])
    if len(fem["results"]) >= 2 and len(bem["results"]) >= 2:
        coarser = {r["ring"]: r for r in ring_ratios(fem["results"][-2], bem["results"][-2])}
        for r in row["rings"]:
            c = coarser.get(r["ring"], {}).get("ring_force_ratio")
            r["ring_force_ratio_change"] = (None if c is None or r["ring_force_ratio"] is None
                                            else r["ring_force_ratio"] - c)
    row["fem_levels"], row["bem_levels"] = fem["levels"], bem["levels"]
    row["status"] = "ok" if row["converged"] else "not converged"
    return row


def lattice_study(folder, *, engine: Engine | None = None, points=None, fem_levels=FEM_LEVELS,
                  bem_levels=BEM_LEVELS) -> dict:
    """Run (or resume) the study into ``folder``/cases; returns the JSON-ready report."""
    from pathlib import Path

    points = list(points or grid())
    engine = engine or Engine("serial")
    all_cases = [c for p in points for c in cases(p, fem_levels, bem_levels)]
    # Cheap BEM cases first, then the FEM from coarse to fine: a long run shows its
    # table early and an interruption loses at most one FEM solve.
    order = sorted(range(len(all_cases)),
                   key=lambda i: (all_cases[i].model == FEM_MODEL,
                                  -all_cases[i].options.get("mesh_size", 0.0), i))
    outcomes = [None] * len(all_cases)
    ran = engine.run([all_cases[i] for i in order], Path(folder) / "cases", "lattice")
    for i, o in zip(order, ran):
        outcomes[i] = o
    rows, k = [], 0
    nf, nb = len(fem_levels), len(bem_levels)
    for p in points:
        fem_o, bem_o = outcomes[k:k + nf], outcomes[k + nf:k + nf + nb]
        k += nf + nb
        rows.append(compare_point(p, fem_o, bem_o))
    return {"zeta_um": ZETA_UM, "E_lens_Pa": E_LENS, "substrate": "E_s = E_l",
            "fem": {"model": FEM_MODEL, "mesh_size": list(fem_levels)},
            "bem": {"model": BEM_MODEL, "cells_per_diameter": list(bem_levels)},
            "rows": rows}


def table_text(report: dict) -> str:
    """Plain-text table: per scene and quantity, the FEM/BEM difference and the band."""
    head = (f"{'Phi':>6} {'Ep/El':>7} " + " ".join(f"{q.key + ' diff':>12} {'band':>7}"
                                                 for q in QUANTITIES[:3])
            + f" {'pillars F/B':>12} {'ring0 F/B':>9}")
    lines = [head]
    for r in report["rows"]:
        if not r["status"].startswith(("ok", "not")):
            lines.append(f"{r['surface_fraction']:>6g} {r['ratio']:>7g}  {r['status']}")
            continue
        cells = []
        for q in QUANTITIES[:3]:
            d = r["quantities"][q.key]
            mark = "*" if d["significant"] else " "
            cells.append(f"{100 * d['difference']:>+11.2f}%{mark}{100 * d['band']:>6.2f}%")
        ring0 = next((x["ring_force_ratio"] for x in r["rings"] if x["ring"] == 0), None)
        pic = r["pillars_in_contact"]
        lines.append(f"{r['surface_fraction']:>6g} {r['ratio']:>7g} " + " ".join(cells)
                     + f" {pic['fem']:>5d}/{pic['bem']:<6d} "
                     + ("-" if ring0 is None else f"{ring0:>9.4f}")
                     + ("" if r["status"] == "ok" else "  NOT CONVERGED"))
    lines.append("diff = (FEM - BEM) / BEM of the Richardson estimates; band = both GCI bands "
                 "over BEM; * = beyond the band (a modelling difference, not noise)")
    return "\n".join(lines)


def rows_csv(report: dict) -> str:
    import csv
    import io

    buf = io.StringIO()
    w = csv.writer(buf)
    cols = ["surface_fraction", "Ep_over_El", "status", "pillars_fem", "pillars_bem"]
    for q in QUANTITIES:
        cols += [f"{q.key}_fem_{q.unit}", f"{q.key}_fem_band_{q.unit}",
                 f"{q.key}_bem_{q.unit}", f"{q.key}_bem_band_{q.unit}",
                 f"{q.key}_difference", f"{q.key}_band", f"{q.key}_significant"]
    w.writerow(cols)
    for r in report["rows"]:
        row = [r["surface_fraction"], r["ratio"], r["status"]]
        if "quantities" not in r or not r["quantities"]:
            w.writerow(row)
            continue
        row += [r["pillars_in_contact"]["fem"], r["pillars_in_contact"]["bem"]]
        for q in QUANTITIES:
            d = r["quantities"][q.key]
            row += [repr(d["fem"]), repr(d["fem_band"]), repr(d["bem"]), repr(d["bem_band"]),
                    repr(d["difference"]), repr(d["band"]), d["significant"]]
        w.writerow(row)
    return buf.getvalue()


def rings_csv(report: dict) -> str:
    import csv
    import io

    buf = io.StringIO()
    w = csv.writer(buf)
    cols = ["ring", "pillars", "ratio_mean", "ratio_min", "ratio_max", "ring_force_ratio",
            "ring_force_ratio_change", "fem_only", "bem_only", "fem_force_N", "bem_force_N"]
    w.writerow(["surface_fraction", "Ep_over_El", *cols])
    for r in report["rows"]:
        for ring in r.get("rings", []):
            w.writerow([r["surface_fraction"], r["ratio"],
                        *("" if ring.get(c) is None else ring.get(c) for c in cols)])
    return buf.getvalue()


# --- report folder -----------------------------------------------------------------------
OUTPUTS = ("lattice.csv", "rings.csv", "lattice.png", "summary.md", "lattice.json")


def plot_lattice(report: dict, path) -> None:
    """Four panels: (FEM - BEM) / BEM of F_T, sigma0 and a against Phi, one line per
    E_p/E_l with both models' bands as error bars; and the FEM/BEM force ratio by ring."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..output.report import save_figure, stamp_not_converged

    rows = [r for r in report["rows"] if r.get("quantities")]
    ratios = sorted({r["ratio"] for r in rows})
    phis = sorted({r["surface_fraction"] for r in rows})
    colours = dict(zip(ratios, plt.cm.viridis(np.linspace(0.0, 0.9, max(len(ratios), 1)))))
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    names = {"F_T": "total force F_T", "sigma0": "centre pressure σ0", "a": "contact radius a"}
    for ax, key in zip(axes.ravel()[:3], ("F_T", "sigma0", "a")):
        for ratio in ratios:
            mine = sorted((r for r in rows if r["ratio"] == ratio),
                          key=lambda r: r["surface_fraction"])
            x = [r["surface_fraction"] for r in mine]
            y = [100 * r["quantities"][key]["difference"] for r in mine]
            err = [100 * r["quantities"][key]["band"] for r in mine]
            ax.errorbar(x, y, yerr=err, fmt="o-", capsize=3, color=colours[ratio],
                        label=f"E_p/E_l = {ratio:g}")
        ax.axhline(0.0, color="k", lw=0.8)
        ax.set(xscale="log", xlabel="surface fraction Φ",
               ylabel="(FEM − BEM) / BEM (%)", title=names[key])
        ax.grid(True, which="both", alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    ax = axes[1, 1]
    markers = dict(zip(phis, "osd^v<>"))
    for r in rows:
        rings = [x for x in r["rings"] if x["ring_force_ratio"] is not None]
        ax.plot([x["ring"] for x in rings], [x["ring_force_ratio"] for x in rings],
                marker=markers[r["surface_fraction"]], color=colours[r["ratio"]], lw=1,
                label=f"Φ = {r['surface_fraction']:g}" if r["ratio"] == ratios[0] else None)
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set(xlabel="lattice ring (0 = centre pillar)", ylabel="force FEM / BEM",
           title="per-ring force ratio (finest levels; colour: E_p/E_l)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.suptitle(f"Hooke BEM ({report['bem']['model']}) vs elastic-pillar FEM "
                 f"({report['fem']['model']}), ζ = {report['zeta_um']:g} µm, "
                 f"{report['substrate']}; error bars: both GCI bands")
    bad = [f"Phi={r['surface_fraction']:g} Ep/El={r['ratio']:g}" for r in report["rows"]
           if r["status"] != "ok"]
    if bad:
        stamp_not_converged(fig, bad)
    save_figure(fig, path)


def summary_markdown(report: dict) -> str:
    lines = ["# Multi-pillar cross-validation: Hooke BEM against the elastic-pillar 3D FEM", "",
             f"- zeta = {report['zeta_um']:g} um, Table 1 lens and pillars, {report['substrate']}",
             f"- FEM: {report['fem']['model']}, mesh_size "
             f"{', '.join(f'{v:g}' for v in report['fem']['mesh_size'])}",
             f"- BEM (the paper's Hooke pillars): {report['bem']['model']}, cells per diameter "
             f"{', '.join(str(v) for v in report['bem']['cells_per_diameter'])}",
             "- each value is its model's Richardson estimate (or its finest level with the "
             "spread band when the levels have no observed order)", "",
             "```", table_text(report), "```", ""]
    sig = [f"Phi={r['surface_fraction']:g}, Ep/El={r['ratio']:g}: "
           + ", ".join(k for k, d in r["quantities"].items() if d["significant"])
           for r in report["rows"] if r.get("quantities")
           and any(d["significant"] for d in r["quantities"].values())]
    lines.append("Differences beyond both bands (modelling error of the Hooke pillar):")
    lines += [f"- {s}" for s in sig] or ["- none"]
    failed = [r for r in report["rows"] if r["status"] != "ok"]
    if failed:
        lines += ["", "**Not converged or failed:** " + "; ".join(
            f"Phi={r['surface_fraction']:g} Ep/El={r['ratio']:g}: {r['status']}"
            for r in failed)]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out) -> list[str]:
    """The report folder, lattice.json last (its presence means a whole report)."""
    import json
    from pathlib import Path

    from outcome import write_atomic

    out = Path(out)
    write_atomic(out / "lattice.csv", rows_csv(report))
    write_atomic(out / "rings.csv", rings_csv(report))
    plot_lattice(report, out / "lattice.png")
    write_atomic(out / "summary.md", summary_markdown(report))
    write_atomic(out / "lattice.json", json.dumps(report, indent=2, allow_nan=False))
    return list(OUTPUTS)
