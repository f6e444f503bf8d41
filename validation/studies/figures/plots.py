"""The paper's Figs. 3-8 drawn from the data of :mod:`validation.studies.figures`.

Each function takes the figure's data (SI inside, as the study returns it) per pillar model
(``{"hooke": ..., "elastic": ...}``) and a path, and writes one PNG; axes are in the paper's
units (um, kPa, uN) and scales (log where the paper's quantities span decades).  Every title
states the paper's convention E_s = E_p (the figures' default) and the pillar model; with
both models on one axes the Hooke pillar is drawn dashed with open markers (faint where the
line style already encodes E_p/E_l, Figs. 7-8) and the elastic pillar solid and filled.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...output.report import legend_outside, save_figure

UM, KPA = 1e6, 1e-3
CONVENTION = "Table 1, the paper's E_s = E_p"
PILLAR_NAMES = {"hooke": "Hooke", "elastic": "elastic"}


def convention(variants) -> str:
    """The title's tail: Table 1, the paper's convention E_s = E_p, the pillar model(s)."""
    variants = list(variants)
    if len(variants) == 1:
        return f"{CONVENTION}, {PILLAR_NAMES.get(variants[0], variants[0])} pillars"
    return f"{CONVENTION}; pillars: Hooke dashed/open, elastic solid/filled"


def variant_style(pillars: str, variants) -> dict:
    """How one pillar model is drawn among ``variants``: ``ls`` (the line style of a curve
    whose style is free), ``mfc`` (marker face: None filled, "none" open), ``alpha``, ``lw``
    (a factor), ``suffix`` (for labels)."""
    if len(list(variants)) == 1:
        return {"ls": "-", "mfc": None, "alpha": 1.0, "lw": 1.0, "suffix": ""}
    if pillars == "hooke":
        return {"ls": "--", "mfc": "none", "alpha": 0.55, "lw": 0.8, "suffix": ", Hooke"}
    return {"ls": "-", "mfc": None, "alpha": 1.0, "lw": 1.2,
            "suffix": f", {PILLAR_NAMES.get(pillars, pillars)}"}
RATIO_STYLES = {1e-3: "-.", 1.0: "-", 1e6: "--"}


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _ratio_label(ratio: float) -> str:
    k = math.log10(ratio)
    if abs(k - round(k)) < 1e-9 and k != 0:
        return f"E_p/E_l = 10{_superscript(int(round(k)))}"
    return f"E_p/E_l = {ratio:g}"


def _superscript(k: int) -> str:
    return str(k).translate(str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹"))


def _dress(ax, xlabel: str, ylabel: str, title: str, legend: str | None = None, **legend_kw):
    """Labels, a title, a light grid and (unless ``legend`` is None) a small legend at
    ``legend`` (a matplotlib location, or "outside": right of the axes, clear of the data)."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10, pad=legend_kw.pop("pad", None))
    ax.grid(True, which="both", alpha=0.25)
    if legend == "outside":
        legend_outside(ax, fontsize=7, **legend_kw)
    elif legend is not None:
        ax.legend(fontsize=7, loc=legend, **legend_kw)


def _ratio_colours(ratios):
    """Hard (red) to soft (violet), as in the paper's Fig. 4a."""
    plt = _pyplot()
    logs = np.log10(ratios)
    span = (logs.max() - logs.min()) or 1.0
    return {r: plt.cm.rainbow(0.95 * (lg - logs.min()) / span) for r, lg in zip(ratios, logs)}


