"""gmsh (OpenCASCADE) builder of the 3D sector meshes: lens block, pillars, substrate block.

gmsh works in units of the focus radius; points come back in metres.  The lens block, the
pillars and the substrate block are cylindrical sectors (``addCylinder`` with an opening
angle); pillars centred on a mirror plane are intersected with the sector.  Pillars and
substrate are fragmented together, so the pillar bases are shared faces (a bonded,
conforming interface).  The lens is fragmented with copies of the pillar tops (flat: of the
candidate contact sector), which imprints them on its bottom face; it shares no entity with
the lower bodies, so the two sides of every contact face are distinct nodes.  Each imprinted
lens face is meshed as a periodic copy (identity transform) of the face it touches: the two
sides of a contact face match node for node, which makes the mortar contact exact and simple
(the lens needs the pillars' resolution there anyway, for the same edge singularity).  The
candidate floor (the sector's disk of radius c_f less the pillars) is imprinted on the
substrate's top at z = -h and on the lens's bottom, and meshed on the substrate as the lens's
face moved down by h.
"""

from __future__ import annotations

import math

import numpy as np

from .._common import MeshError
from .._session import gmsh_model, set_size_callback
from .mesh import MIN_QUALITY_3D, WedgeMesh
from .geometry import WedgeGeometry

IDENTITY = [1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, 1.0]
# Geometric tolerance for classifying faces, in focus-radius units.
TOL = 1e-5  # OCC pads bounding boxes by 1e-7


def build_wedge_mesh(geometry: WedgeGeometry, *, progress=None) -> WedgeMesh:
    """Mesh ``geometry`` with linear tetrahedra and return it with named groups.

    Groups (subdomains): ``lens``, ``pillar``, ``substrate`` (those meshed) and
    ``pillar_{n}_{m}`` per pillar.  Boundaries: ``contact_lens`` and ``contact_lens_{n}_{m}``
    (lens faces over each pillar top; flat: over the candidate sector), ``contact_pillar`` and
    ``contact_pillar_{n}_{m}`` (pillar tops), flat ``contact_substrate``, with a candidate
    floor ``contact_lens_floor`` and ``contact_floor`` (its two sides), ``pillar_base`` and
    ``pillar_base_{n}_{m}``, ``mirror_0`` (theta = 0) and ``mirror_1`` (theta = alpha) with
    per-body ``mirror_0_lens`` etc., ``far_lens`` (z = L), ``far_substrate`` (bottom),
    ``side_lens``, ``side_substrate`` (r = L), ``free_lens``, ``free_pillar``,
    ``free_substrate``.

    Raises
    ------
    MeshError
        If gmsh fails, a body gets no elements or the mesh fails its checks.
    """
    with gmsh_model(f"wedge-{id(geometry)}", "the sector geometry") as gmsh:
        volumes, pairs = _build_geometry(gmsh, geometry)
        groups = _name_groups(gmsh, geometry, volumes)
        if progress:
            progress(f"gmsh: meshing {len(volumes)} volumes")
        _mesh(gmsh, geometry, pairs)
        mesh = _collect(gmsh, geometry, groups)
        worst = float(mesh.quality().min())
        if worst < MIN_QUALITY_3D:
            # gmsh's own optimiser leaves a sliver now and then (q ~ 0.004-0.0196, far out on
            # the skew mirror plane or at a pillar's edge, on about one scene in four drawn
            # at random); Netgen's optimiser removes them (q >= 0.2 on those scenes) and
            # keeps the surface meshes, so the contact faces still match.  Meshes that pass
            # are left as they were.
            if progress:
                progress(f"gmsh: a tetrahedron of quality {worst:.3g} < "
                         f"{MIN_QUALITY_3D}: optimising the mesh (Netgen)")
            gmsh.model.mesh.optimize("Netgen")
            mesh = _collect(gmsh, geometry, groups)
            mesh.optimised = True
    mesh.check()
    return mesh


