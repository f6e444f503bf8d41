"""What every study refines and what it measures: :class:`Ladder` (a field of a model's
declaration, :mod:`.models`) and the compared :data:`QUANTITIES`.

``converge``, ``compare`` and ``gecit`` climb a model's ladder geometrically from its
``coarsest`` rung by ``factor`` per level (:meth:`Ladder.value`); ``tradeoff``, ``calibrate``
and the planner walk its ``rungs``, a gentler sequence that samples the cost curve.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pillar_xval.outcome import ContactResult


@dataclass(frozen=True)
class Quantity:
    """A compared quantity: short ``key``, :class:`ContactResult` attribute, SI unit, label."""

    key: str
    attr: str
    unit: str
    label: str


# The quantities every study reports, in this order.
QUANTITIES: tuple[Quantity, ...] = (
    Quantity("F_T", "total_force_N", "N", "total force F_T"),
    Quantity("sigma0", "centre_pressure_Pa", "Pa", "centre pressure sigma_0"),
    Quantity("a", "contact_radius_m", "m", "contact radius a"),
    Quantity("A", "real_contact_area_m2", "m^2", "real contact area A"),
)


# The floor's share where the lens touches the floor between the pillars (a mixed contact):
# studies add them to QUANTITIES on results that have it.
FLOOR_QUANTITIES: tuple[Quantity, ...] = (
    Quantity("F_floor", "floor_force_N", "N", "floor force"),
    Quantity("A_floor", "floor_contact_area_m2", "m^2", "floor contact area"),
    Quantity("a_floor", "floor_contact_radius_m", "m", "floor contact radius"),
)


# What a check may compare besides: the indentation, given under indentation control and solved
# under force control (where F_T is the given force, the same in every model).
LOAD_QUANTITIES: tuple[Quantity, ...] = (
    Quantity("zeta", "indentation_m", "m", "indentation zeta"),
)


def quantity_values(result: ContactResult) -> dict[str, float]:
    """The :data:`QUANTITIES` of a result, and the :data:`FLOOR_QUANTITIES`, SI, by key."""
    return {q.key: float(getattr(result, q.attr)) for q in QUANTITIES + FLOOR_QUANTITIES}


@dataclass(frozen=True)
class Ladder:
    """How a model is refined.

    Option ``option`` takes ``coarsest * factor**k`` on level k, rounded by ``kind``:
    ``"float"`` (three significant digits), ``"int"`` (nearest integer) or ``"odd"``
    (``round((coarsest + 1) factor**k) - 1``, which keeps an odd count odd for factor 2, so a
    centre element stays centred).  ``rungs`` are the explicit values, coarse to fine, that a
    cost study walks.  The relative cell size of a value is ``h = value**h_power``; ``fixed``
    holds the options every rung shares.
    """

    option: str
    coarsest: float
    factor: float
    kind: str
    h_power: float
    rungs: tuple = ()
    fixed: dict = field(default_factory=dict)
    h_meaning: str = ""

    def value(self, k: int, coarsest: float | None = None):
        """Value of the refined option on level ``k`` (0 = coarsest)."""
        v0 = self.coarsest if coarsest is None else coarsest
        if self.kind == "odd":
            return int(round((v0 + 1) * self.factor**k)) - 1
        if self.kind == "int":
            return int(round(v0 * self.factor**k))
        return float(f"{v0 * self.factor**k:.3g}")  # 2.83 / sqrt(2)^k: 2.83, 2, 1.41

    def size(self, value) -> float:
        """Relative cell size h of an option value."""
        return float(value) ** self.h_power

    def options(self, k: int, coarsest: float | None = None) -> dict:
        """Model options of level ``k``: the fixed ones and the refined one."""
        return self.options_at(self.value(k, coarsest))

    def options_at(self, value) -> dict:
        """Model options with the refined option at ``value``."""
        return {**self.fixed, self.option: value}
