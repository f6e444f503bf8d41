"""``--set table.key=value`` overrides of a scene table, in file units.

Rules (the README's scene-file section states them for users):

- values are read strictly: a decimal number (``0.3``, ``2``, ``-1.5e-3``; no ``_``, no hex,
  no ``inf`` or ``nan``) for numeric keys, ``true``/``false`` for ``rigid``;
- the last override of a key wins;
- an override of ``pitch_um`` replaces the file's ``surface_fraction`` and the other way
  round, and so do ``force_uN`` and ``indentation_um`` (the load: ``--set load.force_uN=20``
  presses a preset by 20 uN instead of its indentation), and ``E_Pa`` and ``rigid = true``;
  overriding both keys of such a pair is refused, as a file holding both is;
- ``rigid=false`` makes a body elastic again with the file's ``E_Pa`` (or, for the
  substrate, the pillars' material);
- ``table=none`` removes a table (``pillars=none``: a flat substrate, which keeps the pillars'
  material if the file had no [substrate]).
"""

from __future__ import annotations

import copy
import re

from ._errors import SceneError
from ._tables import KEYS

# A plain decimal number, as people type it: TOML's stricter rules (no leading zeros) would
# refuse "007", which is harmless; float() alone would accept "0_3" as 3 and "infinity".
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
_PAIRS = {"pitch_um": "surface_fraction", "surface_fraction": "pitch_um",
          "indentation_um": "force_uN", "force_uN": "indentation_um"}


def apply_overrides(data: dict, overrides: list[str] | tuple[str, ...]) -> dict:
    """``data`` with the ``table.key=value`` overrides applied (``data`` is not changed)."""
    return apply_overrides_traced(data, overrides)[0]


def apply_overrides_traced(data: dict, overrides) -> tuple[dict, dict[str, str]]:
    """As :func:`apply_overrides`, and the provenance of each overridden file key: the
    ``key=value`` text that set it, for error messages."""
    if not isinstance(data, dict):
        raise SceneError(f"expected a scene table to override, got {type(data).__name__}")
    if isinstance(overrides, str):
        overrides = [overrides]  # a lone string is one override, not its characters
    base, data = data, copy.deepcopy(data)
    provenance: dict[str, str] = {}
    for item in overrides:
        if not isinstance(item, str):
            raise SceneError(f"--set {item!r}: expected a string table.key=value")
        lhs, eq, rhs = (s.strip() for s in item.partition("="))
        shown = f"{lhs}={_abbreviate(rhs)}"
        if not eq:
            raise SceneError(f"--set {_abbreviate(item) or repr(item)}: expected "
                             "table.key=value")
        table, dot, key = lhs.partition(".")
        if table not in KEYS:
            raise SceneError(f"--set {shown}: expected table.key=value with table one of "
                             f"{', '.join(KEYS)}")
        if not dot:
            if rhs.lower() != "none":
                raise SceneError(f"--set {shown}: a whole table takes only {table}=none")
            _remove(data, table, provenance)
            continue
        if key not in KEYS[table]:
            raise SceneError(f"--set {shown}: unknown key {lhs}; [{table}] takes "
                             f"{', '.join(KEYS[table])}")
        section = data.setdefault(table, {})
        if not isinstance(section, dict):
            raise SceneError(f"--set {shown}: {table} in the scene is not a table")
        value = _parse(rhs, key, shown)
        _set(section, table, key, value, shown, provenance, base.get(table))
    return data, provenance


def _set(section: dict, table: str, key: str, value, shown: str, provenance: dict,
         base_section) -> None:
    partner = _PAIRS.get(key)
    if partner is not None:
        if f"{table}.{partner}" in provenance:
            raise SceneError(f"--set {provenance[f'{table}.{partner}']} and --set {shown}: give "
                             f"one of {table}.{key} and {table}.{partner}, not both (as in a "
                             "scene file)")
        section.pop(partner, None)
    elif key == "E_Pa" or (key == "rigid" and value is True):
        other = "rigid" if key == "E_Pa" else "E_Pa"
        if f"{table}.{other}" in provenance and section.get(other) is not False:
            raise SceneError(f"--set {provenance[f'{table}.{other}']} and --set {shown}: give "
                             f"{table}.E_Pa or {table}.rigid=true, not both")
        section.pop(other, None)
        provenance.pop(f"{table}.{other}", None)
    elif key == "rigid" and "E_Pa" not in section and isinstance(base_section, dict) \
            and "E_Pa" in base_section:
        section["E_Pa"] = base_section["E_Pa"]  # rigid=false: elastic again, as in the file
    section[key] = value
    provenance[f"{table}.{key}"] = shown


def _remove(data: dict, table: str, provenance: dict) -> None:
    removed = data.pop(table, None)
    moved = {k.split(".", 1)[1]: provenance.pop(k) for k in list(provenance)
             if k.startswith(f"{table}.")}
    if table == "pillars" and isinstance(removed, dict) and "substrate" not in data:
        # The substrate was implied by the pillars' material: keep it.
        data["substrate"] = {k: v for k, v in removed.items() if k in KEYS["substrate"]}
        provenance.update({f"substrate.{k}": v for k, v in moved.items()
                           if k in data["substrate"]})


def _parse(text: str, key: str, shown: str):
    if key == "rigid":
        if text.lower() in ("true", "false"):
            return text.lower() == "true"
        raise SceneError(f"--set {shown}: expected true or false")
    if _INTEGER.fullmatch(text):
        try:
            return int(text)
        except ValueError:  # beyond Python's digit limit: overflows like a huge float
            return float("-inf" if text.startswith("-") else "inf")
    if _NUMBER.fullmatch(text):
        return float(text)
    hint = (" (a rigid body: rigid=true)" if key == "E_Pa" and "inf" in text.lower()
            else "")
    raise SceneError(f"--set {shown}: expected a decimal number such as 0.3, 2 or 1.6e6"
                     f"{hint}")


def _abbreviate(text: str) -> str:
    text = text if text.isprintable() else repr(text)
    return text if len(text) <= 40 else f"{text[:24]}...{text[-8:]} ({len(text)} characters)"
