"""The lattice study's figures: the differences over Phi and the centre pillar's profiles."""

from __future__ import annotations

import numpy as np

from ..targets import TARGETS
from .points import BEM_NAMES, CONVENTIONS, ELASTIC, FEM_MODEL, HOOKE, LENS, PILLAR

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

    from ...output.report import save_figure, stamp_not_converged

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

    from ...output.report import save_figure, stamp_not_converged

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
        ax.plot(x, fem, "k.-", lw=1, label=FEM_MODEL)
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
