"""The hand entries of the installed planner data (``source``/``note`` starting with
"hand"), which a calibration that does not measure them carries over."""

from __future__ import annotations

import json
from pathlib import Path





HAND = "hand"


def is_hand(entry: dict, key: str = "source") -> bool:
    """Whether a data entry (candidate, table, cost fit) was written by hand, not measured."""
    return str(entry.get(key, "")).startswith(HAND)


def keep_hand_entries(errors: dict, costs: dict, folder: Path | None = None) -> None:
    """Carry the installed data's hand entries (``source``/``note`` starting with "hand":
    fem-3d and the elastic-pillar BEMs as candidates) into a new calibration that
    does not measure them yet: candidates, error tables, cost fits and cost variants that the
    calibration did not write itself.  ``folder``: the installed data (default the
    package's)."""
    from ...planner.tables import data_dir

    folder = Path(folder) if folder is not None else data_dir()
    try:
        old_errors = json.loads((folder / "error_models.json").read_text())
        old_costs = json.loads((folder / "cost_models.json").read_text())
    except (OSError, ValueError):
        return
    labels = {c["label"] for c in errors["candidates"]}
    errors["candidates"] = list(errors["candidates"]) + [
        c for c in old_errors.get("candidates", ())
        if is_hand(c) and c["label"] not in labels]
    def measured(t):  # the calibration measured this table itself (e.g. from the lattice),
        # or a more specific one that holds it: an elastic rung's whole error against fem-3d
        # holds the coupling a hand bound stood for
        def covers(m):
            same = m.get("component") == t.get("component") and m.get("option") == t.get("option")
            specific = m.get("source", "").startswith("lattice") and t.get("option") and \
                t["option"].items() < m.get("option", {}).items()
            return (same or specific) and set(m.get("regimes", ())) & set(t.get("regimes", ())) \
                and set(m.get("models", ())) & set(t.get("models", ()))
        return any(covers(m) for m in errors["tables"])

    errors["tables"] = list(errors["tables"]) + [
        t for t in old_errors.get("tables", ()) if is_hand(t)
        and t not in errors["tables"] and not measured(t)]
    for name, fit in old_costs.get("models", {}).items():
        if name not in costs["models"] and is_hand(fit, "note"):
            # its seconds are of the machine the installed data was measured on
            costs["models"][name] = {"machine": old_costs.get("machine", {}), **fit}
    variants = {k: v for k, v in old_costs.get("variants", {}).items()
                if is_hand(v, "note") and v["base"] in costs["models"]}
    if variants:
        costs["variants"] = variants
    hand = old_errors.get("provenance", {}).get("hand_entries")
    if hand:
        errors["provenance"] = {**errors["provenance"], "hand_entries": hand}