def _build_geometry(gmsh, geo: WedgeGeometry):
    """OCC solids in focus units; returns ({body or pillar name: [volume tags]}, pairs of
    (lens face tag, lower face tag) to mesh as periodic copies)."""
    occ = gmsh.model.occ
    f = geo.focus_radius_m
    L = geo.block_size_m / f
    alpha = geo.sector_angle
    H = geo.pillar_height_m / f if geo.has_pillars else 0.0
    volumes: dict[str, list] = {}

    lens = occ.addCylinder(0, 0, 0, 0, 0, L, L, angle=alpha) if "lens" in geo.bodies else None
    substrate = (occ.addCylinder(0, 0, -H - L, 0, 0, L, L, angle=alpha)
                 if "substrate" in geo.bodies else None)

    if geo.has_pillars:
        pillar_vols = {}
        cut = []
        for p in geo.pillars:
            cx, cy = p.x_m / f, p.y_m / f
            if p.share < 1.0 and math.hypot(cx, cy) < TOL:
                pillar_vols[p.name] = occ.addCylinder(0, 0, -H, 0, 0, H, 1.0, angle=alpha)
            else:
                pillar_vols[p.name] = occ.addCylinder(cx, cy, -H, 0, 0, H, 1.0)
                if p.share < 1.0:
                    cut.append(p.name)
        if cut:
            reach = max(math.hypot(p.x_m / f, p.y_m / f) for p in geo.pillars) + 2.0
            prism = occ.addCylinder(0, 0, -H - 1.0, 0, 0, H + 2.0, reach, angle=alpha)
            for name in cut:
                out, _ = occ.intersect([(3, pillar_vols[name])], [(3, prism)],
                                       removeObject=True, removeTool=False)
                if len(out) != 1:
                    raise MeshError(f"cutting pillar {name} by the mirror planes gave "
                                    f"{len(out)} pieces")
                pillar_vols[name] = out[0][1]
            occ.remove([(3, prism)], recursive=True)
        occ.synchronize()
        tops = {k: _face_at(gmsh, v, 0.0) for k, v in pillar_vols.items()}
        bases = {k: _face_at(gmsh, v, -H) for k, v in pillar_vols.items()}
        top_copies = {k: occ.copy([(2, t)])[0][1] for k, t in tops.items()}
        floor_top, floor_low = _floor_faces(occ, geo, tops.values(), H)
        if "pillar" in geo.bodies:
            if substrate is not None:
                out, out_map = occ.fragment([(3, substrate)],
                                            [(3, v) for v in pillar_vols.values()]
                                            + [(2, t) for t in floor_low])
                substrate = _only(out_map[0], "substrate")
                for k, mp in zip(pillar_vols, out_map[1:]):
                    pillar_vols[k] = _only(mp, f"pillar {k}")
            for k, v in pillar_vols.items():
                volumes[f"pillar_{k}"] = [v]
            volumes["pillar"] = list(pillar_vols.values())
        else:
            base_copies = [occ.copy([(2, b)])[0][1] for b in bases.values()]
            occ.remove([(3, v) for v in pillar_vols.values()], recursive=True)
            if substrate is not None:
                out, out_map = occ.fragment([(3, substrate)], [(2, b) for b in base_copies]
                                            + [(2, t) for t in floor_low])
                substrate = _only(out_map[0], "substrate")
        if substrate is None and floor_low:
            occ.remove([(2, t) for t in floor_low], recursive=True)
        lower_faces = {**top_copies, **{f"floor{i}": t for i, t in enumerate(floor_top)}}
    else:
        disk = _sector_disk(occ, geo.contact_radius_m / f, alpha)
        lower_faces = {"flat": disk}
        if substrate is not None:
            copy = occ.copy([(2, disk)])[0][1]
            out, out_map = occ.fragment([(3, substrate)], [(2, copy)])
            substrate = _only(out_map[0], "substrate")

    if lens is not None:
        out, out_map = occ.fragment([(3, lens)], [(2, t) for t in lower_faces.values()])
        lens = _only(out_map[0], "lens")
    else:
        occ.remove([(2, t) for t in lower_faces.values()], recursive=True)
    occ.synchronize()
    if lens is not None:
        volumes["lens"] = [lens]
    if substrate is not None:
        volumes["substrate"] = [substrate]
    pairs = []
    if lens is not None and (("pillar" in geo.bodies) or
                             (not geo.has_pillars and substrate is not None)):
        lens_faces = _faces_at(gmsh, lens, 0.0)
        lower_vols = volumes.get("pillar", []) if geo.has_pillars else [substrate]
        lower = [s for v in lower_vols for s in _faces_at(gmsh, v, 0.0)]
        for s in lower:
            match = [t for t in lens_faces if _same_face(gmsh, s, t)]
            if len(match) != 1:
                raise MeshError(f"no lens face matches contact face {s}")
            pairs.append((match[0], s, 0.0))
    if lens is not None and substrate is not None and geo.floor_radius_m is not None:
        lens_faces = _faces_at(gmsh, lens, 0.0)
        for s in _faces_at(gmsh, substrate, -H):
            if not _in_floor(gmsh, s, geo):
                continue
            match = [t for t in lens_faces if _same_face(gmsh, s, t, H)]
            if len(match) != 1:
                raise MeshError(f"no lens face matches floor face {s}")
            pairs.append((match[0], s, H))
    return volumes, pairs


