"""The regime map: which model the planner picks over surface fraction x indentation, and
where the Hooke pillar's sigma0 error makes the paper's model untrustworthy.

For one base scene (default Table 1, ``paper-fig3-sparse``: E_s = E_p = E_l) the map varies
the pillars' surface fraction Phi (the pitch; diameter, height and materials kept) on a log
grid from :data:`PHI_RANGE` and the indentation zeta as a share of the pillar height on a log
grid from :data:`ZETA_RANGE`, and at every point asks the planner
(:func:`validation.planner.plan`) for the cheapest model within the tolerance: its choice,
the choice's family (:data:`FAMILIES`: Hertz, the spring model, the Hooke BEM, the elastic
BEM, fem-axisym, fem-3d), predicted error and time, and the reason.  Beside it, the Hooke
pillar's sigma0 model error as the planner counts it for a Hooke model
(:func:`validation.planner.plan.hooke_error`, the same function ``plan`` adds), drawn as
contours at :data:`HOOKE_LEVELS`.

Nothing is solved: a point costs one plan (tens of ms).  Outputs (:func:`write_outputs`):
``regimes.png``, ``regimes.csv`` (one row per point), ``summary.md`` (a reading of the map,
generated from the data) and ``regimes.json``, written last and atomically.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import time
from pathlib import Path

import numpy as np

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import InputError, Pillars, Scene
from ..output.formatting import percent

__all__ = ["CSV_COLUMNS", "DEFAULT_POINTS", "FAMILIES", "FORMAT", "HOOKE_LEVELS",
           "PHI_RANGE", "POINTS_RANGE", "ZETA_RANGE", "family_of", "grid_axes", "grid_scene",
           "read_csv", "regime_map", "summary_markdown", "write_outputs"]

FORMAT = "pillar-xval regimes 1"
# Phi from a sparse lattice to just below close packing (pi / (2 sqrt 3) = 0.9069).
PHI_RANGE = (0.002, 0.9)
# zeta / h up to deep indentations: past h + g(d/2) the lens can reach the floor
# between the pillars (the mixed regime), where only a model with the floor is a candidate.
ZETA_RANGE = (0.01, 10.0)
# Points per axis: the default map plans 30 x 30 scenes (about 25 ms each on an idle core).
DEFAULT_POINTS = 30
POINTS_RANGE = (3, 120)
# Contours of the Hooke pillar's sigma0 error (relative).
HOOKE_LEVELS = (0.05, 0.2, 0.5)
# Model families, in the legend's order: (key, label, colour).
FAMILIES = (
    ("hertz", "Hertz", "#fdd835"),
    ("spring", "spring model", "#ffb74d"),
    ("hooke-bem", "Hooke BEM", "#64b5f6"),
    ("elastic-bem", "elastic BEM", "#81c784"),
    ("fem-axisym", "fem-axisym", "#ce93d8"),
    ("fem-3d", "fem-3d", "#e57373"),
    ("other", "another model", "#bcaaa4"),
    ("none", "no model", "#9e9e9e"),
)
FAMILY_LABEL = {k: label for k, label, _ in FAMILIES}
CSV_COLUMNS = ("phi", "zeta_over_h", "regime", "family", "model", "label", "options",
               "within_tolerance", "predicted_error", "time_s", "memory_MB",
               "hooke_sigma0_error", "reason")


def family_of(choice: dict | None) -> str:
    """The family key (:data:`FAMILIES`) of a plan's choice: the closed forms by name, the
    BEMs by their pillar physics (the registry's ``physics_of``: ``pillars = elastic`` is the
    elastic BEM), the FEMs by name."""
    if choice is None:
        return "none"
    model = choice["model"]
    if model in ("hertz", "spring", "fem-axisym", "fem-3d"):
        return model
    if model.startswith("bem"):
        from ..registry import MODELS

        entry = MODELS.get(model)
        physics = entry.physics_of(choice.get("options")) if entry is not None else ""
        return "elastic-bem" if physics == "elastic-pillar" else "hooke-bem"
    return "other"


def grid_axes(points: int) -> tuple[list[float], list[float]]:
    """(Phi values, zeta/h values): ``points`` each, evenly spaced in log10."""
    if not (isinstance(points, int) and POINTS_RANGE[0] <= points <= POINTS_RANGE[1]):
        raise InputError(f"--points {points!r}: allowed range is [{POINTS_RANGE[0]}, "
                         f"{POINTS_RANGE[1]}] points per axis")
    phis = np.geomspace(*PHI_RANGE, points)
    zetas = np.geomspace(*ZETA_RANGE, points)
    return [float(v) for v in phis], [float(v) for v in zetas]


def grid_scene(base: Scene, phi: float, zeta_over_h: float) -> Scene:
    """``base`` with surface fraction ``phi`` (its pitch) and indentation ``zeta_over_h`` x
    the pillar height; diameter, height, materials and lens kept."""
    p = base.pillars
    pillars = Pillars(p.diameter_m, p.height_m, Pillars.pitch_from_fraction(p.diameter_m, phi),
                      p.material)
    return base.replace(pillars=pillars, indentation_m=zeta_over_h * p.height_m,
                        force_N=None,  # the map sets the indentation, whatever the base's load
                        name=f"{base.name} Phi={phi:.4g} zeta/h={zeta_over_h:.4g}")


def _point(scene: Scene, phi: float, z: float, tolerance: float, quantities,
           data) -> tuple[dict, dict]:
    """The record of one grid point, and the provenance of the planner's data."""
    from ..planner.plan import hooke_error, plan

    p = plan(scene, tolerance, quantities, data=data)
    reg, choice = p["regime"], p["choice"]
    hooke = hooke_error(scene, "sigma0", data, reg, p["features"])
    errors = {} if choice is None else {q: float(v)
                                        for q, v in choice["predicted_errors"].items()}
    return {
        "phi": phi, "zeta_over_h": z, "regime": reg["label"], "phi_s": reg["phi_s"],
        "family": family_of(choice),
        "model": None if choice is None else choice["model"],
        "label": None if choice is None else choice["label"],
        "options": {} if choice is None else dict(choice["options"]),
        "within_tolerance": bool(choice is not None and choice["within_tolerance"]),
        "predicted_errors": errors,
        "predicted_error": max(errors.values()) if errors else None,
        "time_s": None if choice is None else float(choice["time_s"]),
        "memory_MB": None if choice is None else float(choice["memory_MB"]),
        "hooke_sigma0_error": None if hooke is None else float(hooke),
        "reason": p["reason"],
    }, p["data"]


