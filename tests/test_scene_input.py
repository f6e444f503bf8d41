"""Scene input that never surprises: each reported case, the
allowed ranges, overrides, file modes, and a seeded fuzz test of files and overrides."""

import math
import os
import random
import re
import sys
from importlib import resources

import pytest

from pillar_xval.outcome import write_atomic
from pillar_xval.scenes import (LENGTH_RANGE_M, MODULUS_RANGE_PA, PHI_CLOSE_PACKING, InputError, Lens,
                    Material, Pillars, Scene, SceneError, analytic, load_scene, preset_names,
                    scene_from_dict, scene_to_toml)

# A user's file without [substrate]: the substrate takes the pillars' material (E_s = E_p).
IMPLIED_SUBSTRATE = """name = "implied"
[lens]
radius_mm = 2.0
E_Pa = 1.6e6
nu = 0.5
[pillars]
diameter_um = 4.0
height_um = 2.0
surface_fraction = 0.1
E_Pa = 1.6e6
nu = 0.5
[load]
indentation_um = 0.3
"""


def scene_file(tmp_path, text, name="scene.toml"):
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return str(path)


def refused(source, overrides=()):
    """The one-line message of the SceneError that loading raises."""
    with pytest.raises(SceneError) as info:
        load_scene(source, list(overrides))
    message = str(info.value)
    assert "\n" not in message and len(message) < 400, message
    return message


# --- each reported case ------------------------------------------------------------------
def test_huge_integer_modulus_is_one_line(tmp_path):
    digits = "9" * 400
    message = refused("single-pillar", [f"lens.E_Pa={digits}"])
    assert message.startswith("--set lens.E_Pa=") and "allowed range" in message
    path = scene_file(tmp_path, IMPLIED_SUBSTRATE.replace("E_Pa = 1.6e6", f"E_Pa = {digits}", 1))
    message = refused(path)
    assert message.startswith(f"{path}: lens.E_Pa = 99999999...") and "400-digit" in message
    # Beyond Python's int <-> str digit limit, in a file and in an override.
    huge = IMPLIED_SUBSTRATE.replace("E_Pa = 1.6e6", "E_Pa = " + "9" * 5000, 1)
    path = scene_file(tmp_path, huge)
    assert refused(path).startswith(f"{path}: not valid TOML")
    assert "allowed range" in refused("single-pillar", ["lens.E_Pa=" + "9" * 5000])


@pytest.mark.parametrize("key", ["lens.E_Pa", "pillars.E_Pa", "substrate.E_Pa"])
@pytest.mark.parametrize("value", ["1e-320", "1e-310", "0", "-5", "1e17"])
def test_modulus_outside_the_stated_range_is_refused(key, value):
    lo, hi = MODULUS_RANGE_PA
    message = refused("single-pillar", [f"{key}={value}"])
    assert message == (f"--set {key}={value}: allowed range is [{lo:g}, {hi:g}] Pa "
                       "(a stiffer body: rigid = true)")


def test_extreme_moduli_and_lengths_keep_every_compliance_finite():
    """At the corners of the allowed ranges the compliances, the Hooke spring, the Hertz and
    spring-model answers are finite, positive normal doubles (no underflow, no overflow)."""
    (e_lo, e_hi), (l_lo, l_hi) = MODULUS_RANGE_PA, LENGTH_RANGE_M
    tiny = sys.float_info.min  # the smallest normal double, 2.2e-308
    for E_l in (e_lo, e_hi):
        for E_p in (e_lo, e_hi):
            for d, h, zeta, R in ((l_lo * 10, l_lo * 10, l_lo, l_hi),
                                  (l_hi / 100, l_hi / 100, l_hi / 200, l_hi)):
                scene = Scene(Lens(R, Material(E_l, 0.5)), Material(E_p, 0.0), zeta,
                              Pillars(d, h, d, Material(E_p, 0.25)))
                values = [scene.half_space_compliance, scene.pillar_spring_compliance,
                          analytic.effective_compliance(scene),
                          analytic.hertz(scene).force, analytic.hertz(scene).centre_pressure,
                          analytic.spring_model(scene).force,
                          analytic.spring_model(scene).centre_pressure,
                          analytic.stiffness_number(scene)]
                assert all(math.isfinite(v) and v > tiny for v in values), (E_l, E_p, d, values)


@pytest.mark.parametrize("key, unit_scale", [
    ("lens.radius_mm", 1e-3), ("pillars.diameter_um", 1e-6), ("pillars.height_um", 1e-6),
    ("pillars.pitch_um", 1e-6), ("load.indentation_um", 1e-6)])
