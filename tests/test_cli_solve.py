"""``pillar-xval solve``: one JSON document on stdout, report files a script can read back."""

import csv
import json

import pytest

from pillar_xval.outcome import ContactResult
from validation.cli import main


def test_json_is_one_document_and_round_trips(tmp_path, capsys):
    code = main(["solve", "--scene", "paper-fig3-sparse", "--elements-per-diameter", "7",
                 "--pillars", "hooke", "--json", "--out", str(tmp_path)])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)  # exactly one JSON document
    for key in ("model", "scene", "discretisation", "total_force_N", "centre_pressure_Pa",
                "contact_radius_m", "real_contact_area_m2", "pillars_in_contact",
                "pillar_forces", "converged", "iterations", "wall_time_s", "version"):
        assert key in doc
    back = ContactResult.from_json((tmp_path / "result.json").read_text())
    assert back.total_force_N == doc["total_force_N"] and back.pillars_in_contact == 7
    with open(tmp_path / "pillars.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 7
    assert sum(float(r["force_N"]) for r in rows) == pytest.approx(doc["total_force_N"], rel=1e-9)
    with open(tmp_path / "elements.csv") as fh:
        header = next(csv.reader(fh))
    assert {"x_m", "y_m", "pressure_Pa", "force_N", "weight"} <= set(header)
    assert (tmp_path / "pressure.png").read_bytes()[:4] == b"\x89PNG"


def test_paper_search_and_centre_cells_from_the_cli(capsys):
    assert main(["solve", "--scene", "single-pillar", "--contact", "paper", "--cells",
                 "centre", "--pillars", "hooke", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["discretisation"]["contact"] == "paper"
    assert doc["discretisation"]["cells"] == "centre"


# --- the solve's figure: readable ------------------------------------------------------------
def _lines(ax, style):
    return [ln for ln in ax.get_lines() if ln.get_linestyle() == style]


def test_grid_pressure_map_is_an_image_and_its_profile_a_density():
    """8e3 FFT cells: the map is one image (not 8e3 polygons), sigma(r) a density (hexbin),
    not a blob of points."""
    from matplotlib.collections import PolyCollection

    from bem_solver import solve_fft
    from pillar_xval.scenes import load_scene
    from validation.output.report import SCATTER_MAX, pressure_plot

    result = solve_fft(load_scene("paper-fig3-dense"), 6)
    assert result.fields["x_m"].size > SCATTER_MAX
    ax_map, ax_prof = pressure_plot(result).axes[:2]
    assert len(ax_map.images) == 1 and ax_map.images[0].get_array().count() == \
        result.fields["x_m"].size  # every cell a pixel, nothing else
    assert any(isinstance(c, PolyCollection) for c in ax_prof.collections)  # the hexbin
    assert max(len(ln.get_xdata()) for ln in ax_prof.get_lines()) < SCATTER_MAX


def test_dense_map_draws_the_lattice_wedge_only_with_a_lattice():
    from bem_solver import solve_dense
    from pillar_xval.scenes import load_scene
    from validation.output.report import pressure_plot

    lattice = pressure_plot(solve_dense(load_scene("paper-fig3-sparse"), 5)).axes[0]
    flat = pressure_plot(solve_dense(load_scene("hertz"), 5)).axes[0]
    assert len(_lines(lattice, "-.")) == 2  # theta = 0 and pi/6: the primitive cell
    assert _lines(flat, "-.") == []  # no lattice, no wedge
    assert not lattice.images and lattice.collections  # rotated squares, as computed


def test_model_without_element_map_gets_one_panel_sized_to_the_pillar():
    from fakes import fake_fem
    from pillar_xval.scenes import load_scene
    from validation.output.report import pressure_plot

    scene = load_scene("single-pillar")
    fig = pressure_plot(fake_fem(scene, 1.0))
    (ax,) = fig.axes  # no empty panel
    assert ax.get_xlim()[1] == pytest.approx(1.05 * scene.pillars.diameter_m / 2 * 1e6)
    assert "µm" in ax.get_xlabel() and "kPa" in ax.get_ylabel()
    assert not any("NOT CONVERGED" in t.get_text() for t in fig.texts)


def test_not_converged_figures_say_so():
    from bem_solver import solve_fft
    from pillar_xval.scenes import load_scene
    from validation.output.report import pressure_plot

    result = solve_fft(load_scene("paper-fig3-sparse"), 8, max_iterations=2)
    assert not result.converged
    texts = [t.get_text() for t in pressure_plot(result).texts]
    assert "NOT CONVERGED" in texts
    assert any(result.diagnostics["message"] in t for t in texts)


def test_solve_hands_the_model_a_progress_callback(monkeypatch, capsys):
    """A model that reports progress gets the CLI's reporter; its lines go to stderr and
    stdout stays one JSON document."""
    import sys
    import types

    from fakes import register

    seen = []

    def slow_model(scene, elements_per_diameter=11, progress=None):
        seen.append(progress)
        from fakes import fake_bem

        return fake_bem(scene, elements_per_diameter)

    module = types.ModuleType("xval_slow")
    module.slow_model = slow_model
    monkeypatch.setitem(sys.modules, "xval_slow", module)
    register(monkeypatch, "bem", "xval_slow:slow_model", ("elements_per_diameter",))
    assert main(["solve", "--scene", "hertz", "--json"]) == 0
    assert callable(seen[0])
    json.loads(capsys.readouterr().out)


def test_progress_lines_of_a_long_solve():
    """Phases print as they come, iterations at most every `every_s`, a silent phase by a
    heartbeat; nothing in the first `after_s` seconds."""
    import io
    import time

    from validation.engine import SolveProgress

    stream = io.StringIO()
    with SolveProgress("solve x", stream=stream, every_s=0.2, after_s=0.0) as progress:
        progress("meshing")
        for k in range(1, 200):
            progress(k, 1.0 / k)
        time.sleep(0.5)
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("[solve x] meshing")
    assert any(ln.startswith("[solve x] iteration ") and "residual" in ln for ln in lines)
    assert 2 <= len(lines) <= 6  # throttled: 199 iterations, about 3 lines
    quiet = io.StringIO()
    with SolveProgress("y", stream=quiet, after_s=10.0) as progress:
        progress("meshing")
    assert quiet.getvalue() == ""


def test_a_reference_curve_that_does_not_apply_is_left_out(tmp_path, capsys):
    """A rigid lens has no rigid-punch curve: the report leaves it out, and the finished
    solve still writes its result (it once exited 2 with 'rigid punch limit needs an elastic
    lens' and no result.json)."""
    code = main(["solve", "--model", "fem-axisym", "--scene", "single-pillar",
                 "--set", "lens.rigid=true", "--json", "--out", str(tmp_path)])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["converged"] and (tmp_path / "result.json").is_file()
    assert (tmp_path / "pressure.png").read_bytes()[:4] == b"\x89PNG"


def test_fft_precision_from_the_cli(capsys):
    """--precision reaches the FFT model: 'double' runs no float32 application, the default
    'mixed' runs its steps in float32 and meets the same tolerance (F_T within the solver's
    tolerance times the problem's conditioning, ~1e2: 1e-6); a precision it lacks is refused
    in one line naming the option and the choices."""
    docs = {}
    for precision in ("double", "mixed"):
        assert main(["solve", "--scene", "paper-fig3-sparse", "--model", "bem-fft",
                     "--cells-per-diameter", "12", "--precision", precision, "--pillars",
                     "hooke", "--json"]) == 0
        docs[precision] = json.loads(capsys.readouterr().out)
    assert docs["double"]["diagnostics"]["single_precision_applications"] == 0
    assert docs["mixed"]["diagnostics"]["single_precision_applications"] > 0
    assert docs["mixed"]["converged"] and docs["double"]["converged"]
    assert docs["mixed"]["total_force_N"] == pytest.approx(docs["double"]["total_force_N"],
                                                           rel=1e-6)
    assert main(["solve", "--scene", "paper-fig3-sparse", "--model", "bem-fft",
                 "--precision", "single"]) != 0
    err = capsys.readouterr().err
    assert "--precision" in err and "mixed" in err and "double" in err


# --- which model answered --------------------------------------------------------------------
def fake_bem_pillars(scene, elements_per_diameter=11, cells="covered", contact="exact",
                     pillars="hooke"):
    """A fake dense BEM with a pillar model, which its result records as the BEMs do."""
    from fakes import CALLS, _result

    CALLS.append(("bem", pillars))
    result = _result("bem", scene, 1.0, {"elements_per_diameter": elements_per_diameter})
    if scene.pillars is not None:
        result.diagnostics["pillars"] = pillars
    return result


@pytest.fixture
def pillar_bem(fakes, monkeypatch):
    from fakes import register
    from validation.registry.options import CELLS, CONTACT, ELEMENTS_PER_DIAMETER, PILLARS

    register(monkeypatch, "bem", f"{__name__}:fake_bem_pillars",
             {"elements_per_diameter": ELEMENTS_PER_DIAMETER, "cells": CELLS,
              "contact": CONTACT, "pillars": PILLARS})
    return fakes


@pytest.mark.parametrize("sets, given, said", [
    ([], [], "bem, elastic pillars"),                     # elastic pillars: the elastic model
    (["pillars.rigid=true"], [], "bem, Hooke pillars"),   # rigid ones: the paper's spring
    ([], ["--pillars", "hooke"], "bem, Hooke pillars"),   # as asked
])
def test_the_pillar_model_defaults_to_the_scenes(pillar_bem, cli, sets, given, said):
    argv = ["solve", "--scene", "single-pillar", *given]
    for s in sets:
        argv += ["--set", s]
    code, out, err = cli(*argv)
    assert code == 0, err
    assert out.splitlines()[0].startswith(f"model            {said}  (")
    assert pillar_bem == [("bem", said.split(", ")[1].split()[0].lower())]


def test_auto_names_the_elastic_pillar_it_chose(pillar_bem, cli, monkeypatch):
    import importlib

    planner = importlib.import_module("validation.planner.plan")

    choice = {"model": "bem", "options": {"elements_per_diameter": 11, "pillars": "elastic"},
              "label": "bem P=11 elastic"}
    monkeypatch.setattr(planner, "plan", lambda *a, **k: {"choice": choice, "reason": "why"})
    monkeypatch.setattr(planner, "compact", lambda p: p)
    code, out, err = cli("solve", "--scene", "single-pillar", "--model", "auto")
    assert code == 0, err
    assert out.splitlines()[0].startswith("model            bem, elastic pillars  (")
    assert "auto: chose bem P=11 elastic: why" in out


def test_a_capped_moduli_contrast_is_said_in_the_result_and_its_summary():
    """E_p/E_s = 1e9 was modelled as 1e6 without a word."""
    from bem_solver._elastic_pillar import pillar_record
    from fem_reference import PillarKind
    from pillar_xval.scenes import load_scene

    scene = load_scene("single-pillar", ["pillars.E_Pa=1.6e15"])
    record = pillar_record(scene, "elastic", PillarKind.of_scene(scene))
    assert record["pillars"] == "elastic"
    (note,) = record["notes"]
    assert note.startswith("E_p/E_s = 1e+09 modelled as E_p/E_s = 1e+06")
    assert "notes" not in pillar_record(load_scene("single-pillar"), "elastic",
                                        PillarKind.of_scene(load_scene("single-pillar")))
    result = ContactResult(model="bem", scene=scene.to_dict(), discretisation={},
                           total_force_N=1.0, centre_pressure_Pa=1.0, contact_radius_m=1.0,
                           real_contact_area_m2=1.0, pillars_in_contact=1, pillar_forces=[],
                           converged=True, iterations=1, wall_time_s=0.0, diagnostics=record)
    assert f"note             {note}" in result.summary()
    assert result.summary().startswith("model            bem, elastic pillars  (")


def test_the_pillar_default_is_the_same_on_either_device():
    """The elastic pillar's default on elastic pillars holds on --device gpu too (it runs
    there); a model asked for is kept."""
    from pillar_xval.scenes import load_scene
    from validation.registry import scene_defaults

    scene = load_scene("single-pillar")
    assert scene_defaults("bem-fft", scene, {"device": "gpu"})["pillars"] == "elastic"
    assert scene_defaults("bem-fft", scene, {"device": "cpu"})["pillars"] == "elastic"
    assert scene_defaults("bem-fft", scene, {"device": "gpu", "pillars": "hooke"}) == \
        {"device": "gpu", "pillars": "hooke"}  # as asked