def regime_map(base: Scene, tolerance: float = 0.05, quantities=("F_T", "sigma0"),
               points: int = DEFAULT_POINTS, overrides=(), progress=None, data=None) -> dict:
    """The map's data (JSON-ready): the axes, one record per grid point (Phi outer, zeta/h
    inner), the shares per family and the planning time.

    ``progress(done, total, elapsed_s)`` is called now and then; ``overrides`` are recorded
    as given (the ``--set`` values that made ``base``)."""
    from ..planner.plan import check_request

    tolerance, quantities, _ = check_request(tolerance, quantities)
    if base.pillars is None:
        raise InputError(f"--scene {base.name}: has no pillars; the regime map varies the "
                         "pillars' surface fraction (use a scene with a [pillars] table)")
    phis, zetas = grid_axes(points)
    total = len(phis) * len(zetas)
    records, t0, shown = [], time.perf_counter(), 0.0
    for phi in phis:
        for z in zetas:
            record, provenance = _point(grid_scene(base, phi, z), phi, z, tolerance,
                                        quantities, data)
            records.append(record)
            elapsed = time.perf_counter() - t0
            if progress is not None and (len(records) == total or elapsed - shown >= 5.0):
                shown = elapsed
                progress(len(records), total, elapsed)
    wall = time.perf_counter() - t0
    shares = {k: sum(r["family"] == k for r in records) / total for k, _, _ in FAMILIES}
    return {
        "format": FORMAT, "base_scene": base.to_dict(), "overrides": list(overrides),
        "tolerance": tolerance, "quantities": list(quantities),
        "axes": {"phi": phis, "zeta_over_h": zetas}, "hooke_levels": list(HOOKE_LEVELS),
        "families": [{"key": k, "label": label, "colour": c} for k, label, c in FAMILIES],
        "shares": shares,
        "within_tolerance_share": sum(r["within_tolerance"] for r in records) / total,
        "points": records,
        "timing": {"wall_s": wall, "per_point_s": wall / total, "points": total},
        "planner_data": provenance,
    }


# ---- reading ------------------------------------------------------------------------------

def _pct(x: float) -> str:
    return percent(x, ".3g")


def _span(values: list[float]) -> str:
    return f"{min(values):.3g} to {max(values):.3g}" if values else "-"


def _gist(reason: str) -> str:
    """A reason without its numbers and model labels' resolutions, so that equal reasons
    group."""
    text = re.sub(r"\(([^()]*\([^()]*\))*[^()]*\)", "(...)", reason)
    return re.sub(r"[-+]?\d[\d.eE+-]*", "#", text)[:200]


