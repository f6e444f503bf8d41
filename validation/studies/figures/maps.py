"""Pressure maps of the dense BEM as images on its own element grid (the paper's Fig. 3).

The dense model solves for one element per symmetry orbit; its result keeps their pressures.
:class:`ElementMap` rebuilds the discretisation from the result (same scene, level and
candidate radius, so the same elements in the same order), finds the grid cell of every image
element (each element's collocation point lies in its own cell, so the cell is the image of
the representative's cell that lies nearest to it), and looks up any point: inside an
element's square cell and on its pillar top, that element's pressure; on a pillar top outside
the candidate region, zero (no contact there); elsewhere, no value.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from bem_solver import discretise
from pillar_xval.scenes import Scene
from pillar_xval.scenes.lattice import d6_images, pillars_within

__all__ = ["ElementMap"]

# Nearest cell centres tried per point: a cell's square may stick out of its pillar top into
# a neighbour's (close packing), where the nearest centre can belong to the other pillar.
_NEIGHBOURS = 4


def _fine_level(result) -> int:
    disc = result.discretisation
    return int(disc.get("fine_elements_per_diameter", disc["elements_per_diameter"]))


class ElementMap:
    """The element pressures of a dense-BEM result on its pillar tops.

    Parameters
    ----------
    result : ContactResult
        A ``bem`` or ``bem-richardson`` result (its fine level) on a scene with pillars.
    pressure : array_like
        The representative elements' pressures (Pa): ``fields["pressure_Pa"]`` of the result.
    """

    def __init__(self, result, pressure):
        scene = Scene.from_dict(result.scene)
        if scene.pillars is None:
            raise ValueError("ElementMap: the scene has no pillars")
        self.scene = scene
        disc = discretise(scene, _fine_level(result), result.discretisation.get("cells", "covered"),
                          result.diagnostics["candidate_radius_m"])
        self.pressure = np.asarray(pressure, float)
        if len(self.pressure) != disc.n_unknowns:
            raise ValueError(f"ElementMap: {len(self.pressure)} pressures for "
                             f"{disc.n_unknowns} elements: not this result's discretisation")
        self.disc = disc
        self.b = disc.cell_side
        self.radius = scene.pillars.diameter_m / 2.0
        first = disc.rep_start[:-1]
        centre = disc.pillar_xy[disc.img_pillar[first]]
        c, s = np.cos(disc.rep_angle), np.sin(disc.rep_angle)
        lx, ly = disc.rep_local[:, 0], disc.rep_local[:, 1]
        gx = centre[:, 0] + c * lx - s * ly
        gy = centre[:, 1] + s * lx + c * ly
        cand_x, cand_y, _, _ = d6_images(gx, gy)
        cx, cy = cand_x[:, disc.img_rep], cand_y[:, disc.img_rep]
        pick = np.argmin(np.hypot(cx - disc.img_x, cy - disc.img_y), axis=0)
        cols = np.arange(disc.n_elements)
        self.cell = np.column_stack([cx[pick, cols], cy[pick, cols]])
        self._tree = cKDTree(self.cell)

    def values(self, x, y) -> np.ndarray:
        """Pressure (Pa) at points (x, y) (m): an element's pressure on its cell, 0 on a pillar
        top without an element, NaN off the pillar tops."""
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        pts = np.column_stack([x.ravel(), y.ravel()])
        out = np.full(len(pts), np.nan)
        reach = float(np.hypot(pts[:, 0], pts[:, 1]).max()) + 2.0 * self.radius
        lattice = pillars_within(reach, self.scene.pillars.pitch_m)[:, 2:4]
        near, _ = _nearest(lattice, pts)
        on_top = np.hypot(*(pts - lattice[near]).T) <= self.radius
        out[on_top] = 0.0
        d = self.disc
        _, idx = self._tree.query(pts, k=min(_NEIGHBOURS, d.n_elements))
        idx = np.asarray(idx).reshape(len(pts), -1)
        found = np.zeros(len(pts), bool)
        for k in range(idx.shape[1]):
            e = idx[:, k]
            dx, dy = pts[:, 0] - self.cell[e, 0], pts[:, 1] - self.cell[e, 1]
            c, s = np.cos(d.img_angle[e]), np.sin(d.img_angle[e])
            u, v = c * dx + s * dy, -s * dx + c * dy
            pillar = d.pillar_xy[d.img_pillar[e]]
            inside = ((np.abs(u) <= 0.5 * self.b * (1 + 1e-9))
                      & (np.abs(v) <= 0.5 * self.b * (1 + 1e-9))
                      & (np.hypot(pts[:, 0] - pillar[:, 0], pts[:, 1] - pillar[:, 1])
                         <= self.radius * (1 + 1e-9)))
            take = inside & ~found
            out[take] = self.pressure[d.img_rep[e[take]]]
            found |= take
        return out.reshape(x.shape)

    def image(self, extent: tuple[float, float, float, float], pixels: int = 500):
        """(array, extent) of the pressure (Pa) on ``pixels`` x ``pixels`` points covering
        ``extent`` = (x0, x1, y0, y1) (m); rows run along y, as imshow(origin="lower") wants."""
        x0, x1, y0, y1 = extent
        ny = max(2, int(round(pixels * (y1 - y0) / (x1 - x0))))
        xs = x0 + (np.arange(pixels) + 0.5) * (x1 - x0) / pixels
        ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        X, Y = np.meshgrid(xs, ys)
        return self.values(X, Y), extent

    def along_x(self, r_max: float, samples: int = 4000) -> tuple[np.ndarray, np.ndarray]:
        """The pressure along theta = 0, r in [0, r_max] (m): through the centre pillar and
        the pillars (n, 0) of the lattice row on the x axis."""
        r = np.linspace(0.0, r_max, samples)
        return r, self.values(r, np.zeros_like(r))


def _nearest(centres: np.ndarray, pts: np.ndarray):
    tree = cKDTree(centres)
    dist, idx = tree.query(pts)
    return idx, dist


def quadrant_extent(result, margin: float = 1.12) -> tuple[float, float, float, float]:
    """The first quadrant out to ``margin`` times the contact radius (m), at least one pitch."""
    scene = Scene.from_dict(result.scene)
    reach = max(result.contact_radius_m * margin, scene.pillars.pitch_m + scene.pillars.diameter_m)
    return (0.0, reach, 0.0, reach * math.sin(math.pi / 3))