# --- Fig. 3 -----------------------------------------------------------------------------
def plot_fig3(panels: list[dict], path: Path, pixels: int = 520, dpi: int = 120,
              variants=("hooke",)) -> Path:
    """Pressure maps (left, images on the element grid) and sigma(r) along theta = 0 (right),
    one row per scene and pillar model.  ``panels``: dicts with ``result``, ``map``
    (ElementMap), ``extent``, ``hertz``, ``punch`` (closed forms), ``phi`` and ``pillars``."""
    plt = _pyplot()
    from matplotlib import cm, colors

    fig, axes = plt.subplots(len(panels), 2, figsize=(12.5, 4.9 * len(panels)),
                             gridspec_kw={"width_ratios": [1.25, 1]}, squeeze=False)
    for (ax_map, ax_prof), p in zip(axes, panels):
        res, emap = p["result"], p["map"]
        img, ext = emap.image(p["extent"], pixels)
        positive = img[np.isfinite(img) & (img > 0)]
        vmax = float(np.percentile(positive, 99.0)) * KPA if positive.size else 1.0
        norm = colors.Normalize(0.0, vmax)
        rgba = cm.viridis(norm(np.nan_to_num(img) * KPA))
        rgba[np.isfinite(img) & (img <= 0)] = (0.86, 0.86, 0.86, 1.0)  # top out of contact
        rgba[~np.isfinite(img)] = (1.0, 1.0, 1.0, 1.0)                 # between the pillars
        um_ext = [v * UM for v in ext]
        ax_map.imshow(rgba, origin="lower", extent=um_ext, interpolation="nearest")
        fig.colorbar(cm.ScalarMappable(norm, "viridis"), ax=ax_map, extend="max",
                     label="contact pressure σ (kPa)")
        reach = um_ext[1]
        for angle in (0.0, math.pi / 6):
            ax_map.plot([0, reach * math.cos(angle)], [0, reach * math.sin(angle)], "r-.",
                        lw=1.0, label="primitive cell" if angle else None)
        a = res.contact_radius_m * UM
        t = np.linspace(0, math.pi / 2, 200)
        ax_map.plot(a * np.cos(t), a * np.sin(t), "r:", lw=1.4, label="contact radius a")
        ax_map.set_xlim(um_ext[0], um_ext[1])
        ax_map.set_ylim(um_ext[2], um_ext[3])
        ax_map.set_aspect("equal")
        ax_map.set_xlabel("x (µm)")
        ax_map.set_ylabel("y (µm)")
        ax_map.legend(loc="upper right", fontsize=8, framealpha=0.9)
        who = (f"{PILLAR_NAMES.get(p.get('pillars', 'hooke'), p.get('pillars'))} pillars, "
               if len(variants) > 1 else "")
        ax_map.set_title(f"{who}Φ = {p['phi']:g}: {res.pillars_in_contact} pillars in contact, "
                         f"F_T = {res.total_force_N * UM:.3g} µN", fontsize=10)

        r, s = emap.along_x(max(res.contact_radius_m * 1.1, p["hertz"].contact_radius * 1.05))
        ax_prof.plot(r * UM, np.where(np.isfinite(s), s, np.nan) * KPA, color="0.2", lw=1.0,
                     label="BEM, along θ = 0")
        ax_prof.plot(r * UM, p["hertz"].pressure(r) * KPA, "b-", lw=1.2, label="Hertz")
        d2 = emap.radius
        rp = np.linspace(0, 0.995 * d2, 300)
        ax_prof.plot(rp * UM, p["punch"].pressure(rp) * KPA, "g-", lw=1.2,
                     label="soft flat punch (eq. S0SFP)")
        s0 = res.centre_pressure_Pa
        ah = res.contact_radius_m
        ax_prof.plot(r * UM, s0 * np.sqrt(np.clip(1 - (r / ah) ** 2, 0, None)) * KPA, "r--",
                     lw=1.2, label="Hertz-like (σ₀, a of the BEM)")
        ax_prof.set_ylim(0, 4.0 * max(s0, p["hertz"].centre_pressure) * KPA)
        ax_prof.set_xlim(0, r[-1] * UM)
        ax_prof.set_xlabel("r (µm)")
        ax_prof.set_ylabel("σ (kPa)")
        ax_prof.legend(fontsize=8)
        ax_prof.set_title(f"σ₀ = {s0 * KPA:.3g} kPa, a = {ah * UM:.3g} µm",
                          fontsize=10)
    models = (convention(variants) if len(variants) == 1 else
              f"{CONVENTION}; Hooke and elastic pillars, one row each")
    fig.suptitle(f"Fig. 3: contact pressure at ζ = 0.3 µm, "
                 f"E_p = E_s = E_l = 1.6 MPa ({models})", fontsize=11)
    # Room for the suptitle above the first row's titles (about 0.5 in).
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.5 / fig.get_size_inches()[1]))
    return save_figure(fig, path, dpi, layout=False)


