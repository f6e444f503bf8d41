"""A scene table in file units (a parsed TOML file with its overrides) made into a Scene.

Every error names the key as the file writes it (``load.indentation_um``), the value as the
user wrote it (``2``, not ``2e-06 m``) and the allowed range in file units, and says where
the value came from: the scene file or preset, or the ``--set`` that gave it.  The checks
themselves are those of :mod:`pillar_xval.scenes._checks`, run on the same SI floats the constructors see.
"""

from __future__ import annotations

import math

from . import _checks as ck
from ._checks import Naming
from ._errors import SceneError, show, show_amount
from ._scene import Lens, Material, Pillars, Scene

# File units per SI unit (exact doubles: see scenes._checks.as_float).
PER_UM = 1e6
PER_MM = 1e3

KEYS = {
    "lens": ("radius_mm", "E_Pa", "nu", "rigid"),
    "pillars": ("diameter_um", "height_um", "surface_fraction", "pitch_um", "E_Pa", "nu", "rigid"),
    "substrate": ("E_Pa", "nu", "rigid"),
    "load": ("indentation_um", "force_uN"),
}
TOP_KEYS = ("name", "description")
# SI quantity -> (file key, file units per SI unit, file unit); others keep their key.
_FILE_KEYS = {
    "lens.radius_m": ("lens.radius_mm", PER_MM, "mm"),
    "pillars.diameter_m": ("pillars.diameter_um", PER_UM, "um"),
    "pillars.height_m": ("pillars.height_um", PER_UM, "um"),
    "pillars.pitch_m": ("pillars.pitch_um", PER_UM, "um"),
    "load.indentation_m": ("load.indentation_um", PER_UM, "um"),
    "load.force_N": ("load.force_uN", PER_UM, "uN"),
}
_MISSING = object()


class FileNaming(Naming):
    """Names quantities by their file keys and values as written in ``data``; ``origin``
    (a file path or ``preset NAME``) prefixes errors about file values, and ``provenance``
    (file key -> ``key=value`` as given to ``--set``) those about overridden values."""

    def __init__(self, data: dict, origin: str | None = None,
                 provenance: dict[str, str] | None = None):
        self.data, self.origin, self.provenance = data, origin, provenance or {}

    def key(self, q: str) -> str:
        return _FILE_KEYS.get(q, (q,))[0]

    def unit(self, q: str) -> str:
        return _FILE_KEYS[q][2] if q in _FILE_KEYS else super().unit(q)

    def amount(self, q: str, si: float) -> str:
        return show_amount(si * (_FILE_KEYS[q][1] if q in _FILE_KEYS else 1.0))

    def raw(self, q: str):
        table, _, key = self.key(q).partition(".")
        section = self.data.get(table)
        return section.get(key, _MISSING) if isinstance(section, dict) else _MISSING

    def where(self, file_key: str | None = None) -> str:
        """The prefix saying where a value came from."""
        if file_key in self.provenance:
            return f"--set {self.provenance[file_key]}: "
        return f"{self.origin}: " if self.origin else ""

    def error(self, q: str, problem: str, value=None) -> SceneError:
        key = self.key(q)
        if key in self.provenance:
            return SceneError(f"{self.where(key)}{problem}")
        raw = self.raw(q)
        shown = (show(raw) if raw is not _MISSING
                 else self.amount(q, value) if isinstance(value, float) else show(value))
        return SceneError(f"{self.where(key)}{key} = {shown}: {problem}")

    def quote(self, q: str, si: float) -> str:
        raw = self.raw(q)
        if raw is _MISSING:
            return super().quote(q, si)
        return f"{self.key(q)} = {show(raw)} {self.unit(q)}".rstrip()

    def fail(self, problem: str, file_key: str | None = None) -> SceneError:
        return SceneError(f"{self.where(file_key)}{problem}")

    def missing(self, file_key: str, hint: str = "") -> SceneError:
        """A missing key; when every key of its table came from ``--set``, the table is one
        that the overrides added, and the message says so."""
        table = file_key.split(".", maxsplit=1)[0]
        given = [k for k in self.data.get(table, {}) if f"{table}.{k}" in self.provenance]
        if given and len(given) == len(self.data[table]):
            return SceneError(f"--set {self.provenance[f'{table}.{given[0]}']}: adds a "
                              f"[{table}] table to the scene, which also needs "
                              f"{file_key}{hint}")
        return SceneError(f"{self.where()}{file_key} is missing{hint}")


def scene_from_dict(data: dict, origin: str | None = None,
                    provenance: dict[str, str] | None = None) -> Scene:
    """Build a validated :class:`Scene` from a table in file units.

    Parameters
    ----------
    data : dict
        The scene as a TOML file holds it (tables ``lens``, ``pillars``, ``substrate``,
        ``load``; lengths in mm or um as the keys say, moduli in Pa).
    origin : str, optional
        Where ``data`` came from (a file path, ``preset NAME``), to prefix error messages.
    provenance : dict, optional
        File keys set by ``--set`` overrides, each with the ``key=value`` text the user gave.
    """
    naming = FileNaming(data if isinstance(data, dict) else {}, origin, provenance)
    if not isinstance(data, dict):
        raise naming.fail(f"expected a table of scene tables, got {show(data)}")
    _check_structure(data, naming)
    radius = _length(naming, "lens.radius_m")
    lens = Lens(radius, _material(naming, "lens", data["lens"]))

    pillars = None
    if "pillars" in data:
        pillars = _pillars(naming, data["pillars"])
    if "substrate" in data:
        substrate = _material(naming, "substrate",
                              _completed(data["substrate"], data.get("pillars")))
    elif pillars is not None:
        substrate = pillars.material  # the paper's E_s = E_p, nu_s = nu_p
    else:
        raise naming.fail("[substrate] table is missing (a flat scene needs one: E_Pa or "
                          "rigid = true, and nu)")
    zeta, force = _load(naming, data["load"])
    shape = None if pillars is None else (pillars.diameter_m, pillars.height_m)
    ck.check_scene(radius, zeta, shape, lens.material.rigid, substrate.rigid, naming)
    if force is not None:
        problem = ck.force_problem(radius, force, lens.material.compliance, shape, naming)
        if problem:
            raise naming.error("load.force_N", problem, force)
    name = data.get("name", "custom")
    return Scene(lens=lens, substrate=substrate, indentation_m=zeta, pillars=pillars, name=name,
                 force_N=force)


