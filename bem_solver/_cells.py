"""Square cells on one pillar top, in the pillar's own frame (x along its radial direction).

Two variants:

``centre``  the paper's cells: side b = d/P, kept when the cell centre lies on the disk.  The
            total area jumps with P (+7.0, -3.9, +8.5, +2.1 % for P = 5, 7, 9, 11), which spoils
            convergence studies (PHYSICS.md, "Boundary-element model of [P]").
``covered`` every cell that overlaps the disk, carrying its exact covered area phi b^2: its
            pressure acts on an equivalent square of that area centred on the centroid of the
            covered part, where it is also collocated.  The total area is exact for every P.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ._disk import disk_rectangle_area, disk_rectangle_centroid

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

    area = disk_rectangle_area(gx - b / 2, gx + b / 2, gy - b / 2, gy + b / 2, 0.5)
    keep = area > 1e-12 * b * b
    gx, gy, area = gx[keep], gy[keep], area[keep]
    full = area >= b * b * (1.0 - 1e-14)
    cx, cy = disk_rectangle_centroid(gx - b / 2, gx + b / 2, gy - b / 2, gy + b / 2, 0.5)
    # Whole cells: exactly their centre and area (no rounding from the closed forms).
    cx, cy, area = np.where(full, gx, cx), np.where(full, gy, cy), np.where(full, b * b, area)
    return CellPattern(cx, cy, np.sqrt(area), area, gx, gy, b)
