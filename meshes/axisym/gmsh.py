"""gmsh builder of the axisymmetric (r, z) meshes: lens block, pillar, substrate block.

gmsh works in units of the focus radius (its geometric tolerances are absolute, so metres
at the micrometre scale would be unsafe); points come back in metres.  Every body is its own
plane surface.  Lens and lower body share no geometric entity, so their meshes are
disconnected: the contact line is meshed twice, on identical curves with the same
orientation and the same position-only size rule, which gives node-for-node identical 1D
meshes (checked after meshing).  Pillar and substrate share the pillar-base curve, so they
are bonded by a conforming mesh.
"""

from __future__ import annotations

import numpy as np

from .._common import MeshError
from .._session import gmsh_model, set_size_callback
from .geometry import AxisymmetricGeometry
from .mesh import AxisymmetricMesh


def build_axisymmetric_mesh(geometry: AxisymmetricGeometry) -> AxisymmetricMesh:
    """Mesh ``geometry`` with linear triangles and return it with named groups.

    Parameters
    ----------
    geometry : AxisymmetricGeometry
        Bodies, sizes (m) and grading.

    Returns
    -------
    AxisymmetricMesh
        Points in metres, triangles, line elements and the physical groups by name:
        subdomains ``lens``, ``pillar``, ``substrate`` (those meshed) and boundaries
        ``contact_lens``, ``contact_pillar`` or ``contact_substrate``, with a floor segment
        ``contact_lens_floor`` and ``contact_floor``, ``pillar_base``,
        ``axis``, ``far_lens``, ``far_substrate``, ``side_lens``, ``side_substrate``,
        ``free_lens``, ``free_pillar``, ``free_substrate``.

    Raises
    ------
    MeshError
        If gmsh fails, a body gets no elements or the mesh fails its quality check.
    """
    with gmsh_model(f"axisym-{id(geometry)}", str(geometry)) as gmsh:
        gmsh.option.setNumber("Geometry.AutoCoherence", 0)  # keep the two contact lines apart
        groups = _build_geometry(gmsh, geometry)
        _mesh(gmsh, geometry)
        mesh = _collect(gmsh, geometry, groups)
    mesh.check()
    return mesh


def _build_geometry(gmsh, geo: AxisymmetricGeometry) -> dict:
    """Points, lines and surfaces in focus-radius units; returns {name: (dim, [tags])}."""
    g = gmsh.model.geo
    L = geo.block_size_m / geo.focus_radius_m
    c = geo.contact_radius_m / geo.focus_radius_m
    groups: dict[str, tuple[int, list]] = {}

    def add(name, dim, tag):
        groups.setdefault(name, (dim, []))[1].append(tag)

    def loop_surface(lines):
        return g.addPlaneSurface([g.addCurveLoop(lines)])

    cf = None if geo.floor_radius_m is None else geo.floor_radius_m / geo.focus_radius_m
    if "lens" in geo.bodies:
        p0, pc, pl = g.addPoint(0, 0, 0), g.addPoint(c, 0, 0), g.addPoint(L, 0, 0)
        pt, pa = g.addPoint(L, L, 0), g.addPoint(0, L, 0)
        bottom = [("contact_lens", g.addLine(p0, pc))]
        if cf is not None:  # same orientation as the floor line: (1, 0) -> (c_f, 0)
            pf = g.addPoint(cf, 0, 0)
            bottom += [("contact_lens_floor", g.addLine(pc, pf))]
            pc = pf
        bottom += [("free_lens", g.addLine(pc, pl))]
        rest = [g.addLine(pl, pt), g.addLine(pt, pa), g.addLine(pa, p0)]
        for name, tag in bottom + list(zip(("side_lens", "far_lens", "axis"), rest)):
            add(name, 1, tag)
        add("lens", 2, loop_surface([tag for _, tag in bottom] + rest))

    top = 0.0
    corner = None  # the pillar-base points (axis, edge), shared by pillar and substrate
    if geo.has_pillar:
        H = geo.pillar_height_m / geo.focus_radius_m
        top = -H
        q3, q2 = g.addPoint(0, -H, 0), g.addPoint(1, -H, 0)
        corner = (q3, q2)
        base = g.addLine(q3, q2)
        add("pillar_base", 1, base)
        if "pillar" in geo.bodies:
            # Same orientation as the lens contact line: (0, 0) -> (1, 0).
            q0, q1 = g.addPoint(0, 0, 0), g.addPoint(1, 0, 0)
            lines = [g.addLine(q0, q1), g.addLine(q1, q2), -base, g.addLine(q3, q0)]
            for name, tag in zip(("contact_pillar", "free_pillar", None, "axis"), lines):
                if name:
                    add(name, 1, tag)
            add("pillar", 2, loop_surface(lines))
    if "substrate" in geo.bodies:
        if corner is None:
            s0, sc = g.addPoint(0, top, 0), g.addPoint(c, top, 0)
            first = g.addLine(s0, sc)
            add("contact_substrate", 1, first)
        else:
            s0, sc = corner
            first = groups["pillar_base"][1][0]
        s1, s2, s3 = g.addPoint(L, top, 0), g.addPoint(L, top - L, 0), g.addPoint(0, top - L, 0)
        floor = []
        if cf is not None:
            sf = g.addPoint(cf, top, 0)
            floor = [("contact_floor", g.addLine(sc, sf))]
            sc = sf
        lines = [(None, first), *floor, ("free_substrate", g.addLine(sc, s1)),
                 ("side_substrate", g.addLine(s1, s2)), ("far_substrate", g.addLine(s2, s3)),
                 ("axis", g.addLine(s3, s0))]
        for name, tag in lines:
            if name:
                add(name, 1, tag)
        add("substrate", 2, loop_surface([tag for _, tag in lines]))
    if geo.has_pillar and "pillar" not in geo.bodies and "substrate" not in geo.bodies:
        groups.pop("pillar_base")  # neither body is meshed: nothing to name
    g.synchronize()
    for name, (dim, tags) in groups.items():
        gmsh.model.addPhysicalGroup(dim, tags, name=name)
    return groups