def _load(naming: FileNaming, table: dict) -> tuple[float | None, float | None]:
    """(indentation in m, force in N) of the [load] table: exactly one of them is given."""
    if _first_of(naming, "load", table, "indentation_um", "force_uN"):
        return _length(naming, "load.indentation_m"), None
    q = "load.force_N"
    return None, ck.check_force(q, ck.as_float(q, _value(naming, q), naming, PER_UM), naming)


def _first_of(naming: FileNaming, name: str, table: dict, first: str, second: str) -> bool:
    """Whether [name] gives ``first`` (True) or ``second`` (False): exactly one of them."""
    has_first, has_second = first in table, second in table
    if has_first == has_second:
        raise naming.fail(f"[{name}] needs exactly one of {first} and {second} "
                          f"({'both' if has_first else 'neither'} given)")
    return has_first


def _check_structure(data: dict, naming: FileNaming) -> None:
    allowed = sorted((*KEYS, *TOP_KEYS))
    unknown = sorted(str(k) for k in data if k not in KEYS and k not in TOP_KEYS)
    if unknown:
        raise naming.fail(f"unknown key(s) {', '.join(map(show, unknown))}; allowed at the top "
                          f"level: {', '.join(allowed)}")
    for key in TOP_KEYS:
        value = data.get(key, "")
        if not (isinstance(value, str) and value.isprintable() and len(value) <= 200):
            raise naming.fail(f"{key} = {show(value)}: expected one line of printable text "
                              "(at most 200 characters)", key)
    for table, keys in KEYS.items():
        if table not in data:
            if table in ("lens", "load"):
                raise naming.fail(f"[{table}] table is missing")
            continue
        section = data[table]
        if not isinstance(section, dict):
            raise naming.fail(f"{table} = {show(section)}: expected a table [{table}]", table)
        bad = sorted(str(k) for k in section if k not in keys)
        if bad:
            raise naming.fail(f"unknown key(s) {', '.join(map(show, bad))} in [{table}]; "
                              f"allowed: {', '.join(keys)}")


def _value(naming: FileNaming, q: str):
    raw = naming.raw(q)
    if raw is _MISSING:
        raise naming.missing(naming.key(q))
    return raw


def _length(naming: FileNaming, q: str) -> float:
    si = ck.as_float(q, _value(naming, q), naming, _FILE_KEYS[q][1])
    return ck.check_length(q, si, naming)


def _pillars(naming: FileNaming, table: dict) -> Pillars:
    d = _length(naming, "pillars.diameter_m")
    h = _length(naming, "pillars.height_m")
    if _first_of(naming, "pillars", table, "pitch_um", "surface_fraction"):
        e = ck.check_pitch(d, _length(naming, "pillars.pitch_m"), naming)
    else:
        q = "pillars.surface_fraction"
        e = ck.check_surface_fraction(q, ck.as_float(q, table[q.split(".")[1]], naming), d,
                                      naming)
    return Pillars(d, h, e, _material(naming, "pillars", table))


def _completed(substrate: dict, pillars: dict | None) -> dict:
    """A partial [substrate] completed from the pillars' material (the documented default)."""
    table = dict(substrate)
    if not isinstance(pillars, dict):
        return table
    table.setdefault("nu", pillars.get("nu"))
    if table["nu"] is None:
        del table["nu"]
    if "E_Pa" not in table and table.get("rigid") is not True:
        if "E_Pa" in pillars:
            table["E_Pa"] = pillars["E_Pa"]
        elif "rigid" not in table and pillars.get("rigid") is True:
            table["rigid"] = True
    return table


def _material(naming: FileNaming, owner: str, table: dict) -> Material:
    q_rigid, q_e, q_nu = f"{owner}.rigid", f"{owner}.E_Pa", f"{owner}.nu"
    rigid = table.get("rigid", False)
    if not isinstance(rigid, bool):
        raise naming.error(q_rigid, "expected true or false", rigid)
    if "nu" not in table:
        raise naming.missing(q_nu, " (allowed range [0, 0.5])")
    nu = ck.check_poisson(q_nu, ck.as_float(q_nu, table["nu"], naming), naming)
    if rigid:
        if "E_Pa" in table:
            raise naming.fail(f"[{owner}] gives both E_Pa and rigid = true: give one", q_e)
        return Material(math.inf, nu)
    if "E_Pa" not in table:
        lo, hi = ck.MODULUS_RANGE_PA
        raise naming.missing(q_e, f" (allowed range [{lo:g}, {hi:g}] Pa, or {q_rigid} = true)")
    E = ck.as_float(q_e, table["E_Pa"], naming)
    return Material(ck.check_modulus(q_e, E, naming, rigid_allowed=False), nu)
