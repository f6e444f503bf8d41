"""Outputs of ``pillar-xval extremes``: the summary table, the heat map of pass or fail per
model and corner, the records as JSON and CSV."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from pillar_xval.outcome import write_atomic

__all__ = ["STATUSES", "counts", "heatmap", "summary_text", "write_outputs"]

# Verdicts, in the heat map's colour order.
STATUSES = ("pass", "not converged", "refused", "skipped", "fail", "error")
COLOURS = ("#2e7d32", "#f9a825", "#9e9e9e", "#d7ccc8", "#c62828", "#4a148c")
SHORT = {"pass": "pass", "not converged": "n.c.", "refused": "refused", "skipped": "skip",
         "fail": "FAIL", "error": "ERROR"}


def counts(doc: dict) -> dict:
    """Verdicts per model: {model: {status: n}}."""
    out = {m: dict.fromkeys(STATUSES, 0) for m in doc["models"]}
    for r in doc["records"]:
        out[r["model"]][r["status"]] += 1
    return out


def summary_text(doc: dict) -> str:
    """One row per corner, one column per model (verdict and time), then the counts and every
    fail, error and non-convergence with its reason."""
    models = doc["models"]
    by = {(r["corner"], r["model"]): r for r in doc["records"]}
    width = 26
    lines = [f"{'corner':<{width}}" + "".join(f"{m:>18}" for m in models), "-" * (
        width + 18 * len(models))]
    for c in doc["corners"]:
        cells = []
        for m in models:
            r = by[(c["label"], m)]
            t = r.get("wall_time_s")
            cells.append(f"{SHORT[r['status']]}{'' if t is None else f' {t:.2g}s':<8}")
        lines.append(f"{c['label']:<{width}}" + "".join(f"{x:>18}" for x in cells))
    lines += ["", "verdicts per model: " + "; ".join(
        f"{m}: " + ", ".join(f"{n} {s}" for s, n in cnt.items() if n)
        for m, cnt in counts(doc).items())]
    notable = [r for r in doc["records"] if r["status"] in ("fail", "error", "not converged")]
    if notable:
        lines.append("fail, error and not converged:")
        lines += [f"  {r['corner']} / {r['model']}: {r['status']}: {r['reason']}"
                  for r in notable]
    refusals = {}
    for r in doc["records"]:
        if r["status"] in ("refused", "skipped"):
            refusals.setdefault((r["model"], _gist(r["reason"])), []).append(r["corner"])
    if refusals:
        lines.append("refusals and cost skips (up front, with the reason):")
        lines += [f"  {m}: {why} [{len(cs)} corners]" for (m, why), cs in refusals.items()]
    return "\n".join(lines)


def _gist(reason: str) -> str:
    """A refusal's reason without its numbers, so that equal reasons group."""
    import re

    text = re.sub(r"[-+]?\d[\d.eE+-]*", "#", reason)
    return text[:140]


def heatmap(doc: dict, path: Path) -> None:
    """Verdict of each model (rows) on each corner (columns), coloured by :data:`STATUSES`."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    from ...output.report import save_figure

    models, corners = doc["models"], [c["label"] for c in doc["corners"]]
    by = {(r["corner"], r["model"]): STATUSES.index(r["status"]) for r in doc["records"]}
    grid = [[by[(c, m)] for c in corners] for m in models]
    fig, ax = plt.subplots(figsize=(max(8.0, 0.24 * len(corners) + 2.5), 1.0 + 0.5 * len(models)))
    ax.imshow(grid, cmap=ListedColormap(COLOURS), vmin=-0.5, vmax=len(STATUSES) - 0.5,
              aspect="auto", interpolation="nearest")
    ax.set_yticks(range(len(models)), models)
    ax.set_xticks(range(len(corners)), corners, rotation=90, fontsize=7)
    ax.set_xticks([x - 0.5 for x in range(1, len(corners))], minor=True)
    ax.set_yticks([y - 0.5 for y in range(1, len(models))], minor=True)
    ax.grid(which="minor", color="white", linewidth=0.8)
    ax.tick_params(which="minor", length=0)
    ax.legend(handles=[Patch(color=c, label=s) for s, c in zip(STATUSES, COLOURS)],
              loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8, frameon=False)
    ax.set_title("every model over the corners of the parameter space "
                 "(E_p/E_l, E_s/E_l, Phi, zeta/h, R, nu)", fontsize=10)
    save_figure(fig, path, 120)


CSV_COLUMNS = ("corner", "model", "status", "reason", "converged", "iterations", "residual",
               "wall_time_s", "F_T", "sigma0", "pillars", "min_pressure_ratio",
               "interpenetration_over_zeta", "force_balance", "F_increases_with_zeta",
               "F_increases_with_E")


def write_outputs(doc: dict, out: Path) -> list:
    """extremes.json, extremes.csv, summary.txt and extremes.png in ``out``."""
    out = Path(out)
    write_atomic(out / "extremes.json", json.dumps(doc, indent=1, allow_nan=False))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, extrasaction="ignore")
    w.writeheader()
    for r in doc["records"]:
        row = {**r, **r.get("checks", {})}
        w.writerow({k: ("" if row.get(k) is None else row.get(k)) for k in CSV_COLUMNS})
    write_atomic(out / "extremes.csv", buf.getvalue())
    write_atomic(out / "summary.txt", summary_text(doc) + "\n")
    heatmap(doc, out / "extremes.png")
    return ["extremes.json", "extremes.csv", "summary.txt", "extremes.png"]
