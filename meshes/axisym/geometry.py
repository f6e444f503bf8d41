"""What an axisymmetric (r, z) mesh describes: bodies, sizes and the grading rule.

Lengths are in metres.  The contact plane is z = 0: the lens block sits above it with a flat
bottom (its curvature is carried by the gap function g(r) = R - sqrt(R^2 - r^2) in the
contact model, not by the mesh); a pillar of radius d/2 and height h stands below it on a
substrate block whose top is z = -h; without a pillar the substrate top is z = 0.  Where the
lens may reach the floor around the pillar, the floor segment [d/2, c_f] at z = -h is a second
contact line, paired with the lens bottom's segment [d/2, c_f] at z = 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .._common import BODIES, GeometryError

# The allowed mesh_size (the factor on every element size) of the axisymmetric meshes; the
# toolkit's --mesh-size range for fem-axisym reads it (validation.registry).
MESH_SIZE_RANGE = (0.02, 4.0)


@dataclass(frozen=True)
class AxisymmetricGeometry:
    """Geometry and grading of the (r, z) half-plane model.

    Parameters
    ----------
    focus_radius_m : float
        Radius of the expected edge of contact (m): the pillar radius d/2 for a pillar scene,
        the Hertz radius a for a flat one.  It is the length unit of the size rule.
    block_size_m : float
        Side L of the square lens and substrate blocks (m); the truncation error of a
        half-space is about 2 a / (pi L).
    contact_radius_m : float, optional
        End of the candidate contact segment [0, c] on z = 0 (m), on which lens and lower body
        get node-for-node identical 1D meshes.  Defaults to ``focus_radius_m``; for a pillar
        it must equal d/2.
    pillar_height_m : float, optional
        Pillar height h (m); None for the flat (Hertz) geometry.
    floor_radius_m : float, optional
        End c_f of the candidate floor segment [d/2, c_f] at z = -h (m), paired node for node
        with the lens bottom's [d/2, c_f] at z = 0; None: the floor is not a contact line.
    bodies : tuple of str
        Bodies to mesh, a subset of ("lens", "pillar", "substrate"); rigid bodies are left out.
    mesh_size : float
        Dimensionless refinement factor: every element size is multiplied by it (0.5 halves
        every element), so one number drives a convergence study.
    elements_across_contact : float
        Elements across the focus radius at ``mesh_size`` = 1 (far from the edge).
    edge_ratio : float
        Element size at the singular points (pillar-top edge, pillar-base corner, Hertz contact
        edge) relative to the contact element size.
    growth : float
        Slope of the size rule: size = h_f + growth * distance, a geometric grading whose
        neighbouring elements differ by about a factor (1 + growth).
    """

    focus_radius_m: float
    block_size_m: float
    contact_radius_m: float | None = None
    pillar_height_m: float | None = None
    floor_radius_m: float | None = None
    bodies: tuple = BODIES
    mesh_size: float = 1.0
    elements_across_contact: float = 16.0
    edge_ratio: float = 0.02
    growth: float = 0.25

    def __post_init__(self):
        def positive(name, value):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise GeometryError(f"{name} = {value!r}: must be a finite number > 0")

        positive("focus_radius_m", self.focus_radius_m)
        positive("block_size_m", self.block_size_m)
        positive("mesh_size", self.mesh_size)
        positive("elements_across_contact", self.elements_across_contact)
        positive("edge_ratio", self.edge_ratio)
        positive("growth", self.growth)
        if self.contact_radius_m is None:
            object.__setattr__(self, "contact_radius_m", self.focus_radius_m)
        positive("contact_radius_m", self.contact_radius_m)
        bodies = tuple(self.bodies)
        unknown = [b for b in bodies if b not in BODIES]
        if unknown or not bodies:
            raise GeometryError(f"bodies = {bodies!r}: choose a non-empty subset of {BODIES}")
        object.__setattr__(self, "bodies", bodies)
        if self.pillar_height_m is None:
            if "pillar" in bodies:
                raise GeometryError("bodies include 'pillar' but pillar_height_m is None "
                                    "(the flat geometry has no pillar)")
        else:
            positive("pillar_height_m", self.pillar_height_m)
            if not math.isclose(self.contact_radius_m, self.focus_radius_m, rel_tol=1e-12):
                raise GeometryError(
                    f"contact_radius_m = {self.contact_radius_m:g} m: with a pillar the "
                    f"contact segment is the pillar top, radius {self.focus_radius_m:g} m")
        if self.floor_radius_m is not None:
            positive("floor_radius_m", self.floor_radius_m)
            if not self.has_pillar or self.floor_radius_m <= 1.001 * self.focus_radius_m:
                raise GeometryError(
                    f"floor_radius_m = {self.floor_radius_m:g} m: needs a pillar and must "
                    f"exceed the pillar radius {self.focus_radius_m:g} m by 0.1 % or more")
        # The blocks must hold the contact zone and the pillar with room to grade away.
        inner = max(self.contact_radius_m, self.pillar_height_m or 0.0,
                    self.floor_radius_m or 0.0)
        if self.block_size_m < 4.0 * inner:
            raise GeometryError(
                f"block_size_m = {self.block_size_m:g} m: must be >= 4 x "
                f"{inner:g} m (the larger of contact radius and pillar height); "
                "the truncation error is about 2a/L, so use L >= 1e3 a")
        if self.block_size_m > 1e8 * self.focus_radius_m:
            raise GeometryError(
                f"block_size_m = {self.block_size_m:g} m: more than 1e8 x the focus radius "
                f"{self.focus_radius_m:g} m exceeds double-precision geometry")
        lo, hi = MESH_SIZE_RANGE
        if self.mesh_size > hi or self.mesh_size < lo:
            raise GeometryError(f"mesh_size = {self.mesh_size:g}: allowed range is "
                                f"[{lo:g}, {hi:g}]")

    @property
    def has_pillar(self) -> bool:
        return self.pillar_height_m is not None

    # --- size rule in units of the focus radius ---------------------------------------
    def size_at(self, r, z):
        """Target element size (in units of ``focus_radius_m``) at (r, z), also in those units.

        The minimum over features f of h_f + growth * distance_f, times ``mesh_size``:
        the contact segment (size 1/n), the singular points (size edge_ratio/n), capped at a
        tenth of the block.  Halving ``mesh_size`` halves every element size, except in and
        near a short pillar, whose elements are at most its height (graded away from it; a
        pillar with h >= d/8 never meets that cap).  With a floor
        segment, it and its image on z = 0 are contact segments too: the two singular points
        are mirror images about z = -h/2, so the rule is the same at (r, 0) and (r, -h) for r
        on the floor segment, and the two lines get the same nodes.
        """
        h_contact = 1.0 / self.elements_across_contact
        h_edge = self.edge_ratio * h_contact
        c = self.contact_radius_m / self.focus_radius_m
        g = self.growth
        # distance to the contact segment [0, c] x {0}
        d_seg = math.hypot(max(r - c, 0.0), z)
        size = h_contact + g * d_seg
        if self.floor_radius_m is not None:
            cf = self.floor_radius_m / self.focus_radius_m
            run = max(1.0 - r, r - cf, 0.0)
            H = self.pillar_height_m / self.focus_radius_m
            size = min(size, h_contact + g * math.hypot(run, z),
                       h_contact + g * math.hypot(run, z + H))
        for (rp, zp) in self.singular_points():
            size = min(size, h_edge + g * math.hypot(r - rp, z - zp))
        cap = 0.1 * self.block_size_m / self.focus_radius_m
        size = self.mesh_size * min(size, cap)
        if self.has_pillar:  # a short pillar: elements no larger than its height (q > 0.5)
            H = self.pillar_height_m / self.focus_radius_m
            box = math.hypot(max(r - 1.0, 0.0), max(z, -H - z, 0.0))
            size = min(size, H + self.mesh_size * g * box)
        return size

    def singular_points(self):
        """Points (in focus-radius units) where the mesh is graded geometrically."""
        pts = [(1.0, 0.0)]  # pillar-top edge, or the Hertz contact edge
        if self.has_pillar:
            pts.append((1.0, -self.pillar_height_m / self.focus_radius_m))  # re-entrant corner
        return pts


def pillar_geometry(diameter_m: float, height_m: float, block_size_m: float, *,
                    bodies=BODIES, mesh_size: float = 1.0, floor_radius_m=None,
                    **grading) -> AxisymmetricGeometry:
    """Lens block over a pillar of diameter d and height h bonded to a substrate block (m).

    The contact segment is the pillar top [0, d/2], and with ``floor_radius_m`` the floor
    [d/2, c_f] too; ``grading`` passes ``elements_across_contact``, ``edge_ratio`` or
    ``growth`` on.
    """
    return AxisymmetricGeometry(focus_radius_m=0.5 * diameter_m, block_size_m=block_size_m,
                                pillar_height_m=height_m, floor_radius_m=floor_radius_m,
                                bodies=tuple(bodies),
                                mesh_size=mesh_size, **grading)


def flat_geometry(contact_radius_m: float, block_size_m: float, *, candidate_radius_m=None,
                  bodies=("lens", "substrate"), mesh_size: float = 1.0,
                  **grading) -> AxisymmetricGeometry:
    """Lens block on a flat substrate block (Hertz); refined towards the expected contact
    radius a, with the candidate contact segment [0, candidate_radius_m] (default 1.5 a)."""
    grading.setdefault("edge_ratio", 0.25)  # the Hertz edge is smooth (sqrt): mild refinement
    return AxisymmetricGeometry(
        focus_radius_m=contact_radius_m, block_size_m=block_size_m,
        contact_radius_m=candidate_radius_m or 1.5 * contact_radius_m, bodies=tuple(bodies),
        mesh_size=mesh_size, **grading)
