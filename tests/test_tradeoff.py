"""``pillar-xval tradeoff``: ladders, Richardson references, outputs."""

from __future__ import annotations

import csv
import json

import pytest

from pillar_xval.scenes import load_scene
from validation.registry import Ladder, OptionSpec, ladders
from validation.studies._ladder import reference_values
from validation.studies.tradeoff import tradeoff, write_outputs


def _ladder(option, rungs):
    return Ladder(option, rungs[0], 2.0, "int", -1.0, tuple(rungs))


def _rows(model, levels, values):
    return [{"model": model, "level": n, "h": 1.0 / n, "converged": True, "wall_time_s": n,
             "F_T": f, "sigma0": f, "a": f, "A": f} for n, f in zip(levels, values)]


def test_reference_is_richardson_of_the_tightest_model():
    # f = 1 + h (first order) for one model, f = 1 + 0.1 h^2 for the other: both extrapolate
    # to 1; the second has the smaller band and is chosen.
    rows = _rows("coarse", (4, 8, 16), [1 + 1 / n for n in (4, 8, 16)])
    rows += _rows("fine", (4, 8, 16), [1 + 0.1 / n**2 for n in (4, 8, 16)])
    ref = reference_values(rows)["F_T"]
    assert ref["status"] == "richardson" and ref["model"] == "fine"
    assert ref["value"] == pytest.approx(1.0, rel=1e-12)
    assert ref["order"] == pytest.approx(2.0, rel=1e-9)


def test_models_of_other_physics_get_their_own_reference():
    from validation.studies.tradeoff import physics_group

    pillars, flat = load_scene("single-pillar"), load_scene("hertz")
    assert physics_group("bem", pillars) == physics_group("bem-fft", pillars)
    assert physics_group("fem-axisym", pillars) != physics_group("bem", pillars)
    assert physics_group("fem-axisym", flat) == physics_group("bem", flat)


def test_reference_falls_back_to_the_most_expensive_solution():
    rows = _rows("m", (4, 8), [1.5, 1.25])
    ref = reference_values(rows)["F_T"]
    assert ref["value"] == 1.25 and ref["order"] is None


def test_every_registered_ladder_names_a_model():
    from validation.registry import MODELS

    for name, ladder in ladders().items():
        assert name in MODELS
        sizes = [ladder.size(level) for level in ladder.rungs]
        assert sizes == sorted(sizes, reverse=True)  # coarse to fine
        assert ladder.option in MODELS[name].options


def test_tradeoff_writes_csv_json_png(tmp_path):
    scene = load_scene("single-pillar")
    ladders = {"bem-fft": _ladder("cells_per_diameter", (8, 16, 32))}
    doc = tradeoff(scene, ["bem-fft"], repeats=2, ladders=ladders)
    assert [r["level"] for r in doc["rows"]] == [8, 16, 32]
    assert doc["references"]["hooke-pillar"]["F_T"]["status"] == "richardson"
    for row in doc["rows"]:
        assert row["wall_time_s"] > 0 and row["peak_memory_MB"] > 0 and row["converged"]
    errors = [r["err_F_T"] for r in doc["rows"]]
    assert errors == sorted(errors, reverse=True)  # refinement buys accuracy
    write_outputs(doc, tmp_path)
    with open(tmp_path / "tradeoff.csv") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == 3 and float(table[-1]["err_F_T"]) == pytest.approx(errors[-1])
    assert json.loads((tmp_path / "tradeoff.json").read_text())["scene"]["name"] == \
        "single-pillar"
    assert (tmp_path / "tradeoff.png").stat().st_size > 1000


def test_cli_tradeoff(tmp_path, capsys):
    from validation.cli import main

    code = main(["tradeoff", "--scene", "single-pillar", "--models", "bem-fft",
                 "--pillars", "hooke", "--repeats", "1", "--out", str(tmp_path)])
    assert code == 0
    out = capsys.readouterr()
    assert "bem-fft" in out.out and "references (hooke-pillar):" in out.out
    assert "[tradeoff] " in out.err and "bem-fft" in out.err  # progress lines on stderr
    assert (tmp_path / "tradeoff.csv").exists()


