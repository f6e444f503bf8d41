"""What a 3D sector mesh describes: the sector of the lattice, its bodies, sizes and grading.

Lengths are in metres.  The sector 0 <= theta <= alpha (alpha = pi/6, the D6 primitive
wedge, or pi/3 / pi/2 for symmetry checks: every theta = k pi/6 is a mirror line of the
lattice) is centred on pillar (0, 0).  The lens is a cylindrical sector block above the
contact plane z = 0 with a flat bottom (its curvature is the gap g(r) = R - sqrt(R^2 - r^2)
of the contact model); the pillars of diameter d and height h stand on a substrate block whose
top is z = -h; without pillars (Hertz) the substrate top is z = 0.  Pillars centred on a
mirror plane are cut by it (the centre pillar by both); no other pillar crosses a mirror plane
(the nearest lattice row parallel to it lies e/2 >= d/2 away).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .._common import BODIES, GeometryError

SQRT3 = math.sqrt(3.0)

# Sector angles whose two bounding planes are both mirror planes of the hexagonal lattice.
SECTORS = (math.pi / 6.0, math.pi / 3.0, math.pi / 2.0)
# The allowed mesh_size of the 3D sector meshes; the toolkit's --mesh-size range for fem-3d
# reads it (validation.registry).
MESH_SIZE_RANGE_3D = (0.05, 4.0)


@dataclass(frozen=True)
class SectorPillar:
    """A pillar of the sector: lattice indices, centre (m) and the share of its top that
    lies in the sector (1, 1/2 on one mirror plane, alpha / (2 pi) for the centre pillar)."""

    n: int
    m: int
    x_m: float
    y_m: float
    share: float

    @property
    def name(self) -> str:
        return f"{self.n}_{self.m}"


@dataclass(frozen=True)
class WedgeGeometry:
    """Geometry and grading of a 3D sector model.

    Parameters
    ----------
    focus_radius_m : float
        Length unit of the size rule (m): the pillar radius d/2, or the Hertz radius a.
    block_size_m : float
        Radius and height L of the lens and substrate blocks (m); the truncation error of a
        half-space is about 2 a_c / (pi L) for a contact of radius a_c.
    pillars : tuple of SectorPillar
        Pillars in the sector (empty for the flat geometry).
    pillar_height_m : float, optional
        Pillar height h (m); None for the flat geometry.
    contact_radius_m : float, optional
        Flat geometry: radius of the candidate contact sector on z = 0 (m).
    floor_radius_m : float, optional
        Radius c_f of the candidate floor (m): the sector's disk less the pillars, on the
        substrate's top z = -h and its copy on the lens's bottom; its circle must cross no
        pillar (:func:`floor_clear_of_pillars`).  None: the floor is not a contact face.
    floor_fine_radius_m : float, optional
        Radius (m) of the floor's fine disk, the part of the candidate floor that holds its
        contact: there the floor and its copy on the lens take the size floor_ratio * h_c,
        graded beyond it.  None: the whole candidate floor at the contact size h_c.
    sector_angle : float
        alpha in radians, one of pi/6 (default), pi/3, pi/2.
    bodies : tuple of str
        Bodies to mesh, a subset of ("lens", "pillar", "substrate"); rigid bodies are left out
        (their contact or bonded faces are still imprinted on the elastic ones).
    mesh_size : float
        Dimensionless refinement factor: every element size is multiplied by it.
    elements_across_contact : float
        Elements across the focus radius on a contact face at ``mesh_size`` = 1.
    edge_ratio : float
        Element size at the pillar-top edges and base corners (flat: the Hertz edge)
        relative to the contact element size.
    growth : float
        Slope of the size rule, size = h_f + growth * distance (geometric grading).
    centre_ratio : float
        Element size on the top of the pillar at the origin (the centre pillar, whose top
        holds sigma0 and the pressure profile), relative to the contact element size.
    floor_ratio : float
        Element size on the floor's fine disk relative to the contact element size.
    """

    focus_radius_m: float
    block_size_m: float
    pillars: tuple = ()
    pillar_height_m: float | None = None
    contact_radius_m: float | None = None
    floor_radius_m: float | None = None
    floor_fine_radius_m: float | None = None
    sector_angle: float = math.pi / 6.0
    bodies: tuple = BODIES
    mesh_size: float = 1.0
    elements_across_contact: float = 4.0
    edge_ratio: float = 0.25
    growth: float = 0.35
    centre_ratio: float = 1.0
    floor_ratio: float = 1.0

    def __post_init__(self):
        def positive(name, value):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise GeometryError(f"{name} = {value!r}: must be a finite number > 0")

        for name in ("focus_radius_m", "block_size_m", "mesh_size", "elements_across_contact",
                     "edge_ratio", "growth", "centre_ratio", "floor_ratio"):
            positive(name, getattr(self, name))
        if not any(math.isclose(self.sector_angle, s, rel_tol=1e-12) for s in SECTORS):
            raise GeometryError(f"sector_angle = {self.sector_angle!r}: allowed values are pi/6, "
                            "pi/3 and pi/2 (both planes must be mirror planes of the lattice)")
        bodies = tuple(self.bodies)
        unknown = [b for b in bodies if b not in BODIES]
        if unknown or not bodies:
            raise GeometryError(f"bodies = {bodies!r}: choose a non-empty subset of {BODIES}")
        object.__setattr__(self, "bodies", bodies)
        object.__setattr__(self, "pillars", tuple(self.pillars))
        if self.pillar_height_m is None:
            if "pillar" in bodies or self.pillars:
                raise GeometryError("pillars given but pillar_height_m is None")
            if self.contact_radius_m is None:
                raise GeometryError("the flat geometry needs contact_radius_m (candidate zone)")
            positive("contact_radius_m", self.contact_radius_m)
        else:
            positive("pillar_height_m", self.pillar_height_m)
            if not self.pillars:
                raise GeometryError("pillar_height_m given but no pillar lies in the sector")
            if self.floor_radius_m is not None:
                positive("floor_radius_m", self.floor_radius_m)
                clear = floor_clear_of_pillars(self.floor_radius_m, self.pillars,
                                               self.focus_radius_m)
                if clear != self.floor_radius_m:
                    raise GeometryError(f"floor_radius_m = {self.floor_radius_m:g} m: its "
                                        "circle crosses a pillar (or the centre pillar's rim)")
            if self.floor_fine_radius_m is not None:
                positive("floor_fine_radius_m", self.floor_fine_radius_m)
                if self.floor_radius_m is None:
                    raise GeometryError("floor_fine_radius_m given without a candidate floor "
                                        "(floor_radius_m)")
        lo, hi = MESH_SIZE_RANGE_3D
        if self.mesh_size > hi or self.mesh_size < lo:
            raise GeometryError(f"mesh_size = {self.mesh_size:g}: allowed range is "
                                f"[{lo:g}, {hi:g}]")
        inner = self.extent_m
        if self.block_size_m < 4.0 * inner:
            raise GeometryError(
                f"block_size_m = {self.block_size_m:g} m: must be >= 4 x {inner:g} m (the "
                "reach of the pillars or the contact zone); use L >= 1e3 x the contact radius")
        if self.block_size_m > 1e8 * self.focus_radius_m:
            raise GeometryError(f"block_size_m = {self.block_size_m:g} m: more than 1e8 x the "
                            f"focus radius {self.focus_radius_m:g} m")

    @property
    def has_pillars(self) -> bool:
        return self.pillar_height_m is not None

    @property
    def extent_m(self) -> float:
        """Radius (m) that holds every pillar (or the candidate zone) and the pillar height."""
        if not self.has_pillars:
            return self.contact_radius_m
        reach = max(math.hypot(p.x_m, p.y_m) for p in self.pillars) + self.focus_radius_m
        return max(reach, self.pillar_height_m, self.floor_radius_m or 0.0)

    # --- size rule in units of the focus radius ------------------------------------------
    def size_at(self, x: float, y: float, z: float) -> float:
        """Target element size at (x, y, z), all in units of ``focus_radius_m``.

        Minimum over features of h_f + growth * distance_f, times ``mesh_size``: the contact
        faces (size 1/n), the pillar-top edges and base corners (flat: the Hertz edge circle)
        (size edge_ratio / n) and the centre pillar's top (size centre_ratio / n), capped at a
        tenth of the block.
        """
        return self.size_callback()(0, 0, x, y, z, 0.0)

    def size_callback(self):
        """The size rule of :meth:`size_at` as gmsh's size callback ``f(dim, tag, x, y, z,
        lc)``, its constants bound once and the centres that can be nearest to a point found
        once per cell of a grid (:class:`_CellGrid`): gmsh calls it ~5e5 times a mesh, mostly
        to integrate the size along the curves near the pillars."""
        cached = self.__dict__.get("_size_callback")
        if cached is not None:
            return cached
        hypot, inf, floor, frexp, ldexp = math.hypot, math.inf, math.floor, math.frexp, math.ldexp
        h_c = 1.0 / self.elements_across_contact
        h_e = self.edge_ratio * h_c
        g = self.growth
        cap = 0.1 * self.block_size_m / self.focus_radius_m
        scale = self.mesh_size
        if not self.has_pillars:
            c = self.contact_radius_m / self.focus_radius_m

            def size(dim, tag, x, y, z, lc):
                rho = hypot(x, y)
                s = min(h_c + g * hypot(max(rho - c, 0.0), z), h_e + g * hypot(rho - 1.0, z))
                return scale * min(s, cap)

            object.__setattr__(self, "_size_callback", size)
            return size
        H = self.pillar_height_m / self.focus_radius_m
        h_0 = self.centre_ratio * h_c
        centred = self.centre_ratio < 1.0
        table, e = self._lattice
        centres = list(table.values())
        # With a floor the rule is the same at z and -h - z (the floor's faces and their
        # copies on the lens, the pillars' tops and bases get the same curves' nodes).
        mirror = self.floor_radius_m is not None
        # The floor's candidate disk is a contact face as the tops are: a uniform size on the
        # disk that holds its contact, h_c or floor_ratio * h_c on the fine disk, graded
        # beyond (graded from the nearest rim instead, the floor's contact edges, far from
        # the rims on a sparse lattice, were resolved by a few elements).  Outside the
        # pillars only: their tops keep the contact size.
        fine = self.floor_fine_radius_m
        c_f = (fine or self.floor_radius_m or 0.0) / self.focus_radius_m
        h_fl = h_c if fine is None else self.floor_ratio * h_c
        only = centres[0] if len(centres) == 1 else None
        cell_of = _CellGrid(centres, e)
        cells = {}  # cell key -> the centres that can be nearest to a point of the cell
        w0, inv0, R, invR = cell_of.w0, 1.0 / cell_of.w0, cell_of.R, 1.0 / cell_of.R

        def size(dim, tag, x, y, z, lc):
            # The nearest meshed pillar: among the centres that can be nearest anywhere in
            # the point's cell (one, but near the cells' Voronoi edges; the cell's key inlined
            # from _CellGrid.key, as gmsh calls this ~5e5 times a mesh).  Only the nearest
            # pillar matters: pillars do not overlap, so the nearest centre is also nearest
            # to every top, rim and base feature (and each size grows with distance).
            # Comparisons spell out min, max and abs (the first of equal values wins, as with
            # them), and hypot takes signed arguments: the same values, without the
            # builtins' calls.
            if only is None:
                a, b = (x if x >= 0.0 else -x), (y if y >= 0.0 else -y)
                if (a if a > b else b) < R:
                    key = (0, floor(x * inv0), floor(y * inv0))
                else:
                    level = frexp((a if a > b else b) * invR)[1]
                    w = ldexp(w0, level)
                    key = (level, floor(x / w), floor(y / w))
                candidates = cells.get(key)
                if candidates is None:
                    candidates = cells[key] = cell_of.candidates(key)
                if len(candidates) == 1:
                    cx, cy = candidates[0]
                else:
                    best = inf
                    for p in candidates:
                        d2 = (p[0] - x) ** 2 + (p[1] - y) ** 2
                        if d2 < best:
                            best, (cx, cy) = d2, p
            else:
                cx, cy = only
            rim = hypot(x - cx, y - cy) - 1.0
            s = cap
            top, base = (z if z >= 0.0 else -z), (z + H if z + H >= 0.0 else -(z + H))
            zf = base if mirror and base < top else z
            t = h_c + g * hypot(rim if rim > 0.0 else 0.0, zf)
            if t < s:
                s = t
            t = h_e + g * hypot(rim, base if base < top else top)
            if t < s:
                s = t
            if mirror:  # the floor's disk rho <= c_f at z = -h and its copy at z = 0
                rf = hypot(x, y) - c_f
                t = h_fl + g * hypot(hypot(rf if rf > 0.0 else 0.0, rim if rim < 0.0 else 0.0),
                                     zf)
                if t < s:
                    s = t
            if centred:  # the centre pillar's top: the disk r <= 1 at z = 0
                r0 = hypot(x, y) - 1.0
                t = h_0 + g * hypot(r0 if r0 > 0.0 else 0.0, zf)
                if t < s:
                    s = t
            return scale * s

        object.__setattr__(self, "_size_callback", size)
        return size

    @property
    def _lattice(self):
        """({(n, m): centre in focus units}, pitch in focus units) of the meshed pillars."""
        cached = self.__dict__.get("_lattice_cache")
        if cached is None:
            f = self.focus_radius_m
            table = {(p.n, p.m): (p.x_m / f, p.y_m / f) for p in self.pillars}
            ring = [p for p in self.pillars if (p.n, p.m) != (0, 0)]
            e = 0.0
            if ring:  # |c| = e sqrt(n^2 - n m + m^2)
                p = ring[0]
                e = math.hypot(p.x_m, p.y_m) / f / math.sqrt(p.n**2 - p.n * p.m + p.m**2)
            cached = (table, e)
            object.__setattr__(self, "_lattice_cache", cached)
        return cached


class _CellGrid:
    """Square cells (focus units) that hold the answer to "which meshed centre is nearest":
    a quarter pitch wide within ``R`` of the axis (the pillars' region and a pitch around
    it), doubling in width with each doubling of the distance beyond (far out, where the
    sizes are large and gmsh integrates them along the block's long edges, a few hundred
    cells).  A cell's candidates are the centres that can be nearest to one of its points:
    those no farther from the cell than the farthest point of the cell is from the centre
    nearest to that far point (one centre, but near the Voronoi edges), in the centres'
    order, so that the first of equally near centres wins as in a scan of them all."""

    def __init__(self, centres, pitch: float):
        self.centres = list(centres)
        self.w0 = 0.25 * pitch if pitch > 0.0 else 1.0
        self.R = max(math.hypot(cx, cy) for cx, cy in self.centres) + max(pitch, 2.0)

    def key(self, x: float, y: float) -> tuple:
        """The cell holding (x, y): (level, i, j), the cell [i, i + 1] x [j, j + 1] times its
        width w0 2^level (level 0 within R of the axis in the max norm)."""
        far = max(abs(x), abs(y))
        if far < self.R:
            return (0, math.floor(x / self.w0), math.floor(y / self.w0))
        level = math.frexp(far / self.R)[1]
        w = math.ldexp(self.w0, level)
        return (level, math.floor(x / w), math.floor(y / w))

    def candidates(self, key: tuple) -> tuple:
        """The centres that can be nearest to a point of cell ``key``; the cell is widened
        by 1e-9 of its width, for a point that rounding put in a neighbour's key."""
        level, i, j = key
        w = math.ldexp(self.w0, level)
        pad = 1e-9 * w
        x0, x1, y0, y1 = i * w - pad, (i + 1) * w + pad, j * w - pad, (j + 1) * w + pad

        def farthest(c):
            return math.hypot(max(abs(x0 - c[0]), abs(x1 - c[0])),
                              max(abs(y0 - c[1]), abs(y1 - c[1])))

        def nearest(c):
            return math.hypot(max(x0 - c[0], 0.0, c[0] - x1), max(y0 - c[1], 0.0, c[1] - y1))

        bound = min(farthest(c) for c in self.centres) * (1.0 + 1e-12)
        return tuple(c for c in self.centres if nearest(c) <= bound)


