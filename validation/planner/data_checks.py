"""The planner's data files checked when they are read, before any planning.

``error_models.json`` and ``cost_models.json`` (:mod:`.tables`) are written by ``calibrate``
and edited by hand; a damaged one (truncated, a key missing, a NaN, a negative cost) once
failed as an internal error without naming the file, after a plan of 30 s, or was read and
changed the plans.  Every entry is checked against what the planner does with it, and the
first that is wrong is refused as an :class:`~pillar_xval.scenes.InputError` in one line
naming the file and the entry (``tables[3].errors.F_T[2] = nan: ...``).

What is checked: the format; the policy (``margin_scale`` a finite number >= 0,
``sign_share`` in (0.5, 1]); each candidate's model, options, label and regimes; each error
table's kind, models, regimes, features (those :mod:`.features` computes), its points (finite,
one coordinate per feature) and, per quantity (those the registry compares), its errors
(finite or null, one per point) and leave-one-out misfits (finite and >= 0, or null); each
cost fit's size function, powers and coefficients (finite, a coefficient >= 0, as many as
powers), residual, memory law, sample count and workload shares (known reference workloads,
in (0, 1], summing to 1); each cost variant's base, factor (> 0) and set-up (a known kind, a
time >= 0, its workload); the reference machine's seconds (> 0).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from pillar_xval.scenes import InputError

__all__ = ["read_json", "check_cost_models", "check_error_models"]

REGIMES = ("flat", "single", "multi")
TABLE_KINDS = ("discretisation", "model")
# The numbers each memory law needs (a fixed law without one takes 0 bytes).
MEMORY_KINDS = {"estimate": (), "fixed": (), "per_point": ("fixed", "per_point")}


class _Bad(Exception):
    """An entry and what is wrong with it: ``where`` and ``what`` ("= nan: ..." after a
    value, ": ..." otherwise)."""

    def __init__(self, where: str, what: str):
        super().__init__(f"{where} {what}" if what.startswith("=") else f"{where}: {what}")


def read_json(path: Path) -> dict:
    """The JSON document of ``path``; InputError naming the file when it is missing, cannot
    be read or is not a JSON object."""
    try:
        doc = json.loads(path.read_text())
    except FileNotFoundError:
        raise InputError(f"planner data: {path} is missing; run `pillar-xval calibrate --out "
                         "validation/planner/data` (make calibrate)") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"planner data: {path}: cannot be read ({exc})") from None
    except (ValueError, RecursionError) as exc:
        raise InputError(f"planner data: {path}: not valid JSON ({exc}); regenerate it with "
                         "make calibrate") from None
    if not isinstance(doc, dict):
        raise InputError(f"planner data: {path}: not a JSON object")
    return doc


def check_error_models(doc: dict, path: Path) -> None:
    """Refuse ``doc`` (``error_models.json`` read from ``path``) at its first bad entry."""
    _checked(_error_models, doc, path)


def check_cost_models(doc: dict, path: Path) -> None:
    """Refuse ``doc`` (``cost_models.json`` read from ``path``) at its first bad entry."""
    _checked(_cost_models, doc, path)


def _checked(check, doc: dict, path: Path) -> None:
    from .tables import DATA_FORMAT

    if doc.get("format") != DATA_FORMAT:
        raise InputError(f"planner data: {path} is not in the format {DATA_FORMAT!r}; "
                         "regenerate it with make calibrate")
    try:
        check(doc)
    except _Bad as exc:
        raise InputError(f"planner data: {path}: {exc}; regenerate it with make calibrate "
                         "or mend that entry") from None


# --- the pieces --------------------------------------------------------------------------
def _get(table: dict, key: str, where: str):
    if not isinstance(table, dict):
        raise _Bad(where, f"expected an object, got {_show(table)}")
    if key not in table:
        raise _Bad(where, f"the key {key!r} is missing")
    return table[key]


def _show(value) -> str:
    text = json.dumps(value, allow_nan=True) if not isinstance(value, float) else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _number(value, where: str, low: float | None = None, above: float | None = None,
            high: float | None = None) -> float:
    finite = (isinstance(value, (int, float)) and not isinstance(value, bool)
              and math.isfinite(value))
    if finite and (low is None or value >= low) and (above is None or value > above) and \
            (high is None or value <= high):
        return float(value)
    left = f"[{low:g}" if low is not None else f"({above:g}" if above is not None else "(-inf"
    allowed = f"{left}, {f'{high:g}]' if high is not None else 'inf)'}"
    if not finite:
        raise _Bad(where, f"= {_show(value)}: expected a finite number"
                          + ("" if allowed == "(-inf, inf)" else f" in {allowed}"))
    raise _Bad(where, f"= {_show(value)}: allowed range is {allowed}")


def _numbers(values: list, where: str, low: float | None = None, nulls: bool = False) -> None:
    """:func:`_number` on each entry of ``values`` (or null, with ``nulls``); the list checked
    at once (a table holds hundreds), entry by entry only to name the first bad one."""
    kinds = {float, int, type(None)} if nulls else {float, int}
    if {type(v) for v in values} <= kinds:
        given = [v for v in values if v is not None]
        if all(map(math.isfinite, given)) and (low is None or not given or min(given) >= low):
            return
    for j, v in enumerate(values):
        if v is not None or not nulls:
            _number(v, f"{where}[{j}]", low=low)


def _typed(value, kind, where: str, what: str):
    if not isinstance(value, kind) or (isinstance(value, bool) and kind is not bool):
        raise _Bad(where, f"= {_show(value)}: expected {what}")
    return value


def _strings(value, where: str, allowed=None) -> list:
    _typed(value, list, where, "a list of names")
    for i, v in enumerate(value):
        _typed(v, str, f"{where}[{i}]", "a name")
        if allowed is not None and v not in allowed:
            raise _Bad(f"{where}[{i}]", f"= {v!r}: allowed: {', '.join(allowed)}")
    return value


# --- error_models.json --------------------------------------------------------------------
def _error_models(doc: dict) -> None:
    from .features import FEATURES

    policy = _typed(doc.get("policy", {}), dict, "policy", "an object")
    for key, value in policy.items():
        if key == "margin_scale":
            _number(value, "policy.margin_scale", low=0.0)
        elif key == "sign_share":
            _number(value, "policy.sign_share", above=0.5, high=1.0)
        else:
            raise _Bad(f"policy.{key}", "unknown; allowed: margin_scale, sign_share")
    for i, c in enumerate(_typed(_get(doc, "candidates", "the top level"), list, "candidates",
                                 "a list")):
        where = f"candidates[{i}]"
        _typed(_get(c, "model", where), str, f"{where}.model", "a model name")
        _typed(_get(c, "options", where), dict, f"{where}.options", "an object")
        _typed(_get(c, "label", where), str, f"{where}.label", "a label")
        _strings(_get(c, "regimes", where), f"{where}.regimes", REGIMES)
    for i, t in enumerate(_typed(_get(doc, "tables", "the top level"), list, "tables", "a list")):
        _table(t, f"tables[{i}]", FEATURES)


def _table(t: dict, where: str, known_features) -> None:
    from ..registry import QUANTITIES

    from .tables import ErrorTable

    fields = set(ErrorTable.__dataclass_fields__)
    for key in t if isinstance(t, dict) else ():
        if key not in fields:
            raise _Bad(f"{where}.{key}", f"unknown; allowed: {', '.join(sorted(fields))}")
    kind = _get(t, "kind", where)
    if kind not in TABLE_KINDS:
        raise _Bad(f"{where}.kind", f"= {_show(kind)}: allowed: {', '.join(TABLE_KINDS)}")
    _strings(_get(t, "models", where), f"{where}.models")
    _strings(_get(t, "regimes", where), f"{where}.regimes", REGIMES)
    features = _strings(_get(t, "features", where), f"{where}.features", known_features)
    _typed(t.get("option", {}), dict, f"{where}.option", "an object")
    _typed(t.get("signed", False), bool, f"{where}.signed", "true or false")
    points = _typed(_get(t, "points", where), list, f"{where}.points", "a list")
    n = len(features)
    if not all(type(p) is list and len(p) == n for p in points):
        for j, p in enumerate(points):
            _typed(p, list, f"{where}.points[{j}]", f"a list of {n} numbers")
            if len(p) != n:
                raise _Bad(f"{where}.points[{j}]", f"has {len(p)} coordinates, {n} features")
    try:
        _numbers([x for p in points for x in p], f"{where}.points")
    except _Bad:  # name the point
        for j, p in enumerate(points):
            _numbers(p, f"{where}.points[{j}]")
    quantities = [q.key for q in QUANTITIES]
    for name, low in (("errors", None), ("loo", 0.0)):
        table = _typed(_get(t, name, where) if name == "errors" else t.get(name, {}), dict,
                       f"{where}.{name}", "an object of quantities")
        for q, values in table.items():
            at = f"{where}.{name}.{q}"
            if q not in quantities:
                raise _Bad(at, f"unknown quantity; allowed: {', '.join(quantities)}")
            _typed(values, list, at, f"a list of {len(points)} numbers or nulls")
            if len(values) != len(points):
                raise _Bad(at, f"has {len(values)} values for {len(points)} points")
            _numbers(values, at, low=low, nulls=True)


# --- cost_models.json ---------------------------------------------------------------------
def _cost_models(doc: dict) -> None:
    from .costs import SETUPS, SIZES
    from .tables import CostFit

    fields = set(CostFit.__dataclass_fields__)
    models = _typed(_get(doc, "models", "the top level"), dict, "models", "an object")
    for name, fit in models.items():
        where = f"models.{name}"
        for key in fit if isinstance(fit, dict) else ():
            if key not in fields:
                raise _Bad(f"{where}.{key}", f"unknown; allowed: {', '.join(sorted(fields))}")
        _typed(_get(fit, "model", where), str, f"{where}.model", "a model name")
        size = _get(fit, "size", where)
        if size not in SIZES:
            raise _Bad(f"{where}.size", f"= {_show(size)}: allowed: {', '.join(SIZES)}")
        for key in ("option", "term"):
            if _get(fit, key, where) is not None:
                _typed(fit[key], str, f"{where}.{key}", "a name or null")
        powers = _typed(_get(fit, "powers", where), list, f"{where}.powers", "a list")
        coef = _typed(_get(fit, "coef", where), list, f"{where}.coef", "a list")
        if not powers or len(coef) != len(powers):
            raise _Bad(f"{where}.coef", f"has {len(coef)} coefficients for {len(powers)} "
                                        "powers (at least one)")
        for j, (p, c) in enumerate(zip(powers, coef)):
            _number(p, f"{where}.powers[{j}]")
            _number(c, f"{where}.coef[{j}]", low=0.0)
        _workload(fit.get("workload", {}), f"{where}.workload")
        _number(fit.get("rms", 0.0), f"{where}.rms", low=0.0)
        samples = fit.get("samples", 0)
        if isinstance(samples, bool) or not isinstance(samples, int) or samples < 0:
            raise _Bad(f"{where}.samples", f"= {_show(samples)}: expected an integer >= 0")
        _memory(fit.get("memory", {}), f"{where}.memory")
    for key, v in _typed(doc.get("variants", {}), dict, "variants", "an object").items():
        where = f"variants.{key}"
        if _get(v, "base", where) not in models:
            raise _Bad(f"{where}.base", f"= {_show(v['base'])}: no such entry in models")
        factor = v.get("factor", 1.0)
        if isinstance(factor, dict):
            _get(factor, "default", f"{where}.factor")
            for regime, f in factor.items():
                _number(f, f"{where}.factor.{regime}", above=0.0)
        else:
            _number(factor, f"{where}.factor", above=0.0)
        setup = _typed(v.get("setup", {}), dict, f"{where}.setup", "an object")
        if setup:
            if _get(setup, "kind", f"{where}.setup") not in SETUPS:
                raise _Bad(f"{where}.setup.kind", f"= {_show(setup['kind'])}: allowed: "
                                                  f"{', '.join(SETUPS)}")
            _number(_get(setup, "time_s", f"{where}.setup"), f"{where}.setup.time_s", low=0.0)
            _workload(setup.get("workload", {}), f"{where}.setup.workload")
    machine_doc = _typed(doc.get("machine", {}), dict, "machine", "an object")
    for name, seconds in _typed(machine_doc.get("seconds", {}), dict, "machine.seconds",
                                "an object").items():
        _number(seconds, f"machine.seconds.{name}", above=0.0)


def _workload(workload, where: str) -> None:
    """A fit's workload shares: known reference workloads (:mod:`.machine`), shares in
    (0, 1] summing to 1 (none: the fit's seconds are not rescaled)."""
    from .machine import WORKLOADS

    for name, share in _typed(workload, dict, where, "an object").items():
        if name not in WORKLOADS:
            raise _Bad(f"{where}.{name}", f"unknown; allowed: {', '.join(WORKLOADS)}")
        _number(share, f"{where}.{name}", above=0.0, high=1.0)
    if workload and abs(sum(workload.values()) - 1.0) > 1e-9:
        raise _Bad(where, f"shares sum to {sum(workload.values()):g}, not 1")


def _memory(memory, where: str) -> None:
    _typed(memory, dict, where, "an object")
    kind = memory.get("kind", "fixed")
    if kind not in MEMORY_KINDS:
        raise _Bad(f"{where}.kind", f"= {_show(kind)}: allowed: {', '.join(MEMORY_KINDS)}")
    for key in ("fixed", "per_point"):
        if key in memory or key in MEMORY_KINDS[kind]:
            _number(_get(memory, key, where), f"{where}.{key}", low=0.0)
