"""Scene files (TOML, units in the key names), presets and dotted overrides.

File format (units are part of each key: mm, um, Pa; ``nu`` and ``surface_fraction`` are
dimensionless)::

    name = "my-scene"                    # optional
    [lens]       radius_mm, E_Pa, nu      (or rigid = true instead of E_Pa)
    [pillars]    diameter_um, height_um, surface_fraction | pitch_um, E_Pa, nu (or rigid)
    [substrate]  E_Pa, nu (or rigid)      (defaults to the pillars' material; nu defaults to theirs)
    [load]       indentation_um

A file without a ``[pillars]`` table is a flat substrate (the Hertz problem).
"""

from __future__ import annotations

import copy
import math
import tomllib
from importlib import resources
from pathlib import Path

from ._scene import Lens, Material, Pillars, Scene, SceneError

_UM = 1e-6
_MM = 1e-3

_KEYS = {
    "lens": {"radius_mm", "E_Pa", "nu", "rigid"},
    "pillars": {"diameter_um", "height_um", "surface_fraction", "pitch_um", "E_Pa", "nu", "rigid"},
    "substrate": {"E_Pa", "nu", "rigid"},
    "load": {"indentation_um"},
}
_TOP = {"name", "description"}
# Setting one key of a pair through an override drops the other one.
_EXCLUSIVE = {"pitch_um": "surface_fraction", "surface_fraction": "pitch_um",
              "E_Pa": "rigid", "rigid": "E_Pa"}


def preset_names() -> list[str]:
    folder = resources.files("scenes") / "presets"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def _read_toml_text(text: str, origin: str) -> dict:
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"{origin}: not valid TOML ({exc})") from None


def scene_dict(source: str) -> dict:
    """The raw table of a preset name or a TOML file path."""
    if source in preset_names():
        text = (resources.files("scenes") / "presets" / f"{source}.toml").read_text()
        data = _read_toml_text(text, f"preset {source}")
        data.setdefault("name", source)
        return data
    path = Path(source)
    if not path.is_file():
        raise SceneError(
            f"scene = {source!r}: neither a preset ({', '.join(preset_names())}) nor a file")
    data = _read_toml_text(path.read_text(), str(path))
    data.setdefault("name", path.stem)
    return data


def apply_overrides(data: dict, overrides: list[str] | tuple[str, ...]) -> dict:
    """Apply ``table.key=value`` overrides (``table=none`` removes a table)."""
    data = copy.deepcopy(data)
    for item in overrides:
        if "=" not in item:
            raise SceneError(f"--set {item!r}: expected table.key=value")
        lhs, rhs = (s.strip() for s in item.split("=", 1))
        parts = lhs.split(".")
        if len(parts) == 1 and parts[0] in _KEYS and rhs.lower() == "none":
            removed = data.pop(parts[0], None)
            if parts[0] == "pillars" and removed and "substrate" not in data:
                # The substrate was implied by the pillars' material: keep it.
                data["substrate"] = {k: v for k, v in removed.items()
                                     if k in _KEYS["substrate"]}
            continue
        if len(parts) != 2 or parts[0] not in _KEYS:
            raise SceneError(
                f"--set {item!r}: expected table.key=value with table in {sorted(_KEYS)}")
        table, key = parts
        if key not in _KEYS[table]:
            raise SceneError(
                f"--set {item!r}: unknown key {table}.{key}; allowed: {sorted(_KEYS[table])}")
        section = data.setdefault(table, {})
        section[key] = value = _parse_value(rhs, lhs)
        if not (key == "rigid" and value is False):
            section.pop(_EXCLUSIVE.get(key, ""), None)
    return data


def _parse_value(text: str, name: str):
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    try:
        return float(text)
    except ValueError:
        raise SceneError(f"{name} = {text!r}: expected a number or true/false") from None


def _material(table: dict, owner: str) -> Material:
    rigid = table.get("rigid", False)
    if not isinstance(rigid, bool):
        raise SceneError(f"{owner}.rigid = {rigid!r}: expected true or false")
    if "nu" not in table:
        raise SceneError(f"{owner}.nu is missing (allowed range [0, 0.5])")
    if rigid:
        if "E_Pa" in table:
            raise SceneError(f"{owner}: give either E_Pa or rigid = true, not both")
        return Material(math.inf, table["nu"])
    if "E_Pa" not in table:
        raise SceneError(f"{owner}.E_Pa is missing (> 0, or rigid = true)")
    return Material(_number(table, owner, "E_Pa", 1.0), table["nu"])


