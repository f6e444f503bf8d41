"""Where each model puts the floor's contact: the elastic-pillar BEM's and fem-3d's contact
maps on one lattice, overlaid in fem-3d's sector (``pillar-xval floor-check --maps``).

The floor-check table compares the floor's contact area; when the two models disagree, the
picture says where: a hole around every pillar, the outer edge, a tongue between two pillars,
and how many of fem-3d's floor vertices span each.  Each map solves both models once more, at
the study's finest levels, since the cached cases keep the answers, not the fields.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..output.report import legend_outside, pyplot, save_figure

__all__ = ["floor_map", "map_name"]


def map_name(label: str) -> str:
    """The PNG's file name for a scene label: letters, digits, dots and dashes only."""
    return "floor_map_" + re.sub(r"[^A-Za-z0-9.]+", "-", label).strip("-") + ".png"


def floor_map(point, bem_cells: int, mesh_size: float, path: Path) -> Path:
    """Solve ``point`` (a :class:`.floor_check.FloorPoint` on a lattice) with the elastic
    BEM at ``bem_cells`` per diameter and fem-3d at ``mesh_size``, and write the overlay of
    their contacts in fem-3d's sector (pi/6) to ``path`` (PNG, atomically)."""
    from pillar_xval.scenes.lattice import pillars_within

    from ..registry import run_model

    scene = point.scene()
    bem = run_model("bem-fft", scene, cells_per_diameter=int(bem_cells), pillars="elastic")
    fem = run_model("fem-3d", scene, mesh_size=float(mesh_size))
    um = 1e6
    f = bem.fields
    x, y = np.asarray(f["collocation_x_m"]) * um, np.asarray(f["collocation_y_m"]) * um
    on_floor, pressed = np.asarray(f["floor"], bool), np.asarray(f["pressure_Pa"]) > 0
    theta = np.arctan2(y, x)
    sector = (theta >= -1e-9) & (theta <= math.pi / 6 + 1e-9)
    g = fem.fields
    vx, vy = np.asarray(g["vertex_x_m"]) * um, np.asarray(g["vertex_y_m"]) * um
    v_floor, v_pressed = np.asarray(g["floor_vertex"], bool), np.asarray(
        g["contact_pressure_Pa"]) > 0
    reach = max(float(np.max(np.hypot(x[pressed], y[pressed]), initial=0.0)),
                float(np.max(np.hypot(vx[v_pressed], vy[v_pressed]), initial=0.0)))
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8.0, 5.0))
    ax.scatter(x[sector & on_floor & pressed], y[sector & on_floor & pressed], s=1.5,
               c="tab:blue", label=f"bem-fft floor contact (N = {bem_cells})")
    ax.scatter(x[sector & ~on_floor & pressed], y[sector & ~on_floor & pressed], s=1.5,
               c="lightsteelblue", label="bem-fft top contact")
    ax.scatter(vx[v_floor & v_pressed], vy[v_floor & v_pressed], s=14, facecolors="none",
               edgecolors="tab:red", label=f"fem-3d floor vertex in contact ({mesh_size:g})")
    ax.scatter(vx[v_floor & ~v_pressed], vy[v_floor & ~v_pressed], s=3, c="0.65",
               label="fem-3d floor vertex free")
    radius = 0.5 * scene.pillars.diameter_m * um
    for _, _, cx, cy in pillars_within((reach + radius) / um, scene.pillars.pitch_m):
        ax.add_patch(plt.Circle((cx * um, cy * um), radius, fill=False, lw=0.8))
    top = reach * 1.08 + radius
    ax.set_xlim(-radius, top)
    ax.set_ylim(-radius, top * math.sin(math.pi / 6) + radius)
    ax.set_aspect("equal")
    ax.set_xlabel("x (um)")
    ax.set_ylabel("y (um)")
    ax.set_title(f"{point.label}: floor area bem-fft {bem.floor_contact_area_m2 * 1e12:.0f}, "
                 f"fem-3d {fem.floor_contact_area_m2 * 1e12:.0f} um^2", fontsize=9)
    legend_outside(ax)
    return save_figure(fig, path)
