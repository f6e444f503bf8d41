"""Where the elastic BEM's floor contact area parts from fem-3d on dense lattices.

``python -m validation.bench.floor_gap --out DIR [--only bem,column,coupled,fem,rule,contact]
[--phi 0.2,0.4]``

The floor-check scene that fails (Phi = 0.4, E_p/E_l = 0.1, zeta = 7 um; PHYSICS.md, "The
floor between the pillars") and a stiff-pillar one at the same floor share (Phi = 0.2,
E_p = E_l, zeta = 10 um), each measured by parts:

- bem: the elastic bem-fft's floor quantities over N (observed order, GCI), and the floor
  area's sensitivity to a floor-only gap offset (the gap error a missing term would make).
- column: the floor's displacement beside one pillar loaded on its top, the bonded pillar on
  its substrate (the Fourier FEM of the pillar compliance, mode 0) less the column model
  (the same load on the bare substrate at the base), per unit force, 1/(E_p a).
- coupled: the BEM with that excess added between the floor cells and the pillars' forces
  (symmetric: the floor's loads move the tops by the same table), against the BEM without.
- fem: fem-3d at mesh_size 2.83 with the floor's fine disk at 1/2, 1/4 and 1/8 of the
  contact element size, and at mesh_size 2 (1/2): the floor's own mesh against the rest;
  also on Phi = 0.1, E_p/E_l = 0.1, 4 um (the floor one patch).  The 1/8 floor takes 3-6
  minutes and 6-11 GiB a solve.
- rule: fem-3d's ladder with the fine floor sized by the floor patches' width as well as the
  contact size (:func:`fem_reference._floor.patch_floor_ratio`, not the driver's rule) on the
  floor-check scenes Phi = 0.2 and 0.4 (E_p/E_l = 0.1), mesh_size 4 to 2 or 1: each level's
  values, time and peak memory, the observed order and GCI, each level written as it ends,
  and the elastic bem-fft's ladder judged against it as the floor-check judges.
- contact: the same ladders with the fine floor at half the contact size (the driver's
  FLOOR_RATIO): what the patch rule changes; also the floor-check's sparser lattices (Phi =
  0.03 and 0.1) at its ladder there, mesh_size 2.83, 2, 1.41.

Writes ``bench_floor_gap.json`` and ``.md`` in DIR (each part as it finishes).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np

PARTS = ("bem", "column", "coupled", "fem", "rule", "contact")
# (Phi, E_p/E_l, zeta um): the failing floor-check scene, and stiffer pillars on a lattice
# whose floor carries the same share (~7.5 %), the floor out of reach at Phi = 0.4 (below).
SCENES = ((0.4, 0.1, 7.0), (0.2, 1.0, 10.0))
BEM_LEVELS = {(0.4, 0.1, 7.0): (16, 32, 64), (0.2, 1.0, 10.0): (16, 24, 32, 48)}
OFFSETS_NM = (0.0, 10.0, 20.0, 40.0)
FEM_LEVELS = ((2.83, 0.5), (2.83, 0.25), (2.83, 0.125), (2.0, 0.5))
# fem-3d also where the floor is one patch with holes (Phi = 0.1, E_p/E_l = 0.1, 4 um): its
# area was level-converged from 2.83 to 2 and 3.3 % below the BEM's.
FEM_SCENES = SCENES + ((0.1, 0.1, 4.0),)
# The floor rules' ladders on the floor-check's two dense lattices (both E_p/E_l = 0.1):
# Phi = 0.4 stops at mesh_size 2 (9.2 GiB), Phi = 0.2 goes a level further.
RULE_SCENES = ((0.2, 0.1, 3.5), (0.4, 0.1, 7.0))
RULE_LEVELS = {RULE_SCENES[0]: (4.0, 2.83, 2.0, 1.41), RULE_SCENES[1]: (4.0, 2.83, 2.0)}
# contact also on the floor-check's sparser lattices, at the study's ladder there.
SPARSE_SCENES = ((0.03, 1e6, 2.0), (0.1, 1.0, 4.0))
RULE_LEVELS.update(dict.fromkeys(SPARSE_SCENES, (2.83, 2.0, 1.41)))
COLUMN_RATIOS = (0.1, 1.0)       # E_p / E_s, at h / a = 0.5 (the floor-check's h/d = 0.25)
TABLE_RHO = (1.0, 1.05, 1.1, 1.2, 1.35, 1.5, 2.0, 2.5, 3.0)


def _scene(point):
    from validation.studies.floor_check import FloorPoint

    return FloorPoint(*point).scene()


def _row(r) -> dict:
    return {"F_T": r.total_force_N, "floor_share": r.floor_force_N / r.total_force_N,
            "floor_area_um2": r.floor_contact_area_m2 * 1e12,
            "floor_radius_um": r.floor_contact_radius_m * 1e6, "converged": r.converged}


def _fft(point, n, offset_m=0.0, coupling=None):
    """The elastic bem-fft at N = ``n``; ``offset_m`` added to every floor cell's gap;
    ``coupling``: (rho_m, m_per_N) the floor-pillar excess table (see :func:`column`)."""
    import bem_solver._fft as fft

    build, tops, term_cls = fft.build_grid, fft.tops_grid, fft.TopsOnlyTerm
    seen = {}

    def offset_grid(*a, **k):
        g = build(*a, **k)
        if g.floor is not None:
            g.gap0[g.floor] += offset_m
        return g

    def keep_grid(grid):
        seen["grid"] = grid
        return tops(grid)

    fft.build_grid = offset_grid
    if coupling is not None:
        fft.tops_grid = keep_grid
        coupled_term = _coupled_class()
        fft.TopsOnlyTerm = lambda term, n_cells: coupled_term(term, n_cells, seen["grid"],
                                                              *coupling)
    try:
        start = time.perf_counter()
        r = fft.solve_fft(_scene(point), n, pillars="elastic")
        return {**_row(r), "N": n, "wall_s": time.perf_counter() - start}
    finally:
        fft.build_grid, fft.tops_grid, fft.TopsOnlyTerm = build, tops, term_cls


def _coupled_class():
    from bem_solver._elastic_pillar import TopsOnlyTerm

    class Coupled(TopsOnlyTerm):
        """The tops-only term plus the excess W between floor cells and pillar forces:
        u_floor += W F_pillars, u_top(cell of j) += (W^T F_floor)_j (a measurement device,
        not a model: mode 0, one load shape per pillar)."""

        def __init__(self, term, n_cells, grid, rho_m, excess):
            import scipy.sparse as sp

            super().__init__(term, n_cells)
            n, n_p = grid.n_top, len(grid.pillar_nm)
            fx, fy = grid.colloc_x[n:], grid.colloc_y[n:]
            rows, cols, vals = [], [], []
            for j, (cx, cy) in enumerate(grid.pillar_xy):
                rr = np.hypot(fx - cx, fy - cy)
                k = np.flatnonzero(rr < rho_m[-1])
                rows.append(k)
                cols.append(np.full(k.size, j))
                vals.append(np.interp(rr[k], rho_m, excess))
            self.W = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows),
                                    np.concatenate(cols))), shape=(fx.size, n_p))
            self.WT = self.W.T.tocsr()
            self.owner, self.n_p, self.L2 = np.asarray(grid.pillar[:n]), n_p, grid.cell_size**2

        def __call__(self, q):
            u = super().__call__(q)
            n = self.n_top
            forces = np.bincount(self.owner, weights=q[:n], minlength=self.n_p) * self.L2
            u[n:] += self.W @ forces
            u[:n] += (self.WT @ (q[n:] * self.L2))[self.owner]
            return u

        def apply_few(self, index, values):
            return None  # the whole application

    return Coupled


def bem() -> dict:
    from validation.analysis.verification import study

    out = {}
    for point in SCENES:
        rows = [_fft(point, n) for n in BEM_LEVELS[point]]
        h = [1.0 / row["N"] for row in rows]
        studies = {k: study(h, [row[k] for row in rows])
                   for k in ("F_T", "floor_share", "floor_area_um2")}
        summary = {k: {"order": s["gci"]["order"], "gci_fine": s["gci"]["gci_fine"],
                       "f_exact": s["gci"]["f_exact"], "lsq_order": s["lsq"]["order"]}
                   for k, s in studies.items()}
        offsets = [{"offset_nm": d, **_fft(point, 32, d * 1e-9)} for d in OFFSETS_NM]
        out[str(point)] = {"levels": rows, "studies": summary, "offsets_N32": offsets}
    return out


def excess_table(ratio: float, height_over_radius: float = 0.5, mesh_size: float = 1.0):
    """Floor displacement beside one pillar under a unit force on its top, uniform and
    parabolic (2 (1 - r^2)), bonded pillar minus column, and the column's own: arrays over
    the floor's P2 points rho (units of a; displacements in 1/(E_p a), E_s = E_p / ratio,
    every nu = 1/2)."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import spsolve
    from skfem import Basis, ElementTriP2, ElementVector

    import fem_reference._pillar_compliance as pc

    H = float(height_over_radius)
    mesh = pc.pillar_halfspace_mesh(H, mesh_size)
    sk = mesh.to_skfem()
    ub = Basis(sk, ElementVector(ElementTriP2(), 3), intorder=4)
    pillar = pc._Body(ub, sk, mesh.subdomains["pillar"], 1.0, 0.5)
    subst = pc._Body(ub, sk, mesh.subdomains["substrate"], 1.0 / ratio, 0.5)
    ur, ut, uz = ub.split_indices()
    axis_r = ub.get_dofs("axis").all("u^1")
    far = ub.get_dofs("far").all()

    def solve(bodies, load):  # mode 0: u_t = 0, u_r = 0 on the axis, the far side fixed
        A = sum(b.blocks(0)[0] for b in bodies)
        B = sp.vstack([b.blocks(0)[1] for b in bodies])
        C = sp.block_diag([b.blocks(0)[2] for b in bodies])
        K = sp.bmat([[A, B.T], [B, C]], format="csr")
        active = np.zeros(ub.N, bool)
        for b in bodies:
            active[b.udofs] = True
        fixed = np.concatenate([np.flatnonzero(~active), far, ut, axis_r])
        free = np.setdiff1d(np.arange(K.shape[0]), fixed)
        rhs = np.zeros(K.shape[0])
        rhs[:ub.N] = load
        x = np.zeros(K.shape[0])
        x[free] = spsolve(K[free][:, free].tocsc(), rhs[free])
        return x[:ub.N]

    def line(name):
        d = ub.get_dofs(name).all("u^3")
        order = np.argsort(ub.doflocs[0, d])
        return d[order], ub.doflocs[0, d][order]

    def consistent(r, p):  # int p phi_i r dr over P2 segments (vertex, mid, vertex, ...)
        f = np.zeros(len(r))
        g, w = np.polynomial.legendre.leggauss(6)
        s = 0.5 * (g + 1.0)
        phi = ((1 - s) * (1 - 2 * s), 4 * s * (1 - s), s * (2 * s - 1))
        for k in range(0, len(r) - 2, 2):
            rr = r[k] + s * (r[k + 2] - r[k])
            for i in range(3):
                f[k + i] += np.sum(w * 0.5 * (r[k + 2] - r[k]) * p(rr) * phi[i] * rr)
        return f

    top, r_top = line("top")
    base, r_base = line("pillar_base")
    z, r = ub.doflocs[1, uz], ub.doflocs[0, uz]
    floor = uz[(np.abs(z + H) < 1e-9) & (r >= 1.0 - 1e-9) & (r < 6.0)]
    floor = floor[np.argsort(ub.doflocs[0, floor])]
    out = {"rho": ub.doflocs[0, floor]}
    for name, p in (("uniform", np.ones_like),
                    ("parabolic", lambda x: 2.0 * (1.0 - x * x))):
        on_top = consistent(r_top, p)
        total = 2.0 * np.pi * on_top.sum()   # mode 0's loads carry 1/(2 pi)
        fa, fc = np.zeros(ub.N), np.zeros(ub.N)
        fa[top] = on_top / total
        fc[base] = consistent(r_base, p) / total
        column_u = solve([subst], fc)[floor]
        out[name] = solve([pillar, subst], fa)[floor] - column_u
        out[name + "_column"] = column_u
    return out


