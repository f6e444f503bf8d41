"""Files written by ``pillar-xval solve --out DIR``: result.json, elements.csv, pillars.csv and
pressure.png (the paper's Fig. 3 layout: pressure map of the primitive cell, radial profile)."""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

import numpy as np

from scenes import ContactResult, write_atomic


def _csv_text(header: list[str], rows) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(header)
    for row in rows:
        writer.writerow([f"{v:.10g}" if isinstance(v, float) else v for v in row])
    return buf.getvalue()


def figure_png(fig, dpi: int = 120) -> bytes:
    """Lay out ``fig``, close it and return its PNG bytes (write them with write_atomic)."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    plt.close(fig)
    return buf.getvalue()


def save_figure(fig, path, dpi: int = 120) -> Path:
    """Write ``fig`` as a PNG atomically and close it."""
    return write_atomic(path, figure_png(fig, dpi))


def write_solve_report(result: ContactResult, out: Path) -> None:
    out = Path(out)
    write_atomic(out / "result.json", result.to_json() + "\n")
    f = result.fields
    if "x_m" in f:
        cols = [c for c in ("x_m", "y_m", "pillar_orbit", "weight", "area_m2", "pressure_Pa",
                            "force_N", "gap_m") if c in f]
        rows = zip(*[np.asarray(f[c]).tolist() for c in cols])
        write_atomic(out / "elements.csv", _csv_text(cols, rows))
    write_atomic(out / "pillars.csv", _csv_text(
        ["n", "m", "x_m", "y_m", "force_N"],
        ([p.n, p.m, p.x_m, p.y_m, p.force_N] for p in result.pillar_forces)))
    write_atomic(out / "pressure.png", pressure_figure(result))


def pressure_figure(result: ContactResult) -> bytes:
    """PNG bytes: primitive-cell pressure map (left) and sigma(r) with the limits (right)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import PolyCollection

    from scenes import Scene, analytic

    scene = Scene.from_dict(result.scene)
    f = result.fields
    fig, (ax_map, ax_prof) = plt.subplots(1, 2, figsize=(12, 5))
    um, kpa = 1e6, 1e-3
    if "x_m" in f:
        x, y, p = f["x_m"], f["y_m"], f["pressure_Pa"]
        side, ang = f["side_m"], f["angle_rad"]
        corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * 0.5
        polys = []
        for xi, yi, si, ai in zip(x, y, side, ang):
            c, s = math.cos(ai), math.sin(ai)
            local = corners * si
            polys.append(np.column_stack([xi + c * local[:, 0] - s * local[:, 1],
                                          yi + s * local[:, 0] + c * local[:, 1]]) * um)
        coll = PolyCollection(polys, array=p * kpa, cmap="viridis", edgecolors="none")
        ax_map.add_collection(coll)
        fig.colorbar(coll, ax=ax_map, label="pressure (kPa)")
        rmax = max(np.hypot(x, y).max() * um * 1.05, 1.0)
        for ang_line in (0.0, math.pi / 6):
            ax_map.plot([0, rmax * math.cos(ang_line)], [0, rmax * math.sin(ang_line)],
                        "r-.", lw=0.8)
        if result.contact_radius_m > 0:
            t = np.linspace(0, math.pi / 2, 100)
            a = result.contact_radius_m * um
            ax_map.plot(a * np.cos(t), a * np.sin(t), "r:", lw=1)
        ax_map.set_xlim(-0.1 * rmax, rmax)
        ax_map.set_ylim(-0.1 * rmax, 0.75 * rmax)
        ax_map.set_aspect("equal")
        ax_map.set_xlabel("x (um)")
        ax_map.set_ylabel("y (um)")
        ax_map.set_title("primitive cell (dash-dot): unknown elements")
        r = np.hypot(x, y)
        ax_prof.plot(r * um, p * kpa, ".", ms=3, color="0.3", label=f"{result.model} elements")

    prof = result.pillar_top_profile
    if prof.get("r_m") and "x_m" not in f:  # models without an element map: their profile
        ax_prof.plot(np.asarray(prof["r_m"]) * um, np.asarray(prof["pressure_Pa"]) * kpa,
                     "-", color="0.3", label=f"{result.model} profile")
        ax_map.text(0.5, 0.5, "no element map for this model", ha="center",
                    transform=ax_map.transAxes)
    hz = analytic.hertz(scene)
    r_line = np.linspace(0, max(hz.contact_radius, result.contact_radius_m) * 1.05, 400)
    ax_prof.plot(r_line * um, hz.pressure(r_line) * kpa, "b-", label="Hertz")
    if scene.pillars is not None:
        punch = analytic.spring_model(scene)
        d = scene.pillars.diameter_m
        rp = np.linspace(0, 0.999 * d / 2, 200)
        ax_prof.plot(rp * um, punch.pressure(rp) * kpa, "g-", label="soft flat punch (spring model)")
    if result.contact_radius_m > 0:
        a = result.contact_radius_m
        s0 = result.centre_pressure_Pa
        ax_prof.plot(r_line * um, s0 * np.sqrt(np.clip(1 - (r_line / a) ** 2, 0, None)) * kpa,
                     "r--", label="Hertz-like (sigma_0, a from the model)")
    top = max(result.centre_pressure_Pa, hz.centre_pressure) * 6 * kpa
    ax_prof.set_ylim(0, top)
    ax_prof.set_xlabel("r (um)")
    ax_prof.set_ylabel("pressure (kPa)")
    ax_prof.legend(fontsize=8)
    name = result.scene.get("name", "")
    ax_prof.set_title(f"{name}: F = {result.total_force_N * 1e6:.3g} uN, "
                      f"sigma_0 = {result.centre_pressure_Pa * kpa:.3g} kPa")
    return figure_png(fig)
