"""Tolerance checks on contact results, for a user's own pytest suite (as ``numpy.testing`` is
for arrays).

Each assertion raises :class:`AssertionError` with a message that names the quantity, both
values, their difference, the tolerance and where the tolerance comes from, and records the
check (:class:`Check`) for the pytest plugin's summary::

    from validation.testing import assert_close, assert_matches_closed_form

    assert_close(bem, fem, quantities=("F_T", "sigma0"), rtol=0.01,
                 source="P = 11 against fem-axisym, measured 0.3 %")
    assert_matches_closed_form(result, "hertz", rtol=1e-3)

Quantities are named by their short keys: ``F_T`` (total force, N), ``sigma0`` (centre
pressure, Pa), ``a`` (contact radius, m) and ``A`` (real contact area, m^2).  A study is the
dict that :func:`validation.studies.converge.converge_study` returns (or its ``converge.json``
read back): ``studies[key]`` holds the Richardson estimate and the GCI band of a quantity.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from pillar_xval.outcome import ContactResult
from pillar_xval.scenes import InputError

from .registry import LOAD_QUANTITIES, QUANTITIES

__all__ = ["QUANTITY_BY_KEY", "Check", "assert_agree", "assert_close", "assert_converged",
           "assert_matches_closed_form", "assert_order", "check_tolerance", "checks_made",
           "closed_form_refusal", "quantity_value"]

QUANTITY_BY_KEY = {q.key: q for q in (*QUANTITIES, *LOAD_QUANTITIES)}
CLOSED_FORMS = ("hertz", "punch", "spring")


@dataclass(frozen=True)
class Check:
    """One check as the plugin's summary lists it: values in SI, tolerance as written."""

    name: str        # the assertion, e.g. "assert_close"
    quantity: str    # "F_T", or "converged", or "order of F_T"
    value: float
    reference: float
    tolerance: str   # "rtol 1 %", "combined bands 2.1e-09 N", ...
    source: str      # where the tolerance comes from
    passed: bool


_RECORD: list[Check] = []


def checks_made(clear: bool = False) -> list[Check]:
    """The checks made so far in this process (the plugin reads and clears them per test)."""
    out = list(_RECORD)
    if clear:
        _RECORD.clear()
    return out


def _finish(name: str, rows: list[tuple[Check, str]], header: str) -> None:
    """Record every row; raise with the failing rows' lines under ``header``."""
    _RECORD.extend(check for check, _ in rows)
    failed = [line for check, line in rows if not check.passed]
    if failed:
        raise AssertionError(f"{name}: {header}\n" + "\n".join("  " + f for f in failed))


def _unit(key: str) -> str:
    return QUANTITY_BY_KEY[key].unit if key in QUANTITY_BY_KEY else ""


def _label(result, name: str = "") -> str:
    if name:
        return name
    if isinstance(result, ContactResult):
        disc = ", ".join(f"{k} {v:g}" if isinstance(v, (int, float)) else f"{k} {v}"
                         for k, v in result.discretisation.items()
                         if k in ("elements_per_diameter", "cells_per_diameter", "mesh_size"))
        return f"{result.model}" + (f", {disc}" if disc else "")
    return "given"


def _check_quantities(quantities) -> tuple[str, ...]:
    if isinstance(quantities, str):
        quantities = (quantities,)
    quantities = tuple(quantities)
    unknown = [q for q in quantities if q not in QUANTITY_BY_KEY]
    if not quantities or unknown:
        raise ValueError(f"quantities = {quantities!r}: give one or more of "
                         f"{', '.join(QUANTITY_BY_KEY)}")
    return quantities