# --- Fig. 4 -----------------------------------------------------------------------------
def plot_fig4(curves: dict, area_rows: dict, path: Path, dpi: int = 120) -> Path:
    """Fig. 4: (a) sigma_0(Phi) at zeta = 0.3 um per E_p/E_l with the fitted master
    curves; (b) A against pi a^2 at E_p = E_l per Phi, with A = Phi pi a^2.  ``curves`` and
    ``area_rows`` per pillar model."""
    plt = _pyplot()
    variants = list(curves)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(14.5, 5.4),
                                 gridspec_kw={"width_ratios": [1.25, 1]})
    ratios = sorted({r for v in variants for r in curves[v]}, reverse=True)
    colours = _ratio_colours(ratios) if ratios else {}
    for v in variants:
        st = variant_style(v, variants)
        for ratio in sorted(curves[v], reverse=True):
            c = curves[v][ratio]
            ax.loglog(c["phi"], np.asarray(c["sigma0_Pa"]) * KPA, "o", ms=4, mfc=st["mfc"],
                      color=colours[ratio], alpha=st["alpha"],
                      label=_ratio_label(ratio) + st["suffix"])
            phis = np.geomspace(min(c["phi"]), max(c["phi"]), 200)
            ax.loglog(phis, np.asarray(c["master_Pa"](phis)) * KPA, st["ls"],
                      lw=1.0 * st["lw"], color=colours[ratio], alpha=st["alpha"])
    # Ten stiffness ratios: the legend goes beside the axes, clear of the curves.
    _dress(ax, "surface fraction Φ", "centre pressure σ₀ (kPa)",
           "(a) σ₀ at ζ = 0.3 µm; lines: master curve with fitted Φ_S, Φ_H", "upper left",
           bbox_to_anchor=(1.01, 1.0), frameon=False)

    phis = sorted({r["phi"] for v in variants for r in area_rows[v]}, reverse=True)
    cmap = plt.cm.rainbow
    for k, phi in enumerate(phis):
        colour = cmap(0.95 * k / max(1, len(phis) - 1))
        for v in variants:
            st = variant_style(v, variants)
            rows = sorted((r for r in area_rows[v] if r["phi"] == phi),
                          key=lambda r: r["zeta_m"])
            if not rows:
                continue
            apparent = np.array([math.pi * r["a_m"] ** 2 for r in rows]) * UM**2
            real = np.array([r["A_m2"] for r in rows]) * UM**2
            bx.loglog(apparent, real, "o" + st["ls"], ms=3.5, lw=0.8 * st["lw"], color=colour,
                      mfc=st["mfc"], alpha=st["alpha"], label=f"Φ = {phi:g}{st['suffix']}")
            if v != variants[-1]:
                continue
            # A = Phi pi a^2 where it exceeds one pillar top: the large-zeta asymptote.
            start = max(apparent.min(), 0.8 * real.min() / phi)
            if start < apparent.max():
                line = np.geomspace(start, apparent.max(), 20)
                bx.loglog(line, phi * line, ":", lw=0.8, color=colour)
    _dress(bx, "apparent contact area π a² (µm²)", "real contact area A (µm²)",
           "(b) E_p = E_l, ζ = 0.005-0.5 µm; dotted: A = Φ π a²",
           "upper left" if len(variants) == 1 else "outside")
    fig.suptitle(f"Fig. 4 ({convention(variants)})", fontsize=11)
    return save_figure(fig, path, dpi)


