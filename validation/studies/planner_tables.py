"""Measured error tables and cost fits: the data the planner reads, and how it reads them.

The data files (``validation/data/error_models.json``, ``cost_models.json``) are written by
``pillar-xval calibrate`` and shipped with the package.  Everything model-specific is data:
a new model, a new rung or a new study adds candidates, tables and fits, not code.

An error table holds one measured relative error per calibration scene (a point in a
feature space, :mod:`.planner_features`) and quantity.  ``kind`` says what it measures:

- ``discretisation``: |f(option) - f_ref| / |f_ref| of one candidate (a model at one option
  value) against a converged reference of the same physics; interpolated in log10;
- ``model``: the signed relative error of a model's physics against a more complete one
  (``component`` names it: the Hooke pillar against the elastic pillar, the flat punch
  against the curved lens, a closed form against the lattice, a finite block against a
  half-space); interpolated linearly.

Interpolation is piecewise linear on the Delaunay triangulation of the points (features
scaled to [0, 1] by their measured range), and the nearest point outside it: a prediction
outside the measured range is marked ``extrapolated``.  ``loo`` holds the table's
leave-one-out misfit (90th percentile of |log10 predicted / measured| for discretisation
tables, of |predicted - measured| for model tables), the margin the planner adds.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path

import numpy as np

from scenes import InputError

__all__ = ["CostFit", "DATA_FORMAT", "ErrorTable", "PlannerData", "load_data"]

DATA_FORMAT = "pillar-xval planner data 1"
# Errors below this are round-off, not discretisation: floor of the log10 interpolation.
ERROR_FLOOR = 1e-9
LOO_QUANTILE = 0.9


@dataclass
class ErrorTable:
    """One measured error table (see the module docstring)."""

    kind: str
    models: list
    regimes: list
    features: list
    points: list
    errors: dict
    component: str = "discretisation"
    option: dict = field(default_factory=dict)
    source: str = ""
    note: str = ""
    loo: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("kind", "component", "models", "option",
                                               "regimes", "features", "points", "errors",
                                               "loo", "source", "note")}

    @property
    def log_scale(self) -> bool:
        return self.kind == "discretisation"

    def applies(self, model: str, option: dict, regime: str) -> bool:
        if model not in self.models or regime not in self.regimes:
            return False
        return all(option.get(k) == v for k, v in self.option.items())

    @cached_property
    def _scaled(self):
        pts = np.asarray(self.points, dtype=float).reshape(len(self.points), len(self.features))
        lo, hi = (pts.min(axis=0), pts.max(axis=0)) if len(pts) else (None, None)
        span = np.where(hi - lo > 0, hi - lo, 1.0) if len(pts) else None
        return pts, lo, hi, span

    def _values(self, quantity: str) -> tuple[np.ndarray, np.ndarray]:
        """(points scaled to the unit box, values) where the quantity was measured (a
        calibration scene without a converged reference of a quantity holds None)."""
        pts, lo, hi, span = self._scaled
        v = np.array([np.nan if e is None else e for e in self.errors[quantity]], dtype=float)
        keep = np.isfinite(v)
        v = v[keep]
        v = np.log10(np.maximum(np.abs(v), ERROR_FLOOR)) if self.log_scale else v
        return (pts[keep] - lo) / span, v

    def predict(self, x: dict, quantity: str) -> tuple[float, bool] | None:
        """(error, extrapolated) at features ``x``; None when the table lacks the quantity."""
        if quantity not in self.errors or not self.points:
            return None
        pts, lo, hi, span = self._scaled
        scaled, vals = self._values(quantity)
        if not len(vals):
            return None
        q = np.array([float(x[f]) for f in self.features])
        value, outside = _interpolate(scaled, vals, (q - lo) / span)
        if not self.features:
            outside = False
        else:
            outside = outside or bool(np.any(q < lo - 1e-9 * span) or
                                      np.any(q > hi + 1e-9 * span))
        return (10.0 ** value if self.log_scale else value), outside

    def margin(self, quantity: str) -> float:
        """Leave-one-out misfit: a factor (discretisation) or an absolute error (model)."""
        m = self.loo.get(quantity)
        if m is None:
            return 1.0 if self.log_scale else 0.0
        return 10.0 ** m if self.log_scale else m

    def leave_one_out(self) -> dict:
        """The LOO_QUANTILE quantile of each quantity's leave-one-out misfit."""
        out = {}
        for quantity in self.errors:
            scaled, vals = self._values(quantity)
            if len(vals) < 3:
                continue
            miss = []
            for i in range(len(vals)):
                keep = np.arange(len(vals)) != i
                v, _ = _interpolate(scaled[keep], vals[keep], scaled[i])
                miss.append(abs(v - vals[i]))
            out[quantity] = float(np.quantile(miss, LOO_QUANTILE))
        return out