def _describe_base(doc: dict) -> str:
    s = doc["base_scene"]
    p, lens, sub = s["pillars"], s["lens"], s["substrate"]

    def modulus(m):
        return "rigid" if m["rigid"] else f"{m['E_Pa'] / 1e6:.4g} MPa"

    if p["rigid"] or sub["rigid"]:
        es = f"E_s {modulus(sub)}"
    elif math.isclose(sub["E_Pa"], p["E_Pa"], rel_tol=1e-12):
        es = "E_s = E_p"
    else:
        es = f"E_s/E_p = {sub['E_Pa'] / p['E_Pa']:.3g}"
    return (f"{s['name']}{' (' + ', '.join(doc['overrides']) + ')' if doc['overrides'] else ''}"
            f": E_l {modulus(lens)}, E_p {modulus(p)}, {es}; d = {1e6 * p['diameter_m']:.3g} um,"
            f" h = {1e6 * p['height_m']:.3g} um, R = {1e3 * lens['radius_m']:.3g} mm")


def summary_markdown(doc: dict) -> str:
    """A short reading of the map, generated from its data."""
    pts = doc["points"]
    n = len(pts)
    tol = doc["tolerance"]
    lines = [f"# Regime map: which model for {_pct(tol)} on {', '.join(doc['quantities'])}",
             "", f"Base scene: {_describe_base(doc)}.",
             f"Grid: {len(doc['axes']['phi'])} x {len(doc['axes']['zeta_over_h'])} points, "
             f"Phi {_span(doc['axes']['phi'])} (log), zeta/h {_span(doc['axes']['zeta_over_h'])}"
             f" (log); planned in {doc['timing']['wall_s']:.3g} s "
             f"({1e3 * doc['timing']['per_point_s']:.3g} ms a point).", "",
             "## Which model wins where", "",
             "| model | share of the grid | Phi | zeta/h | predicted error | time |",
             "|---|---|---|---|---|---|"]
    for key, label, _ in FAMILIES:
        mine = [r for r in pts if r["family"] == key]
        if not mine:
            continue
        errs = [r["predicted_error"] for r in mine if r["predicted_error"] is not None]
        times = [r["time_s"] for r in mine if r["time_s"] is not None]
        names = sorted({r["label"] for r in mine if r["label"]})
        lines.append(
            f"| {label} ({', '.join(names) or '-'}) | {_pct(len(mine) / n)} "
            f"| {_span([r['phi'] for r in mine])} | {_span([r['zeta_over_h'] for r in mine])} "
            f"| {_pct(min(errs)) + ' to ' + _pct(max(errs)) if errs else '-'} "
            f"| {_span(times) + ' s' if times else '-'} |")
    outside = [r for r in pts if not r["within_tolerance"]]
    lines += ["", f"Within {_pct(tol)}: {_pct(1 - len(outside) / n)} of the grid."]
    if outside:
        lines.append(f"No model is predicted within {_pct(tol)} on {_pct(len(outside) / n)} "
                     f"of the grid (Phi {_span([r['phi'] for r in outside])}, zeta/h "
                     f"{_span([r['zeta_over_h'] for r in outside])}): the plan takes the "
                     "closest (hatched on the map).")
    hooke = [r for r in pts if r["hooke_sigma0_error"] is not None]
    lines += ["", "## The paper's Hooke pillar: sigma0 model error", ""]
    if hooke:
        values = [r["hooke_sigma0_error"] for r in hooke]
        lines.append(f"The planner's Hooke-pillar sigma0 error (interpolated measurement plus "
                     f"its margin) runs from {_pct(min(values))} to {_pct(max(values))} "
                     "over the grid.")
        for level in doc["hooke_levels"]:
            over = [r for r in hooke if r["hooke_sigma0_error"] > level]
            where = (f": Phi {_span([r['phi'] for r in over])}, zeta/h "
                     f"{_span([r['zeta_over_h'] for r in over])}" if over else "")
            lines.append(f"- above {_pct(level)} on {_pct(len(over) / n)} of the grid{where}")
        trusted = [r for r in hooke if r["hooke_sigma0_error"] <= tol]
        lines.append("")
        lines.append(
            f"The paper's model (Hooke pillars) is within {_pct(tol)} on sigma0 on "
            f"{_pct(len(trusted) / n)} of the grid"
            + (f" (Phi {_span([r['phi'] for r in trusted])})" if trusted else
               ": nowhere on this map; an elastic-pillar model (the elastic BEM or fem-3d) "
               "is needed for sigma0 at this tolerance"))
        by_regime = {}
        for r in hooke:
            by_regime.setdefault(r["regime"], []).append(r["hooke_sigma0_error"])
        lines.append("By regime: " + "; ".join(
            f"{reg} {_pct(min(v))} to {_pct(max(v))}" for reg, v in by_regime.items()) + ".")
    else:
        lines.append("No Hooke error table covers these scenes.")
    reasons = {}
    for r in pts:
        reasons.setdefault((r["family"], _gist(r["reason"])), []).append(r)
    lines += ["", "## Why (the planner's reasons, grouped)", ""]
    for (fam, gist), rs in sorted(reasons.items(), key=lambda kv: -len(kv[1]))[:8]:
        lines.append(f"- {FAMILY_LABEL.get(fam, fam)}, {len(rs)} points: {rs[0]['reason']}")
    return "\n".join(lines) + "\n"