def _mesh(gmsh, geo: AxisymmetricGeometry) -> None:
    # The size comes from the position-only rule alone, so that the two contact lines,
    # identical curves, get identical nodes.
    for key in ("MeshSizeExtendFromBoundary", "MeshSizeFromPoints", "MeshSizeFromCurvature"):
        gmsh.option.setNumber(f"Mesh.{key}", 0)
    gmsh.option.setNumber("Mesh.Algorithm", 6)  # Frontal-Delaunay: good angles when graded
    gmsh.option.setNumber("Mesh.ElementOrder", 1)  # scikit-fem raises the order itself
    set_size_callback(gmsh, lambda dim, tag, x, y, z, lc: geo.size_at(x, y))
    gmsh.model.mesh.generate(2)


def _collect(gmsh, geo: AxisymmetricGeometry, groups: dict) -> AxisymmetricMesh:
    tags, xyz, _ = gmsh.model.mesh.getNodes()
    index = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    index[tags.astype(np.int64)] = np.arange(len(tags))
    points = xyz.reshape(-1, 3)[:, :2].T * geo.focus_radius_m

    def elements_of(dim, entity_tags, gmsh_type, nper):
        blocks = []
        for tag in entity_tags:
            types, _, nodes = gmsh.model.mesh.getElements(dim, abs(tag))
            for t, n in zip(types, nodes):
                if t != gmsh_type:
                    raise MeshError(f"unexpected gmsh element type {t} on ({dim}, {tag})")
                blocks.append(index[n.astype(np.int64)].reshape(-1, nper).T)
        return np.hstack(blocks) if blocks else np.zeros((nper, 0), dtype=np.int64)

    triangles, subdomains = [], {}
    lines, boundaries = [], {}
    ntri = nline = 0
    for name, (dim, entity_tags) in groups.items():
        if dim == 2:
            tri = elements_of(2, entity_tags, 2, 3)
            if tri.shape[1] == 0:
                raise MeshError(f"gmsh produced no triangles in body {name!r}")
            triangles.append(tri)
            subdomains[name] = np.arange(ntri, ntri + tri.shape[1])
            ntri += tri.shape[1]
        else:
            seg = elements_of(1, entity_tags, 1, 2)
            lines.append(seg)
            boundaries[name] = np.arange(nline, nline + seg.shape[1])
            nline += seg.shape[1]
    triangles = np.hstack(triangles)
    # Drop nodes used by no triangle (e.g. the pillar-base points when no body holds them).
    used = np.unique(triangles)
    renumber = np.full(points.shape[1], -1, dtype=np.int64)
    renumber[used] = np.arange(len(used))
    lines = renumber[np.hstack(lines)] if lines else np.zeros((2, 0), dtype=np.int64)
    return AxisymmetricMesh(points=points[:, used], triangles=renumber[triangles],
                            lines=lines, subdomains=subdomains, boundaries=boundaries,
                            geometry=geo)
