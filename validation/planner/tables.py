"""Measured error tables and cost fits: the data the planner reads, and how it reads them.

The data files (``validation/planner/data/error_models.json``, ``cost_models.json``) are written by
``pillar-xval calibrate`` and shipped with the package; entries whose ``source`` (``note``
for costs) starts with "hand" are written by hand from validation studies until calibrate
measures them (fem-3d, the elastic-pillar BEMs), and calibrate carries them over.  A
candidate may name its ``physics`` (the components it does not carry: ``plan.REMOVED_BY``)
and its ``cost`` (a key of the cost models: a fit, or a :class:`ScaledCost` variant).  Everything model-specific is data:
a new model, a new rung or a new study adds candidates, tables and fits, not code.

An error table holds one measured relative error per calibration scene (a point in a
feature space, :mod:`.features`) and quantity.  ``kind`` says what it measures:

- ``discretisation``: (f(option) - f_ref) / |f_ref| of one candidate (a model at one option
  value) against a converged reference of the same physics; its magnitude interpolated in
  log10;
- ``model``: the signed relative error of a model's physics against a more complete one
  (``component`` names it: the Hooke pillar against the elastic pillar, the flat punch
  against the curved lens, a closed form against the lattice, a finite block against a
  half-space); interpolated linearly.

Interpolation is piecewise linear on the Delaunay triangulation of the points (features
scaled to [0, 1] by their measured range), and the nearest point outside it: a prediction
outside the measured range is marked ``extrapolated``.  ``loo`` holds each point's
leave-one-out misfit (|log10 predicted / measured| for discretisation tables, |predicted -
measured| for model tables; on a tensor grid, along its grid lines); interpolated at a
scene's features it is the local margin the planner adds to a prediction, so rough
regions of a table carry wide margins and smooth ones narrow.

A measured table is ``signed`` (a hand bound is not): its errors carry their sign, and
:meth:`ErrorTable.sign` gives a quantity's systematic sign, the one that at least
``sign_share`` of its measured points share (policy), or 0.  The planner uses it to add a
discretisation error and a model error with their signs (:func:`.plan.combined_error`).
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path

import numpy as np

__all__ = ["CostFit", "DATA_FORMAT", "ErrorTable", "PlannerData", "ScaledCost", "load_data",
           "machine_data"]

DATA_FORMAT = "pillar-xval planner data 1"
# Errors below this are round-off, not discretisation: floor of the log10 interpolation.
ERROR_FLOOR = 1e-9
# Discretisation misfits are counted where the measured error is at least this: below it a
# factor-2 misprediction cannot carry an error past any useful tolerance.
LOO_RELEVANT = 1e-3
# The planner's margin: the local leave-one-out misfit times ``margin_scale``.  A table's
# error has a systematic sign when at least ``sign_share`` of its measured points share it
# (ErrorTable.sign).  On the calibration the Hooke BEMs' discretisation errors on one pillar
# and on lattices are one-signed (F_T low at 97-99 % of the points, sigma0 high at 100 %), the
# Hooke pillar's sigma0 error mostly negative (81 % of the Gecit grid, 94 % of the lattice
# study) and its F_T error of either sign (58-63 % one way): 0.75 separates the groups.
DEFAULT_POLICY = {"margin_scale": 1.0, "sign_share": 0.75}
# A sign seen at fewer points is not called systematic (a one-point table, e.g. fem-axisym's
# truncation, has one sign by construction).
SIGN_MIN_POINTS = 10
EXTRAPOLATION_SLACK = 0.05


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
    signed: bool = False

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("kind", "component", "models", "option",
                                               "regimes", "features", "points", "errors",
                                               "loo", "signed", "source", "note")}

    def sign(self, quantity: str, share: float) -> int:
        """+1 or -1 when at least ``share`` of the quantity's measured non-zero errors (and
        :data:`SIGN_MIN_POINTS` of them) have that sign: a systematic sign; else 0, and 0 for a
        table that is not ``signed``."""
        if not self.signed or quantity not in self._positive_shares:
            return 0
        up, count = self._positive_shares[quantity]
        if count < SIGN_MIN_POINTS:
            return 0
        return 1 if up >= share else -1 if 1.0 - up >= share else 0

    @cached_property
    def _positive_shares(self) -> dict:
        """Per quantity: (share of the measured non-zero errors that are positive, their
        count), counted once (every plan asks every table)."""
        out = {}
        for quantity, raw in self.errors.items():
            v = np.array([e for e in raw if e is not None], dtype=float)
            v = v[np.isfinite(v) & (v != 0.0)]
            out[quantity] = (float(np.mean(v > 0)) if len(v) else 0.0, len(v))
        return out

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
        value, _ = _interpolate(scaled, vals, (q - lo) / span)
        # Beyond the measured range by more than EXTRAPOLATION_SLACK of it: extrapolated
        # (inside the range but outside the triangulation, the nearest point stands in).
        slack = EXTRAPOLATION_SLACK * span
        outside = bool(self.features) and bool(np.any(q < lo - slack) or np.any(q > hi + slack))
        return (10.0 ** value if self.log_scale else value), outside

    def margin(self, quantity: str, x: dict, scale: float = 1.0) -> float:
        """The local leave-one-out misfit at ``x`` (the misfits of the measured points,
        interpolated like the errors), times ``scale``: a factor for discretisation tables,
        an absolute error for model ones; none (1 or 0) where it was not measured."""
        misfits = self.loo.get(quantity)
        none = 1.0 if self.log_scale else 0.0
        if not misfits:
            return none
        pts, lo, hi, span = self._scaled
        m = np.array([np.nan if v is None else v for v in misfits], dtype=float)
        keep = np.isfinite(m)
        if not keep.any():
            return none
        q = np.array([float(x[f]) for f in self.features])
        value, _ = _interpolate((pts[keep] - lo) / span, m[keep], (q - lo) / span)
        value = max(value, 0.0) * scale
        return 10.0 ** value if self.log_scale else value

    def leave_one_out(self) -> dict:
        """Each measured point's leave-one-out misfit (the point predicted from the others):
        |log10 ratio| in discretisation tables, where the measured error is at least
        :data:`LOO_RELEVANT` (None below); |difference| in model tables.  Lists aligned with
        ``errors``; a quantity measured on fewer than three points has none.

        On a tensor grid (:func:`_grid_interpolate`) a node is predicted along the grid
        lines through it (:meth:`_GridLines.misfit`): the misfit of the multilinear
        interpolation the planner does, not the step to the nearest node that the grid
        left with a hole would give.  Elsewhere (and at a grid's corners) the others'
        interpolant predicts the point."""
        out = {}
        pts, lo, hi, span = self._scaled
        for quantity, raw in self.errors.items():
            v = np.array([np.nan if e is None else e for e in raw], dtype=float)
            idx = np.nonzero(np.isfinite(v))[0]
            if len(idx) < 3:
                continue
            vals = np.log10(np.maximum(np.abs(v), ERROR_FLOOR)) if self.log_scale else v
            scaled = (pts - lo) / span
            grid = _GridLines(scaled[idx]) if _grid_interpolate(
                scaled[idx], vals[idx], scaled[idx[0]]) is not None else None
            miss = [None] * len(raw)
            for i in idx:
                if self.log_scale and vals[i] < np.log10(LOO_RELEVANT):
                    continue
                misfit = None if grid is None else \
                    grid.misfit(vals[idx], int(np.searchsorted(idx, i)))
                if misfit is None:
                    others = idx[idx != i]
                    pred, _ = _interpolate(scaled[others], vals[others], scaled[i])
                    misfit = float(abs(pred - vals[i]))
                miss[i] = misfit
            out[quantity] = miss
        return out


class _GridLines:
    """The grid lines of a tensor grid of points (scaled), set up once per table."""

    def __init__(self, points: np.ndarray):
        self.axes = [np.unique(np.round(points[:, k], 12)) for k in range(points.shape[1])]
        self.nodes = np.round(points, 12)
        self.where = {tuple(p): j for j, p in enumerate(self.nodes)}

    def misfit(self, values: np.ndarray, i: int) -> float | None:
        """Leave-one-out misfit of node ``i``: for each axis along which the node has
        measured neighbours on both sides, e_k = |linear interpolation between them -
        value|; returned as sum_k e_k / 4, the size of the multilinear interpolation's error
        in a cell of the grid that these second differences imply (interpolating over 2 h
        misses by ~h^2 f''_k / 2, a cell's centre by sum_k h^2 f''_k / 8).  None where the
        node has two neighbours along no axis (a corner: the caller predicts it from the
        others)."""
        node = self.nodes[i]
        misfits = []
        for k, a in enumerate(self.axes):
            j = int(np.searchsorted(a, node[k]))
            if not 0 < j < len(a) - 1:
                continue
            below, above = node.copy(), node.copy()
            below[k], above[k] = a[j - 1], a[j + 1]
            jb, ja = self.where.get(tuple(below)), self.where.get(tuple(above))
            if jb is None or ja is None:
                continue
            f = (node[k] - a[j - 1]) / (a[j + 1] - a[j - 1])
            misfits.append(abs((1.0 - f) * values[jb] + f * values[ja] - values[i]))
        return float(sum(misfits) / 4.0) if misfits else None


def _interpolate(points: np.ndarray, values: np.ndarray, q: np.ndarray) -> tuple[float, bool]:
    """Piecewise-linear interpolation of scattered ``values`` at ``q`` (all scaled to the
    unit box): multilinear on a tensor grid (:func:`_grid_interpolate`), else on the Delaunay
    triangulation; nearest neighbour outside it.  Returns (value, outside)."""
    n, dim = points.shape if points.ndim == 2 else (len(points), 0)
    if dim == 0 or n == 1:
        return float(np.mean(values)), False
    if dim == 1:
        order = np.argsort(points[:, 0])
        x, v = points[order, 0], values[order]
        outside = bool(q[0] < x[0] or q[0] > x[-1])
        return float(np.interp(q[0], x, v)), outside
    grid = _grid_interpolate(points, values, q)
    if grid is not None:
        return grid
    if n > dim:
        linear = _triangulated(points, values)
        value = math.nan if linear is None else float(linear(q[None, :])[0])
        if math.isfinite(value):
            return value, False
    nearest = int(np.argmin(np.sum((points - q[None, :]) ** 2, axis=1)))
    return float(values[nearest]), True


# Triangulated interpolants kept for reuse (a plan interpolates the same tables at every
# scene; building one, and its first evaluation, costs milliseconds, a lookup microseconds).
TRIANGULATION_CACHE = 512
_TRIANGULATIONS: OrderedDict = OrderedDict()
_TRIANGULATIONS_LOCK = threading.Lock()


def _triangulated(points: np.ndarray, values: np.ndarray):
    """The piecewise-linear interpolant of ``values`` on the Delaunay triangulation of
    ``points`` (None where Qhull cannot triangulate them), built once per (points, values)
    and kept in a bounded cache: the same interpolant, so the same values, as a fresh one."""
    key = (points.shape, points.tobytes(), values.tobytes())
    with _TRIANGULATIONS_LOCK:
        if key in _TRIANGULATIONS:
            _TRIANGULATIONS.move_to_end(key)
            return _TRIANGULATIONS[key]
    from scipy.interpolate import LinearNDInterpolator
    from scipy.spatial import QhullError

    try:
        linear = LinearNDInterpolator(points, values)
    except (QhullError, ValueError):
        linear = None
    with _TRIANGULATIONS_LOCK:
        _TRIANGULATIONS[key] = linear
        while len(_TRIANGULATIONS) > TRIANGULATION_CACHE:
            _TRIANGULATIONS.popitem(last=False)
    return linear


# A table is a tensor grid when its points take few distinct values per feature and fill at
# least this share of their combinations (failed calibration cases leave holes).
GRID_FILL = 0.6


def _grid_interpolate(points, values, q):
    """Multilinear interpolation when the points lie on a tensor grid (a Gecit-like study):
    a triangulation of an anisotropic grid makes long thin simplices that mix far rows.  The
    cell's missing corners are left out and the weights renormalised (all missing: each
    takes the nearest measured node on its grid lines, :func:`_along_grid_lines`); outside
    the grid the query is clamped to it.  None when the points are no grid."""
    axes = [np.unique(np.round(points[:, k], 12)) for k in range(points.shape[1])]
    cells = math.prod(len(a) for a in axes)
    if any(len(a) < 2 for a in axes) or cells > 10 * len(points) or \
            len(points) < GRID_FILL * cells:
        return None
    index = tuple(np.searchsorted(a, np.round(points[:, k], 12)) for k, a in enumerate(axes))
    table = np.full([len(a) for a in axes], np.nan)
    table[index] = values
    if np.count_nonzero(np.isfinite(table)) != len(values):
        return None  # repeated points: not a grid
    outside = False
    lower, frac = [], []
    for k, a in enumerate(axes):
        x = float(np.clip(q[k], a[0], a[-1]))
        outside |= x != q[k]
        i = min(int(np.searchsorted(a, x, side="right")) - 1, len(a) - 2)
        lower.append(i)
        frac.append((x - a[i]) / (a[i + 1] - a[i]))
    total = weight = 0.0
    missing = []
    for corner in np.ndindex(*(2,) * len(axes)):
        at = tuple(i + c for i, c in zip(lower, corner))
        w = math.prod(f if c else 1.0 - f for f, c in zip(frac, corner))
        if np.isfinite(table[at]) and w > 0:
            total += w * table[at]
            weight += w
        elif w > 0:
            missing.append((at, w))
    if weight <= 1e-12:
        # Every corner that counts is missing (a part of the grid measured at fewer points,
        # such as one substrate convention at one indentation): each takes the nearest
        # measured node along one grid line through it; none at all: the nearest point.
        order = _smoothest_axes(table)
        for at, w in missing:
            v = _along_grid_lines(table, axes, at, order)
            if v is not None:
                total += w * v
                weight += w
        if weight <= 1e-12:
            return float(values[np.argmin(np.sum((points - q[None, :]) ** 2, axis=1))]), True
        return total / weight, True
    return total / weight, outside


def _smoothest_axes(table: np.ndarray) -> list:
    """The grid's axes from the one on which the table changes least from node to node (the
    median |difference| of measured neighbours) to the one on which it changes most."""
    roughness = []
    for k in range(table.ndim):
        steps = np.abs(np.diff(table, axis=k))
        steps = steps[np.isfinite(steps)]
        roughness.append(float(np.median(steps)) if steps.size else math.inf)
    return sorted(range(table.ndim), key=lambda k: roughness[k])


def _along_grid_lines(table: np.ndarray, axes: list, at: tuple, order: list) -> float | None:
    """A value for the missing grid node ``at`` from the grid lines through it: along the
    first axis of ``order`` (:func:`_smoothest_axes`), the nearest measured node; the next
    axis where that line holds none; None when no line does.  (A sparser part of a grid,
    such as the E_s = E_p rows at one indentation, then borrows along the indentation or
    substrate axis, not across the stiffness ratio, where the errors change by decades.)"""
    for k in order:
        found = [(abs(j - at[k]), float(table[at[:k] + (j,) + at[k + 1:]]))
                 for j in range(len(axes[k])) if j != at[k]
                 and np.isfinite(table[at[:k] + (j,) + at[k + 1:]])]
        if found:
            return min(found)[1]
    return None


@dataclass
class CostFit:
    """Time and memory of one model's solves, carried to this machine.

    time (s) = sum_k coef_k n^powers_k with n = exp(``term``) of the size function ``size``
    of :mod:`.costs` applied to the model option ``option`` (n: the dense BEM's
    unknowns, the FFT's padded points, the FEM's unknowns; a constant for closed forms), so
    that a fixed start-up, assembly (n^2) and dense solves (n^3) each keep their own law when
    extrapolated; ``rms`` is the fit's residual in ln(time).  Those are seconds of the machine
    it was measured on, whose calibration ``machine`` holds (``{"threads", "seconds"}``, the
    document's unless the fit has its own); ``workload`` says which reference workloads of
    :mod:`.machine` its time follows (shares summing to 1), and ``here`` (set by
    :func:`.machine_data`, never stored) this machine's seconds of them: the prediction is
    the time times :func:`.machine.speed_factor` (1 without a calibration).  ``memory``:
    ``{"kind": "estimate"}`` takes the size function's own estimate,
    ``{"kind": "per_point", "fixed": B, "per_point": b}`` a line in the FFT's padded points,
    ``{"kind": "fixed", "fixed": B}`` a constant (bytes).
    """

    model: str
    size: str
    option: str | None
    term: str | None
    powers: list
    coef: list
    rms: float = 0.0
    memory: dict = field(default_factory=dict)
    samples: int = 0
    note: str = ""
    workload: dict = field(default_factory=dict)
    machine: dict = field(default_factory=dict)
    here: dict | None = field(default=None, compare=False, repr=False)

    def to_dict(self) -> dict:
        out = {k: getattr(self, k) for k in ("model", "size", "option", "term", "powers",
                                              "coef", "rms", "memory", "samples", "workload")}
        if self.note:
            out["note"] = self.note
        return out

    def time(self, n: float) -> float:
        return float(sum(c * n**p for c, p in zip(self.coef, self.powers)))

    @property
    def speed(self) -> float:
        """Time here over time on the fit's machine (:func:`.machine.speed_factor`)."""
        from .machine import speed_factor

        return speed_factor(self.workload, self.machine, self.here)

    def setup_time(self, scene) -> float:
        """Seconds of a one-off set-up still to pay on ``scene`` (none for a fit)."""
        return 0.0

    def predict(self, scene, options: dict, regime: str | None = None) -> tuple[float, float]:
        """(wall time s, peak memory bytes) of the model with ``options`` on ``scene``."""
        from .costs import size_terms

        value = options.get(self.option) if self.option else None
        terms, estimate = size_terms(self.size, scene, value)
        n = math.exp(terms[self.term]) if self.term else 1.0
        kind = self.memory.get("kind", "fixed")
        if kind == "estimate" and estimate is not None:
            memory = estimate
        elif kind == "per_point":
            memory = self.memory["fixed"] + self.memory["per_point"] * math.exp(
                terms["log_points"])
        else:
            memory = self.memory.get("fixed", 0.0)
        return self.time(n) * self.speed, float(memory)


@dataclass
class ScaledCost:
    """A variant of a measured model: its ``base`` fit's time times ``factor`` (one number,
    or one per regime with ``"default"``), the base's memory, plus a one-off ``setup``
    (``{"kind": K, "time_s": t, "workload": {...}}``, :data:`.costs.SETUPS`: t seconds of
    the base's machine, carried here by its own workload, unless already paid on the scene,
    e.g. the elastic pillar's compliance in the disk cache).  Written by hand where a
    variant's own timings are a ratio measured against its base (``note`` says where)."""

    key: str
    base_fit: CostFit
    factor: float | dict = 1.0
    setup: dict = field(default_factory=dict)
    note: str = ""

    @property
    def model(self) -> str:
        return self.base_fit.model

    @property
    def option(self) -> str | None:
        return self.base_fit.option

    def to_dict(self) -> dict:
        return {"base": self.base_fit.model, "factor": self.factor, "setup": self.setup,
                "note": self.note}

    def _factor(self, regime: str | None) -> float:
        if isinstance(self.factor, dict):
            return float(self.factor.get(regime, self.factor["default"]))
        return float(self.factor)

    def setup_time(self, scene) -> float:
        from .costs import SETUPS

        if not self.setup:
            return 0.0
        from .machine import speed_factor

        paid = SETUPS[self.setup["kind"]](scene)
        speed = speed_factor(self.setup.get("workload", {}), self.base_fit.machine,
                             self.base_fit.here)
        return 0.0 if paid else float(self.setup["time_s"]) * speed

    def predict(self, scene, options: dict, regime: str | None = None) -> tuple[float, float]:
        """(wall time s, peak memory bytes): the base's, the time scaled, the set-up added."""
        time_s, memory = self.base_fit.predict(scene, options, regime)
        return time_s * self._factor(regime) + self.setup_time(scene), memory


@dataclass
class PlannerData:
    """The candidates, error tables and cost fits the planner works from."""

    candidates: list
    tables: list
    costs: dict
    provenance: dict = field(default_factory=dict)
    policy: dict = field(default_factory=lambda: dict(DEFAULT_POLICY))

    def tables_for(self, model: str, option: dict, regime: str, kind: str) -> list:
        """The tables of ``kind`` that apply, the most specific first (the most option
        keys: a table of the elastic-pillar rung before the same rung's Hooke table)."""
        found = [t for t in self.tables if t.kind == kind and t.applies(model, option, regime)]
        return sorted(found, key=lambda t: -len(t.option))


def machine_data(data: "PlannerData", here: dict | None) -> "PlannerData":
    """``data`` with this machine's seconds per workload (``here``, from
    :func:`.machine.seconds_here`) given to every fit: its predictions carried here; the
    same object where ``here`` is None."""
    if here is None:
        return data
    from dataclasses import replace

    costs = {}
    for key, fit in data.costs.items():
        if isinstance(fit, ScaledCost):
            base = replace(fit.base_fit, here=here)
            costs[key] = replace(fit, base_fit=base)
        else:
            costs[key] = replace(fit, here=here)
    return replace(data, costs=costs)


def data_dir() -> Path:
    return Path(str(resources.files("validation.planner") / "data"))


def load_data(folder: str | Path | None = None) -> PlannerData:
    """Read ``error_models.json`` and ``cost_models.json`` (default: the shipped ones),
    every entry checked first (:mod:`.data_checks`: a damaged file is one line naming it and
    the entry)."""
    from .data_checks import check_cost_models, check_error_models, read_json

    folder = Path(folder) if folder is not None else data_dir()
    errors = read_json(folder / "error_models.json")
    costs = read_json(folder / "cost_models.json")
    check_error_models(errors, folder / "error_models.json")
    check_cost_models(costs, folder / "cost_models.json")
    fits = {m: CostFit(**{"machine": costs.get("machine", {}), **c})
            for m, c in costs["models"].items()}
    for key, c in costs.get("variants", {}).items():
        fits[key] = ScaledCost(key, fits[c["base"]], c.get("factor", 1.0), c.get("setup", {}),
                               c.get("note", ""))
    return PlannerData(
        candidates=errors["candidates"],
        tables=[ErrorTable(**t) for t in errors["tables"]],
        costs=fits,
        provenance={"errors": errors.get("provenance", {}),
                    "costs": costs.get("provenance", {})},
        policy={**DEFAULT_POLICY, **errors.get("policy", {})})