# ---- files --------------------------------------------------------------------------------

def _csv_text(doc: dict) -> str:
    buf = io.StringIO()
    qs = doc["quantities"]
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(list(CSV_COLUMNS[:9]) + [f"error_{q}" for q in qs] + list(CSV_COLUMNS[9:]))
    for r in doc["points"]:
        row = [r["phi"], r["zeta_over_h"], r["regime"], r["family"], r["model"] or "",
               r["label"] or "", json.dumps(r["options"], sort_keys=True),
               int(r["within_tolerance"]), _cell(r["predicted_error"])]
        row += [_cell(r["predicted_errors"].get(q)) for q in qs]
        row += [_cell(r["time_s"]), _cell(r["memory_MB"]), _cell(r["hooke_sigma0_error"]),
                r["reason"]]
        w.writerow(row)
    return buf.getvalue()


def _cell(v) -> str:
    return "" if v is None else repr(float(v))


def read_csv(path: Path) -> list[dict]:
    """The rows of ``regimes.csv`` with their types back (floats, bools, options as a dict,
    ``predicted_errors`` per quantity): equal to the JSON's points but for ``phi_s``."""
    rows = []
    with open(path, newline="") as f:
        for raw in csv.DictReader(f):
            num = {k: (None if raw[k] == "" else float(raw[k]))
                   for k in ("predicted_error", "time_s", "memory_MB", "hooke_sigma0_error")}
            rows.append({
                "phi": float(raw["phi"]), "zeta_over_h": float(raw["zeta_over_h"]),
                "regime": raw["regime"], "family": raw["family"],
                "model": raw["model"] or None, "label": raw["label"] or None,
                "options": json.loads(raw["options"]),
                "within_tolerance": raw["within_tolerance"] == "1",
                "predicted_errors": {k[len("error_"):]: float(v) for k, v in raw.items()
                                     if k.startswith("error_") and v != ""},
                **num, "reason": raw["reason"]})
    return rows