def test_lengths_have_a_stated_range(key, unit_scale):
    lo, hi = (x / unit_scale for x in LENGTH_RANGE_M)
    for value in (lo / 10, hi * 10, 1e-300, -1.0):
        message = refused("single-pillar", [f"{key}={value!r}"])
        assert message == f"--set {key}={value!r}: allowed range is [{lo:g}, {hi:g}] " + \
            key.rsplit("_", 1)[1]


def test_pitch_and_fraction_overrides_refused_together_like_a_file(tmp_path):
    message = refused("paper-fig3-sparse", ["pillars.pitch_um=20", "pillars.surface_fraction=0.1"])
    assert "--set pillars.pitch_um=20 and --set pillars.surface_fraction=0.1" in message
    refused("paper-fig3-sparse", ["pillars.surface_fraction=0.1", "pillars.pitch_um=20"])
    both = IMPLIED_SUBSTRATE.replace("surface_fraction = 0.1",
                                     "surface_fraction = 0.1\npitch_um = 20")
    assert "both" in refused(scene_file(tmp_path, both))
    # One override still replaces the file's other key; the last of one key wins.
    s = load_scene("paper-fig3-sparse", ["pillars.pitch_um=10", "pillars.pitch_um=20"])
    assert s.pillars.pitch_m == 20e-6
    s = load_scene(scene_file(tmp_path, scene_to_toml(s)), ["pillars.surface_fraction=0.2"])
    assert s.pillars.surface_fraction == pytest.approx(0.2, rel=1e-15)


@pytest.mark.parametrize("text", ["0_3", "0x10", "1e", ".", "+", "1 000", "\u0663", "0.3um",
                                  "inf", "nan", "-inf", "Infinity", "", "true", "3,5"])
def test_override_numbers_are_read_strictly(text):
    message = refused("single-pillar", [f"load.indentation_um={text}"])
    assert message.startswith("--set load.indentation_um=")
    assert "expected a decimal number" in message


@pytest.mark.parametrize("text, value_um", [("0.3", 0.3), (".3", 0.3), ("3.", 3.0),
                                            ("+3e-1", 0.3), ("1E-1", 0.1), (" 0.25 ", 0.25),
                                            ("1", 1.0)])
def test_override_numbers_in_plain_decimal_notation(text, value_um):
    scene = load_scene("paper-fig3-sparse", [f"load.indentation_um={text}",
                                             "pillars.height_um=4"])
    assert scene.indentation_m == pytest.approx(value_um * 1e-6, rel=1e-15)


def test_values_are_printed_exactly(tmp_path):
    assert refused("hertz", ["lens.nu=0.5000001"]) == \
        "--set lens.nu=0.5000001: allowed range is [0, 0.5]"
    path = scene_file(tmp_path, IMPLIED_SUBSTRATE.replace("nu = 0.5", "nu = 0.5000001", 1))
    assert refused(path) == f"{path}: lens.nu = 0.5000001: allowed range is [0, 0.5]"
    path = scene_file(tmp_path, IMPLIED_SUBSTRATE.replace("nu = 0.5", "nu = -1e-300", 1))
    assert refused(path) == f"{path}: lens.nu = -1e-300: allowed range is [0, 0.5]"


def test_printed_close_packing_is_close_packing():
    for phi in ("0.9069", repr(PHI_CLOSE_PACKING), "0.906899683"):
        s = load_scene("paper-fig3-dense", [f"pillars.surface_fraction={phi}"])
        assert s.pillars.pitch_m == s.pillars.diameter_m
        assert s.pillars.surface_fraction == PHI_CLOSE_PACKING
    message = refused("paper-fig3-dense", ["pillars.surface_fraction=0.90691"])
    assert ", 0.9069]" in message and repr(PHI_CLOSE_PACKING) in message
    for phi in ("1e-300", "5e-324", "1e-17"):  # pitches beyond the longest allowed length
        assert "beyond the longest allowed length, 1e+09 um" in refused(
            "paper-fig3-dense", [f"pillars.surface_fraction={phi}"])
    # Just below close packing stays a lattice with a pitch just above the diameter.
    s = load_scene("paper-fig3-dense", ["pillars.surface_fraction=0.9068"])
    assert s.pillars.pitch_m > s.pillars.diameter_m


@pytest.mark.parametrize("junk", [b"\x00\xff\xfe\x89PNG", b"\x89PNG\r\n\x1a\n\x00\x00",
                                  b"lens = \x00", bytes(range(256))])
