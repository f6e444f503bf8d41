"""What a valid scene is: the allowed ranges of its quantities and the relations between
them, checked once and named in the user's own words.

The checks are written once, on SI values, and used by two callers: the SI constructors
(:mod:`pillar_xval.scenes._scene`), whose errors name the constructors' parameters (``pillars.pitch_m``),
and the scene-file reader (:mod:`pillar_xval.scenes._tables`), whose errors name the file's keys in the
file's units (``pillars.pitch_um = 3.9``) and print the value exactly as it was written.  A
:class:`Naming` is what tells them apart.  Both run the same predicates on the same floats, so
a table that passes the reader's checks always builds a Scene.

Allowed ranges (why: PHYSICS.md, "Scene input")
-----------------------------------------------
- every length (lens radius, pillar diameter, height and pitch, indentation):
  [1e-9, 1e3] m, a nanometre to a kilometre;
- Young's moduli: [1e-3, 1e16] Pa, or ``rigid = true`` (stored as E = inf);
- Poisson's ratios: [0, 0.5];
- surface fraction: (0, 0.9069], where anything from pi/(2 sqrt 3) = 0.90689968... up to the
  printed value 0.9069 means close packing (pitch = diameter), and whose pitch is a length
  in range;
- pitch >= diameter; indentation below 0.106 R, where the lens's slope at the edge of its
  reach is 0.5 (the small-slope half-space model; the floor between the pillars is a
  candidate of the contact, :func:`floor_reach`);
  lens radius above 10 x the larger of pillar diameter and height; not both half-spaces rigid;
- a force (the load of a force-controlled scene, instead of the indentation): [1e-21, 1e22] N,
  the force scale E L^2 of the softest modulus on the shortest length to the stiffest on the
  longest; and an indentation it implies within the limits above.  Before anything is
  solved, the lens pressed on a rigid flat bounds it from below (:func:`force_problem`).
"""

from __future__ import annotations

import math

from ._errors import SceneError, show, show_amount

LENGTH_RANGE_M = (1e-9, 1e3)
MODULUS_RANGE_PA = (1e-3, 1e16)
# E L^2 from the softest modulus on the shortest length to the stiffest on the longest: no
# scene in range balances a force outside it.
FORCE_RANGE_N = (1e-21, 1e22)
POISSON_RANGE = (0.0, 0.5)
# Surface fraction of hexagonal close packing (pitch = diameter), and the value the paper and
# the README print for it, which is accepted as close packing too.
PHI_CLOSE_PACKING = math.pi / (2.0 * math.sqrt(3.0))
PHI_CLOSE_PACKING_PRINTED = 0.9069
# The small-slope half-space model (Boussinesq's kernel on the plane, the gap read along z):
# the lens's slope at the edge of its reach (where its undeformed gap equals zeta) at most
# 0.5, an indentation up to R (1 - 1/sqrt(1.25)) = 0.106 R.  Its neglected terms are of order
# the slope squared (PHYSICS.md, "Scene input").  With R > 10 max(d, h) this keeps every
# indentation up to h valid, and on the paper's lens (R = 2 mm, h = 2 um) up to 106 h, room
# for the deep indentations of zeta = 10 h (slope 0.14).
MAX_LENS_SLOPE = 0.5
SMALL_SLOPE_SHARE = 1.0 - 1.0 / math.sqrt(1.0 + MAX_LENS_SLOPE**2)


class Naming:
    """How a scene error names a quantity: by its SI key (``lens.radius_m``, ``pillars.E_Pa``;
    the constructors' parameters and the keys of ``Scene.to_dict``) and its SI value."""

    def key(self, q: str) -> str:
        return q

    def unit(self, q: str) -> str:
        return ("m" if q.endswith("_m") else "Pa" if q.endswith("E_Pa")
                else "N" if q.endswith("_N") else "")

    def amount(self, q: str, si: float) -> str:
        """A bound or a derived value of quantity ``q`` in the unit of :meth:`unit`."""
        return show_amount(si)

    def error(self, q: str, problem: str, value=None) -> SceneError:
        """``key = value: problem`` (``value`` is the SI value, or the bad object itself)."""
        return SceneError(f"{self.key(q)} = {show(value)}: {problem}")

    def measure(self, q: str, si: float) -> str:
        """An amount of quantity ``q`` with its unit."""
        unit = self.unit(q)
        return f"{self.amount(q, si)} {unit}" if unit else self.amount(q, si)

    def quote(self, q: str, si: float) -> str:
        """Another quantity cited in a message, with its value and unit."""
        return f"{self.key(q)} = {self.measure(q, si)}"