def check_tolerance(name: str, value) -> float:
    """``value`` as a float if it is a finite number >= 0; InputError (a ValueError) naming
    ``name`` otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not \
            math.isfinite(value) or value < 0:
        raise InputError(f"{name} = {value!r}: a finite number >= 0")
    return float(value)


def quantity_value(source, key: str) -> float:
    """Quantity ``key`` (SI) of a ContactResult, a mapping of keys, or a plain number."""
    if isinstance(source, ContactResult):
        return float(getattr(source, QUANTITY_BY_KEY[key].attr))
    if isinstance(source, Mapping):
        if key not in source:
            raise ValueError(f"expected values have no {key!r} (they have "
                             f"{', '.join(map(str, source)) or 'none'})")
        return float(source[key])
    if isinstance(source, (int, float)) and not isinstance(source, bool):
        return float(source)
    raise TypeError(f"expected a ContactResult, a mapping of quantities or a number, not "
                    f"{type(source).__name__}")


def _unconverged(result: ContactResult) -> tuple[Check, str] | None:
    """The failed convergence check of ``result``, None when it converged."""
    if result.converged:
        return None
    d = result.diagnostics
    residuals = ", ".join(f"{k} {v:.3g}" for k, v in d.items()
                          if "residual" in k and isinstance(v, (int, float)))
    return (Check("assert_converged", "converged", 0.0, 1.0, "converged = True",
                  "the model's own verdict", False),
            f"{_label(result)} did not converge: {d.get('message') or 'no message'}"
            + (f" ({residuals})" if residuals else ""))


def assert_converged(result: ContactResult) -> None:
    """The model says it converged; else its own message and residuals."""
    row = _unconverged(result) or (Check("assert_converged", "converged", 1.0, 1.0,
                                         "converged = True", "the model's own verdict",
                                         True), "")
    _finish("assert_converged", [row], "the solve is not a result")


def assert_close(actual: ContactResult, expected, quantities=("F_T",), *, rtol: float,
                 atol: float = 0.0, source: str = "", reference_name: str = "",
                 require_converged: bool = True) -> None:
    """|actual - expected| <= atol + rtol |expected| for every quantity.

    Parameters
    ----------
    actual : ContactResult
    expected : ContactResult, number or mapping
        A number needs exactly one quantity; a mapping is keyed by quantity (SI values).
    quantities : str or sequence of str
        Keys among F_T, sigma0, a, A.
    rtol, atol : float
        Relative and absolute (SI) tolerances.
    source : str
        Where the tolerance comes from ("measured 0.3 % at P = 11", "the GCI of ...");
        the failure message quotes it.
    reference_name : str
        What ``expected`` is ("Hertz", "paper Table 2"); default: its model, or "given".
    require_converged : bool
        An unconverged ``actual`` (or ``expected`` result) fails the check first.
    """
    quantities = _check_quantities(quantities)
    rtol, atol = check_tolerance("rtol", rtol), check_tolerance("atol", atol)
    if not isinstance(actual, ContactResult):
        raise TypeError(f"actual must be a ContactResult, not {type(actual).__name__}")
    if isinstance(expected, (int, float)) and len(quantities) != 1:
        raise ValueError(f"a number as expected value needs one quantity, not {quantities}")
    if require_converged:
        failed = [row for r in (actual, expected) if isinstance(r, ContactResult)
                  for row in [_unconverged(r)] if row is not None]
        if failed:
            _finish("assert_close", failed, "a value from an unconverged solve is no result")
    source = source or "given by the caller"
    tol_text = f"rtol {rtol:.3g}" + (f" + atol {atol:.3g}" if atol else "")
    rows = []
    for key in quantities:
        a, e = quantity_value(actual, key), quantity_value(expected, key)
        allowed = atol + rtol * abs(e)
        diff = a - e
        rel = f" ({diff / e:+.3%})" if e else ""
        unit = _unit(key)
        ok = math.isfinite(a) and abs(diff) <= allowed
        rows.append((Check("assert_close", key, a, e, tol_text, source, ok),
                     f"{key}: actual {a:.6g} {unit} ({_label(actual)}), expected {e:.6g} "
                     f"{unit} ({_label(expected, reference_name)}): difference {diff:+.3g} "
                     f"{unit}{rel} exceeds {allowed:.3g} {unit} ({tol_text}; source: "
                     f"{source})"))
    _finish("assert_close", rows, f"{sum(not c.passed for c, _ in rows)} of {len(rows)} "
                                  "quantities differ beyond the tolerance")


def _estimate(study: Mapping, key: str) -> tuple[float, float, str]:
    """(Richardson estimate, its band, what the band is) of ``key`` in a converge study."""
    try:
        st = study["studies"][key]
    except (KeyError, TypeError):
        raise ValueError(f"not a convergence study with {key!r} (a dict from converge_study "
                         "or a converge.json read back)") from None
    g = st["gci"]
    if g.get("status") == "ok" and g.get("f_exact") is not None:
        return float(g["f_exact"]), float(g["uncertainty"]), f"GCI (Fs = {g['fs']:g})"
    # No observed order: the finest value and the conservative band, said as such.
    return float(st["f"][0]), float(g["fallback_uncertainty"]), \
        f"fallback band ({g.get('status', 'no GCI')})"


def assert_agree(study_a: Mapping, study_b: Mapping, quantities=("F_T",), *,
                 factor: float = 1.0) -> None:
    """The two studies' Richardson estimates differ by less than ``factor`` times their
    combined bands, sqrt(u_a^2 + u_b^2) (each a GCI, or the conservative fallback band where
    a study observed no order; the message says which)."""
    quantities = _check_quantities(quantities)
    factor = check_tolerance("factor", factor)
    name_a, name_b = study_a.get("model", "study a"), study_b.get("model", "study b")
    rows = []
    for key in quantities:
        fa, ua, wa = _estimate(study_a, key)
        fb, ub, wb = _estimate(study_b, key)
        allowed = factor * math.hypot(ua, ub)
        diff = fa - fb
        unit = _unit(key)
        ok = abs(diff) <= allowed
        tol = f"{factor:g} x combined bands {allowed:.3g} {unit}"
        src = f"{name_a}: {wa}; {name_b}: {wb}"
        rows.append((Check("assert_agree", key, fa, fb, tol, src, ok),
                     f"{key}: {name_a} {fa:.6g} +- {ua:.3g} {unit}, {name_b} {fb:.6g} +- "
                     f"{ub:.3g} {unit}: difference {diff:+.3g} {unit} exceeds {tol} ({src})"))
    _finish("assert_agree", rows, "the Richardson estimates disagree beyond their bands")


def assert_order(study: Mapping, expected: float, *, atol: float = 0.1,
                 quantity: str = "F_T") -> None:
    """The observed order of ``quantity``, fitted over every level of ``study`` (least squares
    of log|differences| against log h, three or more levels), is ``expected`` +- ``atol``."""
    (key,) = _check_quantities(quantity)
    atol = check_tolerance("atol", atol)
    st = study.get("studies", {}).get(key) if isinstance(study, Mapping) else None
    if st is None:
        raise ValueError(f"not a convergence study with {key!r}")
    fit = st["lsq"]
    order = fit.get("order")
    levels = len(st.get("f", []))
    src = f"least-squares fit over {levels} levels ({fit.get('status', '')})"
    ok = order is not None and abs(order - expected) <= atol
    shown = "none" if order is None else f"{order:.4g}"
    line = (f"order of {key}: observed {shown}, expected {expected:g} +- {atol:g} ({src})"
            + ("" if levels >= 3 else "; an order needs three or more levels"))
    _finish("assert_order", [(Check("assert_order", f"order of {key}",
                                    float("nan") if order is None else float(order),
                                    float(expected), f"atol {atol:g}", src, ok), line)],
            "the convergence order is off")


def closed_form_refusal(scene, form: str) -> str | None:
    """Why the closed form ``form`` is no reference for ``scene``, or None where it is one.
    Hertz is the flat substrate's solution: on pillars it ignores them (on the sparse paper
    scene its F_T is 3x the lattice's), so it is refused there, not applied.  The rigid
    punch and the spring model are one pillar's: refused on a flat scene and where a second
    pillar touches (Phi >= Phi_S, the spring model's own scope)."""
    from pillar_xval.scenes import analytic

    if form == "hertz":
        if scene.is_flat:
            return None
        return ("Hertz is the flat substrate's solution and ignores the pillars; on a scene "
                "with pillars compare with a model (bem, fem-3d; the paper's Hertz-like limit "
                "of a dense lattice is model = \"hertz\")")
    if scene.is_flat:
        return f"the {form} closed form is one pillar's: the scene is flat (use hertz)"
    phi, phi_s = scene.pillars.surface_fraction, analytic.single_pillar_threshold_rim(scene)
    if phi >= phi_s:
        return (f"the {form} closed form is one pillar's, and a second pillar touches here "
                f"(Phi = {phi:.4g} >= Phi_S = {phi_s:.4g}): compare with a model (bem, fem-3d)")
    return None


def _closed_form_values(result: ContactResult, form: str) -> dict:
    """The closed form's quantities on the result's scene (under a given force, the closed
    form that carries it: each inverts exactly)."""
    from pillar_xval.scenes import Scene, analytic

    scene = Scene.from_dict(result.scene)
    refusal = closed_form_refusal(scene, form)
    if refusal is not None:
        raise ValueError(f"{form}: {refusal}")
    if form == "hertz":
        h = analytic.hertz(scene)
        return {"F_T": h.force, "sigma0": h.centre_pressure, "a": h.contact_radius,
                "A": h.contact_area, "zeta": h.indentation}, "Hertz (Johnson 1985, sec. 4.2)"
    punch = analytic.rigid_punch(scene) if form == "punch" else analytic.spring_model(scene)
    d = scene.pillars.diameter_m
    what = ("rigid flat punch (Johnson 1985, sec. 3.8)" if form == "punch"
            else "the paper's spring model (one Hooke pillar)")
    return {"F_T": punch.force, "sigma0": punch.centre_pressure, "a": d / 2.0,
            "A": math.pi * d * d / 4.0, "zeta": punch.indentation}, what


def assert_matches_closed_form(result: ContactResult, form: str, *, rtol: float,
                               quantities=("F_T",), source: str = "") -> None:
    """``result`` against a closed form of its own scene: ``"hertz"`` (flat substrate),
    ``"punch"`` (rigid pillar pressed into the lens) or ``"spring"`` (the paper's soft flat
    punch: half-spaces and a Hooke pillar in series)."""
    if form not in CLOSED_FORMS:
        raise ValueError(f"form = {form!r}: one of {', '.join(CLOSED_FORMS)}")
    values, what = _closed_form_values(result, form)
    assert_close(result, values, quantities, rtol=rtol, reference_name=what,
                 source=source or "given by the caller")