def plot_map(doc: dict, path: Path) -> Path:
    """The map: regions coloured by the chosen family, hatched where no model is within
    tolerance, the Hooke sigma0 error's contours and the single-pillar threshold."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from ..output.report import save_figure

    phis = np.array(doc["axes"]["phi"])
    zetas = np.array(doc["axes"]["zeta_over_h"])
    keys = [k for k, _, _ in FAMILIES]
    # One colour per chosen candidate: its family's, in shades when a family has several.
    cats = sorted({(keys.index(r["family"]), r["label"] or "") for r in doc["points"]},
                  key=lambda c: (c[0], _resolution(c[1]), c[1]))
    colours = []
    for f, label in cats:
        mine = [c for c in cats if c[0] == f]
        k = mine.index((f, label))
        colours.append(_shade(FAMILIES[f][2], 0.0 if len(mine) == 1 else
                              0.45 - 0.9 * k / (len(mine) - 1)))
    fam = np.zeros((len(zetas), len(phis)), int)
    hooke = np.full(fam.shape, np.nan)
    outside = np.zeros(fam.shape)
    ratio = np.full(fam.shape, np.nan)
    mixed = np.zeros(fam.shape)
    for r in doc["points"]:
        i = int(np.argmin(np.abs(zetas - r["zeta_over_h"])))
        j = int(np.argmin(np.abs(phis - r["phi"])))
        fam[i, j] = cats.index((keys.index(r["family"]), r["label"] or ""))
        if r["hooke_sigma0_error"] is not None:
            hooke[i, j] = 100.0 * r["hooke_sigma0_error"]
        outside[i, j] = 0.0 if r["within_tolerance"] else 1.0
        if r.get("phi_s"):
            ratio[i, j] = math.log10(r["phi"] / r["phi_s"])
        mixed[i, j] = float(str(r["regime"]).startswith("mixed"))

    def edges(v):
        lv = np.log10(v)
        mid = 0.5 * (lv[1:] + lv[:-1])
        return 10.0 ** np.concatenate([[2 * lv[0] - mid[0]], mid, [2 * lv[-1] - mid[-1]]])

    fig, ax = plt.subplots(figsize=(11.0, 6.2))
    ax.pcolormesh(edges(phis), edges(zetas), fam, shading="flat",
                  cmap=ListedColormap(colours), vmin=-0.5, vmax=len(cats) - 0.5)
    handles = [Patch(facecolor=c, edgecolor="0.4", linewidth=0.5,
                     label=FAMILIES[f][1] if label in ("", keys[f]) else label
                     if label.startswith(FAMILIES[f][1]) else f"{FAMILIES[f][1]}: {label}")
               for (f, label), c in zip(cats, colours)]
    if outside.any():
        ax.contourf(phis, zetas, outside, levels=[0.5, 1.5], colors="none", hatches=["//"])
        handles.append(Patch(facecolor="white", edgecolor="black", hatch="//",
                             label=f"none within {_pct(doc['tolerance'])}: the closest"))
    styles = (":", "--", "-")
    known = hooke[np.isfinite(hooke)]
    lo, hi = (known.min(), known.max()) if known.size else (math.inf, -math.inf)
    for level, style in zip(doc["hooke_levels"], styles):
        if lo < 100 * level < hi:
            cs = ax.contour(phis, zetas, hooke, levels=[100 * level], colors="black",
                            linestyles=style, linewidths=1.6)
            ax.clabel(cs, fmt=lambda v: f"{v:.0f} %", fontsize=9)
            drawn = ""
        elif lo >= 100 * level:
            drawn = " (above it everywhere)"
        else:
            drawn = " (nowhere)"
        handles.append(Line2D([], [], color="black", linestyle=style, linewidth=1.6,
                              label=f"Hooke sigma0 error {100 * level:.0f} %{drawn}"))
    if np.isfinite(ratio).any() and np.nanmin(ratio) < 0 < np.nanmax(ratio):
        ax.contour(phis, zetas, ratio, levels=[0.0], colors="#37474f", linestyles="-.",
                   linewidths=1.2)
        handles.append(Line2D([], [], color="#37474f", linestyle="-.",
                              label="Phi_S: a second pillar touches"))
    if 0.0 < mixed.mean() < 1.0:
        ax.contour(phis, zetas, mixed, levels=[0.5], colors="white", linestyles="-",
                   linewidths=2.0)
        handles.append(Line2D([], [], color="0.6", linestyle="-", linewidth=2.0,
                              label="above: the floor within reach (mixed)"))
    if known.size:
        handles.append(Patch(facecolor="none", edgecolor="none",
                             label=f"(Hooke sigma0 error here {lo:.0f} to {hi:.0f} %)"))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("surface fraction Phi")
    ax.set_ylabel("indentation over pillar height zeta/h")
    fig.suptitle(f"Model the planner picks for {_pct(doc['tolerance'])} on "
                 f"{', '.join(doc['quantities'])} (base scene {_describe_base(doc)})",
                 fontsize=10, wrap=True)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9,
              borderaxespad=0.0, frameon=False)
    save_figure(fig, path, 120)
    return Path(path)


def _resolution(label: str) -> float:
    """The resolution in a candidate's label (bem P=11, fem-3d mesh=2): shades in its order."""
    m = re.search(r"=([0-9.]+)", label)
    return float(m.group(1)) if m else 0.0


def _shade(colour: str, amount: float) -> tuple:
    """``colour`` lightened (amount > 0, towards white) or darkened (< 0)."""
    from matplotlib.colors import to_rgb

    rgb = np.array(to_rgb(colour))
    target = np.ones(3) if amount > 0 else np.zeros(3)
    return tuple(rgb + abs(amount) * (target - rgb))


def write_outputs(doc: dict, out: Path) -> list[str]:
    """regimes.csv, regimes.png, summary.md, then regimes.json (last, atomically)."""
    out = Path(out)
    write_atomic(out / "regimes.csv", _csv_text(doc))
    plot_map(doc, out / "regimes.png")
    write_atomic(out / "summary.md", summary_markdown(doc))
    write_atomic(out / "regimes.json", json.dumps(doc, indent=1, allow_nan=False))
    return ["regimes.csv", "regimes.png", "summary.md", "regimes.json"]