def column() -> dict:
    out = {}
    for ratio in COLUMN_RATIOS:
        t = excess_table(ratio)
        rows = []
        for rho in TABLE_RHO:
            row = {"rho_over_a": rho}
            for k in ("uniform", "parabolic"):
                ex, col = (float(np.interp(rho, t["rho"], t[s])) for s in (k, k + "_column"))
                row.update({k: ex, k + "_relative": ex / col})
            rows.append(row)
        out[str(ratio)] = rows
    return out


def coupled() -> dict:
    out = {}
    for point in SCENES:
        scene = _scene(point)
        a, E_p = 0.5 * scene.pillars.diameter_m, scene.pillars.material.E_Pa
        t = excess_table(E_p / scene.substrate.E_Pa)
        rows = [{"shape": "none", **_fft(point, 32)}]
        for shape in ("uniform", "parabolic"):
            rows.append({"shape": shape, **_fft(point, 32, coupling=(t["rho"] * a,
                                                                     t[shape] / (E_p * a)))})
        out[str(point)] = rows
    return out


def fem() -> dict:
    out = {}
    for point in FEM_SCENES:
        out[str(point)] = [{"floor_ratio": floor_ratio,
                            **_fem_row(point, mesh_size, {"floor_ratio": floor_ratio})}
                           for mesh_size, floor_ratio in FEM_LEVELS]
    return out