def test_cli_tradeoff_rejects_unknown_model(tmp_path):
    from validation.cli import main

    assert main(["tradeoff", "--scene", "single-pillar", "--models", "nope",
                 "--out", str(tmp_path)]) == 2


def refusing_model(scene, **kwargs):
    raise ValueError("this model needs a flat scene")


def test_a_model_that_refuses_the_scene_is_skipped(monkeypatch):
    from fakes import register

    register(monkeypatch, "refuser", f"{__name__}:refusing_model", options={"n": OptionSpec(int)})
    ladders = {"refuser": _ladder("n", (1, 2)),
               "bem-fft": _ladder("cells_per_diameter", (8, 12, 16))}
    doc = tradeoff(load_scene("single-pillar"), ["refuser", "bem-fft"], repeats=1,
                   ladders=ladders)
    assert "refused" in doc["skipped"]["refuser"]
    assert {r["model"] for r in doc["rows"]} == {"bem-fft"}


def test_pareto_front_is_the_set_nothing_beats():
    from validation.output.plots import pareto_front

    points = [(1.0, 0.1), (2.0, 0.2), (2.0, 0.05), (3.0, 0.05), (4.0, 0.01), (0.5, 0.5)]
    # (2, 0.2) is beaten by (1, 0.1); (3, 0.05) by (2, 0.05); the rest are each best so far
    assert sorted(pareto_front(points)) == [0, 2, 4, 5]


def test_tradeoff_figure_marks_the_front_labels_rungs_and_crosses_misses(tmp_path,
                                                                          monkeypatch):
    import matplotlib.pyplot as plt

    from validation.output import plots

    rows = [{"model": "bem", "option": "elements_per_diameter", "level": n, "h": 1 / n,
             "wall_time_s": 0.01 * n, "converged": n != 9, "err_F_T": 1.0 / n**2,
             "err_sigma0": 1.0 / n, "err_a": None, "err_A": 1e-6}
            for n in (5, 7, 9)]
    doc = {"models": ["bem"], "rows": rows, "scene": {"name": "s"},
           "references": {"hooke-pillar": {q: {"model": "bem"} for q in
                                           ("F_T", "sigma0", "a", "A")}}}
    figures = []
    monkeypatch.setattr(plots, "save_figure", lambda fig, path, *a, **k: figures.append(fig))
    plots.plot_tradeoff(doc, tmp_path / "t.png")
    fig = figures[0]
    ax = fig.axes[0]
    assert sorted(t.get_text() for t in ax.texts) == ["P=5", "P=7", "P=9"]
    assert any(ln.get_label() == "Pareto front" for ln in ax.get_lines())
    assert any(ln.get_marker() == "x" for ln in ax.get_lines())  # P = 9 did not converge
    assert "NOT CONVERGED" in [t.get_text() for t in fig.texts]
    assert "every rung equals the reference" in fig.axes[2].texts[0].get_text()
    plt.close(fig)


# --- the pillar model decides the physics --------------------------------------------------
def test_the_elastic_pillar_is_the_physics_of_an_elastic_case():
    from validation.registry import MODELS
    from validation.studies.tradeoff import physics_group

    pillars, flat = load_scene("single-pillar"), load_scene("hertz")
    for name in ("bem", "bem-fft", "bem-richardson"):
        model = MODELS[name]
        assert model.physics_of() == model.physics_of({"pillars": "hooke"}) == "hooke-pillar"
        assert model.physics_of({"pillars": "elastic"}) == "elastic-pillar"
        assert model.physics_of({"pillars": None}) == "hooke-pillar"  # left to its default
        assert physics_group(name, pillars, {"pillars": "elastic"}) == \
            physics_group("fem-axisym", pillars)
        assert physics_group(name, pillars, {"pillars": "elastic"}) != \
            physics_group(name, pillars)
        assert physics_group(name, flat, {"pillars": "elastic"}) == "half-space"
    # a model without the option keeps its own physics whatever the case says
    assert MODELS["fem-3d"].physics_of({"pillars": "hooke"}) == "elastic-pillar"