def _floor_faces(occ, geo: WedgeGeometry, tops, H: float):
    """The candidate floor: the sector's disk of radius c_f less the pillars, on z = 0 (to
    imprint on the lens) and a copy on z = -h (on the substrate); ([], []) without one."""
    if geo.floor_radius_m is None:
        return [], []
    disk = _sector_disk(occ, geo.floor_radius_m / geo.focus_radius_m, geo.sector_angle)
    holes = [occ.copy([(2, t)])[0] for t in tops]
    out, _ = occ.cut([(2, disk)], holes, removeObject=True, removeTool=True)
    top = [t for d, t in out if d == 2]
    low = [occ.copy([(2, t)])[0][1] for t in top]
    occ.translate([(2, t) for t in low], 0, 0, -H)
    return top, low


def _sector_disk(occ, radius: float, alpha: float) -> int:
    """The plane face of the sector's disk of ``radius`` on z = 0 (focus units)."""
    p0 = occ.addPoint(0, 0, 0)
    p1 = occ.addPoint(radius, 0, 0)
    p2 = occ.addPoint(radius * math.cos(alpha), radius * math.sin(alpha), 0)
    loop = occ.addCurveLoop([occ.addLine(p0, p1), occ.addCircleArc(p1, p0, p2),
                             occ.addLine(p2, p0)])
    return occ.addPlaneSurface([loop])


def _in_floor(gmsh, s, geo: WedgeGeometry) -> bool:
    """Is face ``s`` (flat, at z = 0 or -h, under no pillar) within the candidate floor?"""
    com = np.array(gmsh.model.occ.getCenterOfMass(2, s))
    return bool(math.hypot(com[0], com[1]) < geo.floor_radius_m / geo.focus_radius_m)


def _only(dimtags, what):
    vols = [t for d, t in dimtags if d == 3]
    if len(vols) != 1:
        raise MeshError(f"OCC boolean split the {what} into {len(vols)} volumes")
    return vols[0]


def _faces_at(gmsh, volume, z):
    out = []
    for _, s in gmsh.model.getBoundary([(3, volume)], oriented=False):
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, s)
        if abs(z0 - z) < TOL and abs(z1 - z) < TOL:
            out.append(s)
    return out


def _face_at(gmsh, volume, z):
    faces = _faces_at(gmsh, volume, z)
    if len(faces) != 1:
        raise MeshError(f"volume {volume} has {len(faces)} faces at z = {z:g}")
    return faces[0]


def _same_face(gmsh, a, b, dz: float = 0.0) -> bool:
    """Is face ``b`` face ``a`` moved up by ``dz``?"""
    ba, bb = np.array(gmsh.model.getBoundingBox(2, a)), np.array(gmsh.model.getBoundingBox(2, b))
    ba[[2, 5]] += dz
    if np.max(np.abs(ba - bb)) > 1e-6:
        return False
    ca = np.array(gmsh.model.occ.getCenterOfMass(2, a))
    cb = np.array(gmsh.model.occ.getCenterOfMass(2, b))
    ca[2] += dz
    return bool(np.max(np.abs(ca - cb)) < 1e-6)


