"""Figures of the cross-validation studies (matplotlib, Agg) and the off-screen pyvista render.

The pyvista render runs in a child process (``python -m validation.plots render ...``):
a headless machine without an OpenGL context can abort inside VTK, and that must cost the
report one picture, never the whole run.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from .ladders import QUANTITIES
from .report import save_figure

_MARKERS = "osd^v<>p"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path) -> Path:
    return save_figure(fig, path, 120)


def plot_convergence(data: dict, path: Path) -> Path:
    """Relative error against the relative cell size h, log-log, one line per quantity.

    The error is |f - f_exact| / |f_exact| with the Richardson estimate when the study has
    one, otherwise |f - f_finest| / |f_finest| on the coarser levels (marked 'vs finest').
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    hs_all, errs_all = [], []
    for i, q in enumerate(QUANTITIES):
        key, label = q.key, q.label
        s = data["studies"][key]
        h, f = np.array(s["h"]), np.array(s["f"])
        ref = s["gci"]["f_exact"]
        how = "vs Richardson"
        if ref is None:
            ref, h, f, how = f[0], h[1:], f[1:], "vs finest"
        if ref == 0:
            continue
        err = np.abs(f - ref) / abs(ref)
        keep = err > 0
        if not keep.any():
            continue
        p = s["gci"]["order"]
        tag = f"{label} ({how}{'' if p is None else f', p = {p:.2f}'})"
        ax.loglog(h[keep], err[keep], marker=_MARKERS[i % len(_MARKERS)], label=tag)
        hs_all.extend(h[keep])
        errs_all.extend(err[keep])
    if hs_all:
        hs = np.array(sorted(set(hs_all)))
        for order, style in ((1, ":"), (2, "--")):
            ax.loglog(hs, 0.5 * max(errs_all) * (hs / hs[-1]) ** order, "k" + style, lw=0.8,
                      label=f"slope {order}")
    ax.set_xlabel(f"relative cell size h ({data['ladder']['h_meaning']})")
    ax.set_ylabel("relative error")
    ax.set_title(f"{data['model']} on {data['scene'].get('name', '?')}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, path)


def plot_profiles(curves: list[dict], radius_m: float, path: Path, title: str,
                  radius_label: str = "d/2") -> Path:
    """Pressure across the pillar top (or the Hertz contact) for several models.

    ``curves`` holds dicts with ``label``, ``r_m``, ``pressure_Pa`` and optional ``style``;
    r is plotted as r / ``radius_m``, the pressure in kPa.  The y range follows the curves
    inside 0.8 ``radius_m``, so edge peaks (singular or mesh-bound) do not flatten the rest.
    """
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    top = 0.0
    for c in curves:
        r = np.asarray(c["r_m"], dtype=float)
        p = np.asarray(c["pressure_Pa"], dtype=float)
        if r.size == 0:
            continue
        ax.plot(r / radius_m, p * 1e-3, c.get("style", "-"), label=c["label"], lw=1.4)
        inner = r <= 0.8 * radius_m
        if inner.any():
            top = max(top, float(np.nanmax(p[inner])))
    if top > 0:  # edge peaks (singular or mesh-bound) run off the top, by design
        ax.set_ylim(0, 1.8 * top * 1e-3)
    ax.set_xlim(0, 1.05)
    ax.set_xlabel(f"r / ({radius_label})")
    ax.set_ylabel("contact pressure (kPa)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    return _save(fig, path)


def plot_gecit(rows: list[dict], path: Path) -> Path:
    """Four panels against E_p/E_l, one line per h/d: Hooke-BEM error in F_T and sigma_0, the
    fitted edge exponent, and the profile shape (plateau and outer-10 % load fraction)."""
    plt = _pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7.5), sharex=True)
    aspects = sorted({r["aspect"] for r in rows})
    panels = (
        (axes[0, 0], "err_F_T", "(F_BEM - F_FEM) / F_FEM", True),
        (axes[0, 1], "err_sigma0", "(sigma0_BEM - sigma0_FEM) / sigma0_FEM", True),
        (axes[1, 0], "edge_exponent", "edge exponent lambda, sigma ~ (d/2 - r)^(-lambda)", False),
        (axes[1, 1], "plateau", "sigma(d/4)/sigma0 (solid), outer-10 % load (dashed)", False),
    )
    for ax, key, label, percent in panels:
        for i, aspect in enumerate(aspects):
            sel = sorted((r for r in rows if r["aspect"] == aspect), key=lambda r: r["ratio"])
            x = np.array([r["ratio"] for r in sel])
            y = np.array([np.nan if r.get(key) is None else r[key] for r in sel], dtype=float)
            m = _MARKERS[i % len(_MARKERS)]
            ax.semilogx(x, 100 * y if percent else y, marker=m, label=f"h/d = {aspect:g}")
            if key == "plateau":
                y2 = np.array([np.nan if r.get("outer_load_fraction") is None
                               else r["outer_load_fraction"] for r in sel], dtype=float)
                ax.semilogx(x, y2, marker=m, ls="--", color=ax.lines[-1].get_color())
        ax.set_ylabel(label + (" (%)" if percent else ""), fontsize=8)
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(True, which="both", alpha=0.3)
    axes[1, 0].axhline(0.5, color="k", lw=0.8, ls=":", label="rigid punch, 1/2")
    for ax in axes[1]:
        ax.set_xlabel("E_p / E_l")
    for ax in (axes[0, 0], axes[1, 0]):
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
    fig.suptitle("Hooke-spring BEM against the elastic-pillar FEM (single pillar)")
    return _save(fig, path)


