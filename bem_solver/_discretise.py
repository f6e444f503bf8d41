"""Elements of the candidate contact region, reduced by the symmetry of the scene.

Every pillar top carries the same square-cell pattern, turned so that its x axis points along
the pillar's radial direction (as in the paper); the centre pillar's grid is aligned with x.
The set of non-centre elements is then invariant under the dihedral group D6, while the
centre pillar's square grid is invariant only under its subgroup D2 (x -> -x, y -> -y).  The
unknowns are therefore one representative element per orbit: D6 orbits of size 6 or 12 off
the centre pillar (the elements of the pillars in the primitive wedge 0 <= theta <= pi/6,
halved on its mirror lines) and D2 orbits of size 1, 2 or 4 on the centre pillar (one
quadrant).  A flat scene is one large "centre pillar": a square grid over a disk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pillar_xval.scenes import Scene
from pillar_xval.scenes.lattice import d6_images, lattice_indices, wedge_orbits

from ._cells import cell_pattern


@dataclass
class Discretisation:
    """Representative elements (``rep_*``, the unknowns) and all their images (``img_*``).

    Positions are global collocation points (m); ``*_angle`` is the orientation of the loaded
    square (rad), ``*_side`` its side (m), ``*_area`` its area (m^2).  ``img_rep`` names the
    representative of each image; images of one representative are contiguous.
    ``*_pillar`` is the lattice pillar (index into ``pillar_nm``); -1 for a flat scene.
    """

    rep_x: np.ndarray
    rep_y: np.ndarray
    rep_angle: np.ndarray
    rep_side: np.ndarray
    rep_area: np.ndarray
    rep_weight: np.ndarray      # orbit size of the representative
    rep_centre: np.ndarray      # True on the centre pillar (D2 orbit)
    rep_local: np.ndarray       # (n, 2) grid-cell centre in the pillar frame (m)
    rep_orbit: np.ndarray       # index of the pillar orbit (into orbit_*), -1 for flat
    img_x: np.ndarray
    img_y: np.ndarray
    img_angle: np.ndarray
    img_side: np.ndarray
    img_area: np.ndarray
    img_rep: np.ndarray
    img_pillar: np.ndarray
    rep_start: np.ndarray       # images of rep j are img_*[rep_start[j]:rep_start[j+1]]
    pillar_nm: np.ndarray       # (n_pillars, 2) lattice indices
    pillar_xy: np.ndarray       # (n_pillars, 2) centres (m)
    pillar_orbit: np.ndarray    # orbit index of each pillar
    orbit_size: np.ndarray      # pillars per orbit (1, 6 or 12)
    cell_side: float            # grid spacing b (m)
    candidate_radius: float     # elements with collocation radius <= this (m)

    @property
    def n_unknowns(self) -> int:
        return len(self.rep_x)

    @property
    def n_elements(self) -> int:
        return len(self.img_x)


def overlap_radius(scene: Scene) -> float:
    """Radius within which the undeformed lens overlaps the pillar-top plane (m).

    Surface displacements only open the gap, so no point beyond it can touch: a rigorous
    outer bound of the contact region (the paper's initial guess).
    """
    R, zeta = scene.lens.radius_m, scene.indentation_m
    return math.sqrt(2.0 * R * zeta - zeta * zeta)


def discretise(scene: Scene, per_diameter: int, variant: str, candidate_radius: float,
               ) -> Discretisation:
    """Elements within ``candidate_radius`` (m) for ``per_diameter`` cells across a pillar
    (for a flat scene: across the Hertz contact diameter 2 sqrt(R zeta))."""
    if scene.pillars is None:
        return _flat(scene, per_diameter, candidate_radius)
    d = scene.pillars.diameter_m
    pattern = cell_pattern(per_diameter, variant)
    cells = pattern.scaled(d)
    gx, gy = pattern.grid_x * d, pattern.grid_y * d
    b = pattern.cell_side * d
    orbits = wedge_orbits(candidate_radius + d / 2.0, scene.pillars.pitch_m)

    reps = []
    for k, orb in enumerate(orbits):
        theta = orb.angle
        c, s = math.cos(theta), math.sin(theta)
        if orb.size == 1:
            keep = (gx >= -1e-12 * d) & (gy >= -1e-12 * d)
        elif orb.size == 6:  # half a pillar on a mirror line: the half inside the wedge
            keep = gy >= -1e-12 * d if orb.m == 0 else gy <= 1e-12 * d
        else:
            keep = np.ones(gx.shape, bool)
        lx, ly = cells["x"][keep], cells["y"][keep]
        px = orb.x + c * lx - s * ly
        py = orb.y + s * lx + c * ly
        inside = np.hypot(px, py) <= candidate_radius
        m = int(inside.sum())
        if m:
            reps.append(np.column_stack([
                px[inside], py[inside], np.full(m, theta), cells["side"][keep][inside],
                cells["area"][keep][inside], np.full(m, float(orb.size == 1)),
                gx[keep][inside], gy[keep][inside], np.full(m, float(k))]))
    reps = np.concatenate(reps) if reps else np.zeros((0, 9))
    return _assemble(reps, orbits, b, candidate_radius, scene.pillars.pitch_m)


def _assemble(reps, orbits, b, candidate_radius, pitch) -> Discretisation:
    rep = np.asarray(reps, dtype=float).reshape(-1, 9)
    n = len(rep)
    px, py, ang, side, area = (rep[:, i] for i in range(5))
    centre = rep[:, 5].astype(bool)
    orbit = rep[:, 8].astype(int)

    # Images: D2 for the centre pillar (or a flat scene), D6 otherwise.  Only elements on a
    # mirror line have coinciding images; those are dropped by position.
    ix, iy, flips, rots = d6_images(px, py)
    img_ang = np.where(flips[:, None], -ang[None, :], ang[None, :]) + rots[:, None]
    use = np.ones((12, n), bool)
    use[:, centre] = np.isin(np.arange(12), (0, 3, 6, 9))[:, None]  # D2: 1, rot pi, mirrors
    tol = 1e-9 * b
    on_mirror = np.zeros(n, bool)
    if n:
        local_y = rep[:, 7]
        local_x = rep[:, 6]
        sizes = (np.array([o.size for o in orbits])[orbit] if orbits is not None
                 else np.ones(n, int))
        on_mirror = ((sizes == 6) & (np.abs(local_y) < tol)) | (
            centre & ((np.abs(local_x) < tol) | (np.abs(local_y) < tol)))
    for j in np.nonzero(on_mirror)[0]:
        g = np.nonzero(use[:, j])[0]
        key = np.round(np.column_stack([ix[g, j], iy[g, j]]) / tol).astype(np.int64)
        _, first = np.unique(key, axis=0, return_index=True)
        use[:, j] = False
        use[g[first], j] = True
    weight = use.sum(axis=0)
    start = np.concatenate([[0], np.cumsum(weight)])
    j_idx, g_idx = np.nonzero(use.T)  # images grouped by rep, then by group element
    img = np.column_stack([ix[g_idx, j_idx], iy[g_idx, j_idx], img_ang[g_idx, j_idx],
                           side[j_idx], area[j_idx], j_idx])

    if orbits is None:  # flat scene
        img_pillar = np.full(len(img), -1)
        pillar_nm = np.zeros((0, 2), int)
        pillar_xy = np.zeros((0, 2))
        pillar_orbit = np.zeros(0, int)
        orbit_size = np.zeros(0, int)
    else:
        # The image of an element under g lies on the image of its pillar under g; pillars
        # are named by lattice indices, which merge the coinciding images of mirror pillars.
        orb_xy = np.array([(o.x, o.y) for o in orbits]).reshape(-1, 2)
        cx, cy, _, _ = d6_images(orb_xy[:, 0], orb_xy[:, 1])
        nn, mm = lattice_indices(cx, cy, pitch)
        ids = {}
        pillar_of = np.empty((12, len(orbits)), int)
        pillar_nm, pillar_xy, pillar_orbit = [], [], []
        for k in range(len(orbits)):
            for g in range(12):
                key = (int(nn[g, k]), int(mm[g, k]))
                if key not in ids:
                    ids[key] = len(pillar_nm)
                    pillar_nm.append(key)
                    pillar_xy.append((cx[g, k], cy[g, k]))
                    pillar_orbit.append(k)
                pillar_of[g, k] = ids[key]
        img_pillar = pillar_of[g_idx, orbit[j_idx]]
        pillar_nm = np.array(pillar_nm, int).reshape(-1, 2)
        pillar_xy = np.array(pillar_xy).reshape(-1, 2)
        pillar_orbit = np.array(pillar_orbit, int)
        orbit_size = np.array([o.size for o in orbits], int)

    return Discretisation(
        rep_x=px, rep_y=py, rep_angle=ang, rep_side=side, rep_area=area, rep_weight=weight,
        rep_centre=centre, rep_local=rep[:, 6:8], rep_orbit=orbit,
        img_x=img[:, 0], img_y=img[:, 1], img_angle=img[:, 2], img_side=img[:, 3],
        img_area=img[:, 4], img_rep=img[:, 5].astype(int), img_pillar=img_pillar,
        rep_start=start, pillar_nm=pillar_nm, pillar_xy=pillar_xy, pillar_orbit=pillar_orbit,
        orbit_size=orbit_size, cell_side=b, candidate_radius=candidate_radius)


def flat_cell_side(scene: Scene, per_diameter: int) -> float:
    """Cell side of a flat scene: ``per_diameter`` cells across 2 sqrt(R zeta) (m)."""
    return 2.0 * math.sqrt(scene.lens.radius_m * scene.indentation_m) / per_diameter


def _flat(scene: Scene, per_diameter: int, candidate_radius: float) -> Discretisation:
    b = flat_cell_side(scene, per_diameter)
    # Same parity as per_diameter so that the grid is the one centred like the pillar grids.
    across = int(math.ceil(2.0 * candidate_radius / b))
    if across % 2 != per_diameter % 2:
        across += 1
    centres = b * (np.arange(across) - (across - 1) / 2.0)
    gx, gy = np.meshgrid(centres, centres, indexing="ij")
    gx, gy = gx.ravel(), gy.ravel()
    keep = (gx >= -1e-12 * b) & (gy >= -1e-12 * b) & (np.hypot(gx, gy) <= candidate_radius)
    m = int(keep.sum())
    reps = np.column_stack([gx[keep], gy[keep], np.zeros(m), np.full(m, b), np.full(m, b * b),
                            np.ones(m), gx[keep], gy[keep], np.full(m, -1.0)])
    return _assemble(reps, None, b, candidate_radius, 1.0)