def _interpolate(points: np.ndarray, values: np.ndarray, q: np.ndarray) -> tuple[float, bool]:
    """Piecewise-linear interpolation of scattered ``values`` at ``q`` (all scaled to the
    unit box); nearest neighbour outside the triangulated hull.  Returns (value, outside)."""
    n, dim = points.shape if points.ndim == 2 else (len(points), 0)
    if dim == 0 or n == 1:
        return float(np.mean(values)), False
    if dim == 1:
        order = np.argsort(points[:, 0])
        x, v = points[order, 0], values[order]
        outside = bool(q[0] < x[0] or q[0] > x[-1])
        return float(np.interp(q[0], x, v)), outside
    if n > dim:
        from scipy.interpolate import LinearNDInterpolator
        from scipy.spatial import QhullError

        try:
            value = float(LinearNDInterpolator(points, values)(q[None, :])[0])
        except (QhullError, ValueError):
            value = math.nan
        if math.isfinite(value):
            return value, False
    nearest = int(np.argmin(np.sum((points - q[None, :]) ** 2, axis=1)))
    return float(values[nearest]), True


@dataclass
class CostFit:
    """Time and memory of one model's solves on this machine.

    ln(time / s) = intercept + sum coef_k term_k, the terms given by the size function
    ``size`` of :mod:`.planner_costs` applied to the model option ``option``; ``rms`` is the
    fit's residual (natural log).  ``memory``: ``{"kind": "estimate"}`` takes the size
    function's own estimate, ``{"kind": "per_point", "fixed": B, "per_point": b}`` a line in
    the FFT's padded points, ``{"kind": "fixed", "fixed": B}`` a constant (bytes).
    """

    model: str
    size: str
    option: str | None
    terms: list
    coef: list
    intercept: float
    rms: float = 0.0
    memory: dict = field(default_factory=dict)
    samples: int = 0

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("model", "size", "option", "terms", "coef",
                                               "intercept", "rms", "memory", "samples")}

    def predict(self, scene, options: dict) -> tuple[float, float]:
        """(wall time s, peak memory bytes) of the model with ``options`` on ``scene``."""
        from .planner_costs import size_terms

        value = options.get(self.option) if self.option else None
        terms, estimate = size_terms(self.size, scene, value)
        log_t = self.intercept + sum(c * _term(terms, name) for c, name in zip(self.coef,
                                                                                 self.terms))
        kind = self.memory.get("kind", "fixed")
        if kind == "estimate" and estimate is not None:
            memory = estimate
        elif kind == "per_point":
            memory = self.memory["fixed"] + self.memory["per_point"] * math.exp(
                terms["log_points"])
        else:
            memory = self.memory.get("fixed", 0.0)
        return math.exp(log_t), float(memory)


def _term(terms: dict, name: str) -> float:
    """A fit term: a size term by name, or ``NAME^2`` its square."""
    if name.endswith("^2"):
        return terms[name[:-2]] ** 2
    return terms[name]


@dataclass
class PlannerData:
    """The candidates, error tables and cost fits the planner works from."""

    candidates: list
    tables: list
    costs: dict
    provenance: dict = field(default_factory=dict)

    def tables_for(self, model: str, option: dict, regime: str, kind: str) -> list:
        return [t for t in self.tables if t.kind == kind and t.applies(model, option, regime)]


def data_dir() -> Path:
    return Path(str(resources.files("validation") / "data"))


def load_data(folder: str | Path | None = None) -> PlannerData:
    """Read ``error_models.json`` and ``cost_models.json`` (default: the shipped ones)."""
    folder = Path(folder) if folder is not None else data_dir()
    try:
        errors = json.loads((folder / "error_models.json").read_text())
        costs = json.loads((folder / "cost_models.json").read_text())
    except FileNotFoundError as exc:
        raise InputError(f"planner data: {exc.filename} is missing; run "
                         "`pillar-xval calibrate --out validation/data` (make calibrate)") \
            from None
    for doc, name in ((errors, "error_models.json"), (costs, "cost_models.json")):
        if doc.get("format") != DATA_FORMAT:
            raise InputError(f"planner data: {folder / name} is not in the format "
                             f"{DATA_FORMAT!r}; regenerate it with make calibrate")
    return PlannerData(
        candidates=errors["candidates"],
        tables=[ErrorTable(**t) for t in errors["tables"]],
        costs={m: CostFit(**c) for m, c in costs["models"].items()},
        provenance={"errors": errors.get("provenance", {}),
                    "costs": costs.get("provenance", {})})
