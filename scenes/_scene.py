"""The scene: geometry, materials and load of one lens-on-pillars contact, validated, in SI.

A scene is immutable.  Every constructor checks its arguments and raises
:class:`SceneError` naming the parameter, its value and the allowed range; nothing is
clipped.  Rigid bodies are a limit, written ``rigid = true`` in a scene file and stored
with ``E_Pa = inf`` (their compliance is then exactly zero).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from ._errors import SceneError

# Surface fraction of hexagonal close packing (pitch = diameter).
PHI_CLOSE_PACKING = math.pi / (2.0 * math.sqrt(3.0))


def _finite(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{name} = {value!r}: expected a number")
    value = float(value)
    if not math.isfinite(value):
        raise SceneError(f"{name} = {value}: must be a finite number")
    return value


def _positive(name: str, value: Any) -> float:
    value = _finite(name, value)
    if value <= 0.0:
        raise SceneError(f"{name} = {value:g}: must be > 0")
    return value


def _poisson(name: str, value: Any) -> float:
    value = _finite(name, value)
    if not 0.0 <= value <= 0.5:
        raise SceneError(f"{name} = {value:g}: allowed range is [0, 0.5]")
    return value


def _modulus(name: str, value: Any) -> float:
    """Young's modulus in Pa: positive and finite, or +inf for a rigid body."""
    if isinstance(value, (int, float)) and not isinstance(value, bool) and value == math.inf:
        return math.inf
    return _positive(name, value)


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
        object.__setattr__(self, "radius_m", _positive("lens.radius", self.radius_m))
        _check_material("lens", self.material)


@dataclass(frozen=True)
class Pillars:
    """Hexagonal lattice of cylindrical pillars: diameter, height and pitch in m."""

    diameter_m: float
    height_m: float
    pitch_m: float
    material: Material

    def __post_init__(self):
        d = _positive("pillars.diameter", self.diameter_m)
        h = _positive("pillars.height", self.height_m)
        e = _positive("pillars.pitch", self.pitch_m)
        if e < d * (1.0 - 1e-12):
            raise SceneError(
                f"pillars.pitch = {e:g} m: must be >= the diameter {d:g} m "
                "(pitch = diameter is close packing)")
        object.__setattr__(self, "diameter_m", d)
        object.__setattr__(self, "height_m", h)
        object.__setattr__(self, "pitch_m", max(e, d))
        _check_material("pillars", self.material)

    @property
    def surface_fraction(self) -> float:
        """Phi = pi / (2 sqrt 3) (d / e)^2 (paper, eq. Frac)."""
        return PHI_CLOSE_PACKING * (self.diameter_m / self.pitch_m) ** 2

    @staticmethod
    def pitch_from_fraction(diameter_m: float, surface_fraction: Any) -> float:
        phi = _finite("pillars.surface_fraction", surface_fraction)
        if not 0.0 < phi <= PHI_CLOSE_PACKING * (1.0 + 1e-12):
            raise SceneError(
                f"pillars.surface_fraction = {phi:g}: allowed range is "
                f"(0, {PHI_CLOSE_PACKING:.6f}] (close packing pi/(2 sqrt 3))")
        return diameter_m * math.sqrt(PHI_CLOSE_PACKING / min(phi, PHI_CLOSE_PACKING))


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
        zeta = _positive("load.indentation", self.indentation_m)
        object.__setattr__(self, "indentation_m", zeta)
        if self.lens.material.rigid and self.substrate.rigid:
            raise SceneError(
                "lens.rigid and substrate.rigid are both true: at least one half-space must be "
                "elastic")
        R = self.lens.radius_m
        if self.pillars is None:
            if zeta >= 0.5 * R:
                raise SceneError(
                    f"load.indentation = {zeta:g} m: allowed range is (0, {0.5 * R:g}) m "
                    "(half the lens radius; the half-space model needs a << R)")
        else:
            h, d = self.pillars.height_m, self.pillars.diameter_m
            if zeta >= h:
                raise SceneError(
                    f"load.indentation = {zeta:g} m: allowed range is (0, {h:g}) m, below the "
                    "pillar height (at zeta >= h the lens reaches the substrate between pillars, "
                    "which this model does not include)")
            if R <= 10.0 * max(d, h):
                raise SceneError(
                    f"lens.radius = {R:g} m: must exceed {10.0 * max(d, h):g} m "
                    "(10 x the larger of pillar diameter and height; the model treats the lens "
                    "as a half-space over many pillars)")

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
    object.__setattr__(m, "E_Pa", _modulus(f"{owner}.E_Pa", m.E_Pa))
    object.__setattr__(m, "nu", _poisson(f"{owner}.nu", m.nu))
