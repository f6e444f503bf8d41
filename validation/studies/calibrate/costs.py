"""The cost model: one fit of wall time and peak memory per model from the cases' samples."""

from __future__ import annotations

import math

import numpy as np


from ...registry import MODELS
from ...planner.costs import size_terms
from ...planner.tables import CostFit


def _cost_fits(samples: list) -> dict:
    """One fit per model with a cost law (its declaration's ``cost``: time =
    sum_k c_k n^p_k, :class:`validation.planner.tables.CostFit`; nonnegative coefficients,
    least squares in ln(time)), and the FFT's memory per padded point."""
    from scipy.optimize import least_squares

    fits = {}
    for model, law in ((m.name, m.cost) for m in MODELS.values() if m.cost is not None):
        size, term, powers, memory = law.size, law.term, list(law.powers), law.memory
        option = _cost_option(model)
        mine = [s for s in samples if s["model"] == model and s["wall_time_s"] > 0]
        if not mine:
            continue
        n = np.array([math.exp(s["terms"][term]) if term else 1.0 for s in mine])
        y = np.log([s["wall_time_s"] for s in mine])
        basis = np.column_stack([n**p for p in powers])

        def residual(log_c):
            return np.log(basis @ np.exp(log_c)) - y

        # start from each law's share of the largest runs
        start = [float(np.median(y))] + [float(np.median(y) - p * np.log(n.max()))
                                         for p in powers[1:]]
        sol = least_squares(residual, start)
        coef = [float(c) for c in np.exp(sol.x)]
        rms = float(np.sqrt(np.mean(sol.fun**2)))
        if memory is None:
            mem = [s["peak_memory_MB"] * 2**20 for s in mine if s["peak_memory_MB"]]
            if term == "log_points" and mem:
                pts = np.array([math.exp(s["terms"]["log_points"]) for s in mine
                                if s["peak_memory_MB"]])
                slope, fixed = np.polyfit(pts, mem, 1)
                memory = {"kind": "per_point", "fixed": float(max(fixed, 0.0)),
                          "per_point": float(max(slope, 0.0))}
            else:
                memory = {"kind": "fixed", "fixed": float(np.median(mem)) if mem else 0.0}
        fits[model] = CostFit(model, size, option, term, list(powers), coef, rms, memory,
                              len(mine), workload=dict(law.workload))
    return fits


def _cost_option(model: str) -> str | None:
    """The option a model's cost law reads: its ladder's."""
    ladder = MODELS[model].ladder
    return ladder.option if ladder is not None else None


def _cost_samples(outcomes: list) -> list:
    out = []
    for o in outcomes:
        if not o.ok:
            continue
        law = MODELS[o.case.model].cost
        size, option = (law.size, _cost_option(o.case.model)) if law else ("none", None)
        value = o.case.options.get(option) if option else None
        terms, _ = size_terms(size, o.case.scene, value)
        out.append({"model": o.case.model, "terms": terms,
                    "wall_time_s": o.timing["wall_time_s"],
                    "peak_memory_MB": o.timing.get("peak_memory_MB")})
    return out