def plot_gecit_profiles(profiles: list[dict], path: Path) -> Path:
    """FEM pressure across the pillar top, sigma/sigma_0 against r/(d/2), one panel per h/d
    and one line per E_p/E_l; ``profiles`` holds ``ratio``, ``aspect``, ``radius_m``,
    ``sigma0_Pa``, ``r_m`` and ``pressure_Pa``."""
    plt = _pyplot()
    aspects = sorted({p["aspect"] for p in profiles})
    ratios = sorted({p["ratio"] for p in profiles})
    fig, axes = plt.subplots(1, max(1, len(aspects)), figsize=(4.2 * max(1, len(aspects)), 4.2),
                             sharey=True, squeeze=False)
    cmap = plt.get_cmap("viridis")
    for ax, aspect in zip(axes[0], aspects):
        for p in sorted((p for p in profiles if p["aspect"] == aspect), key=lambda p: p["ratio"]):
            k = ratios.index(p["ratio"]) / max(1, len(ratios) - 1)
            r = np.asarray(p["r_m"]) / p["radius_m"]
            ax.plot(r, np.asarray(p["pressure_Pa"]) / p["sigma0_Pa"], color=cmap(k),
                    label=f"E_p/E_l = {p['ratio']:g}")
        ax.set_title(f"h/d = {aspect:g}")
        ax.set_xlabel("r / (d/2)")
        ax.set_ylim(0, 3.5)
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_ylabel("sigma / sigma_0 (FEM)")
    if axes[0, 0].get_legend_handles_labels()[0]:
        axes[0, 0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Pressure across the pillar top, elastic pillar (FEM)")
    return _save(fig, path)


# --- pyvista render ----------------------------------------------------------------------
def render_stress(vtu_path: Path, png_path: Path, roi_m: float, *,
                  timeout_s: float = 180.0) -> tuple[bool, str]:
    """Render the FEM stress field revolved about the symmetry axis, off screen.

    Runs in a child process; returns (success, message).  ``roi_m`` is the half-size (m) of
    the region around the axis and the contact that is shown.
    """
    cmd = [sys.executable, "-m", "validation.plots", "render", str(vtu_path),
           str(png_path), repr(float(roi_m))]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return False, f"render timed out after {timeout_s:.0f} s"
    if proc.returncode == 0 and Path(png_path).exists():
        return True, proc.stdout.strip().splitlines()[-1] if proc.stdout.strip() else "rendered"
    tail = (proc.stderr or proc.stdout).strip().splitlines()[-3:]
    return False, f"render failed (exit {proc.returncode}): {' | '.join(tail)}"


def stress_scalar(mesh) -> tuple[str, np.ndarray]:
    """The scalar to colour by: a von Mises array if the file has one, else von Mises of a
    3x3 (9 components) stress tensor, else the first array whose name says stress or
    pressure.  Cell arrays (element averages) are averaged to the points first.  Returns its
    description and point values."""
    mesh = mesh.cell_data_to_point_data() if mesh.cell_data else mesh
    names = list(mesh.point_data.keys())
    low = {n: n.lower() for n in names}
    for n in names:
        if "mises" in low[n] and mesh.point_data[n].ndim == 1:
            return n, np.asarray(mesh.point_data[n])
    for n in names:
        a = np.asarray(mesh.point_data[n])
        if ("stress" in low[n] or "sigma" in low[n]) and a.ndim == 2 and a.shape[1] == 9:
            s = a.reshape(-1, 3, 3)
            dev = s - np.trace(s, axis1=1, axis2=2)[:, None, None] / 3.0 * np.eye(3)
            return f"von Mises of {n}", np.sqrt(1.5 * np.einsum("kij,kij->k", dev, dev))
    for word in ("stress", "sigma", "pressure"):
        for n in names:
            a = np.asarray(mesh.point_data[n])
            if word in low[n]:
                return (n, a) if a.ndim == 1 else (f"|{n}|", np.linalg.norm(a, axis=1))
    if not names:
        raise ValueError("the VTU holds no field")
    a = np.asarray(mesh.point_data[names[0]])
    return (names[0], a) if a.ndim == 1 else (f"|{names[0]}|", np.linalg.norm(a, axis=1))


def _render(vtu: str, png: str, roi_m: float) -> str:
    import pyvista as pv

    pv.OFF_SCREEN = True
    grid = pv.read(vtu)
    name, values = stress_scalar(grid)
    grid = grid.cell_data_to_point_data() if grid.cell_data else grid
    grid.point_data["shown"] = values
    # Keep the neighbourhood of the axis and of the most stressed point (the contact).
    z0 = float(grid.points[int(np.argmax(values)), 1])
    box = (0.0, roi_m, z0 - roi_m, z0 + roi_m, -1.0, 1.0)
    sub = grid.clip_box(box, invert=False, crinkle=False)
    if sub.n_cells == 0:
        sub = grid
    # (r, z) lives in the x-y plane: revolve about y, 270 degrees to open a window.
    revolved = sub.extract_surface(algorithm="dataset_surface").extrude_rotate(
        resolution=96, angle=270.0, rotation_axis=(0, 1, 0), capping=True)
    shown = np.asarray(revolved.point_data["shown"])
    positive = shown[shown > 0]
    log = positive.size > 0 and np.percentile(positive, 99) > 30 * np.percentile(positive, 5)
    clim = np.percentile(positive if log else shown, [5 if log else 1, 99.5])
    plotter = pv.Plotter(off_screen=True, window_size=(1200, 900))
    plotter.add_mesh(revolved, scalars="shown", cmap="viridis", log_scale=bool(log),
                     clim=[float(clim[0]), float(clim[1])], scalar_bar_args={"title": name})
    plotter.view_vector((1.0, 0.7, 1.4), viewup=(0.0, 1.0, 0.0))
    plotter.add_text(f"FEM {name}, (r, z) section revolved 270 deg about the axis; "
                     f"box r < {roi_m * 1e6:.3g} um", font_size=9)
    plotter.screenshot(png)
    plotter.close()
    scale = ", log colour scale" if log else ""
    return f"rendered {name} ({sub.n_cells} cells revolved{scale}) to {png}"


if __name__ == "__main__":  # python -m validation.plots render VTU PNG ROI_M
    if len(sys.argv) == 5 and sys.argv[1] == "render":
        import shutil

        if shutil.which("Xvfb"):
            import pyvista

            pyvista.start_xvfb()  # without Xvfb, VTK >= 9.4 falls back to EGL or OSMesa
        print(_render(sys.argv[2], sys.argv[3], float(sys.argv[4])))
    else:
        sys.exit("usage: python -m validation.plots render VTU PNG ROI_M")