def _name_groups(gmsh, geo: WedgeGeometry, volumes: dict) -> dict:
    """Classify every face of every volume by position and create the physical groups.

    Returns {name: (dim, [entity tags])}."""
    f = geo.focus_radius_m
    L = geo.block_size_m / f
    H = geo.pillar_height_m / f if geo.has_pillars else 0.0
    alpha = geo.sector_angle
    n1 = np.array([-math.sin(alpha), math.cos(alpha), 0.0])
    floor = geo.floor_radius_m is not None
    groups: dict[str, tuple[int, list]] = {}

    def add(name, dim, tag):
        tags = groups.setdefault(name, (dim, []))[1]
        if tag not in tags:
            tags.append(tag)

    def points_of(s):
        pts = gmsh.model.getBoundary([(2, s)], combined=False, oriented=False, recursive=True)
        return np.array([gmsh.model.getValue(0, t, []) for _, t in pts])

    def on_plane(s, normal):
        com = np.array(gmsh.model.occ.getCenterOfMass(2, s))
        if abs(com @ normal) > TOL:
            return False
        return bool(np.all(np.abs(points_of(s) @ normal) < TOL))

    def pillar_under(s):  # its centre and its corners within the pillar's circle
        com = np.array(gmsh.model.occ.getCenterOfMass(2, s))
        for p in geo.pillars:
            c = np.array([p.x_m / f, p.y_m / f])
            if math.hypot(*(com[:2] - c)) < 1.0:
                corners = points_of(s)[:, :2] - c
                if not floor or np.all(np.hypot(*corners.T) < 1.0 + TOL):
                    return p
        return None

    for body in ("lens", "pillar", "substrate"):
        for vol in volumes.get(body, []):
            add(body, 3, vol)
            for _, s in gmsh.model.getBoundary([(3, vol)], oriented=False):
                x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, s)
                flat_z = abs(z1 - z0) < TOL
                if on_plane(s, np.array([0.0, 1.0, 0.0])):
                    add("mirror_0", 2, s), add(f"mirror_0_{body}", 2, s)
                elif on_plane(s, n1):
                    add("mirror_1", 2, s), add(f"mirror_1_{body}", 2, s)
                elif body == "lens" and flat_z and abs(z0) < TOL:
                    p = pillar_under(s) if geo.has_pillars else None
                    inside_flat = not geo.has_pillars and _is_candidate(gmsh, s, geo)
                    if p is not None:
                        add("contact_lens", 2, s), add(f"contact_lens_{p.name}", 2, s)
                    elif inside_flat:
                        add("contact_lens", 2, s)
                    elif floor and _in_floor(gmsh, s, geo):
                        add("contact_lens_floor", 2, s)
                    else:
                        add("free_lens", 2, s)
                elif body == "lens" and flat_z and abs(z0 - L) < TOL:
                    add("far_lens", 2, s)
                elif body == "pillar" and flat_z and abs(z0) < TOL:
                    p = pillar_under(s)
                    add("contact_pillar", 2, s), add(f"contact_pillar_{p.name}", 2, s)
                elif body != "lens" and flat_z and geo.has_pillars and abs(z0 + H) < TOL \
                        and pillar_under(s) is not None:
                    p = pillar_under(s)
                    add("pillar_base", 2, s), add(f"pillar_base_{p.name}", 2, s)
                elif body == "substrate" and flat_z and abs(z0 + H + L) < TOL:
                    add("far_substrate", 2, s)
                elif body == "substrate" and flat_z and not geo.has_pillars and abs(z0) < TOL \
                        and _is_candidate(gmsh, s, geo):
                    add("contact_substrate", 2, s)
                elif body == "substrate" and flat_z and floor and abs(z0 + H) < TOL \
                        and _in_floor(gmsh, s, geo):
                    add("contact_floor", 2, s)
                elif flat_z:
                    add(f"free_{body}", 2, s)
                elif body in ("lens", "substrate") and _radius_of(gmsh, s) > 0.5 * L:
                    add(f"side_{body}", 2, s)
                else:
                    add(f"free_{body}", 2, s)
    if "pillar" in volumes:
        for p in geo.pillars:
            add(f"pillar_{p.name}", 3, volumes[f"pillar_{p.name}"][0])
    for name, (dim, tags) in groups.items():
        gmsh.model.addPhysicalGroup(dim, tags, name=name)
    return groups


