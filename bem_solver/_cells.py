"""Square cells on one pillar top, in the pillar's own frame (x along its radial direction).

Two variants:

``centre``  the paper's cells: side b = d/P, kept when the cell centre lies on the disk.  The
            total area jumps with P (+7.0, -3.9, +8.5, +2.1 % for P = 5, 7, 9, 11), which spoils
            convergence studies (PHYSICS.md).
``covered`` every cell that overlaps the disk, carrying its exact covered area phi b^2: its
            pressure acts on an equivalent square of that area centred on the centroid of the
            covered part, where it is also collocated.  The total area is exact for every P.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

VARIANTS = ("centre", "covered")


@dataclass(frozen=True)
class CellPattern:
    """Cells of a disk of diameter 1 cut by a P x P grid, in units of the diameter."""

    x: np.ndarray        # collocation point (centroid of the loaded area)
    y: np.ndarray
    side: np.ndarray     # side of the (equivalent) loaded square
    area: np.ndarray     # loaded area = side^2
    grid_x: np.ndarray   # centre of the grid cell the element came from
    grid_y: np.ndarray
    cell_side: float     # grid spacing 1/P

    def scaled(self, diameter: float) -> dict:
        d = diameter
        return {"x": self.x * d, "y": self.y * d, "side": self.side * d,
                "area": self.area * d * d}


def _segment_integral(x0, x1, rho):
    """Integral of sqrt(rho^2 - x^2) dx from x0 to x1 (|x| <= rho)."""
    def prim(x):
        x = min(max(x, -rho), rho)
        return 0.5 * (x * math.sqrt(max(rho * rho - x * x, 0.0)) + rho * rho * math.asin(x / rho))
    return prim(x1) - prim(x0)


def disk_rectangle_area(x0, x1, y0, y1, rho=0.5):
    """Exact area of [x0, x1] x [y0, y1] inside the disk of radius ``rho`` centred at 0.

    Integrates L(x) = [min(y1, s) - max(y0, -s)]^+ with s = sqrt(rho^2 - x^2) piecewise: the
    breakpoints are where s crosses |y0| or |y1|, and on each piece every term is a constant
    or +-s, integrated in closed form.
    """
    lo, hi = max(x0, -rho), min(x1, rho)
    if hi <= lo:
        return 0.0
    cuts = {lo, hi}
    if lo < 0.0 < hi:  # s is tangent to y = +-rho at x = 0: keep that point off piece interiors
        cuts.add(0.0)
    for yy in (y0, y1):
        if abs(yy) < rho:
            xc = math.sqrt(rho * rho - yy * yy)
            cuts.update(c for c in (-xc, xc) if lo < c < hi)
    cuts = sorted(cuts)
    area = 0.0
    for a, b in zip(cuts[:-1], cuts[1:]):
        xm = 0.5 * (a + b)
        s = math.sqrt(rho * rho - xm * xm)
        top_is_s = s < y1
        bottom_is_s = -s > y0
        if (y1 if not top_is_s else s) <= (y0 if not bottom_is_s else -s):
            continue
        seg = _segment_integral(a, b, rho)
        width = b - a
        top = seg if top_is_s else y1 * width
        bottom = -seg if bottom_is_s else y0 * width
        area += top - bottom
    return area


@lru_cache(maxsize=64)
def cell_pattern(per_diameter: int, variant: str = "covered") -> CellPattern:
    """Cells of a unit-diameter disk with ``per_diameter`` cells across it."""
    if variant not in VARIANTS:
        raise ValueError(f"cells = {variant!r}: allowed values are {VARIANTS}")
    P = int(per_diameter)
    if P < 1:
        raise ValueError(f"elements_per_diameter = {per_diameter}: must be >= 1")
    b = 1.0 / P
    centres = b * (np.arange(P) - (P - 1) / 2.0)
    gx, gy = np.meshgrid(centres, centres, indexing="ij")
    gx, gy = gx.ravel(), gy.ravel()
    if variant == "centre":
        keep = np.hypot(gx, gy) <= 0.5 * (1.0 + 1e-12)
        gx, gy = gx[keep], gy[keep]
        side = np.full(gx.shape, b)
        return CellPattern(gx, gy, side, side**2, gx, gy, b)

    areas, cxs, cys, gxs, gys = [], [], [], [], []
    sub = (np.arange(64) + 0.5) / 64.0 - 0.5  # sub-samples for the centroid only
    for x, y in zip(gx, gy):
        area = disk_rectangle_area(x - b / 2, x + b / 2, y - b / 2, y + b / 2)
        if area <= 1e-12 * b * b:
            continue
        if area >= b * b * (1.0 - 1e-14):
            cx, cy, area = x, y, b * b
        else:
            sx, sy = np.meshgrid(x + b * sub, y + b * sub, indexing="ij")
            inside = sx**2 + sy**2 <= 0.25
            if inside.any():
                cx, cy = float(sx[inside].mean()), float(sy[inside].mean())
            else:  # a sliver thinner than the sub-sampling: its point nearest the centre
                cx = min(max(0.0, x - b / 2), x + b / 2)
                cy = min(max(0.0, y - b / 2), y + b / 2)
        areas.append(area)
        cxs.append(cx)
        cys.append(cy)
        gxs.append(x)
        gys.append(y)
    area = np.array(areas)
    return CellPattern(np.array(cxs), np.array(cys), np.sqrt(area), area,
                       np.array(gxs), np.array(gys), b)
