"""Files written by ``pillar-xval solve --out DIR`` (result.json, elements.csv, pillars.csv and
pressure.png: the paper's Fig. 3 layout, pressure map and sigma(r)), and what every report
shares: figures saved atomically, stamped NOT CONVERGED when a solver missed its tolerance, and
old report files cleared before a new report is computed."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from pillar_xval.outcome import ContactResult, write_atomic

UM, KPA = 1e6, 1e-3  # display units: micrometres and kilopascals per SI unit
# Above this many elements a scatter of sigma(r) is a grey blob: draw its density instead.
SCATTER_MAX = 5000


def _csv_text(header: list[str], rows) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(header)
    for row in rows:
        writer.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in row])
    return buf.getvalue()


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figure_png(fig, dpi: int = 120, layout: bool = True) -> bytes:
    """Lay out ``fig`` (unless ``layout`` is False: the caller did), close it and return its
    PNG bytes (write them with write_atomic)."""
    import matplotlib.pyplot as plt

    if layout:
        fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=legible_dpi(fig, dpi))
    plt.close(fig)
    return buf.getvalue()


def save_figure(fig, path, dpi: int = 120, layout: bool = True) -> Path:
    """Write ``fig`` as a PNG atomically and close it (see :func:`figure_png`)."""
    return write_atomic(path, figure_png(fig, dpi, layout))


def legend_outside(ax, fontsize: float = 8, **kw):
    """The legend of ``ax`` beside it, right of the axes (the figure's layout makes room), so
    that it never covers a curve or a point: a legend inside the axes sat over the data of
    the sparse lattice's and fem-3d's pressure plots.  A curve that a later one hides
    entirely is not listed on its own: the curve on top says it hides it
    (:func:`merge_hidden`).  None when nothing is labelled."""
    merge_hidden(ax)
    if not ax.get_legend_handles_labels()[0]:
        return None
    return ax.legend(fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                     borderaxespad=0.0, **kw)


# At most this many points stand for a curve when its coverage is judged: the cost of
# merge_hidden stays bounded (a fuzzed scene drew a profile 1e12 px long).
MAX_COVER_POINTS = 2000


def _display_path(line, box) -> np.ndarray:
    """The vertices of ``line`` in display pixels, clipped to ``box`` widened by 10 px (what
    lies beyond is not drawn, and an off-screen vertex 1e12 px away would make a segment of
    that length)."""
    xy = np.column_stack([np.asarray(v, dtype=float) for v in line.get_data()])
    xy = line.get_transform().transform(xy[np.all(np.isfinite(xy), axis=1)])
    if len(xy) == 0:
        return xy.reshape(0, 2)
    return np.column_stack([np.clip(xy[:, 0], box.x0 - 10, box.x1 + 10),
                            np.clip(xy[:, 1], box.y0 - 10, box.y1 + 10)])


def _densified(xy: np.ndarray, step_px: float = 2.0) -> np.ndarray:
    """Points along the polyline ``xy`` every ``step_px`` or so, at most
    :data:`MAX_COVER_POINTS` of them."""
    if len(xy) < 2:
        return xy
    lengths = np.hypot(*np.diff(xy, axis=0).T)
    step = max(step_px, float(lengths.sum()) / MAX_COVER_POINTS)
    out = [xy[:1]]
    for a, b, length in zip(xy[:-1], xy[1:], lengths):
        n = max(1, int(length / step))
        out.append(a + np.outer(np.arange(1, n + 1) / n, b - a))
    return np.concatenate(out)


def _distance_to_path(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """The distance (px) of each point to the polyline ``path``."""
    if len(path) == 1:
        return np.hypot(*(points - path[0]).T)
    a, b = path[:-1], path[1:]
    d = b - a
    length2 = np.maximum((d * d).sum(axis=1), 1e-12)
    best = np.full(len(points), np.inf)
    chunk = max(1, 500_000 // len(a))  # bounded memory: points x segments, ~50 MB at most
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk, None, :]
        t = np.clip(((p - a) * d).sum(axis=2) / length2, 0.0, 1.0)
        gap = p - (a + t[..., None] * d)
        best[start:start + chunk] = np.sqrt((gap * gap).sum(axis=2)).min(axis=1)
    return best


def merge_hidden(ax, slack_px: float = 1.0) -> list[str]:
    """Take out of the legend every labelled curve of ``ax`` that a later, solid curve covers
    along its whole drawn length (within half that curve's width plus ``slack_px``), and name
    it in the covering curve's label instead ("FEM mesh_size=0.5 (hides FEM mesh_size=1)"):
    a legend entry for a curve nobody can see says it is there.  Curves with markers stay
    (their markers show).  Returns the labels taken out."""
    # In drawing order: by zorder, then as added.
    lines = sorted((ln for ln in ax.get_lines() if ln.get_visible()), key=lambda ln: ln.zorder)
    scale = ax.figure.dpi / 72.0
    clip = ax.get_window_extent()
    paths = [_display_path(ln, clip) for ln in lines]
    hidden_by = {}
    for i, line in enumerate(lines):
        if line.get_label().startswith("_") or line.get_marker() not in ("None", None, "", " "):
            continue
        pts = _densified(paths[i])
        inside = pts[(pts[:, 0] >= clip.x0) & (pts[:, 0] <= clip.x1)
                     & (pts[:, 1] >= clip.y0) & (pts[:, 1] <= clip.y1)] if len(pts) else pts
        if len(inside) == 0:
            continue
        for j in range(len(lines) - 1, i, -1):
            top = lines[j]
            if top.get_linestyle() != "-" or len(paths[j]) == 0:
                continue
            reach = 0.5 * top.get_linewidth() * scale + slack_px
            if np.all(_distance_to_path(inside, paths[j]) <= reach):
                hidden_by[i] = j
                break
    names = {}
    for i, j in sorted(hidden_by.items()):
        while j in hidden_by:  # the curve on top of the one that covers it
            j = hidden_by[j]
        names.setdefault(j, []).append(lines[i].get_label())
    for j, hidden in names.items():
        if not lines[j].get_label().startswith("_"):
            lines[j].set_label(f"{lines[j].get_label()} (hides {', '.join(hidden)})")
    taken = [lines[i].get_label() for i in hidden_by]
    for i in hidden_by:
        lines[i].set_label("_" + lines[i].get_label())
    return taken


# The smallest text a figure may carry, in pixels of the saved PNG: quick figures are drawn at
# a lower dpi, which once made 7 pt text 5 px high.
MIN_TEXT_PX = 10.0


def smallest_text_pt(fig) -> float:
    """The smallest font size (pt) of the visible text of ``fig`` (titles, labels, ticks,
    legends, annotations)."""
    from matplotlib.text import Text

    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_visible() and t.get_text()]
    return min(sizes) if sizes else 10.0


def legible_dpi(fig, dpi: float, min_px: float = MIN_TEXT_PX) -> int:
    """``dpi``, raised where needed so that the smallest text of ``fig`` is ``min_px`` pixels
    high in the PNG (a font of s pt is s dpi / 72 px)."""
    return int(math.ceil(max(dpi, min_px * 72.0 / smallest_text_pt(fig))))


def stamp_not_converged(fig, what: list[str]) -> None:
    """Mark a figure whose data come from a solve that missed its tolerance: NOT CONVERGED
    across it, and which run and why along its bottom edge.  Nothing when ``what`` is empty."""
    if not what:
        return
    fig.text(0.5, 0.5, "NOT CONVERGED", color="red", alpha=0.3, fontsize=44, rotation=18,
             ha="center", va="center", weight="bold", zorder=1000)
    text = "; ".join(what)
    text = text if len(text) <= 160 else text[:157] + "..."
    fig.text(0.005, 0.003, f"NOT CONVERGED: {text}", color="red", fontsize=7, ha="left",
             va="bottom", zorder=1000)


# Marks a report folder with the command whose report it holds (one line: the command).
REPORT_MARK = ".pillar-xval-report"
# Each command's main file (written last), to know the owner of a folder made before marks.
MAIN_FILES = {"solve": "result.json", "compare": "report.json", "converge": "converge.json",
              "tradeoff": "tradeoff.json", "gecit": "gecit.json", "lattice": "lattice.json",
              "check": "check.json", "curve": "curve.json"}


def report_owner(out: Path) -> str | None:
    """The command whose report ``out`` holds (its mark, else its main file), None if none."""
    out = Path(out)
    try:
        mark = (out / REPORT_MARK).read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError):
        mark = ""
    if mark:
        return mark
    return next((cmd for cmd, name in MAIN_FILES.items() if (out / name).is_file()), None)


def clear_outputs(out: Path, names, command: str) -> None:
    """Claim ``out`` for ``command``'s report and remove the files ``names`` of its earlier
    report before a new one is computed: a report folder then never holds a mix of old and
    new files, even when the run is killed (each study writes its main file last, so its
    presence means a whole report), nor the reports of two commands (InputError, exit 2: the
    other report is the user's and stays).  A file that cannot be removed is a ToolError
    (exit 3)."""
    from pillar_xval.scenes import InputError, ToolError

    owner = report_owner(out)
    if owner not in (None, command):
        raise InputError(f"--out {out}: holds a report of `pillar-xval {owner}`; a report "
                         f"folder holds one command's report: give {command} another folder")
    for name in names:
        path = Path(out) / name
        try:
            if path.is_file() or path.is_symlink():
                path.unlink()
        except OSError as exc:
            raise ToolError(f"cannot remove the old {path} ({exc.strerror or exc})") from None
    write_atomic(Path(out) / REPORT_MARK, command + "\n")


def write_solve_report(result: ContactResult, out: Path) -> None:
    """elements.csv (models with an element map), pillars.csv, pressure.png, then
    result.json (last: its presence means the folder is whole)."""
    out = Path(out)
    f = result.fields
    if "x_m" in f:
        cols = [c for c in ("x_m", "y_m", "pillar_orbit", "weight", "area_m2", "pressure_Pa",
                            "force_N", "gap_m", "floor") if c in f]
        rows = zip(*[np.asarray(f[c]).tolist() for c in cols])
        write_atomic(out / "elements.csv", _csv_text(cols, rows))
    write_atomic(out / "pillars.csv", _csv_text(
        ["n", "m", "x_m", "y_m", "force_N"],
        ([p.n, p.m, p.x_m, p.y_m, p.force_N] for p in result.pillar_forces)))
    write_atomic(out / "pressure.png", pressure_figure(result))
    write_atomic(out / "result.json", result.to_json() + "\n")


def not_converged_note(result: ContactResult) -> list[str]:
    """[] for a converged result, else one line naming the model and its message."""
    if result.converged:
        return []
    return [f"{result.model}: {result.diagnostics.get('message', 'no message')}"]


def pressure_figure(result: ContactResult) -> bytes:
    """PNG bytes of :func:`pressure_plot`."""
    return figure_png(pressure_plot(result))


def pressure_plot(result: ContactResult):
    """The matplotlib figure of a solve's pressure.

    With an element map (the BEM models): the map of the computed elements (left; a regular
    grid is drawn as an image) and sigma(r) of every element with the Hertz, spring-model and
    Hertz-like curves (right), as in the paper's Fig. 3.  Without one (the FEM): the pressure
    across the pillar top (or the Hertz contact) with its closed forms, on an axis sized to
    it.  Stamped NOT CONVERGED when the solve missed its tolerance."""
    from pillar_xval.scenes import Scene

    plt = pyplot()
    scene = Scene.from_dict(result.scene)
    if "x_m" in result.fields:
        fig, (ax_map, ax_prof) = plt.subplots(1, 2, figsize=(12, 5))
        _pressure_map(fig, ax_map, result, scene)
        _element_profile(ax_prof, result, scene)
    else:
        fig, ax_prof = plt.subplots(figsize=(9.4, 4.8))  # room for the legend beside the axes
        _top_profile(ax_prof, result, scene)
    stamp_not_converged(fig, not_converged_note(result))
    return fig


def _colour_limit(p: np.ndarray) -> tuple[float, bool]:
    """(upper colour limit in Pa, whether peaks above it are cut): the 95th percentile of the
    loaded elements, at most 4 times their median, so that the edge peaks of the pillar tops
    (5 to 15 % of the elements, 10 to 40 times the bulk on Fig. 3's scenes) do not turn the
    map dark."""
    loaded = p[p > 0]
    if loaded.size == 0:
        return 1.0, False
    top = min(float(np.percentile(loaded, 95)), 4.0 * float(np.median(loaded)))
    return (top, True) if p.max() > 1.05 * top else (float(p.max()), False)


def _grid_image(f: dict):
    """The cells of a regular grid as an image (NaN off the candidate cells) and its extent
    in um, or None when the elements are not one regular grid."""
    side = np.asarray(f.get("side_m", []), dtype=float)
    if "cell_size_m" not in f or side.size == 0 or np.ptp(side) > 1e-9 * side[0] \
            or np.any(np.asarray(f.get("angle_rad", 0.0)) != 0):
        return None
    L = float(f["cell_size_m"])
    ix = np.rint(np.asarray(f["x_m"]) / L).astype(int)
    iy = np.rint(np.asarray(f["y_m"]) / L).astype(int)
    image = np.full((iy.max() - iy.min() + 1, ix.max() - ix.min() + 1), np.nan)
    # A rim cell may hold a top and a floor part: the floor first, its top drawn over it.
    order = np.argsort(~np.asarray(f.get("floor", np.zeros(ix.size, dtype=bool))),
                       kind="stable")
    image[iy[order] - iy.min(), ix[order] - ix.min()] = np.asarray(f["pressure_Pa"])[order]
    extent = [(ix.min() - 0.5) * L * UM, (ix.max() + 0.5) * L * UM,
              (iy.min() - 0.5) * L * UM, (iy.max() + 0.5) * L * UM]
    return image, extent


def _pressure_map(fig, ax, result: ContactResult, scene) -> None:
    from matplotlib.collections import PolyCollection

    f = result.fields
    x, y, p = (np.asarray(f[k], dtype=float) for k in ("x_m", "y_m", "pressure_Pa"))
    vmax, cut = _colour_limit(p)
    grid = _grid_image(f)
    if grid is not None:
        image, extent = grid
        shown = ax.imshow(image * KPA, origin="lower", extent=extent, cmap="viridis",
                          vmin=0.0, vmax=vmax * KPA, interpolation="nearest")
        what = f"all {p.size} grid cells"
    else:
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 0.5
        polys = []
        for xi, yi, si, ai in zip(x, y, f["side_m"], f["angle_rad"]):
            c, s = math.cos(ai), math.sin(ai)
            local = corners * si
            polys.append(np.column_stack([xi + c * local[:, 0] - s * local[:, 1],
                                          yi + s * local[:, 0] + c * local[:, 1]]) * UM)
        shown = PolyCollection(polys, array=p * KPA, cmap="viridis", edgecolors="none")
        shown.set_clim(0.0, vmax * KPA)
        ax.add_collection(shown)
        what = f"{p.size} elements, one per symmetry orbit"
    # Below the map: a bar beside it put its label next to the profile's pressure axis, two
    # "pressure (kPa)" side by side for two different scales.
    fig.colorbar(shown, ax=ax, location="bottom", shrink=0.8, pad=0.14,
                 label="pressure on the map (kPa)", extend="max" if cut else "neither")
    rmax = max(np.hypot(x, y).max() * UM * 1.05, 1.0)
    if scene.pillars is not None:  # the lattice's primitive cell, 0 <= theta <= pi/6
        for ang in (0.0, math.pi / 6):
            ax.plot([0, rmax * math.cos(ang)], [0, rmax * math.sin(ang)], "r-.", lw=0.8)
        what += "\nprimitive cell dash-dotted, contact radius dotted"
    else:
        what += "\ncontact radius dotted"
    t = np.linspace(0, 2 * math.pi if grid is not None else math.pi / 2, 200)
    if result.contact_radius_m > 0:
        a = result.contact_radius_m * UM
        ax.plot(a * np.cos(t), a * np.sin(t), "r:", lw=1)
    if result.floor_contact_radius_m > 0:
        a = result.floor_contact_radius_m * UM
        ax.plot(a * np.cos(t), a * np.sin(t), "w--", lw=1)
        what += (f"\nfloor touched out to {a:.3g} µm (dashed): "
                 f"{100 * result.floor_force_N / result.total_force_N:.3g} % of F")
    lo = -0.1 * rmax if grid is None else min(extent[0], extent[2])
    ax.set_xlim(lo, rmax)
    ax.set_ylim(lo, rmax if grid is not None else 0.75 * rmax)
    ax.set_aspect("equal")
    ax.set_xlabel("x (µm)")
    ax.set_ylabel("y (µm)")
    ax.set_title(f"{result.label}: {what}"
                 + (f"\ncolour capped at {vmax * KPA:.3g} kPa (peaks {p.max() * KPA:.3g} kPa)"
                    if cut else ""), fontsize=9)


def _limit(limit, scene):
    """A closed-form limit of ``scene`` to draw as a reference, or None where it does not
    apply (a rigid lens has no rigid-punch curve, say): a reference curve never turns a
    finished solve into an error."""
    from pillar_xval.scenes import SceneError

    try:
        return limit(scene)
    except SceneError:
        return None


def one_pillar(scene) -> bool:
    """Whether one pillar alone touches ``scene`` (Phi below Phi_S, at the next ring's rim):
    where the single-pillar closed forms (the spring model, the rigid punch) describe it; on
    a lattice of many touching pillars they are another problem and are not drawn."""
    from pillar_xval.scenes import analytic

    return scene.pillars is not None and \
        scene.pillars.surface_fraction < analytic.single_pillar_threshold_rim(scene)


def _closed_form_curves(ax, result: ContactResult, scene, r_end: float) -> float:
    """Hertz, the spring model (one pillar alone) and the paper's Hertz-like curve; returns
    the larger centre pressure (Pa) of the model and of Hertz, to size the pressure axis."""
    from pillar_xval.scenes import analytic

    hz = _limit(analytic.hertz, scene)
    r_line = np.linspace(0, r_end, 400)
    if hz is not None:
        ax.plot(r_line * UM, hz.pressure(r_line) * KPA, "b-", lw=1.2, label="Hertz")
    spring = _limit(analytic.spring_model, scene) if one_pillar(scene) else None
    if spring is not None:
        rp = np.linspace(0, 0.999 * scene.pillars.diameter_m / 2, 200)
        ax.plot(rp * UM, spring.pressure(rp) * KPA, "g-", lw=1.2,
                label="soft flat punch (spring model)")
    if result.contact_radius_m > 0:
        a, s0 = result.contact_radius_m, result.centre_pressure_Pa
        ax.plot(r_line * UM, s0 * np.sqrt(np.clip(1 - (r_line / a) ** 2, 0, None)) * KPA,
                "r--", lw=1.2, label=r"Hertz-like ($\sigma_0$, $a$ of the model)")
    return max(result.centre_pressure_Pa, hz.centre_pressure if hz is not None else 0.0)


def _element_profile(ax, result: ContactResult, scene) -> None:
    f = result.fields
    r = np.hypot(f["x_m"], f["y_m"]) * UM
    p = np.asarray(f["pressure_Pa"], dtype=float) * KPA
    from pillar_xval.scenes import analytic

    hz = _limit(analytic.hertz, scene)
    r_end = max(hz.contact_radius if hz is not None else 0.0, result.contact_radius_m) * 1.05
    # Room for the pillar-top edge peaks (up to 6 sigma0: beyond, the edge singularity runs
    # off the top), or just above the highest element: a dense lattice's peaks are a third of
    # that, which left the top 45 % of the axis empty.
    reference = _closed_form_curves(ax, result, scene, r_end)
    top = min((6 if scene.pillars else 1.3) * reference,
              1.08 * max(float(p.max(initial=0.0)) / KPA, reference)) * KPA
    floor = np.asarray(f.get("floor", np.zeros(p.size, dtype=bool)), dtype=bool)
    if floor.any():  # the floor's cells apart, in orange (their pressures drawn over the grey)
        on = floor & (p > 0)
        ax.plot(r[on], p[on], ".", ms=2, color="C1", zorder=2,
                label=f"{result.model} floor cells in contact")
    if p.size <= SCATTER_MAX:
        ax.plot(r, p, ".", ms=3, color="0.3", label=f"{result.model} elements", zorder=1)
    else:  # hundreds of thousands of cells: their density, in grey
        keep = p <= top
        ax.hexbin(r[keep], p[keep], gridsize=(160, 80), bins="log", cmap="Greys", mincnt=1,
                  extent=(0, max(r.max(), r_end * UM), 0, top), zorder=0)
        ax.plot([], [], "s", color="0.4", label=f"{result.model} cells (density, log)")
    ax.set_xlim(0, max(r.max(), r_end * UM))
    ax.set_ylim(0, top)
    ax.set_xlabel("r (µm)")
    ax.set_ylabel("pressure (kPa)")
    legend_outside(ax)
    ax.set_title(f"{scene_label(result.scene)}: F = {result.total_force_N * UM:.3g} µN, "
                 rf"$\sigma_0$ = {result.centre_pressure_Pa * KPA:.3g} kPa")


def _top_profile(ax, result: ContactResult, scene) -> None:
    """The pressure across the pillar top (or the Hertz contact) of a model without an
    element map, with the closed forms, r from 0 to just past the edge."""
    from pillar_xval.scenes import analytic

    prof = result.pillar_top_profile
    r = np.asarray(prof.get("r_m", []), dtype=float)
    p = np.asarray(prof.get("pressure_Pa", []), dtype=float)
    references = 0.0  # the largest inner value of the reference curves: each one listed in
    # the legend is drawn inside the axes (the rigid punch once ran off the top)
    if scene.pillars is not None:
        edge, where = scene.pillars.diameter_m / 2, "pillar top"
        rp = np.linspace(0, 0.999 * edge, 300)
        for limit, style, label in ((analytic.spring_model, "g-.", "soft flat punch (spring "
                                     "model)"), (analytic.rigid_punch, "k--", "rigid flat punch")):
            curve = _limit(limit, scene) if one_pillar(scene) else None
            if curve is not None:
                pc = curve.pressure(rp)
                ax.plot(rp * UM, pc * KPA, style, lw=1.2, label=label)
                finite = pc[(rp <= 0.8 * edge) & np.isfinite(pc)]
                references = max(references, float(finite.max()) if finite.size else 0.0)
    else:
        hz = _limit(analytic.hertz, scene)
        edge, where = 1.3 * (hz.contact_radius if hz else result.contact_radius_m), "contact"
        if hz is not None:
            rh = np.linspace(0, hz.contact_radius, 300)
            ax.plot(rh * UM, hz.pressure(rh) * KPA, "b--", lw=1.2, label="Hertz", zorder=3)
    ax.plot(r * UM, p * KPA, "-", color="0.15", lw=2.0, label=result.label)
    inner = (r <= 0.8 * edge) & np.isfinite(p)
    top = max(float(p[inner].max()) if inner.any() else 0.0, result.centre_pressure_Pa)
    if top > 0:  # a singular edge runs off the top, by design; the caption gives its peak
        ax.set_ylim(0, max((2.0 if scene.pillars else 1.2) * top, 1.1 * references) * KPA)
    ax.set_xlim(0, 1.05 * edge * UM)
    ax.set_xlabel("r (µm)")
    ax.set_ylabel("contact pressure (kPa)")
    ax.grid(True, alpha=0.3)
    legend_outside(ax)
    peak = f"; edge peak {p.max() * KPA:.3g} kPa" if p.size and p.max() > 2.0 * top else ""
    ax.set_title(f"{scene_label(result.scene)}: pressure across the {where}\n"
                 f"F = {result.total_force_N * UM:.3g} µN, "
                 rf"$\sigma_0$ = {result.centre_pressure_Pa * KPA:.3g} kPa{peak}", fontsize=10)


# What a title says of a scene parameter that differs from its preset: (table, key) -> (symbol,
# factor from SI, unit).  The pitch follows the surface fraction and is named only alone.
_PARAMETERS = {("pillars", "surface_fraction"): ("Φ", 1.0, ""),
               ("load", "indentation_m"): ("ζ", UM, " µm"),
               ("pillars", "diameter_m"): ("d", UM, " µm"), ("pillars", "height_m"): ("h", UM, " µm"),
               ("pillars", "pitch_m"): ("pitch", UM, " µm"),
               ("pillars", "E_Pa"): ("E_p", 1.0, " Pa"), ("pillars", "nu"): ("ν_p", 1.0, ""),
               ("pillars", "rigid"): ("rigid pillars", None, ""),
               ("lens", "radius_m"): ("R", 1e3, " mm"), ("lens", "E_Pa"): ("E_l", 1.0, " Pa"),
               ("lens", "nu"): ("ν_l", 1.0, ""), ("lens", "rigid"): ("rigid lens", None, ""),
               ("substrate", "E_Pa"): ("E_s", 1.0, " Pa"), ("substrate", "nu"): ("ν_s", 1.0, ""),
               ("substrate", "rigid"): ("rigid substrate", None, "")}


def _differs(a, b) -> bool:
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) \
            and not isinstance(a, bool) and not isinstance(b, bool):
        return not math.isclose(a, b, rel_tol=1e-9, abs_tol=0.0)
    return a != b


def _say(symbol, factor, unit, value) -> str:
    if factor is None:
        return symbol if value else f"not {symbol}"
    return f"{symbol} = {value * factor:.3g}{unit}"


def scene_label(scene) -> str:
    """The name of a scene (a Scene or its dict) for a title, with what makes it this scene: a
    preset's name alone when the scene is the preset, else the preset's name and the
    parameters that differ from it ("paper-fig3-sparse (Φ = 0.2)"); a scene that is no preset
    (a file) is named with its Φ and ζ, so that a title never names a preset whose
    parameters the run did not have."""
    from pillar_xval.scenes import load_scene, preset_names

    d = scene if isinstance(scene, dict) else scene.to_dict()
    name = str(d.get("name") or "custom")
    base = None
    if name in preset_names():
        try:
            base = load_scene(name).to_dict()
        except Exception:  # noqa: BLE001 - a preset that does not load names nothing
            base = None
    said = []
    if base is not None:
        if (d.get("pillars") is None) != (base.get("pillars") is None):
            said.append("flat" if d.get("pillars") is None else "with pillars")
        if "force_N" in (d.get("load") or {}):
            said.append(_say("F", UM, " µN", d["load"]["force_N"]))
        for (table, key), how in _PARAMETERS.items():
            mine, theirs = (d.get(table) or {}), (base.get(table) or {})
            if key not in mine or key not in theirs or not _differs(mine[key], theirs[key]):
                continue
            if key == "pitch_m" and _differs(mine.get("surface_fraction"),
                                             theirs.get("surface_fraction")):
                continue  # the surface fraction said it
            if key == "E_Pa" and mine.get("rigid"):
                continue  # "rigid ..." says it
            said.append(_say(*how, mine[key]))
        if not said:
            return name
    else:
        if d.get("pillars"):
            said.append(_say("Φ", 1.0, "", d["pillars"]["surface_fraction"]))
        load = d.get("load") or {}
        if "force_N" in load:
            said.append(_say("F", UM, " µN", load["force_N"]))
        elif load:
            said.append(_say("ζ", UM, " µm", load["indentation_m"]))
    return f"{name} ({', '.join(said)})" if said else name