def test_binary_scene_file_names_the_file(tmp_path, junk):
    path = scene_file(tmp_path, junk, "junk.toml")
    assert refused(path).startswith(f"{path}: not ")


def test_unreadable_or_odd_scene_paths_name_the_path(tmp_path):
    assert "neither a preset" in refused(str(tmp_path / "missing.toml"))
    assert "neither a preset" in refused(str(tmp_path))
    big = scene_file(tmp_path, b"#" * (2 << 20), "big.toml")
    assert refused(big).startswith(f"{big}: not a scene file")
    deep = scene_file(tmp_path, "a = " + "[" * 100000 + "]" * 100000, "deep.toml")
    assert refused(deep).startswith(f"{deep}: not valid TOML")


@pytest.mark.parametrize("text, expected", [
    ("indentation_um = 0.3",
     "load.indentation_um = 300: must be below 211.145618 um, 0.1056 x lens.radius_mm = "
     "2.0 mm: beyond it the lens's slope"),
    ("diameter_um = 4.0", "pillars.diameter_um = 1e-12: allowed range is [0.001, 1e+09] um"),
    ("radius_mm = 2.0", "lens.radius_mm = 0.03: must exceed 0.04 mm"),
    ("surface_fraction = 0.1", "pillars.pitch_um = 3.9: must be >= pillars.diameter_um = 4.0"),
])
def test_file_errors_name_file_keys_and_units(tmp_path, text, expected):
    new = {"indentation_um = 0.3": "indentation_um = 300",
           "diameter_um = 4.0": "diameter_um = 1e-12",
           "radius_mm = 2.0": "radius_mm = 0.03",
           "surface_fraction = 0.1": "pitch_um = 3.9"}[text]
    path = scene_file(tmp_path, IMPLIED_SUBSTRATE.replace(text, new))
    message = refused(path)
    assert message.startswith(f"{path}: {expected}")
    assert not re.search(r"_m\b|e-0\d m\b", message)  # no SI key, no SI value


def test_flat_scene_errors_name_file_keys(tmp_path):
    message = refused("hertz", ["load.indentation_um=1000"])
    assert message.startswith("--set load.indentation_um=1000: must be below 211.145618 um, "
                              "0.1056 x lens.radius_mm = 2.0 mm")


def test_partial_substrate_completed_from_the_pillars(tmp_path):
    path = scene_file(tmp_path, IMPLIED_SUBSTRATE)
    s = load_scene(path, ["substrate.nu=0.4999"])
    assert s.substrate == Material(1.6e6, 0.4999)
    s = load_scene(path, ["pillars.rigid=true", "substrate.nu=0.3"])
    assert s.substrate.rigid and s.substrate.nu == 0.3
    # A flat scene has no pillars to complete its substrate from.
    assert refused("hertz", ["substrate=none", "substrate.nu=0.4"]) == (
        "--set substrate.nu=0.4: adds a [substrate] table to the scene, which also needs "
        "substrate.E_Pa (allowed range [0.001, 1e+16] Pa, or substrate.rigid = true)")


def test_presets_state_their_substrate(tmp_path):
    for name in preset_names():
        s = load_scene(name, ["lens.E_Pa=2e6"] if name == "hertz" else ["pillars.E_Pa=1e9"])
        assert s.substrate == Material(1.6e6, 0.5), name  # Table 1, untouched by overrides
    # A file without [substrate] still takes the pillars' material, as documented.
    s = load_scene(scene_file(tmp_path, IMPLIED_SUBSTRATE), ["pillars.E_Pa=1e9"])
    assert s.substrate == Material(1e9, 0.5)
    assert s.to_dict()["substrate"] == {"E_Pa": 1e9, "nu": 0.5, "rigid": False}


def test_summary_shows_every_material():
    from pillar_xval.outcome import ContactResult

    s = load_scene("single-pillar", ["pillars.E_Pa=1e9", "lens.rigid=true"])
    res = ContactResult("bem", s.to_dict(), {}, 1.0, 1.0, 1.0, 1.0, 1, [], True, 1, 0.1)
    line = next(x for x in res.summary().splitlines() if x.startswith("materials"))
    assert "lens rigid" in line and "pillars E = 1 GPa" in line
    assert "substrate E = 1.6 MPa" in line