# --- Fig. 5 -----------------------------------------------------------------------------
def plot_fig5(rows: dict, closed_form, rigid_Pa: float, path: Path,
              dpi: int = 120) -> Path:
    """sigma_0S against E_l/E_p at Phi = 2.3e-3 with eq. S0BvsE (``closed_form(x)``, Pa);
    ``rows`` per pillar model."""
    plt = _pyplot()
    variants = list(rows)
    fig, ax = plt.subplots(figsize=(7, 5))
    x = np.array([r["El_over_Ep"] for v in variants for r in rows[v]])
    line = np.geomspace(x.min() / 2, x.max() * 2, 300)
    ax.semilogx(line, closed_form(line) * KPA, "r-", lw=1.3, label="eq. S0BvsE (spring model)")
    for v in variants:
        st = variant_style(v, variants)
        xs = np.array([r["El_over_Ep"] for r in rows[v]])
        ys = np.array([r["sigma0_Pa"] for r in rows[v]])
        name = PILLAR_NAMES.get(v, v)
        ax.semilogx(xs, ys * KPA, "o", color="k" if v == "hooke" else "tab:blue", ms=5,
                    mfc=st["mfc"], label=f"exact BEM, one {name} pillar")
    ax.axhline(rigid_Pa * KPA, color="0.5", ls=":", lw=1,
               label="rigid punch, σ₀S(E_p → ∞)")
    _dress(ax, "E_l/E_p", "σ₀S (kPa)",
           f"Fig. 5: single pillar, Φ = 2.3e-3, ζ = 0.3 µm\n({convention(variants)})",
           "lower left")
    return save_figure(fig, path, dpi)


# --- Fig. 6 -----------------------------------------------------------------------------
def plot_fig6(points: dict, area_exponent: dict, path: Path, dpi: int = 120) -> Path:
    """(a) sigma_0* against Phi* with (1 + Phi*)^-3; (b) A* against Phi with Phi^0.7 (and
    our fitted exponent).  ``points``: dicts with ``zeta_m``, ``ratio``, ``phi``,
    ``phi_star``, ``sigma_star``, ``area_star``; both arguments per pillar model (open
    markers: Hooke pillars, when both are drawn)."""
    plt = _pyplot()
    variants = list(points)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 5.2))
    zetas = sorted({p["zeta_m"] for v in variants for p in points[v]})
    norm = plt.Normalize(min(zetas) * UM, max(zetas) * UM)
    markers = {1e-3: "v", 1.0: "o", 1e6: "^"}
    for v, ratio in [(var, r) for var in variants
                     for r in sorted({p["ratio"] for p in points[var]})]:
        st = variant_style(v, variants)
        sel = [p for p in points[v] if p["ratio"] == ratio]
        xs = np.array([p["phi_star"] for p in sel])
        ys = np.array([p["sigma_star"] for p in sel])
        cs = np.array([p["zeta_m"] for p in sel]) * UM
        keep = (xs > 0) & (ys > 0)
        a_star = np.array([p["area_star"] for p in sel])
        phis = np.array([p["phi"] for p in sel])
        keep_a = a_star > 0
        for axis, xv, yv, k in ((ax, xs, ys, keep), (bx, phis, a_star, keep_a)):
            colours = plt.cm.viridis(norm(cs[k]))
            kw = ({"facecolors": "none", "edgecolors": colours} if st["mfc"] == "none"
                  else {"c": colours})
            axis.scatter(xv[k], yv[k], s=14, marker=markers.get(ratio, "s"),
                              label=_ratio_label(ratio) + st["suffix"], **kw)
    line = np.geomspace(1e-2, 10, 200)
    ax.loglog(line, (1 + line) ** -3, "k-", lw=1.3, label="(1 + Φ*)⁻³ (paper)")
    ax.set_xlim(1e-2, 10)
    ax.set_ylim(1e-3, 2)
    _dress(ax, "Φ* = (Φ - Φ_S)/Φ_H", "σ₀* = (σ₀ - σ₀H)/(σ₀S - σ₀H)",
           "(a) reduced centre pressure (points with Φ* > 0, σ₀* > 0)", "lower left")
    from matplotlib import cm

    fig.colorbar(cm.ScalarMappable(norm, "viridis"), ax=ax, label="ζ (µm)")
    lphi = np.geomspace(1e-3, 1, 100)
    bx.loglog(lphi, lphi**0.7, "k-", lw=1.3, label="Φ^0.7 (paper)")
    for v in variants:
        m = area_exponent.get(v)
        if m is not None:
            st = variant_style(v, variants)
            bx.loglog(lphi, lphi**m, ":" if v == "hooke" and len(variants) > 1 else "--",
                      color="k", lw=1.0, label=f"Φ^{m:.2f} (fitted{st['suffix']})")
    _dress(bx, "surface fraction Φ", "A* = (A - A_S)/(A_H - A_S)",
           "(b) reduced real contact area (points with A* > 0)", "lower right")
    fig.suptitle(f"Fig. 6: master curves, ζ = 0.05-0.5 µm ({convention(variants)})",
                 fontsize=11)
    return save_figure(fig, path, dpi)


