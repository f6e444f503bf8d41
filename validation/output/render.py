"""Off-screen pyvista render of the axisymmetric FEM stress field, revolved about the axis.

The render runs in a child process (``python -m validation.output.render VTU PNG ROI_M [STAMP]``): a
headless machine without an OpenGL context can abort inside VTK, and that must cost the report
one picture, never the whole run.  The picture is drawn in micrometres with a length scale
(a ruler) and the von Mises stress in kPa on its colour bar.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

UM, KPA = 1e6, 1e-3
VIEW = (1.0, 0.7, 1.4)  # from the front right, above the contact plane


def render_stress(vtu_path: Path, png_path: Path, roi_m: float, *, stamp: str = "",
                  timeout_s: float = 180.0) -> tuple[bool, str]:
    """Render the FEM stress field revolved about the symmetry axis, off screen.

    Runs in a child process; returns (success, message).  ``roi_m`` is the half-size (m) of
    the region around the axis and the contact that is shown; ``stamp`` (e.g. "NOT
    CONVERGED") is written in red on the picture.
    """
    return render_in_child("validation.output.render", [str(vtu_path), str(png_path),
                                                repr(float(roi_m)), stamp], png_path, timeout_s)


def render_in_child(module: str, argv: list[str], png_path, timeout_s: float) -> tuple[bool, str]:
    """``python -m module *argv`` in a child process that writes ``png_path``: (success, its
    last line or why it failed).  A VTK abort costs the picture, never the caller."""
    cmd = [sys.executable, "-m", module, *argv]
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


def readable(name: str) -> str:
    """A colour-bar title for a VTU array name: ``von_mises_Pa`` -> ``von Mises stress``."""
    low = name.lower()
    if "mises" in low:
        return "von Mises stress"
    if "pressure" in low:
        return "pressure"
    return name.replace("_Pa", "").replace("_", " ")


# VTK's text fonts carry Latin-1 only: other letters come out as nothing ("( = 0.2)" for
# "(Φ = 0.2)"), so render texts spell them.
_SPELLED = str.maketrans({"Φ": "Phi", "ζ": "zeta", "ν": "nu", "σ": "sigma", "θ": "theta",
                          "γ": "gamma", "λ": "lambda", "π": "pi"})


def latin1(text: str) -> str:
    """``text`` as VTK can draw it: Greek letters spelled out, anything else outside
    Latin-1 (which holds µ and °) replaced by '?'."""
    return text.translate(_SPELLED).encode("latin-1", "replace").decode("latin-1")


def colour_scale(values) -> tuple[bool, tuple[float, float]]:
    """(log, colour limits) for stresses ``values`` (kPa): a log scale where the positive
    values span more than 30x between their 5th and 99th percentiles (a contact's edge
    peaks over the bulk), limits from the 5th (log) or 1st percentile to the 99.5th.  Both
    renders use it, so their colour scales read alike."""
    values = np.asarray(values, dtype=float)
    positive = values[values > 0]
    log = bool(positive.size > 0
               and np.percentile(positive, 99) > 30 * np.percentile(positive, 5))
    data = positive if log else values
    if data.size == 0:
        return False, (0.0, 1.0)
    lo, hi = np.percentile(data, [5 if log else 1, 99.5])
    return log, (float(lo), float(hi))


def nice_length(span: float) -> float:
    """A round length (1, 2 or 5 times a power of ten) of about a third of ``span``."""
    target = span / 3.0
    power = 10.0 ** np.floor(np.log10(target))
    return float(max(m for m in (1.0, 2.0, 5.0) if m * power <= target) * power)


def _render(vtu: str, png: str, roi_m: float, stamp: str = "") -> str:
    import pyvista as pv

    pv.OFF_SCREEN = True
    grid = pv.read(vtu)
    name, values = stress_scalar(grid)
    grid = grid.cell_data_to_point_data() if grid.cell_data else grid
    grid.points = grid.points * UM  # draw in micrometres: the ruler reads in um
    grid.point_data["shown"] = values * KPA
    roi = roi_m * UM
    # Keep the neighbourhood of the axis and of the most stressed point (the contact).
    z0 = float(grid.points[int(np.argmax(values)), 1])
    box = (0.0, roi, z0 - roi, z0 + roi, -1.0, 1.0)
    sub = grid.clip_box(box, invert=False, crinkle=False)
    if sub.n_cells == 0:
        sub = grid
    # (r, z) lives in the x-y plane: revolve about y, 270 degrees to open a window.
    revolved = sub.extract_surface(algorithm="dataset_surface").extrude_rotate(
        resolution=96, angle=270.0, rotation_axis=(0, 1, 0), capping=True)
    log, clim = colour_scale(revolved.point_data["shown"])
    title = f"{readable(name)} (kPa)"
    plotter = pv.Plotter(off_screen=True, window_size=(1200, 900))
    plotter.add_mesh(revolved, scalars="shown", cmap="viridis", log_scale=bool(log),
                     clim=[float(clim[0]), float(clim[1])],
                     scalar_bar_args={"title": title, "fmt": "%.3g", "vertical": True,
                                      "position_x": 0.86, "position_y": 0.2, "height": 0.6,
                                      "width": 0.06})
    # A length scale: a vertical ruler of a round length left of the body, in the plane
    # through the axis square to the view (vertical lines keep their length in this view,
    # whose up direction is the axis).
    x0, x1, y0, _, _, _ = revolved.bounds
    length = nice_length(x1 - x0)
    side = 0.62 * (x1 - x0) * np.array([-1.4, 0.0, 1.0]) / np.hypot(1.4, 1.0)
    plotter.add_ruler((side[0], y0, side[2]), (side[0], y0 + length, side[2]),
                      title=f"{length:g} µm", show_labels=False, font_size_factor=1.0)
    plotter.view_vector(VIEW, viewup=(0.0, 1.0, 0.0))
    plotter.add_text(latin1(f"FEM {readable(name)}, (r, z) section revolved 270° about the "
                            f"axis; r < {roi:.3g} µm" + (", log colour scale" if log else "")),
                     font_size=9)
    if stamp:
        plotter.add_text(stamp, position="upper_right", font_size=20, color="red")
    plotter.screenshot(png)
    plotter.close()
    scale = ", log colour scale" if log else ""
    return f"rendered {name} ({sub.n_cells} cells revolved{scale}) to {png}"


if __name__ == "__main__":  # python -m validation.output.render VTU PNG ROI_M [STAMP]
    if len(sys.argv) in (4, 5):
        import shutil

        if shutil.which("Xvfb"):
            import pyvista

            pyvista.start_xvfb()  # without Xvfb, VTK >= 9.4 falls back to EGL or OSMesa
        print(_render(sys.argv[1], sys.argv[2], float(sys.argv[3]),
                      sys.argv[4] if len(sys.argv) == 5 else ""))
    else:
        sys.exit("usage: python -m validation.output.render VTU PNG ROI_M [STAMP]")