def test_rigid_override_last_wins_and_restores_the_modulus(tmp_path):
    s = load_scene("single-pillar", ["pillars.rigid=true", "pillars.rigid=false"])
    assert s.pillars.material == Material(1.6e6, 0.5)
    s = load_scene("single-pillar", ["pillars.rigid=false", "pillars.rigid=true"])
    assert s.pillars.material.rigid
    s = load_scene("single-pillar", ["pillars.rigid=true", "pillars.rigid=false",
                                     "pillars.E_Pa=1e9"])
    assert s.pillars.material.E_Pa == 1e9
    assert "not both" in refused("single-pillar", ["pillars.E_Pa=1e9", "pillars.rigid=true"])
    assert "not both" in refused("single-pillar", ["pillars.rigid=true", "pillars.E_Pa=1e9"])
    # A file's rigid body has no modulus to restore: say so.
    rigid = IMPLIED_SUBSTRATE.replace("E_Pa = 1.6e6\nnu = 0.5\n[load]",
                                      "rigid = true\nnu = 0.5\n[load]")
    message = refused(scene_file(tmp_path, rigid), ["pillars.rigid=false"])
    assert "pillars.E_Pa is missing" in message


@pytest.mark.parametrize("umask", [0o022, 0o077, 0o002])
def test_atomic_files_follow_the_umask(tmp_path, umask):
    old = os.umask(umask)
    try:
        path = write_atomic(tmp_path / "out" / "result.json", "{}")
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask
    assert os.listdir(path.parent) == ["result.json"]  # no temporary file left behind


def test_si_constructors_name_their_parameters():
    lens = Lens(2e-3, Material(1.6e6, 0.5))
    with pytest.raises(SceneError, match=r"^pillars\.diameter_m = 1e-15: allowed range"):
        Pillars(1e-15, 2e-6, 4e-6, Material(1e6, 0.5))
    with pytest.raises(SceneError, match=r"^pillars\.E_Pa = 1e-320: allowed range"):
        Scene(lens, Material(1e6, 0.5), 1e-7, Pillars(4e-6, 2e-6, 8e-6, Material(1e-320, 0.5)))
    with pytest.raises(SceneError, match=r"^load\.indentation_m = 0\.0003: must be below "
                                         r"0\.000211145618 m, 0\.1056 x lens\.radius_m = 0\.002 m"):
        Scene(lens, Material(1e6, 0.5), 3e-4, Pillars(4e-6, 2e-6, 8e-6, Material(1e6, 0.5)))
    # Past the pillar height the floor is a candidate: the scene is valid.
    assert Scene(lens, Material(1e6, 0.5), 3e-6, Pillars(4e-6, 2e-6, 8e-6, Material(1e6, 0.5)))
    assert Scene(lens, Material(math.inf, 0.5), 1e-7).substrate.rigid


@pytest.mark.parametrize("value", [None, object(), 10**5000, -10**400, [1.0], {"a": 1}, "2",
                                   float("nan"), True, 1j],
                         ids=["None", "object", "int5000", "int400", "list", "dict", "str",
                              "nan", "bool", "complex"])
def test_python_tables_with_odd_values_are_refused_in_one_line(value):
    """The API takes tables too (scene_from_dict): any Python object in any slot is refused
    with a SceneError, never another exception."""
    good = {"lens": {"radius_mm": 2.0, "E_Pa": 1.6e6, "nu": 0.5}, "load": {"indentation_um": 0.3},
            "substrate": {"E_Pa": 1.6e6, "nu": 0.5}}
    for table in ("lens", "load", "substrate"):
        for key in good[table]:
            data = {t: dict(v) for t, v in good.items()}
            data[table][key] = value
            with pytest.raises(SceneError) as info:
                scene_from_dict(data)
            assert "\n" not in str(info.value) and len(str(info.value)) < 300
            assert str(info.value).startswith(f"{table}.{key} = ")
    odd_tables = [value, {"lens": value, "load": {}}]
    for data in odd_tables + ([] if isinstance(value, str) else [{"name": value, **good}]):
        with pytest.raises(SceneError):
            scene_from_dict(data)


# --- fuzz ----------------------------------------------------------------------------------
BAD_VALUES = ["nan", "inf", "-inf", "-1", "0", "-0.0", "1e-320", "5e-324", "1e400", "9" * 400,
              "9" * 5000,
              "1e308", "0.5000001", "0.9069", "0.90691", "1e-9", "1e9", "true", "false",
              '"text"', "[1, 2]", "{a = 1}", "1979-05-27", "0x10", "1_000", "0_3", "''",
              '"\\u0000"', "[[[[1]]]]", "2.0", "0.3", "1e16", "1e-3", "2", "4", "3.9", "1.9",
              "100", "0.04", "1e5", "0.5", "0.82"]
