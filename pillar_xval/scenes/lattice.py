"""Hexagonal lattice of pillars and its D6 symmetry about the centre pillar.

Pillar (n, m) sits at x = (2n - m) e / 2, y = sqrt(3) m e / 2 (supplementary material,
section 1).  The primitive wedge is 0 <= theta <= pi/6; it holds the pillars with
0 <= m <= n / 2, and the 12 elements of D6 map it onto the whole plane.  Ring n holds 6n
pillars.  Angles use atan2 (the paper's arctan form loses the quadrant for x < 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

SQRT3 = math.sqrt(3.0)


def pillar_position(n, m, pitch: float):
    """Centre (x, y) in m of pillar (n, m); works on arrays."""
    n = np.asarray(n, dtype=float)
    m = np.asarray(m, dtype=float)
    return (2.0 * n - m) * pitch / 2.0, SQRT3 * m * pitch / 2.0


def lattice_indices(x, y, pitch: float):
    """Inverse of :func:`pillar_position`: integer (n, m) of the pillar at (x, y)."""
    m = np.rint(2.0 * np.asarray(y) / (SQRT3 * pitch)).astype(int)
    n = np.rint((2.0 * np.asarray(x) / pitch + m) / 2.0).astype(int)
    return n, m


def ring(n: int, m: int) -> int:
    """Hexagonal ring number (lattice distance from the centre pillar) of pillar (n, m)."""
    # In axial coordinates (q, s) = (n - m, m) the hex distance is max(|q|, |s|, |q + s|).
    q, s = n - m, m
    return max(abs(q), abs(s), abs(q + s))


def pillars_within(radius: float, pitch: float) -> np.ndarray:
    """All pillars with centre distance <= radius, as rows (n, m, x, y), sorted by distance."""
    if radius < 0:
        raise ValueError(f"radius = {radius:g}: must be >= 0")
    kmax = int(math.ceil(2.0 * radius / (SQRT3 * pitch))) + 2
    m = np.arange(-kmax, kmax + 1)
    n = np.arange(-2 * kmax, 2 * kmax + 1)
    nn, mm = np.meshgrid(n, m, indexing="ij")
    x, y = pillar_position(nn, mm, pitch)
    r = np.hypot(x, y)
    keep = r <= radius * (1.0 + 1e-12)
    order = np.lexsort((np.arctan2(y[keep], x[keep]), r[keep]))
    rows = np.column_stack([nn[keep], mm[keep], x[keep], y[keep]])
    return rows[order]


@dataclass(frozen=True)
class Orbit:
    """One D6 orbit of pillars: its representative in the primitive wedge and its size."""

    n: int
    m: int
    x: float
    y: float
    size: int  # 1 (centre), 6 (on a mirror line theta = 0 or pi/6) or 12

    @property
    def radius(self) -> float:
        return math.hypot(self.x, self.y)

    @property
    def angle(self) -> float:
        return math.atan2(self.y, self.x)

    @property
    def on_mirror(self) -> bool:
        """True when the representative lies on a mirror line of D6 (or is the centre)."""
        return self.size < 12


def orbit_size(n: int, m: int) -> int:
    """Size of the D6 orbit of wedge pillar (n, m) with 0 <= m <= n/2 (paper's K index)."""
    if n == 0 and m == 0:
        return 1
    if m == 0 or 2 * m == n:
        return 6
    return 12


def wedge_orbits(radius: float, pitch: float) -> list[Orbit]:
    """D6 orbits of the pillars within ``radius``, one representative each in the wedge
    0 <= theta <= pi/6 (0 <= m <= n/2), sorted by distance."""
    out = []
    for n, m, x, y in pillars_within(radius, pitch):
        n, m = int(n), int(m)
        if 0 <= 2 * m <= n:
            out.append(Orbit(n, m, float(x), float(y), orbit_size(n, m)))
    return out


def d6_images(x, y):
    """The 12 images of points (x, y) under D6: arrays of shape (12, ...) for x and y, and the
    rotation angle of a body attached to the point (for orienting elements).  Images 0..5 are
    rotations by u pi/3; images 6..11 the same after the reflection y -> -y."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    xs, ys, flips, rots = [], [], [], []
    for flip in (False, True):
        yy = -y if flip else y
        for u in range(6):
            c, s = math.cos(u * math.pi / 3.0), math.sin(u * math.pi / 3.0)
            xs.append(c * x - s * yy)
            ys.append(s * x + c * yy)
            flips.append(flip)
            rots.append(u * math.pi / 3.0)
    return np.array(xs), np.array(ys), np.array(flips), np.array(rots)