def _fem_row(point, mesh_size: float, grading=None) -> dict:
    """fem-3d at ``mesh_size`` (``grading``: the driver's default where None): the floor
    quantities, the floor's element ratio, wall time, peak memory and the load average."""
    from fem_reference.solid3d.driver import solve

    start = time.perf_counter()
    r = solve(_scene(point), mesh_size, grading=grading)
    return {"mesh_size": mesh_size, **_row(r), "wall_s": time.perf_counter() - start,
            "peak_rss_GiB": r.diagnostics["peak_rss_GiB"],
            "floor_fine_radius_um": 1e6 * (r.diagnostics.get("floor_fine_radius_m") or 0.0),
            "load_average": os.getloadavg()[0]}


def rule(scenes=RULE_SCENES, out: Path | None = None, contact_size: bool = False) -> dict:
    """fem-3d's :data:`RULE_LEVELS` with the fine floor of the patch rule (with
    ``contact_size``, the driver's own: half the contact size), the elastic bem-fft on the
    floor-check's ladder, and the floor-check's verdicts on F_T, the floor's share and area.
    Each level is written to ``out`` as it ends, and levels found there (the same mesh_size
    and floor ratio) are not solved again."""
    from fem_reference._floor import floor_patch_width, patch_floor_ratio
    from fem_reference.solid3d.driver import FLOOR_RATIO
    from pillar_xval.outcome import write_atomic
    from validation.studies import floor_check as fc

    name = "contact" if contact_size else "rule"
    partial = None if out is None else out / f"bench_floor_gap_{name}_partial.json"
    report = json.loads(partial.read_text()) if partial is not None and partial.exists() else {}

    def save():
        if partial is not None:
            write_atomic(partial, json.dumps(report, indent=2))

    for point in scenes:
        p = _scene(point).pillars
        ratio = FLOOR_RATIO if contact_size else patch_floor_ratio(p.pitch_m, p.diameter_m,
                                                                    FLOOR_RATIO)
        done = {(r["mesh_size"], r["floor_ratio"]): r
                for r in report.get(str(point), {}).get("levels", [])}
        entry = report[str(point)] = {
            "patch_width_um": 1e6 * floor_patch_width(p.pitch_m, p.diameter_m),
            "floor_ratio": ratio, "levels": []}
        for mesh_size in RULE_LEVELS[point]:
            row = done.get((mesh_size, ratio)) or {
                **_fem_row(point, mesh_size, {"floor_ratio": ratio}), "floor_ratio": ratio,
                "floor_element_um": 1e6 * ratio * mesh_size / 4.0 * 0.5 * p.diameter_m}
            entry["levels"].append(row)
            print(json.dumps(row), flush=True)
            save()
        done = {r["N"]: r for r in report.get("bem " + str(point), [])}
        bem_rows = [done.get(n) or _fft(point, n) for n in fc.BEM_LEVELS]
        report["bem " + str(point)] = bem_rows
        ladders = {name: fc._ladder(model, levels, [
            {"F_T": r["F_T"], "floor_share": r["floor_share"],
             "floor_area": r["floor_area_um2"] * 1e-12} for r in rows])
            for name, model, levels, rows in (
                ("fem", "fem-3d", RULE_LEVELS[point], entry["levels"]),
                ("bem", fc.BEM_MODEL, fc.BEM_LEVELS, bem_rows))}
        entry["studies"] = {k: {q: st["gci"][q] for q in ("order", "gci_fine", "f_exact",
                                                          "status")}
                            for k, st in ladders["fem"].items()}
        entry["compared"] = {k: fc._compare(k, ladders["fem"][k], ladders["bem"][k])
                             for k in ("F_T", "floor_share", "floor_area")}
        print(json.dumps({str(point): entry["compared"]}), flush=True)
        save()
    return report


