"""Off-screen pyvista render of a 3D sector solution unfolded to the whole disk.

The VTU of :func:`fem_reference.solid3d.solve` holds one sector 0 <= theta <= alpha; its images
under the mirror group of the sector (rotations by 2 j alpha and the same after the
reflection y -> -y: 12 images for the pi/6 wedge) cover the disk.  The pillars and the
substrate are shown coloured by the von Mises stress (kPa); the lens, which would hide
them, is shown only over the far half of the disk and lifted by a pillar height, so the
stressed pillar tops and the lens bottom are both in view.  A ruler gives the length scale.

Runs in a child process (``python -m validation.output.render3d VTU PNG [STAMP]``), like the
axisymmetric
render of :mod:`validation.output.render`: VTK's off-screen context stays out of the caller.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from .render import colour_scale, latin1

BODY_LENS, BODY_PILLAR, BODY_SUBSTRATE = 0, 1, 2
# The camera's zoom beyond VTK's fit of the bounding sphere, which left a third of the
# picture empty around the disk.
ZOOM = 1.45
# How far the view moves right, in radii of the region of interest: the disk clears the
# colour bar.
PAN = 0.12


def render_sector(vtu_path, png_path, *, stamp: str = "",
                  timeout_s: float = 300.0) -> tuple[bool, str]:
    """Render ``vtu_path`` (with its JSON sidecar) to ``png_path`` in a child process;
    returns (ok, message).  ``stamp`` (e.g. "NOT CONVERGED") is written in red on it."""
    from .render import render_in_child

    return render_in_child("validation.output.render3d", [str(vtu_path), str(png_path), stamp],
                           png_path, timeout_s)


def region_of_interest(meta: dict) -> tuple[float, float, float]:
    """(radius, z_min, z_max) in m around the contact, from the sidecar's scene: the reach
    of the undeformed lens sqrt(2 R zeta) plus a pillar diameter (flat: twice the Hertz
    radius)."""
    s = meta["scene"]
    # A force-controlled scene's indentation is the solved one, beside it in the sidecar.
    R, zeta = s["lens"]["radius_m"], s["load"].get("indentation_m", meta.get("indentation_m"))
    if s.get("pillars"):
        d, h = s["pillars"]["diameter_m"], s["pillars"]["height_m"]
        roi = math.sqrt(2.0 * R * zeta) + d
        return roi, -h - 0.25 * roi, 0.25 * roi
    a = math.sqrt(R * zeta)
    return 2.0 * a, -a, a


def scale_bar(roi: float, z0: float, z1: float):
    """(length, start, end, where its label goes) of the scale bar, in m: a power of ten no
    longer than the region's radius, along x in front of the disk at its bottom, and the
    label a fifth of the region's height below the bar's middle, so that text and line never
    overlap."""
    ruler = 10 ** math.floor(math.log10(roi))
    y = -1.1 * roi
    start, end = (-roi, y, z0), (-roi + ruler, y, z0)
    label_at = (-roi + 0.5 * ruler, y, z0 - 0.2 * (z1 - z0))
    return ruler, start, end, label_at


def _pan_right(camera, distance: float) -> None:
    """Move the camera (and its focal point) ``distance`` to its right: the scene moves left,
    clear of the colour bar on the right."""
    position, focus = np.asarray(camera.position), np.asarray(camera.focal_point)
    right = np.cross(focus - position, np.asarray(camera.up))
    shift = distance * right / np.linalg.norm(right)
    camera.position, camera.focal_point = tuple(position + shift), tuple(focus + shift)


def render_title(meta: dict, images: int, alpha: float, lift_m: float, log: bool) -> str:
    """The render's title, as VTK can draw it (:func:`.render.latin1`): the scene (its Phi
    spelled out), the sector's images, the lens's lift in µm (as the ruler says) and the
    colour scale."""
    from .report import scene_label

    return latin1(f"fem-3d, {scene_label(meta['scene'])}: {images} images of the "
                  f"{math.degrees(alpha):.0f}° sector; lens (far half) lifted by "
                  f"{lift_m * 1e6:.3g} µm" + ("; log colour scale" if log else ""))


def unfold(mesh, alpha: float) -> list:
    """The images of ``mesh`` under the mirror group of the sector [0, alpha]."""
    k = int(round(math.pi / alpha))
    images = []
    for flip in (False, True):
        base = mesh.reflect((0.0, 1.0, 0.0), point=(0.0, 0.0, 0.0)) if flip else mesh
        for j in range(k):
            images.append(base.rotate_z(math.degrees(2.0 * j * alpha), point=(0, 0, 0)))
    return images


def _render(vtu: str, png: str, stamp: str = "") -> str:
    import pyvista as pv

    pv.OFF_SCREEN = True
    meta = json.loads(Path(vtu).with_suffix(".json").read_text())
    alpha = float(meta["discretisation"].get("sector_angle_rad", math.pi / 6.0))
    roi, z0, z1 = region_of_interest(meta)
    grid = pv.read(vtu)
    grid.cell_data["vm_kPa"] = np.asarray(grid.cell_data["von_mises_Pa"]) / 1e3
    body = np.asarray(grid.cell_data["body"])
    pieces = {}
    for name, ids in (("lower", np.nonzero(body != BODY_LENS)[0]),
                      ("lens", np.nonzero(body == BODY_LENS)[0])):
        if len(ids) == 0:
            continue
        part = grid.extract_cells(ids).clip_box((-roi, roi, -roi, roi, z0, z1), invert=False)
        if part.n_cells:
            pieces[name] = part.cell_data_to_point_data().extract_surface(
                algorithm="dataset_surface")
    if not pieces:
        raise ValueError("nothing to render in the region of interest")
    log, clim = colour_scale(np.concatenate([p.point_data["vm_kPa"]
                                             for p in pieces.values()]))
    h = meta["scene"]["pillars"]["height_m"] if meta["scene"].get("pillars") else 0.25 * roi
    plotter = pv.Plotter(off_screen=True, window_size=(1400, 1000))
    bar = {"title": "von Mises\nstress (kPa)", "title_font_size": 18, "label_font_size": 14,
           "fmt": "%.3g", "vertical": True, "position_x": 0.9, "position_y": 0.15,
           "width": 0.05, "height": 0.6}
    shown = 0
    for name, surf in pieces.items():
        for img in unfold(surf, alpha):
            if name == "lens":
                # only the far half of the disk (y > 0), lifted: the pillars stay in view
                img = img.clip_box((-roi, roi, 0.0, roi, -1.0, 1.0), invert=False)
                if img.n_points == 0:
                    continue
                img = img.translate((0.0, 0.0, 2.0 * h))
            plotter.add_mesh(img, scalars="vm_kPa", cmap="viridis", clim=list(clim),
                             log_scale=log, scalar_bar_args=bar, show_scalar_bar=shown == 0)
            shown += 1
    ruler, start, end, label_at = scale_bar(roi, z0, z1)
    # The ruler carries no title (VTK centres it on the ruler itself, where it overlapped the
    # line); its length is a label placed below it, clear of the line.
    plotter.add_ruler(start, end, title="", show_labels=False, font_size_factor=0.8)
    plotter.add_point_labels([label_at], [f"{ruler * 1e6:.3g} µm"], show_points=False,
                             shape=None, font_size=16, text_color="black",
                             justification_horizontal="center", always_visible=True)
    plotter.view_vector((0.35, -1.0, 0.75), viewup=(0.0, 0.0, 1.0))
    plotter.camera.zoom(ZOOM)
    _pan_right(plotter.camera, PAN * roi)
    plotter.add_text(render_title(meta, 2 * int(round(math.pi / alpha)), alpha, 2 * h, log),
                     font_size=10)
    if stamp:
        plotter.add_text(stamp, position="upper_right", font_size=20, color="red")
    plotter.screenshot(png)
    plotter.close()
    return f"rendered von Mises stress (kPa), {shown} surfaces, to {png}"


if __name__ == "__main__":  # python -m validation.output.render3d VTU PNG [STAMP]
    if len(sys.argv) in (3, 4):
        import shutil

        if shutil.which("Xvfb"):
            import pyvista

            pyvista.start_xvfb()
        print(_render(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) == 4 else ""))
    else:
        sys.exit("usage: python -m validation.output.render3d VTU PNG [STAMP]")