def _is_candidate(gmsh, s, geo) -> bool:
    """Flat geometry: is face ``s`` (on z = 0) the candidate contact sector?"""
    com = np.array(gmsh.model.occ.getCenterOfMass(2, s))
    c = geo.contact_radius_m / geo.focus_radius_m
    return bool(math.hypot(com[0], com[1]) < c)


def _radius_of(gmsh, s) -> float:
    com = np.array(gmsh.model.occ.getCenterOfMass(2, s))
    x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(2, s)
    return max(math.hypot(x1, y1), math.hypot(x0, y0), math.hypot(com[0], com[1]))


def _mesh(gmsh, geo: WedgeGeometry, pairs) -> None:
    for key in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
        gmsh.option.setNumber(f"Mesh.{key}", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)    # Frontal-Delaunay surfaces
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)  # Delaunay volumes
    gmsh.option.setNumber("Mesh.ElementOrder", 1)  # scikit-fem raises the order itself
    gmsh.option.setNumber("Mesh.Optimize", 1)
    set_size_callback(gmsh, geo.size_callback())
    for lens_face, lower_face, dz in pairs:
        if dz == 0.0:  # a pillar top (or the flat candidate) copied onto the lens
            gmsh.model.mesh.setPeriodic(2, [lens_face], [lower_face], IDENTITY)
            continue
        # The floor: the lens's face copied down by h onto the substrate.  (The other way
        # round, a lens rim curve would be the copy of both a pillar's top rim and its base.)
        shift = list(IDENTITY)
        shift[11] = -dz
        gmsh.model.mesh.setPeriodic(2, [lower_face], [lens_face], shift)
    gmsh.model.mesh.generate(3)


def _collect(gmsh, geo: WedgeGeometry, groups: dict) -> WedgeMesh:
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    points = xyz.reshape(-1, 3).T * geo.focus_radius_m

    def elements_of(dim, entity_tags, gmsh_type, nper):
        blocks = []
        for tag in entity_tags:
            types, _, nodes = gmsh.model.mesh.getElements(dim, tag)
            for t, n in zip(types, nodes):
                if t != gmsh_type:
                    raise MeshError(f"unexpected gmsh element type {t} on ({dim}, {tag})")
                blocks.append(index[n.astype(np.int64)].reshape(-1, nper).T)
        return np.hstack(blocks) if blocks else np.zeros((nper, 0), dtype=np.int64)

    # Tetrahedra once per volume entity; groups refer to them by index.
    vol_tags = sorted({t for name, (dim, tags) in groups.items() if dim == 3 for t in tags})
    tet_blocks, tet_range, start = [], {}, 0
    for v in vol_tags:
        tet = elements_of(3, [v], 4, 4)
        if tet.shape[1] == 0:
            raise MeshError(f"gmsh produced no tetrahedra in volume {v}")
        tet_blocks.append(tet)
        tet_range[v] = np.arange(start, start + tet.shape[1])
        start += tet.shape[1]
    tets = np.hstack(tet_blocks)
    subdomains = {name: np.concatenate([tet_range[t] for t in tags])
                  for name, (dim, tags) in groups.items() if dim == 3}
    face_tags = sorted({t for name, (dim, tags) in groups.items() if dim == 2 for t in tags})
    tri_blocks, tri_range, start = [], {}, 0
    for s in face_tags:
        tri = elements_of(2, [s], 2, 3)
        tri_blocks.append(tri)
        tri_range[s] = np.arange(start, start + tri.shape[1])
        start += tri.shape[1]
    triangles = np.hstack(tri_blocks) if tri_blocks else np.zeros((3, 0), dtype=np.int64)
    boundaries = {name: np.concatenate([tri_range[t] for t in tags])
                  for name, (dim, tags) in groups.items() if dim == 2}
    used = np.unique(tets)
    renumber = np.full(points.shape[1], -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    return WedgeMesh(points=points[:, used], tets=renumber[tets], triangles=renumber[triangles],
                     subdomains=subdomains, boundaries=boundaries, geometry=geo)
