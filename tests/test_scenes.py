"""Scene model, TOML files, overrides and the CLI's handling of bad input."""

import math

import pytest

from pillar_xval.scenes import (PHI_CLOSE_PACKING, Scene, SceneError, load_scene, preset_names,
                    scene_from_dict, scene_to_toml)
from validation.cli import main


def test_presets_exist_and_match_table_1():
    assert {"paper-fig3-sparse", "paper-fig3-dense", "single-pillar", "hertz"} <= set(preset_names())
    s = load_scene("paper-fig3-sparse")
    assert s.lens.radius_m == 2e-3 and s.lens.material.E_Pa == 1.6e6 and s.lens.material.nu == 0.5
    assert s.pillars.diameter_m == 4e-6 and s.pillars.height_m == 2e-6
    assert s.substrate == s.pillars.material  # Table 1: E_s = E_p
    assert s.pillars.surface_fraction == pytest.approx(0.03, rel=1e-12)
    assert s.indentation_m == pytest.approx(0.3e-6)
    assert load_scene("paper-fig3-dense").pillars.surface_fraction == pytest.approx(0.82)
    assert load_scene("single-pillar").pillars.surface_fraction == pytest.approx(2.3e-3)
    assert load_scene("hertz").is_flat


def test_surface_fraction_of_close_packing():
    s = load_scene("paper-fig3-dense", ["pillars.pitch_um=4"])
    assert s.pillars.surface_fraction == pytest.approx(math.pi / (2 * math.sqrt(3)), rel=1e-14)
    assert PHI_CLOSE_PACKING == pytest.approx(0.9069, abs=1e-4)


def test_override_replaces_the_exclusive_partner():
    s = load_scene("paper-fig3-sparse", ["pillars.pitch_um=10"])
    assert s.pillars.pitch_m == pytest.approx(10e-6)
    s = load_scene("paper-fig3-sparse", ["pillars.rigid=true"])
    assert s.pillars.material.rigid and s.pillars.material.compliance == 0.0
    assert load_scene("paper-fig3-sparse", ["pillars=none"]).is_flat


def test_toml_and_dict_round_trip(tmp_path):
    s = load_scene("paper-fig3-dense", ["lens.rigid=false", "substrate.rigid=true",
                                         "pillars.E_Pa=1e9"])
    path = tmp_path / "scene.toml"
    path.write_text(scene_to_toml(s))
    back = load_scene(str(path))
    assert back.pillars.pitch_m == pytest.approx(s.pillars.pitch_m, rel=1e-15)
    assert back.substrate.rigid and back.pillars.material.E_Pa == 1e9
    assert Scene.from_dict(s.to_dict()) == s


@pytest.mark.parametrize("override, names", [
    ("lens.radius_mm=-1", "lens.radius_mm"),
    ("lens.radius_mm=0", "lens.radius_mm"),
    ("pillars.diameter_um=0", "pillars.diameter_um"),
    ("pillars.height_um=-2", "pillars.height_um"),
    ("lens.nu=0.6", "lens.nu"),
    ("pillars.nu=-0.1", "pillars.nu"),
    ("pillars.surface_fraction=0.95", "pillars.surface_fraction"),
    ("pillars.pitch_um=3.9", "pillars.pitch_um"),
    ("load.indentation_um=212", "load.indentation_um"),  # past the small-slope limit
    ("load.indentation_um=1e4", "load.indentation_um"),
    ("load.indentation_um=nan", "load.indentation_um"),
    ("pillars.E_Pa=inf", "pillars.E_Pa"),
    ("lens.E_Pa=0", "lens.E_Pa"),
    ("lens.colour=1", "lens.colour"),
])
def test_bad_input_names_the_parameter(override, names):
    with pytest.raises(SceneError, match=names.replace(".", r"\.")):
        load_scene("paper-fig3-sparse", [override])


def test_both_or_neither_pitch_and_fraction():
    base = {"lens": {"radius_mm": 2, "E_Pa": 1e6, "nu": 0.5}, "load": {"indentation_um": 0.1},
            "pillars": {"diameter_um": 4, "height_um": 2, "E_Pa": 1e6, "nu": 0.5}}
    with pytest.raises(SceneError, match="neither"):
        scene_from_dict(base)
    base["pillars"].update(pitch_um=10, surface_fraction=0.1)
    with pytest.raises(SceneError, match="both"):
        scene_from_dict(base)


def test_unknown_table_and_all_rigid_refused():
    with pytest.raises(SceneError, match="unknown key.*'extra'"):
        scene_from_dict({"lens": {}, "load": {}, "extra": {}})
    with pytest.raises(SceneError, match="substrate.rigid=true: not with lens.rigid = true"):
        load_scene("hertz", ["lens.rigid=true", "substrate.rigid=true"])


def test_cli_bad_input_is_one_line_and_exit_2(capsys):
    code = main(["solve", "--scene", "paper-fig3-sparse", "--set", "lens.nu=0.7"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "lens.nu" in err[0] and "[0, 0.5]" in err[0]
    code = main(["solve", "--scene", "no-such-scene"])
    assert code == 2 and "no-such-scene" in capsys.readouterr().err
