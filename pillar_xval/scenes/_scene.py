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
from ._errors import SceneError, ScopeError, show_amount


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
    """A lens pressed onto pillars on a substrate (or onto a flat substrate when ``pillars``
    is None, the Hertz problem) by a given indentation ``indentation_m`` (m), or by a given
    normal force ``force_N`` (N; then ``indentation_m`` is None: each model solves for it).
    Exactly one of the two is given."""

    lens: Lens
    substrate: Material
    indentation_m: float | None
    pillars: Pillars | None = None
    name: str = "custom"
    force_N: float | None = None

    def __post_init__(self):
        _check_material("substrate", self.substrate)
        if (self.indentation_m is None) == (self.force_N is None):
            raise SceneError("load: give exactly one of indentation_m and force_N "
                             f"({'both' if self.force_N is not None else 'neither'} given)")
        p = self.pillars
        pillars = None if p is None else (p.diameter_m, p.height_m)
        zeta = None
        if self.force_N is None:
            zeta = ck.as_float("load.indentation_m", self.indentation_m)
            zeta = ck.check_length("load.indentation_m", zeta)
            object.__setattr__(self, "indentation_m", zeta)
        else:
            force = ck.check_force("load.force_N", ck.as_float("load.force_N", self.force_N))
            object.__setattr__(self, "force_N", force)
        ck.check_scene(self.lens.radius_m, zeta, pillars,
                       self.lens.material.rigid, self.substrate.rigid)
        if zeta is None:
            problem = ck.force_problem(self.lens.radius_m, self.force_N,
                                       self.lens.material.compliance, pillars)
            if problem:
                raise ck.SI.error("load.force_N", problem, self.force_N)

    # --- the load ---------------------------------------------------------------------
    @property
    def load_control(self) -> str:
        """``"indentation"`` (the indentation is given) or ``"force"`` (the force is)."""
        return "indentation" if self.force_N is None else "force"

    def at_indentation(self, indentation_m: float) -> "Scene":
        """The same scene pressed by ``indentation_m`` (m), indentation-controlled."""
        return dataclasses.replace(self, indentation_m=indentation_m, force_N=None)

    def at_force(self, force_N: float) -> "Scene":
        """The same scene pressed by ``force_N`` (N), force-controlled."""
        return dataclasses.replace(self, indentation_m=None, force_N=force_N)

    def designed(self, indentation_m: float) -> "Scene":
        """The scene at a *design* indentation: the guess of the indentation a force implies,
        for which a model builds its discretisation, moved into the allowed range where a
        guess falls outside it (:func:`._checks.indentation_limits`).  The indentation the
        model then solves for is checked by :meth:`implied`."""
        p = self.pillars
        lo, hi = ck.indentation_limits(self.lens.radius_m,
                                       None if p is None else (p.diameter_m, p.height_m))
        return self.at_indentation(min(max(indentation_m, lo), hi))

    def implied(self, indentation_m: float, how: str) -> "Scene":
        """The scene at the indentation a model solved for this scene's force, checked by
        the scope check of a given indentation (:func:`._checks.indentation_problem`): a
        ScopeError names the force, the indentation and ``how`` it was found."""
        from ._tables import FileNaming  # the user's keys and units (it imports this module)

        naming = FileNaming({})
        p = self.pillars
        problem = ck.indentation_problem(self.lens.radius_m, indentation_m,
                                         None if p is None else (p.diameter_m, p.height_m),
                                         naming)
        if problem:
            force = float("nan") if self.force_N is None else self.force_N
            raise ScopeError(f"{naming.key('load.force_N')} = "
                             f"{show_amount(force * 1e6)}: "
                             + ck.implied_problem(indentation_m, how, problem, naming))
        return self.at_indentation(indentation_m)

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
        load = data["load"]
        return cls(lens=Lens(data["lens"]["radius_m"], mat(data["lens"])),
                   substrate=mat(data["substrate"]), indentation_m=load.get("indentation_m"),
                   pillars=pillars, name=data.get("name", "custom"),
                   force_N=load.get("force_N"))

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
            "load": ({"indentation_m": self.indentation_m} if self.force_N is None
                     else {"force_N": self.force_N}),
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