# --- Figs. 7 and 8 ----------------------------------------------------------------------
def _faint(st: dict) -> dict:
    """Figs. 7-8 encode E_p/E_l in the line style: a second pillar model is drawn faint and
    thin (with open markers) rather than dashed."""
    return {"alpha": st["alpha"], "lw": st["lw"]}


def _threshold_series(thresholds: dict):
    """(pillars, thresholds, style, E_p/E_l, its line style, fitted curves, exact Phi_S) for
    each pillar model and stiffness ratio that has fitted curves, sorted in zeta/h."""
    variants = list(thresholds)
    for v in variants:
        t, st = thresholds[v], variant_style(v, variants)
        for ratio, style in RATIO_STYLES.items():
            rows = sorted((r for r in t["curves"] if r["ratio"] == ratio),
                          key=lambda r: r["zeta_h"])
            exact = sorted((r for r in t["exact"] if r["ratio"] == ratio),
                           key=lambda r: r["zeta_h"])
            if rows:
                yield v, t, st, ratio, style, rows, exact


def plot_fig7(thresholds: dict, path: Path, dpi: int = 120) -> Path:
    """(a) Phi_S and (b) Phi_H against zeta/h: fitted, exact and closed-form; ``thresholds``
    per pillar model (the study's ``thresholds`` document)."""
    plt = _pyplot()
    variants = list(thresholds)
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(13, 5.2))
    for v, t, st, ratio, style, rows, exact in _threshold_series(thresholds):
        f = _faint(st)
        z = np.array([r["zeta_h"] for r in rows])
        open_ = ratio != 1.0 or st["mfc"] == "none"
        ax.loglog(z, [r["phi_s_fit"] for r in rows], "o", color="tab:blue", ms=4,
                  mfc="none" if open_ else "tab:blue", alpha=f["alpha"])
        ax.loglog([r["zeta_h"] for r in exact], [r["phi_s"] for r in exact], style,
                  color="k", lw=1.2 * f["lw"], alpha=f["alpha"],
                  label=f"exact (bisection), {_ratio_label(ratio)}{st['suffix']}")
        if v == variants[-1]:
            ax.loglog([r["zeta_h"] for r in exact], [r["phi_s_paper"] for r in exact],
                      style, color="tab:brown", lw=1.0)
        bx.semilogx(z, [r["phi_h_fit"] for r in rows], "o" + style, color="tab:purple",
                    ms=4, lw=1.0 * f["lw"], alpha=f["alpha"], mfc=st["mfc"],
                    label=f"fitted, {_ratio_label(ratio)}{st['suffix']}")
        band = [(r["zeta_h"], r["phi_h_band"]) for r in rows if r["phi_h_band"] is not None]
        if band:
            bx.semilogx(*zip(*band), "s" + style, color="tab:green", ms=3.5,
                        lw=0.9 * f["lw"], alpha=f["alpha"], mfc=st["mfc"],
                        label=f"within {t['band']:.0%} of Hertz, "
                              f"{_ratio_label(ratio)}{st['suffix']}")
    t = thresholds[variants[-1]]
    ax.plot([], [], "o", color="tab:blue", ms=4, label="fitted (master curve); open: "
            "E_p/E_l = 10⁻³, 10⁶" + (", Hooke" if len(variants) > 1 else ""))
    ax.plot([], [], "-", color="tab:brown", label="eqs. rSzeta, PhiSrS (paper)")
    zl = np.array(t["large_zeta"]["zeta_h"])
    ax.loglog(zl, t["large_zeta"]["phi_s"], "r:", lw=1.6,
              label="large-ζ limit π d²/(4√3 R ζ)")
    _dress(ax, "ζ/h", "Φ_S", "(a) single-pillar threshold Φ_S",
           "upper right" if len(variants) == 1 else "outside")
    _dress(bx, "ζ/h", "Φ_H", "(b) Hertz threshold Φ_H", "outside")
    fig.suptitle(f"Fig. 7: thresholds against the reduced indentation\n"
                 f"({_fig78_convention(variants)})", fontsize=11)
    return save_figure(fig, path, dpi)


