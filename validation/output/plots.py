"""Figures of the studies (matplotlib, Agg): convergence, pressure profiles, the Gecit-like
study, the time-accuracy trade-off and the loading curve.  Units as units (µm, kPa, µN); a
figure whose data include a solve that missed its tolerance is stamped NOT CONVERGED
(:func:`validation.output.report.stamp_not_converged`).  The renders of FEM fields are
:mod:`validation.output.render` and :mod:`validation.output.render3d`.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from ..registry import QUANTITIES
from .report import KPA, legend_outside, scene_label, pyplot, save_figure, stamp_not_converged

_MARKERS = "osd^v<>p"
# Quantities in mathtext, for labels.
_SYMBOL = {"F_T": "$F_T$", "sigma0": r"$\sigma_0$", "a": "$a$", "A": "$A$"}
_TITLE = {"F_T": "total force $F_T$", "sigma0": r"centre pressure $\sigma_0$",
          "a": "contact radius $a$", "A": "real contact area $A$"}
# The short name of each ladder option, for labels of points: P = 11, N = 32, S = 0.5.
_OPTION_LETTER = {"elements_per_diameter": "P", "cells_per_diameter": "N", "mesh_size": "S"}


def _math(text: str) -> str:
    """Moduli in mathtext: E_s = E_p -> $E_s = E_p$."""
    return text.replace("E_s = E_p", "$E_s = E_p$")


def _save(fig, path) -> Path:
    return save_figure(fig, path, 120)


def _unconverged_levels(data: dict) -> list[str]:
    option = data["ladder"]["option"]
    return [f"{data['model']} {option}={lv['value']}: {lv.get('message', '')}"
            for lv in data["levels"] if not lv["converged"]]


def _h_of(ladder: dict) -> str:
    """How h follows from the refined option: "h = 1/elements_per_diameter", "h = mesh_size"
    (the option's own name, never a description of it wrapped in brackets)."""
    option, power = ladder["option"], ladder.get("h_power")
    if power is None:
        return f"h ({option})"
    if power == 1:
        return f"h = {option}"
    if power == -1:
        return f"h = 1/{option}"
    return f"h = {option}^{power:g}"


def plot_convergence(data: dict, path: Path) -> Path:
    """Relative error against the relative cell size h, log-log, one line per quantity.

    The error is |f - f_exact| / |f_exact| with the Richardson estimate when the study has
    one, otherwise |f - f_finest| / |f_finest| on the coarser levels (marked 'vs finest').
    A quantity equal on every level (to round-off) has no error to draw and says so.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    hs_all, errs_all, flat = [], [], []
    for i, q in enumerate(QUANTITIES):
        key, label = q.key, q.label
        s = data["studies"][key]
        h, f = np.array(s["h"]), np.array(s["f"])
        ref = s["gci"]["f_exact"]
        how = "vs Richardson"
        if ref is None:
            ref, h, f, how = f[0], h[1:], f[1:], "vs finest"
        err = np.abs(f - ref) / abs(ref) if ref else np.zeros_like(f)
        keep = err > 0
        if not keep.any() or s["gci"]["status"] == "round-off":
            flat.append(_SYMBOL.get(key, key))
            continue
        p = s["gci"]["order"]
        tag = f"{label} ({how}{'' if p is None else f', p = {p:.2f}'})"
        ax.loglog(h[keep], err[keep], marker=_MARKERS[i % len(_MARKERS)], label=tag)
        hs_all.extend(h[keep])
        errs_all.extend(err[keep])
    hs = np.array(sorted(set(hs_all)))
    if hs.size >= 2:  # a slope needs two sizes: one point (two levels, vs finest) has none
        for order, style in ((1, ":"), (2, "--")):
            ax.loglog(hs, 0.5 * max(errs_all) * (hs / hs[-1]) ** order, "k" + style, lw=0.8,
                      label=f"slope {order}")
    elif hs.size == 1:
        ax.text(0.02, 0.08, "one size with an error: no slope to draw (add levels)",
                transform=ax.transAxes, fontsize=8, color="0.3")
    if hs_all:
        ax.legend(fontsize=7)
    if flat:
        ax.text(0.02, 0.02, f"{', '.join(flat)}: equal on every level (round-off)",
                transform=ax.transAxes, fontsize=8, color="0.3")
    values = ", ".join(f"{lv['value']:g}" for lv in data["levels"])
    option = data["ladder"]["option"]
    ax.set_xlabel(f"relative cell size {_h_of(data['ladder'])}")
    ax.set_ylabel("relative error")
    ax.set_title(f"{data.get('label', data['model'])} on {scene_label(data['scene'])}: "
                 f"{option} = {values}", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    stamp_not_converged(fig, _unconverged_levels(data))
    return _save(fig, path)


def plot_profiles(curves: list[dict], radius_m: float, path: Path, title: str,
                  radius_label: str = "d/2", not_converged: list[str] = ()) -> Path:
    """Pressure across the pillar top (or the Hertz contact) for several models.

    ``curves`` holds dicts with ``label``, ``r_m``, ``pressure_Pa`` and optional ``style``,
    ``color`` and ``markersize``; one with ``yerr_Pa`` (a band, +- per point) is drawn as
    error bars.  r is plotted as r / ``radius_m``, the pressure in kPa.  The y range follows
    the curves inside 0.8 ``radius_m``, so edge peaks (singular or mesh-bound) do not flatten
    the rest.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(9.6, 4.8))  # room for the legend beside the axes
    top, peak = 0.0, 0.0
    for c in curves:
        r = np.asarray(c["r_m"], dtype=float)
        p = np.asarray(c["pressure_Pa"], dtype=float)
        if r.size == 0:
            continue
        extra = {k: c[k] for k in ("color", "markersize") if k in c}
        if "yerr_Pa" in c:
            ax.errorbar(r / radius_m, p * KPA, yerr=np.asarray(c["yerr_Pa"], float) * KPA,
                        fmt=c.get("style", "none"), capsize=4, elinewidth=1.4,
                        label=c["label"], **extra)
        else:
            ax.plot(r / radius_m, p * KPA, c.get("style", "-"), label=c["label"], lw=1.4,
                    **extra)
        inner = r <= 0.8 * radius_m
        if inner.any():
            top = max(top, float(np.nanmax(p[inner])))
        shown = r <= 1.05 * radius_m
        if shown.any():
            peak = max(peak, float(np.nanmax(p[shown])))
    if top > 0:  # edge peaks (singular or mesh-bound) run off the top, by design; without
        # them (Hertz) the axis ends just above the curves, not 45 % above them
        ax.set_ylim(0, min(1.8 * top, 1.08 * peak) * KPA)
    ax.set_xlim(0, 1.05)
    ax.set_xlabel(f"r / ({radius_label})")
    ax.set_ylabel("contact pressure (kPa)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    legend_outside(ax)
    stamp_not_converged(fig, list(not_converged))
    return _save(fig, path)


def plot_gecit(rows: list[dict], path: Path, convention: str = "") -> Path:
    """Four panels against E_p/E_l, one line per h/d: Hooke-BEM error in F_T and sigma_0 with
    the BEM's GCI band as error bars, the fitted edge exponent, and the profile shape
    (plateau and outer-10 % load fraction).  Rows that did not converge are drawn hollow and
    the figure is stamped."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), sharex=True)
    aspects = sorted({r["aspect"] for r in rows})
    panels = (
        (axes[0, 0], "err_F_T", "U_BEM_F_T", r"error of the Hooke BEM in $F_T$ (%)", True),
        (axes[0, 1], "err_sigma0", "U_BEM_sigma0", r"error of the Hooke BEM in $\sigma_0$ (%)",
         True),
        (axes[1, 0], "edge_exponent", None,
         r"edge exponent $\lambda$, $\sigma \sim (d/2 - r)^{-\lambda}$", False),
        (axes[1, 1], "plateau", None,
         r"$\sigma(d/4)/\sigma_0$ (solid), outer-10 % load share (dashed)", False),
    )
    for ax, key, band, title, percent in panels:
        for i, aspect in enumerate(aspects):
            sel = sorted((r for r in rows if r["aspect"] == aspect), key=lambda r: r["ratio"])
            x = np.array([r["ratio"] for r in sel])
            scale = 100.0 if percent else 1.0
            y = scale * np.array([np.nan if r.get(key) is None else r[key] for r in sel],
                                 dtype=float)
            m = _MARKERS[i % len(_MARKERS)]
            if band is not None:
                u = scale * np.array([0.0 if r.get(band) is None else r[band] for r in sel])
                line = ax.errorbar(x, y, yerr=u, marker=m, capsize=3,
                                   label=f"h/d = {aspect:g}").lines[0]
            else:
                (line,) = ax.plot(x, y, marker=m, label=f"h/d = {aspect:g}")
            bad = np.array([r["status"] != "ok" for r in sel])
            if bad.any():
                ax.plot(x[bad], y[bad], "o", ms=11, mfc="none", mec="red", mew=1.5)
            if key == "plateau":
                y2 = np.array([np.nan if r.get("outer_load_fraction") is None
                               else r["outer_load_fraction"] for r in sel], dtype=float)
                ax.plot(x, y2, marker=m, ls="--", color=line.get_color())
        ax.set_xscale("log")
        ax.set_title(title, fontsize=9)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(True, which="both", alpha=0.3)
    for ax in axes[0]:
        ax.axhline(0.0, color="k", lw=0.6)
    axes[1, 0].axhline(0.5, color="k", lw=0.8, ls=":", label="rigid punch, 1/2")
    for ax in axes[1]:
        ax.set_xlabel("$E_p / E_l$")
    for ax in (axes[0, 0], axes[1, 0]):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle("Hooke-spring BEM against the elastic-pillar FEM (single pillar)"
                 + (f"\n{_math(convention)}" if convention else "")
                 + "; error bars: the BEM's GCI band", fontsize=10)
    stamp_not_converged(fig, [f"E_p/E_l={r['ratio']:g} h/d={r['aspect']:g}" for r in rows
                              if r["status"] == "not converged"])
    return _save(fig, path)


def plot_gecit_profiles(profiles: list[dict], path: Path, convention: str = "") -> Path:
    """FEM pressure across the pillar top, sigma/sigma_0 against r/(d/2), one panel per h/d
    and one line per E_p/E_l; ``profiles`` holds ``ratio``, ``aspect``, ``radius_m``,
    ``sigma0_Pa``, ``r_m`` and ``pressure_Pa``."""
    plt = pyplot()
    aspects = sorted({p["aspect"] for p in profiles})
    ratios = sorted({p["ratio"] for p in profiles})
    fig, axes = plt.subplots(1, max(1, len(aspects)), figsize=(4.2 * max(1, len(aspects)), 4.4),
                             sharey=True, squeeze=False)
    cmap = plt.get_cmap("viridis")
    for ax, aspect in zip(axes[0], aspects):
        for p in sorted((p for p in profiles if p["aspect"] == aspect), key=lambda p: p["ratio"]):
            k = ratios.index(p["ratio"]) / max(1, len(ratios) - 1)
            r = np.asarray(p["r_m"]) / p["radius_m"]
            ax.plot(r, np.asarray(p["pressure_Pa"]) / p["sigma0_Pa"], color=cmap(k),
                    label=f"$E_p/E_l$ = {p['ratio']:g}")
        ax.set_title(f"h/d = {aspect:g}")
        ax.set_xlabel("r / (d/2)")
        ax.set_ylim(0, 3.5)
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel(r"$\sigma / \sigma_0$ (FEM)")
    if axes[0, 0].get_legend_handles_labels()[0]:
        axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Pressure across the pillar top, elastic pillar (FEM)"
                 + (f"\n{_math(convention)}" if convention else ""), fontsize=10)
    return _save(fig, path)


# --- speed against accuracy --------------------------------------------------------------
def pareto_front(points: list[tuple[float, float]], noise: list[float] | None = None,
                 floor: float = 0.0) -> list[int]:
    """Indices of the points (time, error) that no other point beats, by time.

    A point beats another when it is faster beyond their time ``noise`` (s, per point: the
    larger of the two counts) and no less accurate, or more accurate and not slower beyond
    the noise.  Errors below ``floor`` (round-off) are all equal: round-off is no trade."""
    n = len(points)
    noise = list(noise) if noise is not None else [0.0] * n
    t = [float(p[0]) for p in points]
    e = [max(float(p[1]), floor) for p in points]

    def beats(j: int, i: int) -> bool:
        tie = max(noise[i], noise[j])
        return ((e[j] <= e[i] and t[j] < t[i] - tie)
                or (e[j] < e[i] and t[j] <= t[i] + tie))

    front = [i for i in range(n) if not any(beats(j, i) for j in range(n) if j != i)]
    return sorted(front, key=lambda i: (t[i], e[i]))


def two_decades(ax) -> None:
    """Widen each log axis of ``ax`` to the powers of ten around its data until two of them
    lie inside it: the labels are on the decades, and an axis spanning less than a decade
    (times 0.02-0.05 s) showed none at all."""
    for get, set_ in ((ax.get_xlim, ax.set_xlim), (ax.get_ylim, ax.set_ylim)):
        lo, hi = sorted(get())
        if lo <= 0:
            continue
        k_lo, k_hi = np.floor(np.log10(lo) + 1e-9), np.ceil(np.log10(hi) - 1e-9)
        if k_hi - k_lo < 1:
            k_hi = k_lo + 1
        inside = np.ceil(np.log10(lo) - 1e-9), np.floor(np.log10(hi) + 1e-9)
        if inside[1] - inside[0] < 1:  # fewer than two decades inside: take the enclosing
            set_(10.0 ** k_lo, 10.0 ** k_hi)


def rung_label(option: str, level) -> str:
    """``P=11``, ``N=32``, ``S=0.5``: a rung by its refinement."""
    return f"{_OPTION_LETTER.get(option, option)}={level:g}"


def plot_tradeoff(doc: dict, path: Path) -> Path:
    """Relative error against wall time, log-log, one panel per quantity and one colour per
    model; every point labelled by its refinement, the Pareto front (no faster rung is more
    accurate) drawn as a step line, rungs that did not converge crossed in red."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    colours = {m: f"C{i}" for i, m in enumerate(doc["models"])}
    floor = float(doc.get("round_off", 0.0))
    for ax, q in zip(axes.ravel(), QUANTITIES):
        key = f"err_{q.key}"
        rows = [r for r in doc["rows"] if r.get(key)]
        if rows and all(r[key] < floor for r in rows):
            rows = []  # nothing but round-off: no trade to draw
            ax.text(0.5, 0.5, f"{_SYMBOL[q.key]}: every rung at round-off\n(relative error "
                    f"< {floor:g})", ha="center", va="center", transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(_TITLE[q.key], fontsize=10)
            continue
        for model in doc["models"]:
            mine = [r for r in rows if r["model"] == model]
            if not mine:
                continue
            t = [r["wall_time_s"] for r in mine]
            e = [max(r[key], floor) for r in mine]  # round-off drawn at its floor
            ax.loglog(t, e, "o-", color=colours[model], lw=0.8, alpha=0.8,
                      label=mine[0].get("label", model))
            for r in mine:
                ax.annotate(rung_label(r["option"], r["level"]),
                            (r["wall_time_s"], max(r[key], floor)),
                            textcoords="offset points", xytext=(4, 3), fontsize=7,
                            color=colours[model])
                if not r["converged"]:
                    ax.plot(r["wall_time_s"], max(r[key], floor), "x", color="red", ms=10,
                            mew=2)
        if rows:
            pts = [(r["wall_time_s"], max(r[key], floor)) for r in rows]
            front = [pts[i] for i in pareto_front(pts, [r.get("time_noise_s", 0.0)
                                                        for r in rows], floor)]
            if any(r[key] < floor for r in rows):
                ax.axhline(floor, color="0.5", lw=0.8, ls=":",
                           label=f"round-off (< {floor:g}: equal)")
            tf, ef = zip(*front)
            ax.step(tf, ef, where="post", color="k", lw=1.2, ls="--", label="Pareto front")
            ax.plot(tf, ef, "o", ms=10, mfc="none", mec="k")
            lo, hi = min(e for _, e in pts), max(e for _, e in pts)
            if hi < 1.5 * lo:  # errors equal to a few digits: show decades, not 1.61084e-6 x 6
                ax.set_ylim(lo / 3, hi * 3)
            ax.legend(fontsize=7, loc="best")
        else:  # every error is zero (e.g. a contact radius fixed by the pillar's rim)
            ax.text(0.5, 0.5, f"{_SYMBOL[q.key]}: every rung equals the reference",
                    ha="center", transform=ax.transAxes)
            ax.set_xticks([])
            ax.set_yticks([])
        ax.set(xlabel="wall time (s)", ylabel=f"relative error of {_SYMBOL[q.key]}")
        ax.set_title(_TITLE[q.key], fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
        for axis in (ax.xaxis, ax.yaxis):  # decades only: minor labels crowd a short axis
            axis.set_minor_formatter(NullFormatter())
        if rows:
            two_decades(ax)
    fig.suptitle(f"speed against accuracy on {scene_label(doc['scene'])}: each error "
                 "against the Richardson reference of its own physics", fontsize=11)
    refs = ["references: " + "; ".join(
        f"{group} " + ", ".join(f"{_SYMBOL[k]} by {ref[k]['model']}" for k in ref)
        for group, ref in doc["references"].items())]
    fig.text(0.5, 0.022, refs[0], ha="center", fontsize=8, color="0.3")
    fig.tight_layout(rect=(0, 0.04, 1, 1))  # the bottom edge: references, NOT CONVERGED note
    stamp_not_converged(fig, [f"{r['model']} {rung_label(r['option'], r['level'])}"
                              for r in doc["rows"] if not r["converged"]])
    return save_figure(fig, path, 120, layout=False)


def _frame(ax, points: list[tuple[float, float]], scale: str) -> None:
    """Limits around ``points`` (the models' and the measured), 8 % beyond them (a factor on
    log axes), so that a closed form far from them does not squeeze them into a corner."""
    points = [(x, y) for x, y in points if (x > 0 and y > 0) or scale == "linear"]
    if not points:
        return
    for axis, values in (("x", [p[0] for p in points]), ("y", [p[1] for p in points])):
        lo, hi = min(values), max(values)
        if scale == "log":
            lo, hi = lo / 1.25, hi * 1.25
        else:
            pad = 0.08 * (hi - lo) if hi > lo else 0.08 * abs(hi) or 1.0
            lo, hi = min(lo - pad, 0.0) if lo >= 0 else lo - pad, hi + pad
        getattr(ax, f"set_{axis}lim")(lo, hi)


# The loading curve's panels: (x attribute, y attribute, x label, y label, factors to display).
_CURVE_PANELS = (
    ("indentation_m", "total_force_N", "indentation ζ (µm)", "force F (µN)", 1e6, 1e6),
    ("total_force_N", "contact_radius_m", "force F (µN)", "contact radius a (µm)", 1e6, 1e6),
    ("total_force_N", "real_contact_area_m2", "force F (µN)", "real contact area A (µm²)",
     1e6, 1e12),
    ("total_force_N", "centre_pressure_Pa", "force F (µN)", r"centre pressure $\sigma_0$ (kPa)",
     1e6, KPA),
)


def plot_curve(doc: dict, path: Path) -> Path:
    """The loading curve (:mod:`validation.studies.curve`): F-zeta, a-F, A-F and sigma0-F,
    each model with its numerical uncertainty band as error bars (where a ladder gave
    levels), the Hertz and single-pillar closed forms dashed and dotted, the user's measured
    points as black crosses; cases that did not converge crossed in red."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    styles = {"hertz": ("0.45", "--"), "spring": ("0.45", ":")}
    # Loads over a decade or more: log axes, where power laws (Hertz: F ~ zeta^1.5) are lines.
    scale = "log" if max(doc["loads"]) >= 10.0 * min(doc["loads"]) else "linear"
    for ax, (xa, ya, xl, yl, fx, fy) in zip(axes.ravel(), _CURVE_PANELS):
        ax.set_xscale(scale)
        ax.set_yscale(scale)
        if scale == "log":  # plain numbers at the decades and their 2 and 5, nothing between
            for axis in (ax.xaxis, ax.yaxis):
                axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
                axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
                axis.set_minor_formatter(NullFormatter())
        for name, ref in doc["references"].items():
            colour, ls = styles.get(name, ("0.6", "-."))
            ax.plot([v * fx for v in ref[xa]], [v * fy for v in ref[ya]], color=colour, ls=ls,
                    lw=1.0, label=ref["label"])
        for i, model in enumerate(doc["models"]):
            rows = [r for r in doc["rows"] if r["model"] == model and "error" not in r]
            if not rows:
                continue
            x, y = [r[xa] * fx for r in rows], [r[ya] * fy for r in rows]
            xerr = [r.get("bands", {}).get(xa, 0.0) * fx for r in rows]
            yerr = [r.get("bands", {}).get(ya, 0.0) * fy for r in rows]
            ax.errorbar(x, y, xerr=xerr if any(xerr) else None, yerr=yerr if any(yerr) else None,
                        fmt=_MARKERS[i % len(_MARKERS)] + "-", color=f"C{i}", lw=1.0, ms=5,
                        capsize=3, label=model)
            for r in rows:
                if not r["converged"]:
                    ax.plot(r[xa] * fx, r[ya] * fy, "x", color="red", ms=10, mew=2)
            mixed = [r for r in rows if r.get("regime") == "mixed"]
            if mixed:  # the floor touched: open markers on the mixed points
                ax.plot([r[xa] * fx for r in mixed], [r[ya] * fy for r in mixed], "o",
                        mfc="none", mec="k", ms=9, mew=1.0,
                        label=f"{model}: floor touched" if ax is axes.ravel()[0] else None)
        points = [p for p in (doc.get("data") or {}).get("points", []) if xa in p and ya in p]
        if points:
            ax.plot([p[xa] * fx for p in points], [p[ya] * fy for p in points], "kx", ms=7,
                    mew=1.5, label=f"measured ({Path(doc['data']['file']).name})")
        _frame(ax, [(r[xa] * fx, r[ya] * fy) for r in doc["rows"] if "error" not in r]
               + [(p[xa] * fx, p[ya] * fy) for p in points], scale)
        ax.set(xlabel=xl, ylabel=yl)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    crossed = {m: t for m, t in (doc.get("transitions") or {}).items() if t}
    if crossed:
        fig.text(0.5, 0.025, "suspended -> mixed (the lens touches the floor between the "
                 "pillars): " + "; ".join(
                     f"{m} between {t['suspended_load'] * 1e6:.3g} and "
                     f"{t['mixed_load'] * 1e6:.3g} " + ("uN" if doc["control"] == "force"
                                                         else "um")
                     for m, t in crossed.items()), ha="center", fontsize=8)
    control = "forces given" if doc["control"] == "force" else "indentations given"
    if doc["references"]:
        fig.text(0.5, 0.005, "closed forms for reference: Hertz (the lens on a continuum) and "
                 "one Hooke pillar (the paper's spring model), each at the loads given; they "
                 "may leave the frame, which the models and data set", ha="center",
                 fontsize=8, color="0.3")
    fig.suptitle(f"loading curve on {scene_label(doc['scene'])} ({control})", fontsize=11)
    fig.tight_layout(rect=(0, 0.03, 1, 1))  # the bottom edge: the NOT CONVERGED note
    stamp_not_converged(fig, [f"{r['model']} at {r['load']:.3g}" for r in doc["rows"]
                              if "error" not in r and not r["converged"]])
    return save_figure(fig, path, 120, layout=False)