def fake_fft(scene, cells_per_diameter=32, pillars="hooke"):
    from fakes import CALLS, _result

    CALLS.append(("bem-fft", cells_per_diameter, pillars))
    bias = 1.0 if pillars == "elastic" else 1.02  # first order, as bem-fft's declaration
    return _result("bem-fft", scene, bias * (1.0 + 0.5 / cells_per_diameter),
                   {"cells_per_diameter": cells_per_diameter})


@pytest.fixture
def fft_fake(monkeypatch):
    from fakes import CALLS, register

    register(monkeypatch, "bem-fft", f"{__name__}:fake_fft",
             ("cells_per_diameter", "pillars"))
    CALLS.clear()
    return CALLS


def test_cli_tradeoff_with_elastic_pillars_has_its_own_reference(fft_fake, tmp_path, cli):
    code, out, err = cli("tradeoff", "--scene", "single-pillar", "--models", "bem-fft",
                         "--pillars", "elastic", "--cells-per-diameter", "8", "--levels", "3",
                         "--repeats", "1", "--executor", "serial", "--out", tmp_path)
    assert code == 0, err
    assert fft_fake == [("bem-fft", n, "elastic") for n in (8, 12, 16)]  # the ladder's rungs
    doc = json.loads((tmp_path / "tradeoff.json").read_text())
    assert {r["physics"] for r in doc["rows"]} == {"elastic-pillar"}
    assert {r["pillars"] for r in doc["rows"]} == {"elastic"}
    assert list(doc["references"]) == ["elastic-pillar"] and doc["options"] == \
        {"pillars": "elastic"}
    # the elastic fake's limit is the spring force (the Hooke one's is 2 % above)
    from pillar_xval.scenes import analytic

    spring = analytic.spring_model(load_scene("single-pillar"))
    assert doc["references"]["elastic-pillar"]["F_T"]["value"] == \
        pytest.approx(spring.force, rel=1e-9)
    assert "references (elastic-pillar):" in out and "hooke-pillar" not in out
    with open(tmp_path / "tradeoff.csv") as fh:
        assert {r["physics"] for r in csv.DictReader(fh)} == {"elastic-pillar"}


def test_tradeoff_never_mixes_the_two_pillar_models(fft_fake):
    """The same model at both pillar models (two runs) gets two references, each its own
    limit; the default run stays in the Hooke group."""
    scene = load_scene("single-pillar")
    ladders = {"bem-fft": _ladder("cells_per_diameter", (8, 16, 32))}
    hooke = tradeoff(scene, ["bem-fft"], repeats=1, ladders=ladders)
    elastic = tradeoff(scene, ["bem-fft"], repeats=1, ladders=ladders,
                       options={"pillars": "elastic"})
    assert list(hooke["references"]) == ["hooke-pillar"]
    assert list(elastic["references"]) == ["elastic-pillar"]
    ratio = hooke["references"]["hooke-pillar"]["F_T"]["value"] / \
        elastic["references"]["elastic-pillar"]["F_T"]["value"]
    assert ratio == pytest.approx(1.02, rel=1e-9)


def test_cli_tradeoff_refuses_a_bad_pillar_model(fft_fake, tmp_path, cli):
    code, _, err = cli("tradeoff", "--scene", "single-pillar", "--models", "bem-fft",
                       "--pillars", "spring", "--out", tmp_path)
    assert code == 2 and "--pillars" in err and "'spring'" in err
    assert "hooke" in err and "elastic" in err and len(err.strip().splitlines()) == 1
    code, _, err = cli("tradeoff", "--scene", "single-pillar", "--models", "fem-axisym",
                       "--pillars", "elastic", "--out", tmp_path)
    assert code == 2 and "--pillars elastic: does not apply to --model fem-axisym" in err
    assert fft_fake == []
