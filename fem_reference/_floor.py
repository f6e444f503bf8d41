"""The floor between pillars in both FEMs: where it is a contact candidate, the contact's
extent on a floor line, and the side walls' validity diagnostic.

The lens's bottom is the plane z = 0 with its curvature in the gap; the floor lies at z = -h,
so a floor point's gap is u_z(lens) - u_z(floor) + g(r) + h - zeta.  Pressure on either body
only opens a gap (the lens's surface moves up, the floor's down), so contact is confined to
where the rigid gap g(r) + h - zeta is <= 0: within :func:`pillar_xval.scenes.floor.
floor_reach`.

Side walls.  The model is linear with small slopes: the lens's surface beside a pillar moves
as if the pillar had no side wall, so the deformed lens surface may lie inside the pillar
below its top.  :func:`side_wall_overlap` measures how far (horizontally, m) it does; the
model neglects the wall's contact force, which acts over the overlap's depth.  Beyond
:data:`SIDE_WALL_SMALL` of h the summaries say so.
"""

from __future__ import annotations

import numpy as np

from pillar_xval.scenes.floor import floor_reach, floor_reachable

# Candidate floor radius over the rigid reach (contact lies within the reach; the margin
# leaves room for the contact radius fit, which reads gaps outside the edge).
FLOOR_MARGIN = 1.25
# fem-3d's floor is meshed finer than the contact size (WedgeGeometry.floor_ratio) on a disk
# that holds its contact, sized from the floor contact of a coarser solve: FINE_MARGIN times its
# outer radius.  At mesh_size 4 that radius was 17.85 and 24.24 um on the floor-check lattices
# Phi = 0.2 and 0.4, 4.3 and 0.5 % short of fem-3d's at 1.41 and 5.5 and 3.7 % of the BEM's
# (18.89, 25.18 um at N = 32, converged within 0.2 %); on one pillar 24.01 against
# fem-axisym's 24.46 um.  A solve whose floor contact ends beyond FINE_EDGE of its disk (a
# coarse radius 12.5 % short) is meshed again on a disk FINE_MARGIN times wider (the contact
# there may be cut short by the graded elements beyond): the disk holds the converged contact
# with a band of fine elements around it.
FINE_MARGIN = 1.25
FINE_EDGE = 0.9
# A fine floor sized by the floor's patches as well as the contact size: at most
# width / FLOOR_ACROSS at mesh_size 4 (the contact element size there is the pillar radius
# a) and (mesh_size / 4) of it below, a fixed ratio to the contact size on every level.  On
# Phi = 0.4 (d = 4 um, width 1.48 um) 0.37 to 0.18 um at mesh_size 4 to 2, against 1 to
# 0.5 um at half the contact size (the driver's FLOOR_RATIO).  Measured, and not the
# driver's rule (`python -m validation.bench.floor_gap --only rule,contact`, PHYSICS.md):
# with the floor's area from its P2 gaps the contact-size floor met the BEM on both dense
# floor-check scenes, while this one made the ladder oscillate (Phi = 0.4: 627.6, 660.3,
# 609.1 um^2 at 4, 2.83, 2, the BEM 650.4) for twice the memory (9.2 against 4.9 GiB at 2).
FLOOR_ACROSS = 4.0
# The depth of the overlap with a side wall is small next to h below this share.  Measured
# on one pillar (h/d = 0.5, mesh_size 2): 0.4 % of h at zeta = 0.15 h, 4.5 % at 0.75 h, the
# range where the paper's model (the lens on the pillar tops alone, no walls) was
# validated; beyond it the warning says the scene is past that range.
SIDE_WALL_SMALL = 0.05


def floor_candidate(scene, indentation_m: float) -> float | None:
    """End of the candidate floor (m) at ``indentation_m``: :data:`FLOOR_MARGIN` times the
    floor's reach (:func:`pillar_xval.scenes.floor.floor_reach`), or None where the floor is
    out of reach (zeta <= h + g(d/2))."""
    if not floor_reachable(scene, indentation_m):
        return None
    return FLOOR_MARGIN * floor_reach(scene, indentation_m)


def floor_patch_width(pitch_m: float, diameter_m: float) -> float:
    """Width (m) of the floor's narrowest patch between pillars: the radius of the largest
    circle in a hollow of three neighbouring pillars, p / sqrt(3) - d / 2, at most the gap
    between two of them, p - d (the gap is the narrower from Phi ~0.65, close packing)."""
    return min(pitch_m / np.sqrt(3.0) - 0.5 * diameter_m, pitch_m - diameter_m)