SI = Naming()


def as_float(q: str, value, naming: Naming = SI, per_si: float = 1.0) -> float:
    """``value``, a number in a unit of which ``per_si`` make one SI unit (1e6 for um), as an
    SI float; integers too large for a double become +-inf, for the range check to refuse with
    the user's value.  Dividing by the exact 1e6 rounds 20 um to the double nearest 2e-5 m;
    multiplying by the inexact 1e-6 would not."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise naming.error(q, "expected a number", value)
    try:
        return float(value) / per_si
    except OverflowError:
        return -math.inf if value < 0 else math.inf


def check_range(q: str, si: float, lo: float, hi: float, naming: Naming = SI,
                note: str = "") -> float:
    """Refuse ``si`` outside [lo, hi] (NaN included); ``note`` says why the range is what it is."""
    if not lo <= si <= hi:
        unit = f" {naming.unit(q)}" if naming.unit(q) else ""
        raise naming.error(q, f"allowed range is [{naming.amount(q, lo)}, "
                              f"{naming.amount(q, hi)}]{unit}{note}", si)
    return si


def check_length(q: str, si: float, naming: Naming = SI) -> float:
    return check_range(q, si, *LENGTH_RANGE_M, naming)


def check_modulus(q: str, si: float, naming: Naming = SI, rigid_allowed: bool = True) -> float:
    """Young's modulus in range, or +inf (a rigid body) where the caller stores rigid that way."""
    if rigid_allowed and si == math.inf:
        return si
    return check_range(q, si, *MODULUS_RANGE_PA, naming,
                       " (a stiffer body: rigid = true)")


def check_poisson(q: str, si: float, naming: Naming = SI) -> float:
    return check_range(q, si, *POISSON_RANGE, naming)


def check_surface_fraction(q: str, phi: float, diameter_m: float, naming: Naming = SI) -> float:
    """The pitch in m of surface fraction ``phi`` on pillars of ``diameter_m``; refuses phi
    above close packing (as printed) and phi so small that the pitch is beyond the longest
    allowed length."""
    if not 0.0 < phi <= PHI_CLOSE_PACKING_PRINTED:
        raise naming.error(
            q, f"allowed range is (0, {PHI_CLOSE_PACKING_PRINTED}] ({PHI_CLOSE_PACKING_PRINTED} "
            f"or anything above pi/(2 sqrt 3) = {PHI_CLOSE_PACKING!r} is close packing, "
            "pitch = diameter)", phi)
    if phi >= PHI_CLOSE_PACKING:
        return diameter_m
    pitch = diameter_m * math.sqrt(PHI_CLOSE_PACKING / phi)
    if not pitch <= LENGTH_RANGE_M[1]:
        raise naming.error(
            q, f"gives a pitch of {naming.measure('pillars.pitch_m', pitch)}, beyond the "
            f"longest allowed length, {naming.measure('pillars.pitch_m', LENGTH_RANGE_M[1])}",
            phi)
    return pitch


def check_pitch(diameter_m: float, pitch_m: float, naming: Naming = SI) -> float:
    """The pitch, at least the diameter (pitch = diameter is close packing); a relative shortfall
    of 1e-12 is round-off of a pitch computed from close packing and reads as the diameter."""
    if pitch_m < diameter_m * (1.0 - 1e-12):
        raise naming.error(
            "pillars.pitch_m",
            f"must be >= {naming.quote('pillars.diameter_m', diameter_m)} "
            "(pitch = diameter is close packing)", pitch_m)
    return max(pitch_m, diameter_m)


def check_force(q: str, si: float, naming: Naming = SI) -> float:
    """A force in range (NaN, zero and negative values included in the refusal)."""
    return check_range(q, si, *FORCE_RANGE_N, naming)


def check_scene(radius_m: float, indentation_m: float | None,
                pillars: tuple[float, float] | None, lens_rigid: bool, substrate_rigid: bool,
                naming: Naming = SI) -> None:
    """The relations between the parts of a scene; ``pillars`` is (diameter, height) in m, or
    None for a flat substrate; ``indentation_m`` None for a force-controlled scene (its
    indentation is checked once implied: :func:`indentation_problem`).  Each quantity is
    already in its own range."""
    R, zeta = radius_m, indentation_m
    if lens_rigid and substrate_rigid:
        raise naming.error(
            "substrate.rigid", f"not with {naming.key('lens.rigid')} = true (at least one "
            "half-space must be elastic)", True)
    if zeta is not None:
        problem = indentation_problem(R, zeta, pillars, naming)
        if problem:
            raise naming.error("load.indentation_m", problem, zeta)
    if pillars is None:
        return
    d, h = pillars
    if R <= 10.0 * max(d, h):
        raise naming.error(
            "lens.radius_m",
            f"must exceed {naming.measure('lens.radius_m', 10.0 * max(d, h))}, 10 x the larger "
            "of pillar diameter and height (the model treats the lens as a half-space over many "
            "pillars)", R)


