"""Scene files (TOML, units in the key names), presets, and loading a scene with overrides.

File format (units are part of each key: mm, um, Pa; ``nu`` and ``surface_fraction`` are
dimensionless)::

    name = "my-scene"                    # optional
    [lens]       radius_mm, E_Pa, nu      (or rigid = true instead of E_Pa)
    [pillars]    diameter_um, height_um, surface_fraction | pitch_um, E_Pa, nu (or rigid)
    [substrate]  E_Pa, nu (or rigid)      (optional with pillars: missing keys, or the whole
                                           table, take the pillars' material, E_s = E_p)
    [load]       indentation_um | force_uN  (exactly one: the indentation, or the normal
                                           force in micronewtons; each model solves for the
                                           other)

A file without a ``[pillars]`` table is a flat substrate (the Hertz problem).  Allowed ranges:
:mod:`pillar_xval.scenes._checks`; overrides: :mod:`pillar_xval.scenes._overrides`.
"""

from __future__ import annotations

import copy
import functools
import json
import math
import os
from importlib import resources
from pathlib import Path

from ._errors import SceneError
from ._overrides import apply_overrides_traced
from ._scene import Material, Scene
from ._tables import PER_MM, PER_UM, scene_from_dict

# No scene needs more than a few hundred bytes; a bigger "scene file" is something else.
MAX_FILE_BYTES = 1 << 20


def preset_names() -> list[str]:
    return list(_preset_names())


@functools.lru_cache(maxsize=1)
def _preset_names() -> tuple[str, ...]:
    folder = resources.files("pillar_xval.scenes") / "presets"
    return tuple(sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml")))


@functools.cache
def _preset_table(name: str) -> dict:
    """A preset's parsed table, read once: presets are package data (callers copy it)."""
    origin = f"preset {name}"
    data = _parse_toml((resources.files("pillar_xval.scenes") / "presets" / f"{name}.toml").read_bytes(),
                       origin)
    data.setdefault("name", name)
    return data


def _parse_toml(data: bytes, origin: str) -> dict:
    import tomllib

    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SceneError(f"{origin}: not a scene file: byte 0x{data[exc.start]:02x} at offset "
                         f"{exc.start} is not UTF-8 text (a scene file is TOML)") from None
    try:
        return tomllib.loads(text)
    # ValueError: TOMLDecodeError, and integers beyond Python's digit limit; RecursionError:
    # arrays or inline tables nested thousands deep.
    except (ValueError, RecursionError) as exc:
        reason = " ".join(str(exc).split())[:200]
        raise SceneError(f"{origin}: not valid TOML ({reason})") from None


def _read(source) -> tuple[dict, str]:
    """The raw table of a preset name or a TOML file path, and where it came from."""
    if not isinstance(source, (str, os.PathLike)):
        raise SceneError(f"scene = {source!r}: expected a preset name or a file path")
    name = os.fspath(source)
    if isinstance(source, str) and name in _preset_names():
        return copy.deepcopy(_preset_table(name)), f"preset {name}"
    origin = name if name.isprintable() else repr(name)
    path = Path(name)
    try:
        if not path.is_file():
            raise SceneError(f"scene {origin}: neither a preset ({', '.join(preset_names())}) "
                             "nor a file")
        if path.stat().st_size > MAX_FILE_BYTES:
            raise SceneError(f"{origin}: not a scene file (larger than {MAX_FILE_BYTES} bytes)")
        raw = path.read_bytes()
    except OSError as exc:
        raise SceneError(f"{origin}: cannot read the scene file ({exc.strerror})") from None
    data = _parse_toml(raw, origin)
    # The file's stem names the scene unless it cannot (a scene name is one printable line).
    stem = path.stem
    data.setdefault("name", stem if stem.isprintable() and len(stem) <= 200 else "custom")
    return data, origin


def scene_dict(source) -> dict:
    """The raw table of a preset name or a TOML file path."""
    return _read(source)[0]


def load_scene(source, overrides: list[str] | tuple[str, ...] = ()) -> Scene:
    """Load a preset name or TOML file and apply ``--set`` overrides.

    Raises
    ------
    SceneError
        One line naming the file or preset (or the ``--set``), the key as written, its value
        and the allowed range.
    """
    return scene_loader(source)(overrides)


def scene_loader(source):
    """``load(overrides) -> Scene`` for a preset or file read once (a sweep loads thousands
    of points of one scene); errors as :func:`load_scene`'s."""
    data, origin = _read(source)

    def load(overrides: list[str] | tuple[str, ...] = ()) -> Scene:
        table, provenance = apply_overrides_traced(data, overrides)
        return scene_from_dict(table, origin, provenance)

    return load


def _in_file_units(si: float, per_si: float) -> str:
    """The file-unit number that reads back as exactly ``si`` where one exists: x * 1e6 / 1e6
    is x for most doubles and a neighbour of the product is exact for most others; every
    length that came from a file has one.  (About 4 % of doubles are no double divided by
    1e6; they read back within one ulp.)"""
    amount = si * per_si
    for candidate in (amount, math.nextafter(amount, math.inf), math.nextafter(amount, 0.0)):
        if candidate / per_si == si:
            return repr(candidate)
    return repr(amount)


def scene_to_toml(scene: Scene) -> str:
    """The scene as a TOML file in file units; :func:`load_scene` reads a scene that came
    from a file back exactly (any other within one ulp per length)."""
    def mat(m: Material) -> list[str]:
        return ["rigid = true" if m.rigid else f"E_Pa = {m.E_Pa!r}", f"nu = {m.nu!r}"]

    def um(si: float) -> str:
        return _in_file_units(si, PER_UM)

    # A JSON string of printable text is a valid TOML basic string.
    lines = [f"name = {json.dumps(scene.name, ensure_ascii=False)}", "", "[lens]",
             f"radius_mm = {_in_file_units(scene.lens.radius_m, PER_MM)}",
             *mat(scene.lens.material), ""]
    if scene.pillars is not None:
        p = scene.pillars
        lines += ["[pillars]", f"diameter_um = {um(p.diameter_m)}",
                  f"height_um = {um(p.height_m)}", f"pitch_um = {um(p.pitch_m)}",
                  *mat(p.material), ""]
    load = (f"indentation_um = {um(scene.indentation_m)}" if scene.force_N is None
            else f"force_uN = {_in_file_units(scene.force_N, PER_UM)}")
    lines += ["[substrate]", *mat(scene.substrate), "", "[load]", load, ""]
    return "\n".join(lines)