def patch_floor_ratio(pitch_m: float, diameter_m: float, contact_ratio: float) -> float:
    """The fine floor's element size over the contact element size: ``contact_ratio`` (the
    contact-size rule), or finer where a floor patch would be crossed by fewer than
    :data:`FLOOR_ACROSS` elements at mesh_size 4 (the contact size there is the pillar
    radius, ``diameter_m`` / 2)."""
    return float(min(contact_ratio, floor_patch_width(pitch_m, diameter_m)
                     / (FLOOR_ACROSS * 0.5 * diameter_m)))


def fine_floor_radius(contact_radius_m: float, candidate_m: float) -> float | None:
    """Radius (m) of the floor's fine disk for a floor contact ending at
    ``contact_radius_m`` (m; from a coarser solve): :data:`FINE_MARGIN` times it, at most the
    candidate floor's ``candidate_m``; None where that solve had no floor contact (the whole
    candidate at the contact size, as without a disk: the floor is then untouched or touched
    near its onset, and a fine candidate cost 44 % more elements on a lattice whose floor
    stayed untouched, Phi = 0.2 with E_p = E_l at mesh_size 2)."""
    if contact_radius_m <= 0.0:
        return None
    return min(FINE_MARGIN * contact_radius_m, candidate_m)


def outgrown_floor(contact_radius_m: float, fine_m: float | None,
                   candidate_m: float) -> float | None:
    """The wider fine disk (m) to mesh where a solve's floor contact, ending at
    ``contact_radius_m``, passes :data:`FINE_EDGE` of its fine disk ``fine_m``; None where it
    stays inside (or the disk is already the whole candidate ``candidate_m``, whose own end
    the solve's verdict checks)."""
    if fine_m is None or fine_m >= candidate_m or contact_radius_m <= FINE_EDGE * fine_m:
        return None
    return min(FINE_MARGIN * max(contact_radius_m, fine_m), candidate_m)


def floor_contact_area(vertex_points, triangles, floor_vertices, lam, points, w) -> float:
    """Contact area (face units) of the floor's faces, read from the P2 points' gaps.

    The multiplier's own measure, the dual areas of the vertices with lam > 0, falls short
    by a fraction of an element along every contact edge: a mortar vertex closes only where
    the gap weighted over its whole hat does, so a vertex whose hat crosses the edge stays
    open.  On a dense lattice the floor's contact is many small patches, their edge
    1.5 um per um^2 of area (Phi = 0.4), and that deficit was most of fem-3d's gap to the
    BEM (PHYSICS.md).  Here the same dual measure is taken on the P2 points, twice as
    dense: each face splits into its four P2 sub-triangles, and a third of each goes to
    every corner in contact: a point of a floor face whose three vertices hold lam > 0, or
    one whose pointwise gap is at most the closed gaps' own scatter (the 99th percentile
    of |w| on those faces' points; 0 where there is none).

    Parameters
    ----------
    vertex_points : array (2, n_v)
        The contact faces' vertices (x, y), tops and floor (each its own vertices).
    triangles : array (3, m)
        The faces' vertex indices, as the P2 points were numbered from them.
    floor_vertices : bool array (n_v,)
        Which vertices lie on the floor.
    lam : array (n_v,)
        The vertices' multipliers.
    points, w : array (2, n_points), array (n_points,)
        The P2 points (x, y) and their pointwise gaps, numbered as skfem's P2 basis on this
        face mesh numbers them (the vertices, then the edges; checked).

    Returns
    -------
    float
        The floor's contact area, in face units squared.
    """
    from skfem import Basis, ElementTriP2, MeshTri

    if not np.any(floor_vertices):
        return 0.0
    triangles = np.asarray(triangles)
    face = MeshTri(np.ascontiguousarray(vertex_points, dtype=float),
                   np.ascontiguousarray(triangles))
    basis = Basis(face, ElementTriP2(), intorder=2)
    w, xy = np.asarray(w, dtype=float), basis.doflocs
    if len(w) != basis.N or not np.allclose(xy, points, rtol=0.0,
                                            atol=1e-9 * max(1.0, np.max(np.abs(xy)))):
        raise ValueError(f"the {len(w)} gaps are not at the faces' {basis.N} P2 points")
    on = np.all(np.asarray(floor_vertices)[triangles], axis=0)
    dofs = basis.element_dofs[:, on]
    closed = np.all(np.asarray(lam)[triangles[:, on]] > 0.0, axis=0)
    level = float(np.quantile(np.abs(w[dofs[:, closed]]), 0.99)) if closed.any() else 0.0
    shut = w <= level
    shut[dofs[:, closed]] = True  # the multiplier's own contact, whatever its scatter
    shut = shut.astype(float)
    # skfem's P2 triangle: vertices 0, 1, 2, then the midpoints of edges 01, 12, 02
    v0, v1, v2, m01, m12, m02 = dofs
    total = 0.0
    for a, b, c in ((v0, m01, m02), (v1, m12, m01), (v2, m02, m12), (m01, m12, m02)):
        area = 0.5 * np.abs((xy[0, b] - xy[0, a]) * (xy[1, c] - xy[1, a])
                            - (xy[0, c] - xy[0, a]) * (xy[1, b] - xy[1, a]))
        total += float(np.sum(area * (shut[a] + shut[b] + shut[c]) / 3.0))
    return total


