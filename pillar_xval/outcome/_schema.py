"""The one result schema that every model of the toolkit returns.

A comparison, a convergence study or a plot reads these fields and never asks which model
made the result.  ``to_json`` refuses NaN and inf: no non-finite number reaches a file.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from typing import Any

from .._version import package_version

SCHEMA_VERSION = 3
# The contact regimes a result names (``ContactResult.regime``).
REGIMES = ("flat", "single-pillar", "multi-pillar", "mixed")


@dataclass
class PillarForce:
    """Force on one pillar in contact: lattice indices (n, m), centre (m) and force (N)."""

    n: int
    m: int
    x_m: float
    y_m: float
    force_N: float


@dataclass
class ContactResult:
    """Answer of one model on one scene (SI units).

    ``load_control`` says which load the scene gave: ``"indentation"`` (``indentation_m``
    given, ``total_force_N`` solved) or ``"force"`` (``scene["load"]["force_N"]`` given,
    ``indentation_m`` and ``total_force_N`` solved, the latter equal to the given force within
    the model's solver tolerance); both fields are on every result, filled from the scene when
    a model leaves them out.  ``centre_pressure_Pa`` is the contact pressure at r = 0
    (sigma_0); ``contact_radius_m`` the radius of the outermost point of contact;
    ``real_contact_area_m2`` the area where the pressure is positive; ``pillar_top_profile``
    the pressure across the central pillar top (``r_m`` from its centre, ``pressure_Pa``).
    The floor between the pillars is a candidate too once the lens can reach it (zeta > h):
    ``floor_force_N``, ``floor_contact_area_m2`` and ``floor_contact_radius_m`` (the outer
    radius of the floor contact; 0 when none) are its share, included in the totals, and
    ``regime`` names the contact: ``"flat"`` (no pillars), ``"single-pillar"``,
    ``"multi-pillar"`` (pillar tops only) or ``"mixed"`` (tops and floor); a model that
    leaves it out gets it from its pillar count and floor force (:func:`regime_of`).
    ``diagnostics`` holds model-specific numbers (residuals, complementarity errors);
    ``fields`` holds arrays for plots and CSV files and is not part of the JSON document.
    """

    model: str
    scene: dict
    discretisation: dict
    total_force_N: float
    centre_pressure_Pa: float
    contact_radius_m: float
    real_contact_area_m2: float
    pillars_in_contact: int
    pillar_forces: list[PillarForce]
    converged: bool
    iterations: int
    wall_time_s: float
    pillar_top_profile: dict = field(default_factory=lambda: {"r_m": [], "pressure_Pa": []})
    diagnostics: dict = field(default_factory=dict)
    version: str = field(default_factory=package_version)
    schema_version: int = SCHEMA_VERSION
    fields: dict = field(default_factory=dict, repr=False)
    load_control: str = ""
    indentation_m: float | None = None
    floor_force_N: float = 0.0
    floor_contact_area_m2: float = 0.0
    floor_contact_radius_m: float = 0.0
    regime: str = ""

    def __post_init__(self):
        load = self.scene.get("load", {}) if isinstance(self.scene, dict) else {}
        if not self.load_control:
            self.load_control = "force" if "force_N" in load else "indentation"
        if self.indentation_m is None:
            self.indentation_m = load.get("indentation_m")
        if not self.regime:
            flat = isinstance(self.scene, dict) and self.scene.get("pillars") is None
            self.regime = regime_of(flat, self.pillars_in_contact, self.floor_force_N)

    def for_force(self, scene: dict, indentation_m: float, **diagnostics) -> "ContactResult":
        """This result, solved at ``indentation_m`` (m), as the answer to the force-controlled
        ``scene`` (its SI dictionary): its scene, load control and indentation, and the
        ``diagnostics`` of how the force was met.  Returns itself."""
        self.scene = scene
        self.load_control, self.indentation_m = "force", float(indentation_m)
        self.diagnostics.update(diagnostics)
        return self

    def to_dict(self) -> dict:
        out = asdict(self)
        out.pop("fields")
        _check_finite(out, "result")
        return out

    def to_json(self, indent: int | None = 2) -> str:
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    @classmethod
    def from_dict(cls, data: dict) -> "ContactResult":
        data = dict(data)
        data["pillar_forces"] = [PillarForce(**p) for p in data.get("pillar_forces", [])]
        return cls(**data)

    @classmethod
    def from_json(cls, text: str) -> "ContactResult":
        return cls.from_dict(json.loads(text))

    @property
    def label(self) -> str:
        """The model with its pillar model, as summaries, tables and plots name it."""
        return model_label(self.model, self.diagnostics)

    def summary(self) -> str:
        """A few readable lines for the terminal; the model's notes (``diagnostics["notes"]``:
        what it modelled otherwise than asked, the error its pillar model is expected to
        carry) last."""
        s = self.scene
        lines = [
            f"model            {self.label}  ({_fmt_disc(self.discretisation)})",
            f"scene            {s.get('name', '?')}"
            + ("" if s.get("pillars") is None
               else f"  Phi = {s['pillars']['surface_fraction']:.4g}")
            + (f"  zeta = {self.indentation_m * 1e6:.4g} um" if self.load_control != "force"
               else f"  F = {s['load']['force_N'] * 1e6:.4g} uN (given)"),
            "materials        " + "; ".join(
                f"{part} {_fmt_material(s[part])}" for part in ("lens", "pillars", "substrate")
                if s.get(part) is not None),
            *([f"indentation      {self.indentation_m * 1e6:.6g} um (solved)"]
              if self.load_control == "force" else []),
            f"total force      {self.total_force_N * 1e6:.6g} uN",
            f"centre pressure  {self.centre_pressure_Pa * 1e-3:.6g} kPa",
            f"contact radius   {self.contact_radius_m * 1e6:.6g} um",
            f"real area        {self.real_contact_area_m2 * 1e12:.6g} um^2",
            f"pillars touching {self.pillars_in_contact}",
            *([f"floor            {self.floor_force_N * 1e6:.6g} uN "
               f"({100.0 * self.floor_force_N / self.total_force_N:.3g} % of the force), "
               f"{self.floor_contact_area_m2 * 1e12:.6g} um^2, out to "
               f"{self.floor_contact_radius_m * 1e6:.6g} um"]
              if self.floor_force_N > 0.0 and self.total_force_N > 0.0 else []),
            f"regime           {self.regime}",
            *([f"side walls       {self.diagnostics['side_wall_warning']}"]
              if self.diagnostics.get("side_wall_warning") else []),
            f"converged        {self.converged} after {self.iterations} iterations, "
            f"{self.wall_time_s:.3g} s",
        ]
        lines += [f"note             {note}" for note in self.diagnostics.get("notes", [])]
        return "\n".join(lines)


def regime_of(flat: bool, pillars_in_contact: int, floor_force_N: float) -> str:
    """The contact regime (one of :data:`REGIMES`): a flat substrate; the floor touched
    (mixed); else one pillar or several."""
    if flat:
        return "flat"
    if floor_force_N > 0.0:
        return "mixed"
    return "single-pillar" if pillars_in_contact <= 1 else "multi-pillar"


# How a result's pillar model (``diagnostics["pillars"]``, set by every model on a scene with
# pillars) is written.
PILLAR_LABELS = {"hooke": "Hooke pillars", "elastic": "elastic pillars",
                 "none": "no pillar model (a continuum)"}


def model_label(model: str, diagnostics: dict | None = None) -> str:
    """``model`` with its pillar model, the one way every summary, table and plot names a
    result: "bem, elastic pillars", "bem-fft, Hooke pillars"; the model alone on a flat
    scene (no pillar model)."""
    pillars = (diagnostics or {}).get("pillars")
    if not pillars:
        return model
    return f"{model}, {PILLAR_LABELS.get(pillars, f'{pillars} pillars')}"


def _fmt_material(m: dict) -> str:
    """``E = 1.6 MPa, nu = 0.5`` or ``rigid, nu = 0.5``."""
    if m.get("rigid") or m.get("E_Pa") is None:
        return f"rigid, nu = {m['nu']:.6g}"
    E = m["E_Pa"]
    for factor, unit in ((1e9, "GPa"), (1e6, "MPa"), (1e3, "kPa")):
        if abs(E) >= factor:
            return f"E = {E / factor:.6g} {unit}, nu = {m['nu']:.6g}"
    return f"E = {E:.6g} Pa, nu = {m['nu']:.6g}"


def _fmt_disc(disc: dict) -> str:
    return ", ".join(f"{k}={v}" for k, v in disc.items())


def _check_finite(obj: Any, path: str) -> None:
    if isinstance(obj, float):
        if not math.isfinite(obj):
            raise ValueError(f"{path} = {obj}: non-finite number in a result")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            _check_finite(v, f"{path}.{k}")
    elif isinstance(obj, (list, tuple)):
        for i, v in enumerate(obj):
            _check_finite(v, f"{path}[{i}]")