KEYS = ["lens.radius_mm", "lens.E_Pa", "lens.nu", "lens.rigid", "pillars.diameter_um",
        "pillars.height_um", "pillars.surface_fraction", "pillars.pitch_um", "pillars.E_Pa",
        "pillars.nu", "pillars.rigid", "substrate.E_Pa", "substrate.nu", "substrate.rigid",
        "load.indentation_um", "lens.colour", "name", "extra.key", "pillars", "substrate",
        "load", "lens"]


def random_value(rng):
    if rng.random() < 0.5:
        return rng.choice(BAD_VALUES)
    magnitude = 10 ** rng.uniform(-330, 308)
    if rng.random() < 0.8:
        return repr(rng.choice([1, -1]) * magnitude)
    return str(rng.randint(-5, 10**6))


def mutate_file(text, rng):
    """One random mutation of a valid scene file's text (returns bytes)."""
    lines = text.splitlines()
    kind = rng.randrange(8)
    i = rng.randrange(len(lines))
    if kind == 0 and "=" in lines[i]:  # bad value
        lines[i] = lines[i].split("=")[0] + "= " + random_value(rng)
    elif kind == 1:  # drop a line
        del lines[i]
    elif kind == 2:  # duplicate a line (duplicate key or table)
        lines.insert(i, lines[i])
    elif kind == 3:  # unknown key
        lines.insert(i, f"{rng.choice(['colour', 'E', 'nu2', 'radius_m'])} = 1")
    elif kind == 4:  # binary junk
        data = "\n".join(lines).encode()
        k = rng.randrange(len(data))
        return data[:k] + bytes(rng.randrange(256) for _ in range(rng.randint(1, 8))) + data[k:]
    elif kind == 5:  # truncate
        return "\n".join(lines).encode()[: rng.randrange(len("\n".join(lines)))]
    elif kind == 6:  # rename a table
        lines[i] = rng.choice(["[lens]", "[pillars]", "[substrate]", "[load]", "[extra]",
                               "[lens.x]"])
    else:  # wrong type for a value
        if "=" in lines[i]:
            lines[i] = lines[i].split("=")[0] + "= " + rng.choice(['"2"', "[2]", "{}", "true"])
    return "\n".join(lines).encode()


def random_override(rng):
    key = rng.choice(KEYS)
    if rng.random() < 0.1:
        return rng.choice(["", "=", "lens", "lens.", ".nu", "lens.nu==1", "pillars=none",
                           "substrate=none", "lens=none", "load.indentation_um", "x.y.z=1",
                           "lens.E_Pa=1 000", "lens.nu=\u0663", "pillars=0"])
    value = random_value(rng).strip('"')
    return f"{key}={'none' if rng.random() < 0.05 else value}"


def test_fuzz_scene_files_and_overrides(tmp_path):
    """Seeded random mutations: every outcome is a valid Scene (which round-trips through
    TOML) or a one-line SceneError that starts by naming the file, the preset or the --set."""
    rng = random.Random(20240610)
    sources = [(name, (resources.files("pillar_xval.scenes") / "presets" / f"{name}.toml").read_text())
               for name in preset_names()]
    sources.append(("implied", IMPLIED_SUBSTRATE))
    counts = {"scene": 0, "refused": 0}
    for case in range(1500):
        name, text = rng.choice(sources)
        overrides = [random_override(rng) for _ in range(rng.choice([0, 0, 1, 1, 2, 3]))]
        if rng.random() < 0.7:
            path = scene_file(tmp_path, mutate_file(text, rng), f"case{case % 7}.toml")
            origin = path
        else:
            path = origin = name if name in preset_names() else scene_file(tmp_path, text)
        try:
            scene = load_scene(path, overrides)
        except SceneError as exc:
            message = str(exc)
            assert isinstance(exc, InputError)
            assert "\n" not in message and len(message) < 400, (case, message)
            prefix = f"preset {origin}: " if origin in preset_names() else f"{origin}: "
            assert message.startswith((prefix, "--set ", f"scene {origin}: ")), (case, message)
            assert not re.search(r"\.\w+_m\b", message), (case, message)  # no SI keys
            counts["refused"] += 1
        except Exception as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"case {case}: {path} {overrides}: {type(exc).__name__}: {exc}")
        else:
            back = load_scene(scene_file(tmp_path, scene_to_toml(scene), "back.toml"))
            assert back == scene and Scene.from_dict(scene.to_dict()) == scene, case
            counts["scene"] += 1
    # Both outcomes are exercised (a fuzz test that only ever refuses proves little).
    assert counts["scene"] > 100 and counts["refused"] > 500, counts