def _number(table: dict, owner: str, key: str, scale: float) -> float:
    if key not in table:
        raise SceneError(f"{owner}.{key} is missing")
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{owner}.{key} = {value!r}: expected a number")
    if not math.isfinite(value):
        raise SceneError(f"{owner}.{key} = {value}: must be a finite number")
    if value <= 0:
        raise SceneError(f"{owner}.{key} = {value:g}: must be > 0")
    return float(value) * scale


def scene_from_dict(data: dict) -> Scene:
    """Build a validated :class:`Scene` from a table in file units."""
    unknown = set(data) - set(_KEYS) - _TOP
    if unknown:
        raise SceneError(f"unknown table(s) {sorted(unknown)}; allowed: {sorted(set(_KEYS) | _TOP)}")
    for table, keys in _KEYS.items():
        if table in data:
            if not isinstance(data[table], dict):
                raise SceneError(f"[{table}] must be a table")
            bad = set(data[table]) - keys
            if bad:
                raise SceneError(f"unknown key(s) {sorted(bad)} in [{table}]; allowed: {sorted(keys)}")
    for table in ("lens", "load"):
        if table not in data:
            raise SceneError(f"[{table}] table is missing")

    lens_t = data["lens"]
    lens = Lens(_number(lens_t, "lens", "radius_mm", _MM), _material(lens_t, "lens"))
    zeta = _number(data["load"], "load", "indentation_um", _UM)

    pillars = None
    if "pillars" in data:
        p = data["pillars"]
        d = _number(p, "pillars", "diameter_um", _UM)
        h = _number(p, "pillars", "height_um", _UM)
        has_pitch, has_phi = "pitch_um" in p, "surface_fraction" in p
        if has_pitch == has_phi:
            raise SceneError(
                "pillars: give exactly one of pitch_um or surface_fraction "
                f"({'both' if has_pitch else 'neither'} given)")
        if has_pitch:
            e = _number(p, "pillars", "pitch_um", _UM)
        else:
            e = Pillars.pitch_from_fraction(d, p["surface_fraction"])
        pillars = Pillars(d, h, e, _material(p, "pillars"))

    if "substrate" in data:
        table = dict(data["substrate"])
        if "nu" not in table and "pillars" in data and "nu" in data["pillars"]:
            table["nu"] = data["pillars"]["nu"]  # same material family as the pillars
        substrate = _material(table, "substrate")
    elif pillars is not None:
        substrate = pillars.material
    else:
        raise SceneError("[substrate] table is missing (required for a flat scene)")
    name = str(data.get("name", "custom"))
    return Scene(lens=lens, substrate=substrate, indentation_m=zeta, pillars=pillars, name=name)


def load_scene(source: str, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    """Load a preset name or TOML file and apply ``--set`` overrides."""
    return scene_from_dict(apply_overrides(scene_dict(source), overrides))


def scene_to_toml(scene: Scene) -> str:
    """The scene as a TOML file in file units (round-trips through :func:`load_scene`)."""
    def mat(m: Material) -> list[str]:
        return ["rigid = true" if m.rigid else f"E_Pa = {m.E_Pa!r}", f"nu = {m.nu!r}"]

    lines = [f'name = "{scene.name}"', "", "[lens]",
             f"radius_mm = {scene.lens.radius_m / _MM!r}", *mat(scene.lens.material), ""]
    if scene.pillars is not None:
        p = scene.pillars
        lines += ["[pillars]", f"diameter_um = {p.diameter_m / _UM!r}",
                  f"height_um = {p.height_m / _UM!r}", f"pitch_um = {p.pitch_m / _UM!r}",
                  *mat(p.material), ""]
    lines += ["[substrate]", *mat(scene.substrate), "",
              "[load]", f"indentation_um = {scene.indentation_m / _UM!r}", ""]
    return "\n".join(lines)
