"""The lattice study's report folder: summary.md and every file of :data:`OUTPUTS`."""

from __future__ import annotations

from ..targets import TARGETS
from .plots import plot_lattice, plot_profiles
from .tables import profile_csv, rings_csv, rows_csv, table_text

# The files of a report folder.
OUTPUTS = ("lattice.csv", "rings.csv", "profile.csv", "lattice.png", "profiles.png",
           "summary.md", "lattice.json")


def summary_markdown(report: dict) -> str:
    t = report["targets"]
    met = report["targets_met"]
    lines = ["# Multi-pillar cross-validation: Hooke and elastic-pillar BEMs against the "
             "elastic-pillar 3D FEM", "",
             f"- zeta = {report['zeta_um']:g} um, Table 1 lens and pillars; substrate: "
             f"{report['substrate']} (column Es of each table)",
             f"- FEM: {report['fem']['model']}, mesh_size "
             f"{', '.join(f'{v:g}' for v in report['fem']['mesh_size'])}",
             f"- BEMs: {report['bem']['model']} with the paper's Hooke pillars and with elastic "
             f"pillars (pillars = elastic), cells per diameter "
             f"{', '.join(str(v) for v in report['bem']['cells_per_diameter'])}",
             "- each value is its model's Richardson estimate (or its finest level with the "
             "spread band when the levels have no observed order)",
             f"- targets of the elastic BEM: F_T {100 * t['F_T']:g} %, sigma0 "
             f"{100 * t['sigma0']:g} %, every ring's force {100 * t['rings']:g} %, the centre "
             f"pillar's top profile along theta = 0 {100 * t['profile']:g} % at r / (d/2) = "
             + ", ".join(f"{x:g}" for x in t["profile_points_over_radius"])
             + f"; {t['rule']}", "",
             f"**{met['text']}.**", "",
             "```", table_text(report), "```", ""]
    for key, name in (("quantities", "Hooke"), ("elastic_quantities", "elastic")):
        sig = [f"{r.get('title') or r['surface_fraction']}: "
               + ", ".join(k for k, d in r[key].items() if d["significant"])
               for r in report["rows"] if r.get(key)
               and any(d["significant"] for d in r[key].values())]
        lines.append(f"Differences beyond both bands (modelling error of the {name} pillar):")
        lines += [f"- {s}" for s in sig] or ["- none"]
        lines.append("")
    missed = []
    for r in report["rows"]:
        tg = r.get("targets") or {}
        bad = [k for k in TARGETS if (tg.get(k) or {}).get("met") is not True]
        if bad:
            missed.append(f"{r.get('title') or r['surface_fraction']}: " + ", ".join(
                f"{k} {'not judged' if tg[k]['met'] is None else 'missed'}" for k in bad))
    lines.append("Elastic-BEM targets not met:")
    lines += [f"- {s}" for s in missed] or ["- none"]
    failed = [r for r in report["rows"] if r["status"] != "ok"]
    if failed:
        lines += ["", "**Not converged or failed:** " + "; ".join(
            f"{r.get('title') or r['surface_fraction']}: {r['status']}" for r in failed)]
    return "\n".join(lines) + "\n"


def write_report(report: dict, out) -> list[str]:
    """The report folder, lattice.json last (its presence means a whole report)."""
    import json
    from pathlib import Path

    from pillar_xval.outcome import write_atomic

    out = Path(out)
    write_atomic(out / "lattice.csv", rows_csv(report))
    write_atomic(out / "rings.csv", rings_csv(report))
    write_atomic(out / "profile.csv", profile_csv(report))
    plot_lattice(report, out / "lattice.png")
    plot_profiles(report, out / "profiles.png")
    write_atomic(out / "summary.md", summary_markdown(report))
    write_atomic(out / "lattice.json", json.dumps(report, indent=2, allow_nan=False))
    return list(OUTPUTS)
