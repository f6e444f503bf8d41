"""The scene: geometry, materials and load of one lens-on-pillars contact, validated, in SI.

A scene is immutable.  Every constructor checks its arguments (:mod:`pillar_xval.scenes._checks`: the
allowed ranges and why) and raises :class:`SceneError` naming the parameter, its value and
the allowed range.  Nothing is clipped except a pitch within round-off of the diameter, which
is close packing.  Rigid bodies are a limit, written ``rigid = true`` in a scene file and
stored with ``E_Pa = inf`` (their compliance is then exactly zero).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from . import _checks as ck
from ._checks import PHI_CLOSE_PACKING
from ._errors import SceneError


@dataclass(frozen=True)
class Material:
    """Isotropic linear elastic material.  ``E_Pa = inf`` is a rigid body."""

    E_Pa: float
    nu: float

    @property
    def rigid(self) -> bool:
        return math.isinf(self.E_Pa)

    @property
    def compliance(self) -> float:
        """gamma = (1 - nu^2) / E in 1/Pa (zero for a rigid body)."""
        return 0.0 if self.rigid else (1.0 - self.nu**2) / self.E_Pa


@dataclass(frozen=True)
class Lens:
    """Spherical lens of radius ``radius_m`` (m), modelled as a half-space whose surface starts
    at the gap R - sqrt(R^2 - r^2) from the pillar tops."""

    radius_m: float
    material: Material

    def __post_init__(self):
        radius = ck.check_length("lens.radius_m", ck.as_float("lens.radius_m", self.radius_m))
        object.__setattr__(self, "radius_m", radius)
        _check_material("lens", self.material)


@dataclass(frozen=True)
class Pillars:
    """Hexagonal lattice of cylindrical pillars: diameter, height and pitch in m."""

    diameter_m: float
    height_m: float
    pitch_m: float
    material: Material

    def __post_init__(self):
        d, h, e = (ck.check_length(q, ck.as_float(q, v)) for q, v in (
            ("pillars.diameter_m", self.diameter_m), ("pillars.height_m", self.height_m),
            ("pillars.pitch_m", self.pitch_m)))
        object.__setattr__(self, "diameter_m", d)
        object.__setattr__(self, "height_m", h)
        object.__setattr__(self, "pitch_m", ck.check_pitch(d, e))
        _check_material("pillars", self.material)

    @property
    def surface_fraction(self) -> float:
        """Phi = pi / (2 sqrt 3) (d / e)^2 (paper, eq. Frac)."""
        return PHI_CLOSE_PACKING * (self.diameter_m / self.pitch_m) ** 2

    @staticmethod
    def pitch_from_fraction(diameter_m: float, surface_fraction: Any) -> float:
        """Pitch in m of a lattice of pillars of ``diameter_m`` covering ``surface_fraction``
        (close packing up to the printed 0.9069, see :mod:`pillar_xval.scenes._checks`)."""
        q = "pillars.surface_fraction"
        return ck.check_surface_fraction(q, ck.as_float(q, surface_fraction), diameter_m)


@dataclass(frozen=True)
class Scene:
    """A lens pressed by ``indentation_m`` onto pillars on a substrate (or onto a flat
    substrate when ``pillars`` is None, the Hertz problem)."""

    lens: Lens
    substrate: Material
    indentation_m: float
    pillars: Pillars | None = None
    name: str = "custom"

    def __post_init__(self):
        _check_material("substrate", self.substrate)
        zeta = ck.as_float("load.indentation_m", self.indentation_m)
        zeta = ck.check_length("load.indentation_m", zeta)
        object.__setattr__(self, "indentation_m", zeta)
        p = self.pillars
        ck.check_scene(self.lens.radius_m, zeta,
                       None if p is None else (p.diameter_m, p.height_m),
                       self.lens.material.rigid, self.substrate.rigid)

    # --- derived quantities -------------------------------------------------------------
    @property
    def is_flat(self) -> bool:
        return self.pillars is None

    @property
    def half_space_compliance(self) -> float:
        """gamma_l + gamma_s in 1/Pa: lens and substrate both deform as half-spaces."""
        return self.lens.material.compliance + self.substrate.compliance

    @property
    def pillar_spring_compliance(self) -> float:
        """Hooke shortening per unit force, 4 h / (pi d^2 E_p) in m/N (0 for rigid pillars)."""
        p = self.pillars
        if p is None or p.material.rigid:
            return 0.0
        return 4.0 * p.height_m / (math.pi * p.diameter_m**2 * p.material.E_Pa)

    @classmethod
    def from_dict(cls, data: dict) -> "Scene":
        """Inverse of :meth:`to_dict` (the SI dictionary stored in every result)."""
        def mat(t):
            return Material(math.inf if t.get("rigid") else t["E_Pa"], t["nu"])

        p = data.get("pillars")
        pillars = None if not p else Pillars(p["diameter_m"], p["height_m"], p["pitch_m"], mat(p))
        return cls(lens=Lens(data["lens"]["radius_m"], mat(data["lens"])),
                   substrate=mat(data["substrate"]), indentation_m=data["load"]["indentation_m"],
                   pillars=pillars, name=data.get("name", "custom"))

    def replace(self, **changes) -> "Scene":
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """JSON-ready SI description (rigid bodies carry ``E_Pa: null, rigid: true``)."""
        def mat(m: Material) -> dict:
            return {"E_Pa": None if m.rigid else m.E_Pa, "nu": m.nu, "rigid": m.rigid}

        out = {
            "name": self.name,
            "lens": {"radius_m": self.lens.radius_m, **mat(self.lens.material)},
            "substrate": mat(self.substrate),
            "load": {"indentation_m": self.indentation_m},
            "pillars": None,
        }
        if self.pillars is not None:
            p = self.pillars
            out["pillars"] = {
                "diameter_m": p.diameter_m, "height_m": p.height_m, "pitch_m": p.pitch_m,
                "surface_fraction": p.surface_fraction, **mat(p.material)}
        return out


def _check_material(owner: str, m: Material) -> None:
    if not isinstance(m, Material):
        raise SceneError(f"{owner}: expected a Material, got {type(m).__name__}")
    q_e, q_nu = f"{owner}.E_Pa", f"{owner}.nu"
    object.__setattr__(m, "E_Pa", ck.check_modulus(q_e, ck.as_float(q_e, m.E_Pa)))
    object.__setattr__(m, "nu", ck.check_poisson(q_nu, ck.as_float(q_nu, m.nu)))