def _markdown(report: dict) -> str:
    lines = ["# Floor area: elastic BEM against fem-3d, by parts", ""]
    for part, body in report.items():
        lines += [f"## {part}", "", "```", json.dumps(body, indent=1), "```", ""]
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, type=Path)
    ap.add_argument("--only", default=",".join(PARTS),
                    help=f"comma-separated parts of {', '.join(PARTS)}")
    ap.add_argument("--phi", default=None,
                    help="rule, contact: comma-separated surface fractions of their scenes "
                         "(default all)")
    args = ap.parse_args(argv)
    parts = [p for p in args.only.split(",") if p]
    unknown = sorted(set(parts) - set(PARTS))
    if unknown:
        ap.error(f"--only = {args.only}: unknown part(s) {', '.join(unknown)}; "
                 f"allowed: {', '.join(PARTS)}")
    from pillar_xval.outcome import write_atomic

    args.out.mkdir(parents=True, exist_ok=True)
    report: dict = {}
    for part in parts:
        if part in ("rule", "contact"):
            phis = None if args.phi is None else {float(v) for v in args.phi.split(",")}
            scenes = RULE_SCENES + (SPARSE_SCENES if part == "contact" else ())
            report[part] = rule([s for s in scenes if phis is None or s[0] in phis],
                                args.out, contact_size=part == "contact")
        else:
            report[part] = {"bem": bem, "column": column, "coupled": coupled,
                            "fem": fem}[part]()
        print(json.dumps({part: report[part]}, indent=1), flush=True)
        write_atomic(args.out / "bench_floor_gap.json", json.dumps(report, indent=2))
        write_atomic(args.out / "bench_floor_gap.md", _markdown(report))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