def sector_pillars(pitch_m: float, diameter_m: float, reach_m: float,
                   sector_angle: float = math.pi / 6.0) -> tuple:
    """Pillars of the lattice whose centre lies in the sector and whose top comes within
    ``reach_m`` of the axis (nearest top point r = |c| - d/2 <= reach_m), as SectorPillar."""
    from pillar_xval.scenes.lattice import pillars_within

    out = []
    tol = 1e-9 * pitch_m
    for n, m, x, y in pillars_within(reach_m + 0.5 * diameter_m, pitch_m):
        theta = math.atan2(y, x)
        r = math.hypot(x, y)
        if r < tol:
            out.append(SectorPillar(0, 0, 0.0, 0.0, sector_angle / (2.0 * math.pi)))
            continue
        # distances to the two planes (signed, positive inside)
        d0 = y
        d1 = -x * math.sin(sector_angle) + y * math.cos(sector_angle)
        if d0 < -tol or d1 > tol:
            continue
        on_plane = abs(d0) <= tol or abs(d1) <= tol
        if theta < -1e-12 or theta > sector_angle + 1e-12:
            continue
        out.append(SectorPillar(int(n), int(m), float(x), float(y), 0.5 if on_plane else 1.0))
    return tuple(out)


def floor_clear_of_pillars(radius_m: float, pillars, focus_radius_m: float) -> float:
    """The smallest radius >= ``radius_m`` (m) whose circle crosses none of ``pillars`` (a
    gap of a tenth of the pillar radius from their rims): the floor's candidate disk then
    holds whole pillars only, and the centre pillar with room."""
    gap = 0.1 * focus_radius_m
    r = max(radius_m, 1.0 * focus_radius_m + gap)
    moved = True
    while moved:
        moved = False
        for p in pillars:
            c = math.hypot(p.x_m, p.y_m)
            if c > 0.0 and c - focus_radius_m - gap < r < c + focus_radius_m + gap:
                r, moved = c + focus_radius_m + gap, True
    return r