def side_wall_overlap(lens_r, lens_z, pillar_top_z: float, wall_r,
                      wall_z) -> tuple[float, float]:
    """How far (m) the deformed lens surface lies inside a pillar's deformed side wall.

    Parameters
    ----------
    lens_r, lens_z : array
        Deformed positions (m) of lens-surface points beyond the pillar's rim (their
        undeformed radius beyond it), radius from the pillar's axis and height.
    pillar_top_z : float
        Deformed height of the pillar's rim (m): lens points above it pass over the pillar.
    wall_r, wall_z : array
        Deformed positions (m) of points of the pillar's side wall.

    Returns
    -------
    (depth, width) : tuple of float
        The depth below the rim down to which lens points lie inside the wall, and their
        largest horizontal overlap; (0, 0) where the lens stays outside the wall.
    """
    lens_r, lens_z = np.asarray(lens_r, float), np.asarray(lens_z, float)
    below = lens_z < pillar_top_z
    if not below.any() or len(wall_r) == 0:
        return 0.0, 0.0
    order = np.argsort(wall_z)
    wall = np.interp(lens_z[below], np.asarray(wall_z)[order], np.asarray(wall_r)[order])
    inside = wall > lens_r[below]
    if not inside.any():
        return 0.0, 0.0
    depth = pillar_top_z - np.min(lens_z[below][inside])
    return float(depth), float(np.max(wall[inside] - lens_r[below][inside]))


def side_wall_diagnostics(overlap: tuple[float, float], height_m: float) -> dict:
    """``side_wall_overlap_m`` (the depth of :func:`side_wall_overlap`), its ratio to h,
    ``side_wall_overlap_width_m`` and, beyond :data:`SIDE_WALL_SMALL`, the
    ``side_wall_warning`` the summaries show."""
    depth, width = overlap
    ratio = depth / height_m
    out = {"side_wall_overlap_m": float(depth), "side_wall_overlap_ratio": float(ratio),
           "side_wall_overlap_width_m": float(width)}
    if ratio > SIDE_WALL_SMALL:
        out["side_wall_warning"] = (
            f"the deformed lens lies inside a pillar's side wall down to {depth * 1e6:.3g} um "
            f"below its top ({ratio:.1%} of h > {SIDE_WALL_SMALL:.0%}; by up to "
            f"{width * 1e6:.3g} um): the small-slope model, which has no side walls, leaves "
            "out their contact there")
    return out


def annulus_edges(r, lam, w) -> tuple[float, float]:
    """(inner, outer) radius (line units) of the contact on a floor line: its P2 points
    ``r`` (vertices at even indices), vertex pressures ``lam`` and pointwise gaps ``w``.
    The outer edge is :func:`fem_reference._driver.contact_radius`'s; the inner one the root
    of w^(2/3), linear between the last vertex outside and the first in contact (the first
    vertex when the contact reaches the pillar's base).  (0, 0) without contact."""
    from ._driver import contact_radius

    active = np.nonzero(lam > 0)[0]
    if len(active) == 0:
        return 0.0, 0.0
    outer, _ = contact_radius(r, lam, w)
    k = 2 * active[0]
    if k == 0:
        return float(r[0]), outer
    sel = [i for i in (k - 2, k - 1) if w[i] > 0]
    if len(sel) < 2:
        return float(0.5 * (r[k - 2] + r[k])), outer
    slope, intercept = np.polyfit(r[sel], w[sel] ** (2.0 / 3.0), 1)
    inner = -intercept / slope if slope < 0 else 0.5 * (r[k - 2] + r[k])
    return float(np.clip(inner, r[k - 2], r[k])), outer