def _fig78_convention(variants) -> str:
    variants = list(variants)
    if len(variants) == 1:
        return convention(variants)
    return f"{CONVENTION}; pillars: Hooke faint/thin, elastic bold"


def plot_fig8(thresholds: dict, path: Path, dpi: int = 120) -> Path:
    """Phase diagram in (Phi, zeta/h): Hertz beyond Phi_H, one pillar below Phi_S;
    ``thresholds`` per pillar model."""
    plt = _pyplot()
    variants = list(thresholds)
    fig, ax = plt.subplots(figsize=(11, 6))
    for v, t, st, ratio, style, rows, exact in _threshold_series(thresholds):
        f = _faint(st)
        z = [r["zeta_h"] for r in rows]
        ax.semilogx([r["phi_h_fit"] for r in rows], z, style, color="darkviolet",
                    lw=1.6 * f["lw"], alpha=f["alpha"],
                    label=f"Φ_H (fit), {_ratio_label(ratio)}{st['suffix']}")
        ax.semilogx([r["phi_s_fit"] for r in rows], z, style, color="deepskyblue",
                    lw=1.6 * f["lw"], alpha=f["alpha"],
                    label=f"Φ_S (fit), {_ratio_label(ratio)}{st['suffix']}")
        ax.semilogx([r["phi_s"] for r in exact], [r["zeta_h"] for r in exact], style,
                    color="k", lw=0.9 * f["lw"], alpha=f["alpha"],
                    label=f"Φ_S (exact), {_ratio_label(ratio)}{st['suffix']}")
        if v == variants[-1]:
            ax.semilogx([r["phi_s_paper"] for r in exact], [r["zeta_h"] for r in exact],
                        style, color="tab:brown", lw=1.0)
            ax.axhline(t["zeta_t_over_h"][str(ratio)], color="0.6", ls=style, lw=0.8)
    t = thresholds[variants[-1]]
    ax.plot([], [], color="tab:brown", label="eqs. rSzeta, PhiSrS")
    ax.plot([], [], color="0.6", label="ζ_T/h (Hertz σ₀ = single-pillar σ₀)")
    zl = np.array(t["large_zeta"]["zeta_h"])
    ax.semilogx(t["large_zeta"]["phi_s"], zl, "r:", lw=1.8,
                label="π d²/(4√3 R ζ)")
    ax.set_xlim(1e-3, 1)
    ax.set_ylim(0, max(zl) * 1.05)
    ax.text(0.55, 0.5 * max(zl), "Hertz", ha="center", fontsize=12, color="darkviolet")
    ax.text(1.6e-3, 0.6 * max(zl), "one pillar\n(SFP)", ha="left", fontsize=11,
            color="deepskyblue")
    _dress(ax, "surface fraction Φ", "ζ/h",
           f"Fig. 8: contact regimes ({_fig78_convention(variants)})",
           "upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)
    return save_figure(fig, path, dpi)