def indentation_problem(radius_m: float, indentation_m: float,
                        pillars: tuple[float, float] | None, naming: Naming = SI) -> str:
    """Why ``indentation_m`` is outside what the models cover ('' when it is not): the one
    scope check of an indentation, given (:func:`check_scene`) or implied by a force
    (:func:`force_problem`, and each model's solved indentation)."""
    R, zeta = radius_m, indentation_m
    lo, hi = LENGTH_RANGE_M
    if not lo <= zeta <= hi:
        return (f"must lie in [{naming.amount('load.indentation_m', lo)}, "
                f"{naming.amount('load.indentation_m', hi)}] {naming.unit('load.indentation_m')} "
                "(the allowed lengths)")
    top = small_slope_indentation(R)
    if zeta >= top:
        return (f"must be below {naming.measure('load.indentation_m', top)}, "
                f"{SMALL_SLOPE_SHARE:.4f} x {naming.quote('lens.radius_m', R)}: beyond it the "
                f"lens's slope at the edge of its reach, sqrt(2 R zeta - zeta^2) / (R - zeta), "
                f"passes {MAX_LENS_SLOPE:g} and the small-slope half-space model no longer holds")
    return ""


def small_slope_indentation(radius_m: float) -> float:
    """The deepest indentation (m) the models accept on a lens of ``radius_m``: where the
    lens's slope at the edge of its reach (the radius where its undeformed gap equals zeta),
    r / sqrt(R^2 - r^2) with r^2 = 2 R zeta - zeta^2, reaches :data:`MAX_LENS_SLOPE`:
    zeta = R (1 - 1 / sqrt(1 + s^2))."""
    return SMALL_SLOPE_SHARE * radius_m


def indentation_limits(radius_m: float, pillars: tuple[float, float] | None) -> tuple:
    """(smallest, largest) indentation in m that :func:`indentation_problem` accepts, the
    largest a relative 1e-9 inside its open end."""
    return LENGTH_RANGE_M[0], min(LENGTH_RANGE_M[1],
                                  small_slope_indentation(radius_m) * (1.0 - 1e-9))


def rigid_flat_indentation(force_N: float, radius_m: float, lens_compliance: float) -> float:
    """The indentation (m) at which the lens, pressed on a rigid flat, carries ``force_N``:
    Hertz's zeta = (3 F gamma_l / (4 sqrt R))^(2/3) ([J] sec. 4.2).  Any substrate, pillar or
    partial contact deflects more, so it is a lower bound of every model's indentation at that
    force (0 for a rigid lens, which bounds nothing)."""
    return (3.0 * force_N * lens_compliance / (4.0 * math.sqrt(radius_m))) ** (2.0 / 3.0)


def force_problem(radius_m: float, force_N: float, lens_compliance: float,
                  pillars: tuple[float, float] | None, naming: Naming = SI) -> str:
    """Why a force is refused before anything is solved ('' when it is not): the lower bound
    of the indentation it implies (:func:`rigid_flat_indentation`) already fails the
    indentation's scope check."""
    zeta = rigid_flat_indentation(force_N, radius_m, lens_compliance)
    if zeta <= LENGTH_RANGE_M[0]:
        return ""  # a bound below the smallest indentation decides nothing
    problem = indentation_problem(radius_m, zeta, pillars, naming)
    if not problem:
        return ""
    return implied_problem(zeta, "where the lens pressed on a rigid flat carries it; any "
                           "substrate or pillar deflects more", problem, naming, "at least ")


def implied_problem(zeta: float, how: str, problem: str, naming: Naming = SI,
                    bound: str = "") -> str:
    """The refusal of a force whose implied indentation ``zeta`` (m; found ``how``) fails the
    indentation's scope check with ``problem``."""
    q = "load.indentation_m"
    shown = f"{float(naming.amount(q, zeta)):.4g} {naming.unit(q)}"
    return f"implies an indentation of {bound}{shown} ({how}): {naming.key(q)} {problem}"
